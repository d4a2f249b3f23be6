"""docs/plugins.md is enough to write a plugin: each of its Python blocks is a complete
plugin; each integrator passes every line of check-plugin, the unconstrained problem
registers, has the Jacobian it claims (at its range ends too, check-plugin's model
lines), gets a verified reference and runs, and the constrained, driven one registers,
gets its exact reference verified, runs under each family of formulations and passes
every line of check-plugin's problem check."""

import re
from pathlib import Path

import numpy as np
import pytest

from integrator_bench.harness.checks.conformance import check_plugin
from integrator_bench.harness.checks.problem_check import check_problem
from integrator_bench.harness.measure import references
from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import Case
from integrator_bench.harness.run.execution import execute
from integrator_bench.integrators.base import Integrator
from integrator_bench.problems.base import Problem

PAGE = Path(__file__).resolve().parents[3] / "docs" / "plugins.md"


def own(classes: list[type]) -> list[type]:
    """The classes a block defines itself (not the bases it imports)."""
    return [c for c in classes if c.__module__ == "plugin_from_docs"]


def blocks() -> list[str]:
    """The page's Python code blocks, in order."""
    return re.findall(r"```python\n(.*?)```", PAGE.read_text(), flags=re.S)


def plugins(source: str, base: type = Integrator) -> list[type]:
    """The integrators (or, with ``base`` Problem, the problems) a code block defines,
    run as a module of its own."""
    namespace = {"__name__": "plugin_from_docs"}
    exec(compile(source, str(PAGE), "exec"), namespace)
    return [v for v in namespace.values()
            if isinstance(v, type) and issubclass(v, base) and v is not base]


def test_the_page_has_a_stepper_an_own_loop_and_two_problem_plugins():
    found = [cls for source in blocks() for cls in plugins(source)]
    problems = [cls for source in blocks() for cls in plugins(source, Problem)
                if cls.__module__ == "plugin_from_docs"]
    assert len(blocks()) == 4 and len(found) == 2 and len(problems) == 2
    assert found[0].has_stepper() and not found[1].has_stepper()
    assert [c.__name__ for c in problems] == ["DampedDoublePendulum", "BeadOnTurningRod"]


@pytest.mark.parametrize("index", [0, 1])
def test_each_plugin_of_the_page_passes_check_plugin(index):
    cls, = plugins(blocks()[index])
    registry.register(cls, origin="docs/plugins.md")
    try:
        lines = {c.name: c for c in check_plugin(cls.name, timeout=120)}
    finally:
        registry.unregister(cls.name)
    assert all(c.passed is not False for c in lines.values()), \
        [c.line() for c in lines.values()]
    for name in ("declarations", "runs ode", "counts", "inputs", "order", "accuracy",
                 "fails raise", "fails nan", "fails blowup"):
        assert lines[name].passed, lines[name].line()


def test_the_problem_plugin_of_the_page_runs(tmp_path):
    """Section 11's problem, registered as its entry point would: its analytic
    Jacobian agrees with central differences at a state off the start, its two
    reference runs agree to its ``reference_digits``, and a case of it runs to ``ok``
    within its tolerance."""
    cls, = own(plugins(blocks()[2], Problem))
    registry.register(cls, origin="docs/plugins.md")
    try:
        problem = registry.get_problem_class(cls.name)(c2=0.5)
        y = problem.initial_state() + np.array([0.1, -0.2, 0.3, -0.4])
        eps = 1e-6
        differences = np.column_stack([(problem.rhs(0.0, y + eps * e)
                                        - problem.rhs(0.0, y - eps * e)) / (2 * eps)
                                       for e in np.eye(len(y))])
        np.testing.assert_allclose(problem.jac(0.0, y), differences, rtol=1e-6, atol=1e-8)
        ref = references.compute(problem)
        assert references.claimed_digits(ref, problem) >= problem.reference_digits
        references.save(ref, problem, tmp_path)
        record = execute(Case(cls.name, tuple(sorted(problem.params.items())), "ode",
                              "cvode-bdf", rtol=1e-6), reference_dir=tmp_path, repeat=1)
    finally:
        registry.unregister(cls.name)
    assert record["status"] == "ok", record["message"]
    assert 0 < record["err_max"] < 1e-3 and record["njev"] > 0


