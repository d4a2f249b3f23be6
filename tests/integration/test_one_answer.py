"""One answer: a ranking rests only on timed solves that did the counted work,
on the measure the page names, and the summary, answer line and table agree."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.cli.summary import summary
from integrator_bench.harness.run.execution import execute
from integrator_bench.harness.matrix.record import CaseStatus, empty_record
from integrator_bench.harness.ranking.reach import target_table
from integrator_bench.harness.report.profiles import costs
from integrator_bench.harness.report.sections import answer
from integrator_bench.integrators.base import Solution, Status, TimedCall
from records_frame import exact, records_frame

SMALL = "two_mass:c1=0.1,c2=1000,k1=10,k2=10000"   # cvode-bdf solves it in a few ms


# --- what is timed is what was counted ---------------------------------------------------

def test_an_untimed_record_is_ranked_nowhere(monkeypatch):
    """A case is solved once, counted and timed, so a solve that gives up is a
    failed case (no other timing to disagree with it). An ``untimed`` record,
    which older code wrote when its timed solve did other work than its counted
    one (IDA's on the squeezer's ggl form gave up after one output), keeps its
    errors and counts, and no table, profile, answer or summary ranks it."""
    icls = registry.get_integrator("cvode-bdf")

    def gives_up(self, system, **kw):
        return TimedCall(lambda: Solution(system.t_eval[:1], system.y0[None, :],
                                          status=Status.NEWTON_FAILURE, message="gave up"))
    case, = expand(problems=[SMALL], integrators=["cvode-bdf"], rtols=[1e-8])
    good = execute(case)
    monkeypatch.setattr(icls, "timed_call", gives_up)
    failed = execute(case)
    assert good["status"] == CaseStatus.OK
    assert failed["status"] == CaseStatus.FAILED and failed["reason"] == "newton_failure"
    bad = dict(good, status=CaseStatus.UNTIMED, reason="timed_solve_differs", timing=None)
    # the untimed record as the cheapest of its line: it is ranked nowhere
    other = dict(good, integrator="scipy-BDF", label="scipy-BDF", cpu_s=good["cpu_s"] * 5,
                 cpu_samples=exact(good["cpu_s"] * 5))
    rows = pd.DataFrame([dict(bad, cpu_s=good["cpu_s"] / 100,
                              cpu_samples=exact(good["cpu_s"] / 100)), other])
    table = target_table(rows)
    by = table.set_index("label")
    assert by.loc["cvode-bdf", "how_1e-05"] == "not reached"
    assert answer(table).label == "scipy-BDF"
    cpu, _ = costs(rows, 1e-5)
    assert math.isinf(cpu["cvode-bdf"].iloc[0]) and np.isfinite(cpu["scipy-BDF"].iloc[0])
    text = summary(rows)
    assert "1 untimed" in text and "scipy-BDF/ode" in text.splitlines()[1]


# --- one answer ----------------------------------------------------------------------------

def point(integrator, rtol, err, cpu, **extra):
    """An ok record of two_mass whose errors (final and over the run) are ``err``."""
    return empty_record(problem="two_mass", params='{"c1": 0.1}', formulation="ode",
                        integrator=integrator, rtol=rtol, status="ok", scd=-math.log10(err),
                        mescd=-math.log10(err), err_max=err, err_rms=err / 2, cpu_s=cpu,
                        cpu_samples=exact(cpu), created="2026-01-01T00:00:00+00:00", **extra)


@pytest.fixture
def bound_store(tmp_path):
    """radau5's loosest run is already below 1e-5 (a "≤" row, 0.000739 s); cvode-adams
    crosses 1e-5 between two runs at 0.000754 s; bdf does not get there."""
    from integrator_bench.harness.matrix.store import Store, load

    rows = [point("assimulo-radau5", 1e-4, 3e-6, 0.000739),
            point("assimulo-radau5", 1e-6, 1e-8, 0.002),
            point("assimulo-cvode-adams", 1e-4, 1e-4, 0.0004),
            point("assimulo-cvode-adams", 1e-6, 1e-6, 0.000754 ** 2 / 0.0004),
            point("assimulo-cvode-bdf", 1e-4, 1e-3, 0.0001)]
    path = tmp_path / "store.sqlite"
    with Store(path) as store:
        for r in rows:
            store.add(r)
    return path, load(path)


def test_summary_answer_and_table_agree_on_an_upper_bound(bound_store, tmp_path):
    """The "≤" row (the loosest run already below the target) is ranked by its CPU in
    the table, named by the answer line and by the run's summary: one answer."""
    from integrator_bench.harness.report import write_report

    path, rows = bound_store
    table = target_table(rows)
    assert list(table["label"][:2]) == ["assimulo-radau5", "assimulo-cvode-adams"]
    assert table["how_1e-05"].iloc[0] == "at most"
    got = answer(table)
    assert (got.label, got.how, got.cpu_s) == ("assimulo-radau5", "at most", 0.000739)
    line = summary(rows).splitlines()[1]
    assert "assimulo-radau5/ode ≤ 0.000739 rtol=0.0001" in line
    write_report(rows, tmp_path / "report", scaling_dir=tmp_path / "none")
    page = next((tmp_path / "report").glob("two_mass*.md")).read_text(encoding="utf-8")
    assert "**assimulo-radau5 (ode)**, ≤ 0.000739 s CPU at rtol 0.0001" in page
    lines = page.splitlines()
    head = next(k for k, x in enumerate(lines) if "CPU [s] to 1e-05" in x)
    first = lines[head + 2]
    assert first.startswith("| assimulo-radau5 | ode |") and "| ≤ 0.000739 | rtol 0.0001 |" in first
    assert table["cpu_1e-05"].iloc[1] == pytest.approx(0.000754)


