"""studies/rerun_spread.py: the run-to-run spread of the CPU and of the answers,
on hand-built records and stores."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from integrator_bench.harness.matrix.provenance import collect
from integrator_bench.harness.matrix.store import Store
from integrator_bench.harness.ranking.records import clean_records

from records_frame import records_frame

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "studies"))
import rerun_spread  # noqa: E402


def run_records(cpu_x: float, cpu_y: float, cpu_z: float = 2e-4):
    """One run of problem ``p``: lines ``x`` and ``y`` (``ode``) at rtol 1e-3 and
    1e-6 (errors 1e-4 and 1e-7, so both reach 1e-5), their CPU at 1e-6 twice their
    CPU at 1e-3; and a case of ``z`` on problem ``q`` that reaches nothing."""
    rows = [{"problem": "p", "integrator": name, "rtol": rtol, "err_max": err,
             "cpu_s": cpu * scale, "status": "ok", "formulation": "ode"}
            for name, cpu in (("x", cpu_x), ("y", cpu_y))
            for rtol, err, scale in ((1e-3, 1e-4, 1), (1e-6, 1e-7, 2))]
    rows.append({"problem": "q", "integrator": "z", "rtol": 1e-3, "err_max": 1e-2,
                 "cpu_s": cpu_z, "status": "ok", "formulation": "ode"})
    return clean_records(records_frame(rows))


def test_a_case_twice_as_costly_in_one_run_has_ratio_2():
    spread = rerun_spread.cpu_spread([run_records(0.01, 0.015), run_records(0.02, 0.015)])
    assert len(spread) == 5
    assert sorted(spread["ratio"]) == pytest.approx([1, 1, 1, 2, 2])
    rows = {r["cases"]: r for r in rerun_spread.spread_table(spread)}
    assert rows["all"]["max"] == pytest.approx(2) and rows["all"]["n"] == 5
    assert rows["all"]["median"] == pytest.approx(1) and rows["all"]["rel"] == pytest.approx(0)
    # by decade of the median CPU: x and y (15 and 30 ms) in "10 ms", z (0.2 ms) below 1 ms
    assert rows["< 1 ms"]["n"] == 1 and rows["< 1 ms"]["max"] == pytest.approx(1)
    assert rows["10 ms"]["n"] == 4 and rows["10 ms"]["max"] == pytest.approx(2)
    assert rows["10 ms"]["median"] == pytest.approx(1.5)
    assert rows["10 ms"]["rel"] == pytest.approx(0.5)


def test_only_cases_ok_in_every_run_count():
    a, b = run_records(0.01, 0.015), run_records(0.02, 0.015)
    b.loc[b.integrator == "x", "status"] = "failed"
    spread = rerun_spread.cpu_spread([a, b])
    assert len(spread) == 3 and spread["ratio"].max() == pytest.approx(1)


def test_different_winners_without_a_tie_are_inconsistent():
    # 3x apart each time: a winner by any ranking, with or without a noise band
    per_run = [rerun_spread.answers(run_records(0.01, 0.03)),
               rerun_spread.answers(run_records(0.1, 0.03))]
    assert per_run[0][("p", "{}")] == {"x (ode)"} and per_run[1][("p", "{}")] == {"y (ode)"}
    assert per_run[0][("q", "{}")] == {rerun_spread.NOT_REACHED}
    rows, missing = rerun_spread.consistency(per_run)
    assert missing == 0
    assert {r["problem"]: r["consistent"] for r in rows} == {"p": False, "q": True}
    same = [rerun_spread.answers(run_records(0.01, 0.03))] * 3
    assert all(r["consistent"] for r in rerun_spread.consistency(same)[0])


def test_a_tie_holds_where_it_overlaps_the_other_answers():
    top = {"label": "x", "formulation": "ode"}
    tie = {**top, "verdict": "tie", "tied": ["x (ode)", "y (ode)"]}
    assert rerun_spread.answer_set(top) == {"x (ode)"}
    assert rerun_spread.answer_set({**top, "verdict": "winner", "tied": []}) == {"x (ode)"}
    assert rerun_spread.answer_set({**top, "verdict": "unmeasured", "tied": []}) == {"x (ode)"}
    assert rerun_spread.answer_set(tie) == {"x (ode)", "y (ode)"}
    assert rerun_spread.answer_set(None) == {rerun_spread.NOT_REACHED}
    x, y, z = (frozenset([f"{n} (ode)"]) for n in "xyz")
    xy = rerun_spread.answer_set(tie)
    assert rerun_spread.consistent([x, xy, xy])         # every pair overlaps
    assert rerun_spread.consistent([y, xy])
    assert not rerun_spread.consistent([x, xy, y])      # x and y do not
    assert not rerun_spread.consistent([x, xy, z])
    assert not rerun_spread.consistent([x, y])
    assert rerun_spread.consistent([xy, frozenset(["y (ode)", "w (ode)"])])


def _store(path: Path, df, started: str, finished: str) -> None:
    with Store(path) as store:
        run_id = store.begin_run({**collect("test"), "started": started})
        for row in df.to_dict("records"):
            store.add(row)
        store.finish_run(run_id, "finished", finished)


def test_stores_are_read_and_reported(tmp_path, capsys):
    (tmp_path / "run1").mkdir()
    _store(tmp_path / "run1" / "ibench.sqlite", run_records(0.01, 0.03),
           "2026-01-01T00:00:00+00:00", "2026-01-01T00:01:20+00:00")
    _store(tmp_path / "b.sqlite", run_records(0.1, 0.03),
           "2026-01-01T00:02:00+00:00", "2026-01-01T00:03:30+00:00")
    assert rerun_spread.main(["--stores", str(tmp_path / "run1"),
                              str(tmp_path / "b.sqlite")]) == 0
    out = capsys.readouterr().out
    assert "of the 5 cases ok in every run" in out
    assert "| all | 5 | 1.000 | 10.000 | 10.000 | 0.0 % |" in out
    assert "1 of 2 problems consistent" in out
    assert "| p | x (ode) | y (ode) | NO |" in out
    assert "| run 1 |" in out and "| 80 | 0.1 |" in out and "| 90 | 0.4 |" in out


def test_bad_input_exits_2(tmp_path, capsys):
    assert rerun_spread.main(["--stores", str(tmp_path / "none")]) == 2
    assert rerun_spread.main(["--runs", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "no store" in err[0] and "--runs" in err[1]
