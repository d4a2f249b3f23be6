"""The tangent formulation (Sudarsan and Keerthi's TP, problems/tangent.py): it
integrates 2 (nq - nc) chart coordinates, takes a new chart with an integration
restart when ||y'|| / ||v|| falls below 0.5, and maps every output through the
chart in force at its time."""

from __future__ import annotations

import numpy as np
import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.harness.run.execution import execute
from integrator_bench.problems.mechanical import MechanicalProblem


def test_charts_are_tangent_and_a_new_one_restarts_on_the_manifold():
    p = registry.get_problem_class("slider_crank")()
    system = p.formulate("tangent")
    assert system.n == 2 * (p.nq - p.nc)
    chart = system.charts.current
    G = p.constraint_jac(chart["q0"])
    np.testing.assert_allclose(G @ chart["U"], 0, atol=1e-12)
    np.testing.assert_allclose(chart["U"].T @ chart["U"], np.eye(p.nq - p.nc), atol=1e-12)
    Y = system.y0 + np.array([0.3, 2.0])
    q, v = system.charts.lift(chart, Y, 0.5)
    np.testing.assert_allclose(p.constraint(q), 0, atol=1e-12)
    np.testing.assert_allclose(p.constraint_jac(q) @ v, 0, atol=1e-12)
    (event,) = system.events
    Y_new = event.reset(0.5, Y)
    assert len(system.charts.history) == 2
    np.testing.assert_allclose(Y_new[:p.nq - p.nc], 0)
    q2, v2 = system.charts.lift(system.charts.current, Y_new, 0.5)
    np.testing.assert_allclose(q2, q, atol=1e-12)
    np.testing.assert_allclose(v2, v, atol=1e-12)
    # the new chart holds from its time on, the first before it
    assert system.charts.at(0.4) is chart and system.charts.at(0.5) is not chart


def test_a_run_through_new_charts_matches_the_reference():
    """The crank turns: the first chart's ratio falls below 0.5 and the run restarts
    in new charts; the outputs, each through its own chart, keep the accuracy."""
    case = next(c for c in expand(problems=["slider_crank"], formulations=["tangent"],
                                  integrators=["scipy-RK45"], rtols=[1e-8]))
    record = execute(case)
    assert record["status"] == CaseStatus.OK, record["message"]
    assert record["nevents"] >= 1 and record["mescd"] > 6


@pytest.mark.parametrize("name", [n for n, c in registry.problems().items()
                                  if issubclass(c, MechanicalProblem) and c.sparse])
def test_a_sparse_problem_refuses_the_dense_charts(name):
    assert "dense QR" in registry.get_problem_class(name)().formulate("tangent").unsupported
