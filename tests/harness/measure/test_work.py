"""The method's work beside the CPU: unit costs, work and overhead, the expensive-model
option, and ranking by either cost (harness/measure/unit_costs.py, harness/ranking/cost.py)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from integrator_bench.harness.measure import unit_costs
from integrator_bench.harness.measure.unit_costs import UnitCosts, case_work, overhead, work
from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import Case
from integrator_bench.harness.matrix.record import empty_record
from integrator_bench.harness.ranking.cost import by_cost, overhead_table
from integrator_bench.harness.ranking.reach import target_table
from integrator_bench.harness.report import write_report
from integrator_bench.harness.report.ranking_text import cost_text
from integrator_bench.problems.base import MODEL_COST, ProblemError
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits
from records_frame import records_frame

IBENCH = [sys.executable, "-m", "integrator_bench.harness.cli"]


def test_unit_costs_of_each_kind_of_system():
    two_mass = registry.get_problem_class("two_mass")()
    pendulum = registry.get_problem_class("pendulum")()
    ode = two_mass.formulate("ode")
    i3 = pendulum.formulate("i3")
    for system, n, has_jac in [(ode, 4, True), (ode.as_dae(), 4, True),
                               (i3, i3.n, True), (i3.mechanical, i3.mechanical.nq + 1, True),
                               (pendulum.formulate("ode"), 4, False)]:
        costs = unit_costs.measure(system)
        assert costs.n == n and not costs.sparse and costs.nnz == n * n
        assert 0 < costs.rhs < 1e-3 and 0 < costs.lu < 1e-3 and 0 <= costs.solve < 1e-3
        assert (costs.jac is not None) == has_jac
        assert json.loads(costs.to_json())["n"] == n
    # the other callables a run counts: the projection, event functions, the mechanical parts
    assert set(unit_costs.measure(pendulum.formulate("projection")).others) == {"project"}
    assert set(unit_costs.measure(i3.mechanical).others) == {
        "mass", "constraint", "constraint_jac", "accel_term"}
    ball = registry.get_problem_class("bouncing_ball")().formulate("ode")
    assert set(unit_costs.measure(ball).others) == {"events[0].value"}


def test_work_is_the_counts_times_the_unit_costs():
    costs = UnitCosts(rhs=2e-6, jac=5e-6, lu=1e-6, solve=3e-7, n=4, nnz=16, sparse=False)
    assert work(costs, 100, 3, 10, 40) == pytest.approx(100 * 2e-6 + 3 * 5e-6 + 10 * 1e-6
                                                        + 40 * 3e-7)
    # an explicit code: its evaluations only; a count not reported adds nothing
    assert work(costs, 100, 0, None, None) == pytest.approx(2e-4)
    assert work(None, 100, 0, None, None) is None and work(costs, None, 0, 1, 1) is None
    assert overhead(4e-4, 2e-4) == pytest.approx(2.0)
    assert overhead(None, 2e-4) is None and overhead(1.0, 0.0) is None
    # the other model callables' calls at their unit costs; a reset is not timed
    costs = UnitCosts(rhs=2e-6, jac=None, lu=1e-6, solve=3e-7, n=4, nnz=16, sparse=False,
                      others={"project": 1e-5})
    assert work(costs, 100, 0, None, None, {"project": 10, "events[0].reset": 3}) == \
        pytest.approx(100 * 2e-6 + 10 * 1e-5)
    assert case_work({"work": 0.5}) == 0.5 and case_work({"work": None}) is None
    assert case_work(pd.Series({"work": np.nan})) is None and case_work({}) is None


def test_the_model_cost_option_adds_known_cpu_and_keeps_the_reference():
    cls = registry.get_problem_class("two_mass")
    plain, costly = cls(), cls(**{MODEL_COST: 300})
    assert costly.params[MODEL_COST] == 300.0
    assert costly.key_params() == plain.key_params()
    assert costly.fingerprint() == plain.fingerprint()
    assert costly.unscored().params == plain.params
    for formulation, name in [("ode", "fun")]:
        fast, slow = plain.formulate(formulation), costly.formulate(formulation)
        y = slow.y0
        np.testing.assert_array_equal(getattr(slow, name)(0.0, y), getattr(fast, name)(0.0, y))
        assert unit_costs.measure(slow).rhs >= 300e-6 > unit_costs.measure(fast).rhs
        assert unit_costs.measure(slow.as_dae()).rhs >= 300e-6
    with pytest.raises(ProblemError, match="rhs_cost_us='x'.*valid: a number"):
        cls(**{MODEL_COST: "x"})
    with pytest.raises(ProblemError, match="rhs_cost_us=-1"):
        cls(**{MODEL_COST: -1})


#: one explicit and one implicit code of each family: in-house, scipy, SUNDIALS through
#: scikit-sundae, SUNDIALS and Hairer's codes through Assimulo (rtol, or h for the steppers)
CODES = [("rk4", None, 0.1), ("bdf2", None, 0.1), ("scipy-RK45", 1e-3, None),
         ("scipy-BDF", 1e-3, None), ("cvode-adams", 1e-3, None), ("cvode-bdf", 1e-3, None),
         ("assimulo-dopri5", 1e-3, None), ("assimulo-cvode-bdf", 1e-3, None)]
#: microseconds of the expensive model: about 4x the largest overhead per evaluation seen
#: on two_mass (scipy-BDF, the in-house steppers: 60-100 us)
EXPENSIVE_US = 400.0


def test_cpu_approaches_the_work_as_the_model_gets_expensive(tmp_path, run_cases):
    """A slow non-stiff two_mass (k2=10, a few hundred evaluations a case): with
    the model made expensive on purpose every code's CPU is within 50 % of its
    work (measured: 1.01-1.16), and nearer to it than with the cheap model
    (3-30). Up to 3 timed solves a case (until 0.2 s of CPU): one alone may
    carry a forked worker's first page faults."""
    have = set(registry.integrators())
    codes = [c for c in CODES if c[0] in have]
    cases = [Case(problem="two_mass", params=tuple(sorted({"k2": 10.0, MODEL_COST: us}.items())),
                  formulation="ode", integrator=name, rtol=rtol, h=h)
             for us in (0.0, EXPENSIVE_US) for name, rtol, h in codes]
    df = run_cases(cases,
                   RunContext(jobs=1, progress=False, reference_dir=tmp_path, skip=False,
                              limits=Limits(repeat=3)))
    assert (df["status"] == "ok").all(), df[["integrator", "status", "message"]]
    cheap, dear = ({r.integrator: r.overhead for r in df.itertuples()
                    if json.loads(r.params)[MODEL_COST] == us} for us in (0.0, EXPENSIVE_US))
    for name, _, _ in codes:
        assert 0.8 < dear[name] < 1.5, (name, dear[name])
        assert abs(dear[name] - 1) < abs(cheap[name] - 1), (name, cheap[name], dear[name])


