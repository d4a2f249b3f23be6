"""``ibench advise`` names a winner only outside the noise: its verdict is the
report's (:func:`~integrator_bench.harness.ranking.reach.cheapest`) on the same
records, a clear margin names a winner, a margin inside the noise a tie, and the
contenders are timed again before it answers."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from integrator_bench.harness.advise import advice, certificate, page, search
from integrator_bench.harness.advise.candidates import Candidate
from integrator_bench.harness.advise.evidence import LineEntry, Run
from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.store import load
from integrator_bench.harness.paths import REFERENCE_DIR
from integrator_bench.harness.ranking import reach
from integrator_bench.harness.ranking.records import clean_records
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.execution import base_record
from integrator_bench.harness.run.runner import Session, to_dataframe

TARGET = 1e-5
#: the timed solves of the cheapest line's run below the target, in ms: a spread of 8 %
BASE = np.array([1.00, 1.03, 0.98, 1.05, 0.97, 1.02, 0.99, 1.01, 1.04, 0.96])
#: the other line's samples over the cheapest's, solve by solve: 1.5 times (clearly
#: slower), or within 2 % either way (inside the noise: its interval holds 1)
CLEAR = 1.5 * np.array([1.02, 0.97, 1.01, 0.99, 1.03, 0.98, 1.0, 1.02, 0.97, 1.01])
NOISE = np.array([1.01, 0.99, 1.02, 0.98, 1.0, 1.015, 0.99, 1.005, 0.985, 1.01])
#: two wrappers of one library code (SUNDIALS CVODE, Adams), and an explicit code 3x dearer
CHEAPEST, OTHER, FAR = "assimulo-cvode-adams", "cvode-adams", "scipy-DOP853"


def _problem():
    return registry.get_problem_class("two_mass")()


#: each line's runs above and below the target, as shares of its run below's CPU
RUNS = ((1e-3, 3 * TARGET, 0.5), (1e-4, 0.5 * TARGET, 1.0))
#: the other line crosses the target cheaper (interpolated between its runs either
#: side: 0.3^0.39 1.1^0.61 = 0.67 against 0.77) though its run below it costs more
CROSSING = ((1e-3, 3 * TARGET, 0.3), (1e-4, 0.5 * TARGET, 1.1))


def _records(problem, ratio, other_runs=RUNS):
    """Made-up search records: each line a run above the target (rtol 1e-3, error 3
    times it, half the CPU) and one below (rtol 1e-4, error half of it), each with
    its timed solves; the other line's samples are the cheapest's times ``ratio``
    (its runs ``other_runs``), the explicit line's 3 times."""
    scale = {CHEAPEST: np.ones(len(BASE)), OTHER: ratio, FAR: 3.0 * np.ones(len(BASE))}
    cands, cases, rows = [], [], []
    for name, family in ((CHEAPEST, "implicit"), (OTHER, "implicit"), (FAR, "explicit")):
        cand = Candidate("ode", name, (), family)
        cands.append(cand)
        for rtol, err, cost in other_runs if name == OTHER else RUNS:
            case = cand.case(problem, rtol)
            cpus = 1e-3 * cost * BASE * scale[name]
            cases.append(case)
            rows.append({**base_record(case), "status": "ok", "err_max": err,
                         "mescd": -np.log10(err), "cpu_s": float(np.median(cpus)),
                         "cpu_samples": json.dumps(cpus.tolist()), "repeat": len(cpus),
                         "created": "2026-12-01T00:00:00+00:00"})
    return cands, cases, to_dataframe(rows)


def _made_up_advice(monkeypatch, tmp_path, ratio, other_runs=RUNS):
    """An advice on two_mass to 1e-5 whose search is :func:`_records` and whose
    robustness runs are made up (every run on a perturbed set ok, at 0.3 times the
    target): every line checked holds."""
    problem = _problem()
    cands, cases, records = _records(problem, ratio, other_runs)
    refs = tmp_path / "refs"
    shutil.copytree(Path(REFERENCE_DIR) / "two_mass", refs / "two_mass")

    def made_up_search(problem, given, target, measure, budget_s, session, **kw):
        return search.SearchResult([search.Line(c, calibrated=True) for c in cands],
                                   records, target, measure, rounds=2, cases=len(cases),
                                   ran=list(cases))

    def perturbed(self, cases, **kw):
        return to_dataframe([{**base_record(c), "status": "ok", "err_max": 0.3 * TARGET,
                              "cpu_s": 1e-3} for c in cases])

    monkeypatch.setattr(advice.search, "search", made_up_search)
    monkeypatch.setattr(Session, "run", perturbed)
    answer = advice.advise(problem, advice.Question(TARGET, budget_s=120.0,
                                                    integrators=[CHEAPEST, OTHER, FAR]),
                           RunContext(reference_dir=refs, jobs=1, progress=False))
    return answer, records