def test_a_line_never_costs_less_for_a_tighter_target():
    """A loose run dearer than a tighter one (timing noise, rejected steps) is beaten by
    it: the CPU to 1e-3 is never above the CPU to 1e-5."""
    rows = records_frame([point("assimulo-radau5", 1e-3, 5e-4, 0.00677),
                          point("assimulo-radau5", 1e-5, 3e-5, 0.004),
                          point("assimulo-radau5", 1e-7, 2e-6, 0.006)])
    r = target_table(rows).iloc[0]
    assert r["cpu_1e-03"] <= r["cpu_1e-05"] and r["how_1e-03"] == "at most"
    assert r["cpu_1e-03"] == 0.004


def test_a_store_without_the_new_fields_loads_and_reports(tmp_path):
    """A store written before the trajectory errors, events_matched and
    final_degenerate: it loads (the columns read null) and ranks by the final-time
    error when asked, the trajectory one being unknown."""
    import sqlite3

    from integrator_bench.harness.matrix.store import load

    new = ("err_rms", "err_max_rel", "err_rms_rel", "err_floor", "final_degenerate",
           "events_matched")
    from integrator_bench.harness.matrix.store import Store

    path = tmp_path / "old.sqlite"
    with Store(path) as store:
        store.add(point("cvode-bdf", 1e-6, 1e-6, 0.01))
    db = sqlite3.connect(path)
    for name in new:
        db.execute(f"ALTER TABLE records DROP COLUMN {name}")
    db.commit()
    assert not set(new) & {r[1] for r in db.execute("PRAGMA table_info(records)")}
    db.close()
    rows = load(path)
    assert set(new) <= set(rows.columns) and rows["err_rms"].isna().all()
    assert target_table(rows, measure="rms")["how_1e-05"].iloc[0] == "not reached"
    assert target_table(rows, measure="final")["how_1e-05"].iloc[0] == "at most"


# --- events: a run with a bounce wrong reaches no target ----------------------------------

def test_a_bouncing_ball_fmu_run_with_a_bounce_wrong_reaches_no_target(built_fmus, tmp_path):
    """The project's bouncing-ball FMU (built from its C sources): fmpy's CVODE at rtol
    1e-2 finds a bounce the reference has not (8 impacts), with a trajectory error
    under 0.5: it does not reach 0.5, nor would it with a bounce missed instead; with
    its events right it would."""
    from integrator_bench.harness.measure import references
    from integrator_bench.harness.matrix.cases import Case
    from integrator_bench.problems.fmu import FmuProblem

    fmu = FmuProblem(path=str(built_fmus["bouncing_ball"]), score="y")
    references.load(fmu, tmp_path)
    case = Case(fmu.name, tuple(sorted(fmu.params.items())), "ode", "fmpy-cvode", rtol=1e-2)
    record = execute(case, reference_dir=tmp_path)
    assert record["status"] == CaseStatus.OK, record["message"]
    assert record["events_spurious"] >= 1 and record["events_matched"] == 8
    assert record["err_max"] < 0.5 and record["final_degenerate"] == 0
    for error in ("final", "max", "rms"):
        reach = target_table(pd.DataFrame([record]), (0.5,), error)["how_5e-01"].iloc[0]
        assert reach == "not reached", error
    missed = dict(record, events_spurious=0, events_missed=1, events_matched=7)
    right = dict(record, events_spurious=0, events_missed=0)
    assert target_table(pd.DataFrame([missed]), (0.5,))["how_5e-01"].iloc[0] == "not reached"
    assert target_table(pd.DataFrame([right]), (0.5,))["how_5e-01"].iloc[0] == "at most"