def _records(with_work: bool) -> pd.DataFrame:
    rows = []
    for integrator, cpu_per, ratio in [("scipy-RK45", 1e-3, 5.0), ("scipy-Radau", 3e-3, 30.0)]:
        for i, rtol in enumerate([1e-3, 1e-6, 1e-9]):
            cpu = cpu_per * 10 ** i
            rows.append(empty_record(
                problem="spring_pendulum", params='{"k": 100.0}', formulation="ode",
                integrator=integrator, rtol=rtol, atol=rtol, status="ok", mescd=3.0 + 3 * i,
                scd=3.0 + 3 * i, err_max=10.0 ** -(3 + 3 * i), cpu_s=cpu, nfev=100 * 10 ** i,
                created="2024-01-01T00:00:00+00:00", code_version="abc",
                work=cpu / ratio if with_work else None,
                overhead=ratio if with_work else None))
    return records_frame(rows)


def test_ranking_by_work_reverses_what_overhead_decides(tmp_path):
    records = _records(with_work=True)
    table = overhead_table(records)
    assert list(table["label"]) == ["scipy-RK45", "scipy-Radau"]
    assert list(table["overhead"]) == [5.0, 30.0] and list(table["cases"]) == [3, 3]
    ranked = by_cost(records, "work")
    assert np.allclose(ranked["cpu_s"], records["work"]) and ranked["cpu_s_iqr"].isna().all()
    assert by_cost(records, "cpu") is records
    with pytest.raises(ValueError, match="'bogus' is not a cost; valid: cpu, work"):
        by_cost(records, "bogus")
    # at every error RK45 takes a third of Radau's CPU, and Radau half RK45's work
    top = {cost: target_table(by_cost(records, cost), (1e-5,)).iloc[0]["label"]
           for cost in ("cpu", "work")}
    assert top == {"cpu": "scipy-RK45", "work": "scipy-Radau"}
    write_report(records, tmp_path, cost="work", jobs=1, scaling_dir=tmp_path / "none")
    page = next(tmp_path.glob("spring_pendulum*.md")).read_text()
    assert "## Cost: ranked by work" in page and "| scipy-Radau | 30 | 3 |" in page
    answer = next(line for line in page.splitlines() if line.startswith("Answer:"))
    assert "**scipy-Radau (ode)**" in answer and " s work at rtol" in answer
    assert "Ranked by work:" in (tmp_path / "index.md").read_text()
    assert (tmp_path / "profiles.png").exists() and (tmp_path / "profiles_cpu.png").exists()


def test_records_without_work_still_report_and_are_not_ranked_by_it(tmp_path):
    records = _records(with_work=False)
    assert "6 ok records without work" in cost_text(records, "work")
    assert by_cost(records, "work")["cpu_s"].isna().all()
    assert overhead_table(records).empty
    old = records.drop(columns=["work", "overhead", "unit_costs", "njev_model"])
    write_report(old, tmp_path, cost="work", jobs=1, scaling_dir=tmp_path / "none")
    page = next(tmp_path.glob("spring_pendulum*.md")).read_text()
    assert "6 ok records without work" in page and "No overhead" in page


@pytest.mark.parametrize("args", [["report", "--cost", "bogus"],
                                  ["advise", "-p", "two_mass", "--target", "1e-3",
                                   "--cost", "bogus"]])
def test_a_bad_cost_is_one_line_and_exit_2(args, tmp_path):
    r = subprocess.run([*IBENCH, *args, "--store", str(tmp_path / "s.sqlite")],
                       capture_output=True, text=True, timeout=120)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert "'bogus'" in lines[0] and "'cpu', 'work'" in lines[0]
    assert not any(tmp_path.iterdir())


def test_reference_unit_costs_command_prints_each_form():
    r = subprocess.run([*IBENCH, "reference", "-p", "pendulum", "--unit-costs", "--json"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    lines = [json.loads(x) for x in r.stdout.splitlines()]
    forms = {(x["formulation"], x["kind"]) for x in lines}
    assert {("ode", "ode"), ("ode", "dae"), ("i3", "dae"), ("i3", "mechanical")} <= forms
    assert all(x["rhs"] > 0 and x["lu"] > 0 for x in lines)