@pytest.mark.parametrize("ratio, verdict, tied", [
    (CLEAR, "winner", ()),
    (NOISE, "tie", (f"{CHEAPEST} (ode)", f"{OTHER} (ode)")),
])
def test_a_clear_margin_names_a_winner_and_one_inside_the_noise_a_tie(
        monkeypatch, tmp_path, ratio, verdict, tied):
    answer, _ = _made_up_advice(monkeypatch, tmp_path, ratio)
    assert answer.status == "answer", answer.why
    assert answer.winner.label == CHEAPEST and answer.runner_up.label == OTHER
    assert (answer.verdict, answer.tied) == (verdict, tied)
    m = answer.margin
    assert m.line == f"{OTHER} (ode)" and m.paired == len(BASE)
    assert m.ratio == pytest.approx(np.median(ratio), rel=0.02)
    assert (m.low > 1) is (verdict == "winner") and (m.tie is (verdict == "tie"))
    # the samples decide already: nothing is timed again
    assert answer.contenders.contests == 0 and answer.contenders.retimed == 0
    last = page.text(answer).splitlines()[-1]
    assert last.startswith(f"use {CHEAPEST} (default settings) on formulation ode at rtol ")
    assert last.endswith("; verified on 2 perturbed sets")
    interval = f"95 % {m.low:.3g}-{m.high:.3g}"
    if verdict == "winner":
        assert f"; the winner (margin {m.ratio:.3g} over {OTHER} (ode), {interval});" in last, \
            last
        assert answer.same_code == {}
    else:
        assert f"; tie: {CHEAPEST} (ode), {OTHER} (ode) (margin {m.ratio:.3g}, {interval}); " \
               f"{CHEAPEST} (ode) and " \
               f"{OTHER} (ode) are one code, SUNDIALS CVODE (Adams);" in last, last
        assert list(answer.same_code) == ["SUNDIALS CVODE (Adams)"]
    rows = {r.split()[1]: r for r in page.table(answer)[1:]}
    assert rows[OTHER].endswith(" tie" if verdict == "tie" else " runner-up")
    assert rows[CHEAPEST].endswith(" winner" if verdict == "winner" else " tie, advised")
    got = json.loads(json.dumps(answer.to_dict(), default=str))
    assert (got["verdict"], got["tied"]) == (verdict, list(tied))
    assert got["margin"]["low"] == m.low and got["margin"]["tie"] is m.tie


@pytest.mark.parametrize("ratio, other_runs, named", [
    (CLEAR, RUNS, CHEAPEST), (NOISE, RUNS, CHEAPEST), (np.ones(len(BASE)), CROSSING, OTHER),
], ids=["clear", "noise", "crossing"])
def test_the_advice_and_the_reports_rule_name_the_same_answer(monkeypatch, tmp_path, ratio,
                                                              other_runs, named):
    """On the same records, the advice and :func:`reach.cheapest` (the report's answer
    and the run's summary) name the same line, verdict, tie and margin; also where
    the line whose run below the target is the cheaper one crosses the target dearer
    (the advice's ranking by that run named it before)."""
    answer, records = _made_up_advice(monkeypatch, tmp_path, ratio, other_runs)
    top = reach.cheapest(reach.target_table(clean_records(records), (TARGET,), "max"), TARGET)
    assert answer.winner.label == named
    assert (top["label"], top["formulation"]) == answer.winner.key
    assert (top["verdict"], tuple(top["tied"])) == (answer.verdict, answer.tied)
    assert top["runner_up"]["line"] == answer.margin.line
    assert top["runner_up"]["margin"].low == answer.margin.low
    # the ranks are the report's table's order
    table = reach.target_table(clean_records(records), (TARGET,), "max")
    assert [e.label for e in answer.lines if e.rank] == list(table["label"])


def test_a_line_re_tightened_on_the_perturbed_sets_counts_from_its_tighter_run():
    """The cheapest line missed on a perturbed set and held a decade tighter: its
    looser records leave the verdict, its tighter run is its CPU to the target (an
    upper bound), and the other line, cheaper than that, is named."""
    problem = _problem()
    cands, cases, records = _records(problem, CLEAR)
    tighter = cands[0].case(problem, 1e-5)
    slow = 1e-3 * 2.0 * BASE
    records = to_dataframe([*records.to_dict("records"), {
        **base_record(tighter), "status": "ok", "err_max": 0.1 * TARGET, "cpu_s": 2e-3,
        "cpu_samples": json.dumps(slow.tolist()), "created": "2026-12-01T00:00:01+00:00"}])
    first = LineEntry(CHEAPEST, "ode", "implicit", run=Run(1e-5, 0.1 * TARGET, 2e-3,
                                                           case_id=tighter.case_id),
                      retightened_from=1e-4)
    second = LineEntry(OTHER, "ode", "implicit", run=Run(1e-4, 0.5 * TARGET, 1.5e-3))
    top = certificate.verdict(records, [first, second], TARGET, "max")
    assert (top["label"], top["verdict"]) == (OTHER, "winner")
    row = top["table"].set_index("label").loc[CHEAPEST]
    assert row["how_1e-05"] == "at most" and row["cpu_1e-05"] == pytest.approx(2e-3)
    # not re-tightened, the same line is the cheapest again
    again = certificate.verdict(records, [LineEntry(CHEAPEST, "ode", "implicit"), second],
                                TARGET, "max")
    assert again["label"] == CHEAPEST


