"""A winner named only outside the noise: margins, their intervals, the contenders' rounds.

The interval of a margin (harness/ranking/margin.py) names a winner when it lies
above 1 and a tie otherwise; the report's answer, the run's summary and the
ranking's ``cheapest`` say the same of the same records; a case at the budget's
edge is no point of any line; and the contenders' rounds (harness/contend,
harness/run/resample.py) time the lines in contention again, store the records
anew and survive a block whose process dies.
"""

from __future__ import annotations

import json
import math
import os
import signal

import numpy as np
import pandas as pd
import pytest

from integrator_bench.harness.cli.summary import summary
from integrator_bench.harness.contend.rounds import Contention, open_contests, settle
from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.matrix.record import BUDGET_EDGE
from integrator_bench.harness.matrix.store import Store, load
from integrator_bench.harness.ranking import margin, reach
from integrator_bench.harness.ranking.cost import by_cost
from integrator_bench.harness.ranking.records import clean_records
from integrator_bench.harness.report.sections import answer
from integrator_bench.harness.run import resample
from integrator_bench.harness.run.execution import budget_edge
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits
from records_frame import records_frame


def noisy(centre, n=12, spread=0.1, seed=0):
    """``n`` lognormal samples around ``centre``."""
    return centre * np.exp(spread * np.random.default_rng(seed).standard_normal(n))


# --- the interval --------------------------------------------------------------------------

def test_a_clear_margin_names_a_winner():
    got = margin.margin("B", noisy(1.0, seed=1), noisy(1.5, seed=2))
    assert got.measured and got.clear and got.low > 1 and got.n == 12
    assert margin.verdict([got]) == "winner"


def test_a_margin_inside_the_noise_names_a_tie():
    got = margin.margin("B", noisy(1.0, seed=1, spread=0.3), noisy(1.03, seed=2, spread=0.3))
    assert got.measured and got.low < 1 < got.high and not got.clear
    assert margin.verdict([got]) == "tie"
    # the same gap with little noise is clear
    assert margin.margin("B", noisy(1.0, seed=1, spread=0.005),
                         noisy(1.03, seed=2, spread=0.005)).clear


def test_too_few_samples_give_no_interval():
    got = margin.margin("B", noisy(1.0, n=3), noisy(1.5, n=3))
    assert not got.measured and "not measured" in got.text()
    assert margin.verdict([got]) == "tie"                 # the noise may reverse it


def test_the_interval_is_the_same_for_the_same_samples():
    a, b = noisy(1.0, seed=3, spread=0.2), noisy(1.2, seed=4, spread=0.2)
    assert margin.margin("B", a, b) == margin.margin("B", a, b)


def test_samples_are_paired_from_the_end():
    got = margin.crossing_samples(np.array([8.0, 1.0, 4.0]), np.array([1.0, 16.0]), 0.5)
    assert got == pytest.approx([1.0, 8.0])     # (1, 1) and (4, 16)
    assert margin.crossing_samples(None, np.array([1.0]), math.nan) == pytest.approx([1.0])
    assert margin.crossing_samples(None, np.array([1.0]), 0.5) is None


# --- one answer from one set of records ----------------------------------------------------

def lines_frame(cpus: dict, spread=0.02, n=12, **fields) -> pd.DataFrame:
    """Records of two_mass: per integrator a line of two points (errors 1e-4 and
    1e-6) whose timed solves are ``n`` samples around ``cpus[name]`` and twice it."""
    rows = []
    for k, (name, cpu) in enumerate(cpus.items()):
        for i, (err, factor) in enumerate(((1e-4, 1.0), (1e-6, 2.0))):
            s = noisy(cpu * factor, n=n, spread=spread, seed=10 * k + i)
            rows.append(dict(problem="two_mass", formulation="ode", integrator=name,
                             rtol=10.0 ** -(3 + 3 * i), status="ok", err_max=err,
                             mescd=-math.log10(err), cpu_s=float(np.median(s)),
                             cpu_samples=json.dumps(list(s)), repeat=n,
                             case_id=f"{name}-{i}", created="2026-01-01T00:00:00+00:00",
                             **fields))
    return clean_records(records_frame(rows))


