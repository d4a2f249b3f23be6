"""docs/plugins.md is enough to write a plugin: each of its Python blocks is a complete
plugin; each integrator passes every line of check-plugin, and the problem registers,
has the Jacobian it claims, gets a verified reference and runs."""

import re
from pathlib import Path

import numpy as np
import pytest

from integrator_bench.harness.checks.conformance import check_plugin
from integrator_bench.harness.measure import references
from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import Case
from integrator_bench.harness.run.execution import execute
from integrator_bench.integrators.base import Integrator
from integrator_bench.problems.base import Problem

PAGE = Path(__file__).resolve().parents[1] / "docs" / "plugins.md"


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


def test_the_page_has_a_stepper_an_own_loop_and_a_problem_plugin():
    found = [cls for source in blocks() for cls in plugins(source)]
    problems = [cls for source in blocks() for cls in plugins(source, Problem)]
    assert len(blocks()) == 3 and len(found) == 2 and len(problems) == 1
    assert found[0].has_stepper() and not found[1].has_stepper()
    assert [c.__name__ for c in plugins(blocks()[2], Problem)] == [c.__name__ for c in problems]


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
    cls, = plugins(blocks()[2], Problem)
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