# --- the trajectory measure ranks otherwise than the final-time one --------------------------

def test_a_forced_oscillator_ranks_otherwise_over_the_trajectory(tmp_path):
    """two_mass (physically stiff, forced by sin t): DOP853's error at the final time
    at rtol 1e-5 is 2e-7, a lucky end of a run whose error over the output times is
    5e-6. At 3e-6 the final-time error ranks it before cvode-bdf, the trajectory error
    after it. CPU is replaced by a cost proportional to nfev, so that the order is the
    work's, not the machine's load."""
    from integrator_bench.harness.report import write_report

    cases = expand(problems=["two_mass:c2=0.1"], integrators=["scipy-DOP853", "cvode-bdf"],
                   rtols=[1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9], formulations=["ode"])
    rows = pd.DataFrame([execute(c) for c in cases])
    rows = rows.assign(cpu_s=rows["nfev"] * 1e-6)
    rows = rows.assign(cpu_samples=[exact(c) for c in rows["cpu_s"]])
    lucky = rows[(rows["integrator"] == "scipy-DOP853") & (rows["rtol"] == 1e-5)].iloc[0]
    assert 10 ** -lucky["mescd"] < 3e-6 < lucky["err_max"]
    final, trajectory = (list(target_table(rows, (3e-6,), m)["label"])
                         for m in ("final", "max"))
    assert final == ["scipy-DOP853", "cvode-bdf"] and trajectory == ["cvode-bdf", "scipy-DOP853"]
    for error, words in (("final", "largest mixed error at the final time"),
                         ("max", "largest mixed error over the output times")):
        out = tmp_path / error
        write_report(rows, out, scaling_dir=tmp_path / "none", error=error)
        page = next(out.glob("two_mass*.md")).read_text(encoding="utf-8")
        assert f"Answer: cheapest to reach an error of 1e-05 (the {words}" in page
        assert f"the error is the {words}, |y - r| / (floor + |r|) over the error " \
               "components (x1, x2), floor 1" in page


# --- a final-time error that says nothing ------------------------------------------------------

def test_a_reference_at_rest_makes_the_final_error_degenerate():
    from integrator_bench.harness.measure.metrics import at_rest, measure

    t = np.linspace(0.0, 10.0, 101)[:, None]
    decayed = np.exp(-3.0 * t) * np.cos(5.0 * t)            # ends at 1e-13 of its size
    resting = np.minimum(t, 5.0)                             # stops at 5 and stays
    moving = np.sin(t)
    assert at_rest(decayed) and at_rest(resting) and not at_rest(moving)
    assert not at_rest(np.hstack([decayed, moving]))         # every component must be
    Y, R = decayed + 1e-3 * np.sin(7 * t), decayed
    got = measure(Y, R, np.array([1e-3]), {"error": np.array([0]), "velocity": [],
                                           "lambda": []})
    assert got["final_degenerate"] == 1 and got["err_floor"] == 1e-3
    assert got["err_max"] > got["err_rms"] > 0 and got["err_max_rel"] > got["err_rms_rel"] > 0


def test_a_degenerate_final_error_is_ranked_over_the_trajectory(tmp_path):
    """Two lines whose final errors are nil (the body ends at rest) but whose errors
    over the run differ: under --error final the problem is ranked by the largest
    error over the output times, and the page says why."""
    from integrator_bench.harness.report import write_report

    rows = records_frame([point("cheap-wrong", 1e-3, 1e-9, 0.001),
                          point("cheap-wrong", 1e-6, 1e-9, 0.004),
                          point("dear-right", 1e-3, 1e-9, 0.002)])
    rows["err_max"] = [1e-2, 1e-4, 1e-6]
    assert list(target_table(rows, (1e-5,), "final")["how_1e-05"]) == ["at most", "at most"]
    flagged = rows.assign(final_degenerate=1)
    table = target_table(flagged, (1e-5,), "final")
    assert list(table["label"]) == ["dear-right", "cheap-wrong"]
    assert table["how_1e-05"].iloc[1] == "not reached"
    write_report(flagged, tmp_path, scaling_dir=tmp_path / "none", error="final")
    page = next(tmp_path.glob("two_mass*.md")).read_text(encoding="utf-8")
    assert "ranked by it instead of the final-time error, which says nothing here" in page
    assert "**dear-right (ode)**" in page