@pytest.mark.parametrize("cpus, verdict", [
    ({"scipy-RK45": 1.0, "scipy-DOP853": 1.4, "scipy-RK23": 5.0}, "winner"),
    ({"scipy-RK45": 1.0, "scipy-DOP853": 1.01, "scipy-RK23": 5.0}, "tie"),
])
def test_report_summary_and_ranking_say_the_same(cpus, verdict):
    records = lines_frame(cpus, spread=0.1)
    top = reach.cheapest(reach.target_table(records), reach.DEFAULT_TARGET)
    assert top["verdict"] == verdict
    said = answer(reach.target_table(records))
    assert said.verdict == verdict
    said_lines = summary(records).splitlines()
    at = next(i for i, x in enumerate(said_lines) if x.startswith("two_mass"))
    line = " ".join([said_lines[at]] + [x.strip() for x in said_lines[at + 1:at + 3]
                                        if x.startswith(" ")])
    if verdict == "tie":
        assert said.lines == f"tie: {', '.join(top['tied'])}"
        assert "scipy-RK23" not in said.lines
        assert "tie: " + ", ".join(f"{t['label']}/{t['formulation']}"
                                   for t in top["tied_lines"]) in line
    else:
        assert said.lines == f"{top['label']} ({top['formulation']})" == "scipy-RK45 (ode)"
        assert line.split()[-1] != "tie:" and "scipy-RK45/ode" in line
    # the margin and its interval, in the same words
    assert said.why in summary(records)


def test_a_line_beyond_twice_the_cheapest_is_out_of_contention():
    top = reach.cheapest(reach.target_table(lines_frame({"scipy-RK45": 1.0, "scipy-RK23": 3.0},
                                                        n=1)), reach.DEFAULT_TARGET)
    assert top["verdict"] == "winner" and top["margins"] == []
    assert top["runner_up"]["margin"] is None and "runner-up 3x" in reach.answer_text(top)


def test_work_is_exact_so_its_margin_needs_no_samples():
    records = lines_frame({"scipy-RK45": 1.0, "scipy-DOP853": 1.01}, n=1)
    records = records.assign(work=[1.0, 2.0, 1.2, 2.4])
    top = reach.cheapest(reach.target_table(by_cost(records, "work")), reach.DEFAULT_TARGET)
    assert top["verdict"] == "winner" and top["margins"][0].low == pytest.approx(1.2)


def test_two_wrappers_of_one_code_that_tie_are_said_to_be_one_code():
    codes = {}
    for name, cls in registry.integrators().items():
        if cls.code and cls.accepts & {"ode"}:
            codes.setdefault(cls.code, []).append(name)
    pairs = [names[:2] for names in codes.values() if len(names) > 1]
    if not pairs:
        pytest.skip("no two registered integrators run one code (Assimulo absent)")
    a, b = pairs[0]
    top = reach.cheapest(reach.target_table(lines_frame({a: 1.0, b: 1.0}, spread=0.2)),
                         reach.DEFAULT_TARGET)
    assert top["verdict"] == "tie"
    assert " are one code, " in reach.answer_text(top)
    assert registry.integrators()[a].code in reach.answer_text(top)


# --- the budget's edge ----------------------------------------------------------------------

def test_an_ok_case_at_the_budget_edge_is_no_point():
    assert budget_edge({"status": "ok", "budget_s": 2.5, "cpu_samples": "[2.4, 1.0]"}) == 1
    assert budget_edge({"status": "ok", "budget_s": 2.5, "cpu_samples": "[1.0, 2.4]"}) == 0
    assert budget_edge({"status": "timeout", "budget_s": 2.5, "cpu_samples": None}) is None
    assert BUDGET_EDGE == 0.1
    records = lines_frame({"scipy-RK45": 1.0, "scipy-DOP853": 1.5})
    edge = records.assign(budget_edge=[1, 0, 0, 0])      # RK45's loose point at the edge
    assert reach.cheapest(reach.target_table(records), 1e-5)["label"] == "scipy-RK45"
    table = reach.target_table(edge)
    assert table.set_index("label").loc["scipy-RK45", "how_1e-05"] == "at most"
    assert "budget's edge: 1 ok within 10 % of it" in summary(edge)


