"""studies/plan_check.py: a run's plan against its records."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from integrator_bench.harness.matrix.cases import Case
from integrator_bench.harness.matrix.store import Store
from integrator_bench.harness.run.execution import base_record

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "studies"))
import plan_check  # noqa: E402


def test_the_measured_cpu_beside_the_plans_per_problem_and_status(tmp_path, capsys):
    cases = [Case("two_mass", (), "ode", i, rtol=r)
             for i in ("scipy-RK23", "scipy-DOP853") for r in (1e-3, 1e-6)]
    outcomes = {("scipy-RK23", 1e-3): ("ok", 0.05, 3), ("scipy-RK23", 1e-6): ("timeout", 5.2, 1),
                ("scipy-DOP853", 1e-3): ("ok", 0.5, 1), ("scipy-DOP853", 1e-6): ("skipped", None, 0)}
    with Store(tmp_path / "s.sqlite") as store:
        for case in cases:
            status, cpu, repeat = outcomes[(case.integrator, case.rtol)]
            record = base_record(case)
            record.update(status=status, cpu_s=cpu, repeat=repeat, budget_s=5.0,
                          created="2026-12-08",
                          reason="after_timeout" if status == "skipped" else None)
            store.add(record)
        again = base_record(cases[0])   # a contender's timing again: no plan predicts it
        again.update(status="ok", cpu_s=100.0, repeat=1, contended=4, created="2026-12-08")
        store.add(again)
    plan = {"cases": {"runnable": 4, "timeout": 2, "skipped: after_timeout": 1},
            "cpu_s_by_problem": {"two_mass": 10.0}, "wall_s": {"2": {"makespan": 6.0}}}
    (tmp_path / "plan.json").write_text(json.dumps(plan))
    assert plan_check.main([str(tmp_path / "plan.json"), str(tmp_path / "s.sqlite")]) == 0
    out = capsys.readouterr().out
    # 0.05 s x 3 samples + 5.2 s (over its budget) + 0.5 s: 5.85 s of the 10 predicted,
    # the contender's 100 s not among them
    table = plan_check.by_problem(plan, plan_check.load(tmp_path / "s.sqlite"))
    assert table.loc["two_mass", "measured"] == pytest.approx(5.85)
    assert table.loc["all", "ratio"] == pytest.approx(0.585)
    assert "timeout: predicted 2, measured 1" in out
    assert "skipped after_timeout: predicted 1, measured 1" in out


def test_a_plan_that_is_not_json_is_one_line_and_exit_2(tmp_path, capsys):
    (tmp_path / "plan.json").write_text("not json")
    assert plan_check.main([str(tmp_path / "plan.json"), str(tmp_path / "none.sqlite")]) == 2
    assert capsys.readouterr().err.startswith("plan_check: ")
