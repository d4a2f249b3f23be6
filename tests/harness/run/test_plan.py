"""``ibench run --plan`` (harness/run/plan.py): the cases by kind, the predicted CPU and
wall time, nothing run and nothing written; the progress bar's time left."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from integrator_bench.harness.matrix.cases import Case
from integrator_bench.harness.matrix.line import ProblemSpec
from integrator_bench.harness.run import progress
from integrator_bench.harness.run.execution import MIN_CPU_S, sampled_cpu, samples
from integrator_bench.harness.run.plan import MODEL_FILE, committed_model, make_plan, makespan
from integrator_bench.harness.run.schedule import CostModel, Schedule, prior_work

IBENCH = [sys.executable, "-m", "integrator_bench.harness.cli"]
P = (("k", 1.0),)


def test_plan_on_an_empty_store_prints_the_plan_and_writes_nothing(tmp_path):
    store = tmp_path / "s.sqlite"
    args = ["run", "--plan", "-p", "two_mass", "-p", "pendulum", "--store", str(store),
            "--workers", "8"]
    text = subprocess.run([*IBENCH, *args], capture_output=True, text=True, timeout=600)
    assert text.returncode == 0, text.stderr
    assert text.stdout.startswith("plan: ") and "runnable" in text.stdout
    assert "model: the committed model" in text.stdout
    assert "wall on 8 workers" in text.stdout and "two_mass" in text.stdout
    data = subprocess.run([*IBENCH, *args, "--json"], capture_output=True, text=True,
                          timeout=600)
    assert data.returncode == 0, data.stderr
    plan = json.loads(data.stdout)
    assert plan["cases"]["runnable"] > 0 and plan["cpu_s"] > 0
    assert set(plan["wall_s"]) >= {"8"} and set(plan["cpu_s_by_problem"]) == {"two_mass",
                                                                               "pendulum"}
    assert not store.exists() and list(tmp_path.iterdir()) == []


def test_workers_without_plan_is_refused_and_writes_nothing(tmp_path):
    store = tmp_path / "s.sqlite"
    r = subprocess.run([*IBENCH, "run", "-p", "two_mass", "--workers", "8", "--store",
                        str(store)], capture_output=True, text=True, timeout=600)
    assert r.returncode == 2 and "--workers is for --plan" in r.stderr
    assert not store.exists()


def test_makespan_follows_the_schedulers_rule_and_meets_its_lower_bound():
    # lines a (4 s), b (1 s then 1 s), c (2 s) on two workers: a, b; then c; then b's second
    assert makespan({"a": [4.0], "b": [1.0, 1.0], "c": [2.0]}, 2) == 4.0
    # one line's cases run one after the other, whatever the workers
    assert makespan({"a": [1.0, 1.0, 1.0]}, 8) == 3.0


def test_a_case_predicted_over_its_budget_is_a_timeout_and_its_tighter_cases_skipped():
    line = [Case("p", P, "ode", "x", rtol=r) for r in (1e-2, 1e-4, 1e-6)]
    other = [Case("p", P, "ode", "y", rtol=1e-2), Case("p", P, "i3", "x", unsupported="no")]
    model = CostModel({ProblemSpec("p", P): (1, 1.0)})
    model.rates[("p", "x")] = [6.0 / prior_work(line[0], 1, 1.0)]   # 6 s at rtol 1e-2
    model.rates[()] = [1.0 / prior_work(other[0], 1, 1.0)]          # 1 s
    plan = make_plan(line + other, model, budget_s=5.0, workers=[1, 2])
    assert plan.kinds["unsupported"] == 1 and plan.kinds["runnable"] == 4
    assert plan.kinds["timeout"] == 1 and plan.kinds["skipped: after_timeout"] == 2
    assert plan.cpu == 6.0 and plan.dearest == 5.0     # a timeout costs its budget
    assert plan.walls[1] == (6.0, 6.0) and plan.walls[2] == (5.0, 5.0)


def test_the_committed_model_predicts_every_registered_problem():
    data = json.loads(MODEL_FILE.read_text(encoding="utf-8"))
    assert data["rates"][""] > 0
    case = Case("two_mass", P, "ode", "scipy-RK45", rtol=1e-3)
    assert committed_model({ProblemSpec("two_mass", P): (4, 10.0)}).predict(case) > 0


def test_the_bar_shows_the_time_left_from_the_predicted_cpu():
    cases = [Case("p", P, "ode", "x", rtol=r) for r in (1e-2, 1e-4)]
    model = CostModel({ProblemSpec("p", P): (1, 1.0)})
    model.rates[()] = [1e-3]
    schedule = Schedule(cases, model=model)
    left = progress.time_left(schedule, workers=2)
    assert left() == sum(model.predict(c) for c in cases) / 2
    schedule.next()
    assert left() == model.predict(cases[1]) / 2


def test_the_bar_counts_the_cpu_left_as_the_plan_does():
    """A case predicted past the budget costs the budget, and the tighter cases of
    its line nothing (skipped after its timeout): the bar's time left at the start
    is the plan's CPU over the workers (before, 69 min shown for a 19 min plan)."""
    cases = [Case("p", P, "ode", "x", rtol=r) for r in (1e-2, 1e-4, 1e-6, 1e-8)]
    model = CostModel({ProblemSpec("p", P): (1, 1.0)})
    model.rates[()] = [1e-3]
    costs = [model.predict(c) for c in cases]
    timeout = (costs[0] + costs[1]) / 2    # the second case is predicted past it
    assert costs[0] < timeout <= costs[1]
    schedule = Schedule(cases, model=model, budget_s=timeout)
    planned = make_plan(cases, model, timeout, workers=(2,))
    assert progress.time_left(schedule, workers=2)() == pytest.approx(planned.cpu / 2)
    assert planned.cpu == pytest.approx(costs[0] + timeout)


@pytest.mark.parametrize("cpu", [1e-4, 0.01, 0.03, 0.07, 0.2, 0.3, 2.0])
@pytest.mark.parametrize("repeat", [1, 3, 10])
def test_a_case_costs_its_timing_samples_as_the_worker_takes_them(cpu, repeat):
    """The plan counts a case's solve as often as the worker times it (one, then more
    until 0.2 s of CPU or ``repeat``): the full preset's cheap cases cost ten solves."""
    taken, _ = samples(lambda: (cpu, cpu), repeat, MIN_CPU_S)
    assert sampled_cpu(cpu, repeat) == pytest.approx(sum(taken))


def test_the_plan_counts_the_samples_of_a_preset_that_takes_them():
    cases = [Case("p", P, "ode", "x", rtol=r) for r in (1e-2, 1e-4)]
    model = CostModel({ProblemSpec("p", P): (1, 1.0)})
    model.rates[()] = [1e-5]
    one = [model.predict(c) for c in cases]
    assert max(one) < MIN_CPU_S / 10          # ten samples each, under 0.2 s
    assert make_plan(cases, model, 5.0, (1,)).cpu == pytest.approx(sum(one))
    assert make_plan(cases, model, 5.0, (1,), repeat=10).cpu == pytest.approx(10 * sum(one))
    schedule = Schedule(cases, model=model, budget_s=5.0, repeat=10)
    assert progress.time_left(schedule, workers=1)() == pytest.approx(10 * sum(one))