def test_the_problem_plugin_of_the_page_passes_the_model_lines_of_check_plugin():
    """Its Jacobian at its defaults and at each end of its six parameters' ranges."""
    cls, = own(plugins(blocks()[2], Problem))
    registry.register(cls, origin="docs/plugins.md")
    try:
        lines = {c.name: c for c in check_problem(cls.name, only=("model",))}
    finally:
        registry.unregister(cls.name)
    assert lines["builds"].passed and lines["jacobian"].passed, \
        [c.line() for c in lines.values()]
    assert "12 of 12 range ends" in lines["builds"].detail


@pytest.fixture(scope="module")
def bead(tmp_path_factory):
    """Section 11's constrained, driven problem, registered, its reference (the exact
    solution, cross-checked by the harness against a tight run) stored."""
    cls, = own(plugins(blocks()[3], Problem))
    registry.register(cls, origin="docs/plugins.md")
    try:
        folder = tmp_path_factory.mktemp("bead")
        problem = registry.get_problem_class(cls.name)()
        assert problem.driven and problem.formulations[0] == "i3"
        ref = references.compute(problem)
        assert references.claimed_digits(ref, problem) >= problem.reference_digits
        references.save(ref, problem, folder)
        yield cls, problem, ref, folder
    finally:
        registry.unregister(cls.name)


def test_the_driven_problem_of_the_page_has_the_exact_solution_it_claims(bead):
    """The exact solution satisfies g(q, t) = 0, G v + g_t = 0 and the equations of
    motion (differences in time of its velocities), so it is the solution."""
    _, problem, ref, _ = bead
    pos, vel = problem.constraint_residuals(ref.t, ref.Y)
    assert max(pos) < 1e-12 and max(vel) < 1e-11
    t = np.linspace(0.1, 1.9, 7)
    h = 1e-5
    Y = problem.exact(t)
    a = (problem.exact(t + h)[:, 2:4] - problem.exact(t - h)[:, 2:4]) / (2 * h)
    for ti, y, ai in zip(t, Y, a):
        q, lam = y[:2], y[4:]
        balance = problem.mass(q) @ ai - problem.force(ti, q, y[2:4]) \
            + problem.constraint_jac(q, ti).T @ lam
        assert np.max(np.abs(balance)) < 1e-5 * max(1.0, np.max(np.abs(ai)))


def test_the_driven_problem_of_the_page_passes_check_plugin(bead):
    """Every line: its model at its defaults and its range ends, its reference (the
    one stored by the fixture) and a run of each of its formulations."""
    cls, _, _, folder = bead
    lines = check_problem(cls.name, reference_dir=folder)
    assert all(c.passed is not False for c in lines), [c.line() for c in lines]
    assert {c.name for c in lines if c.passed is None} == set(), [c.line() for c in lines]
    assert sum(c.name.startswith("runs ") for c in lines) == len(cls.formulations)


@pytest.mark.parametrize("form, integrator, step", [
    ("ode", "cvode-bdf", {"rtol": 1e-6}), ("i3", "ida", {"rtol": 1e-6}),
    ("ggl", "ida", {"rtol": 1e-6}), ("i3", "hht", {"rtol": 1e-5}),
    ("projection", "scipy-DOP853", {"rtol": 1e-6}), ("al3", "al-trapezoidal", {"h": 1e-3}),
])
def test_the_driven_problem_of_the_page_runs_under_each_formulation(bead, form, integrator,
                                                                    step):
    cls, problem, _, folder = bead
    record = execute(Case(cls.name, tuple(sorted(problem.params.items())), form, integrator,
                          **step), reference_dir=folder, repeat=1)
    assert record["status"] == "ok", record["message"]
    assert record["err_max"] < 1e-2, record["err_max"]