def test_a_small_advice_times_its_contenders_and_agrees_with_the_report(tmp_path):
    """A real advice on two_mass (two wrappers of CVODE-Adams and DOP853, no perturbed
    sets): its answer is :func:`reach.cheapest`'s on the store's records of it (the
    report's and the summary's rule), its contenders' records timed again are stored,
    superseding, and it says what that cost."""
    refs = tmp_path / "data" / "reference"
    shutil.copytree(Path(REFERENCE_DIR) / "two_mass", refs / "two_mass")
    env = {**os.environ, "IBENCH_DATA_DIR": str(tmp_path / "data"),
           "IBENCH_REFERENCE_DIR": str(refs)}
    store = tmp_path / "s.sqlite"
    got = subprocess.run(
        [sys.executable, "-m", "integrator_bench.harness.cli", "advise", "-p",
         "two_mass:score=x1", "--target", "1e-5", "-i", CHEAPEST, "-i", OTHER, "-i", FAR,
         "--perturbed", "0", "--budget", "90s", "--store", str(store), "--json",
         "--jobs", "2", "--out", str(tmp_path / "page")],
        capture_output=True, text=True, env=env, timeout=300)
    assert got.returncode == 0, got.stderr
    answer = json.loads(got.stdout)
    rows = clean_records(load(store))
    top = reach.cheapest(reach.target_table(rows, (1e-5,), "max"), 1e-5)
    assert (top["label"], top["formulation"]) == (answer["winner"]["integrator"],
                                                  answer["winner"]["formulation"])
    assert (top["verdict"], top["tied"]) == (answer["verdict"], answer["tied"])
    assert answer["verdict"] in ("winner", "tie")
    contenders = answer["contenders"]
    assert contenders["cap_s"] > 0 and contenders["cpu_s"] <= answer["cost"]["cpu_s"]
    retimed = rows[rows["contended"].fillna(0) > 0]     # the newest of each case
    assert (len(retimed) > 0) is (contenders["retimed"] > 0)
    assert len(retimed) <= contenders["retimed"]
    assert (len(load(store)) > len(rows)) is (contenders["retimed"] > 0)


@pytest.mark.parametrize("pool, samples, verdict, words, tie, up", [
    ((CHEAPEST, OTHER), False, "tie", f"tie: {CHEAPEST} (ode), {OTHER} (ode) (margin 1.49, "
     f"interval not measured); {CHEAPEST} (ode) and {OTHER} (ode) are one code, SUNDIALS "
     "CVODE (Adams)", True, f"runner-up: {OTHER} (ode): margin 1.49, interval not measured "
     f"({page.TIE_WORDS['unmeasured']})"),
    ((CHEAPEST, FAR), True, "winner", f"the winner (runner-up {FAR} (ode) at 3x)", False,
     f"runner-up: {FAR} (ode) at 3x ({page.OUT_OF_CONTENTION})"),
    ((CHEAPEST,), True, "winner", "the only line verified on the perturbed sets", None, None),
], ids=["unmeasured", "out-of-contention", "only-line"])
def test_the_runner_ups_margin_in_words(pool, samples, verdict, words, tie, up):
    """Without samples a contender's interval is not measured: a tie, since the noise
    may reverse the order; beyond 2x it is out of contention and timed no more;
    alone, the named line is the only one."""
    from integrator_bench.harness.advise.answer import Advice, Asked, Cost

    problem = _problem()
    _, _, records = _records(problem, CLEAR)
    if not samples:
        records = records.assign(cpu_samples=None)
    top = certificate.verdict(records, [LineEntry(n, "ode", "implicit") for n in pool],
                              TARGET, "max")
    winner = LineEntry(CHEAPEST, "ode", "implicit", run=Run(1e-4, 0.5 * TARGET, 1e-3),
                       robustness="holds")
    second = LineEntry(pool[-1], "ode", "implicit", run=Run(1e-4, 0.5 * TARGET, 2e-3))
    answer = Advice(Asked("two_mass", TARGET, "max", "cpu", ("x1",), 60.0), 3, (), "answer",
                    Cost(1.0, 1.0, 6, 6, 0), winner=winner,
                    runner_up=second if len(pool) > 1 else None,
                    margin=certificate.margin_of(top), verdict=top["verdict"],
                    tied=tuple(top["tied"]), same_code=top["same_code"])
    assert page.verdict_words(answer) == words
    shown = page.text(answer).splitlines()
    assert [line.partition(";")[0] for line in shown if line.startswith("runner-up:")] == (
        [up] if up else [])
    assert (answer.margin.tie if answer.margin else None) is tie
    assert top["verdict"] == verdict