# --- the contenders' rounds -----------------------------------------------------------------

@pytest.fixture(scope="module")
def run_store(tmp_path_factory, run_cases):
    """A matrix of two_mass's first set, two explicit codes at two tolerances, one
    of them twice (a step bound above the span changes nothing it does: a contest
    whatever the noise), timed once per case, in a store."""
    path = tmp_path_factory.mktemp("contend") / "store.sqlite"
    cases = expand(problems=["two_mass"], formulations=["ode"],
                   integrators=["scipy-DOP853", "scipy-DOP853:max_step=1000", "scipy-RK45"],
                   rtols=[1e-3, 1e-6])
    cases = [c for c in cases if c.params == cases[0].params]
    df = run_cases(cases, RunContext(store=path, jobs=1, progress=False, limits=Limits(repeat=1)))
    return path, cases, df


def test_the_contenders_are_timed_again_and_stored_anew(run_store):
    path, cases, df = run_store
    assert (df["status"] == "ok").sum() >= 4
    # the twin lines as one sample each left them, within the noise of each other
    twin = df["integrator"] == "scipy-DOP853"
    df = df.assign(cpu_s=df.groupby(["rtol", twin])["cpu_s"].transform("first"))
    df = df.assign(cpu_samples=[json.dumps([c]) for c in df["cpu_s"]])
    with Store(path) as store:
        got = settle(df, cases, store.add, Contention(targets=(1e-3,), cpu_cap_s=30.0, jobs=2))
    retimed = got.records[got.records["contended"].notna()]
    assert got.retimed == len(retimed) > 0 and got.blocks >= 1 and got.cpu_s > 0
    for _, r in retimed.iterrows():
        samples = json.loads(r["cpu_samples"])
        assert len(samples) == 1 + r["contended"] and r["repeat"] == len(samples)
        assert r["cpu_s"] == pytest.approx(float(np.median(samples)))
    stored = load(path)
    assert len(stored) > len(df) and set(df["case_id"]) <= set(stored["case_id"])
    assert len(stored) - len(df) >= got.retimed           # every version kept
    newest = clean_records(stored).set_index("case_id")
    assert newest.loc[retimed["case_id"], "contended"].notna().all()
    # settled or capped: what is left open has its rounds, or the cap was reached
    still = open_contests(clean_records(got.records), (1e-3,))
    assert not still or "reached" in got.stopped


def test_no_block_starts_past_the_cap(run_store):
    _, cases, df = run_store
    got = settle(df, cases, None, Contention(targets=(1e-3,), cpu_cap_s=0.0))
    assert got.blocks == 0 and got.retimed == 0
    assert got.contests == 0 or "CPU cap" in got.stopped


def test_a_block_whose_process_dies_gives_no_samples_and_the_rest_go_on(run_store,
                                                                        monkeypatch):
    _, cases, _ = run_store
    good = resample.Block(tuple(cases[:1]), 2, 5.0)
    real = resample.time_block

    def dies(block):
        if block is not good:
            os.kill(os.getpid(), signal.SIGSEGV)
        return real(block)
    monkeypatch.setattr(resample, "time_block", dies)
    bad = resample.Block(tuple(cases[1:2]), 2, 5.0)
    got = {id(block): result for block, result, _ in resample.run_blocks([bad, good], jobs=2)}
    assert isinstance(got[id(bad)], str) and "died" in got[id(bad)]
    assert len(got[id(good)][cases[0].case_id]) == 2


def test_a_contest_gets_its_next_block_as_its_last_one_ends(run_store):
    _, cases, _ = run_store
    first = resample.Block(tuple(cases[:1]), 1, 5.0)
    asked = []

    def then(block, result, cpu_s):
        asked.append((block, cpu_s))
        return [resample.Block(tuple(cases[:1]), 1, 5.0)] if len(asked) < 3 else []
    got = resample.run_blocks([first], jobs=1, then=then)
    assert len(got) == 3 and got[0][0] is first and all(c > 0 for _, c in asked)
