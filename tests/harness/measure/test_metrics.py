"""Error measurement, checked on two_mass against its exact solution."""

import numpy as np
import pytest

from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.measure.metrics import (DIVERGENCE_BOUND, agreement_digits, divergence,
                                            measure, mescd, scd)
from integrator_bench.harness.run.execution import execute
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.problems.models.two_mass import TwoMass


def test_scd_definitions():
    ref = np.array([1.0, -2.0, 1e-3])
    y = ref * (1 + np.array([1e-6, -1e-8, 1e-4]))
    assert scd(y, ref) == pytest.approx(4.0)
    # mixed errors with scale 1: 1e-6/2, 2e-8/3, 1e-7/1.001; the largest is 5e-7
    assert mescd(y, ref, np.ones(3)) == pytest.approx(-np.log10(5e-7))
    assert mescd(y, ref, np.zeros(3)) == pytest.approx(scd(y, ref))


def test_measure_on_exact_solution_and_a_perturbation():
    p = TwoMass(c2=1000)
    t = p.t_eval
    R = p.exact(t)
    groups = {"error": p.component_index(p.error_components),
              "velocity": p.component_index(p.velocity_components), "lambda": np.array([], int)}
    scale = p.atol_scale_vector()
    perfect = measure(R, R, scale, groups)
    assert perfect["scd"] == 16 and perfect["err_max"] == 0 and perfect["err_lambda"] is None
    Y = R.copy()
    Y[-1, 1] += 1e-7 * abs(R[-1, 1])   # relative error 1e-7 on x2 at the end
    Y[50, 3] += 1e-5                   # a velocity error mid-run
    m = measure(Y, R, scale, groups)
    assert m["scd"] == pytest.approx(7.0, abs=1e-6)
    assert m["err_vel"] == pytest.approx(1e-5 / (1 + abs(R[50, 3])), rel=1e-9)


def test_exact_solution_satisfies_the_ode():
    p = TwoMass(c2=0.1)
    t = np.linspace(0, 10, 11)
    h = 1e-5
    Y, Yp, Ym = p.exact(t), p.exact(t + h), p.exact(t - h)
    deriv = (Yp - Ym) / (2 * h)
    for i, ti in enumerate(t):
        np.testing.assert_allclose(deriv[i], p.rhs(ti, Y[i]), rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("c2", [0.1, 1000.0])
def test_harness_error_matches_independent_computation(c2):
    """The harness's scd equals the error of the same run against expm, computed here."""
    from integrator_bench.harness.matrix import registry
    from integrator_bench.problems.system import convert

    case = next(c for c in expand(problems=[f"two_mass:c2={c2}"], integrators=["cvode-bdf"],
                                  rtols=[1e-6]))
    record = execute(case)
    assert record["status"] == CaseStatus.OK
    p = TwoMass(c2=c2)
    system = p.formulate("ode")
    sol = registry.get_integrator("cvode-bdf")().solve(system, rtol=1e-6, atol=system.atol(1e-6))
    exact = p.exact(sol.t[-1:])[0]
    rel = np.abs(sol.y[-1, :2] - exact[:2]) / np.abs(exact[:2])
    assert record["scd"] == pytest.approx(-np.log10(rel.max()), abs=1e-6)
    assert 3 < record["scd"] < 9


def test_agreement_digits():
    A = np.array([[1.0, 0.0], [2.0, 1e-3]])
    B = A + np.array([[0, 0], [2e-10, 0]])
    d = agreement_digits(A, B)
    assert d[0] == pytest.approx(10.0, abs=1e-6) and d[1] == 16


def test_divergence_bound():
    assert DIVERGENCE_BOUND == 1
    assert divergence(0.0) is None and divergence(5.0) is None   # error 1 is at the bound
    assert "mixed error 1.02 " in divergence(-0.01)
    assert "3.98e+235" in divergence(-235.6)
    assert "mixed error inf " in divergence(float("nan"))       # too large for a float


def test_monitor_error_is_orlovs_measure_over_the_window():
    from integrator_bench.harness.measure.metrics import monitor_error

    t = np.linspace(0.0, 1.0, 11)
    ref = np.where(t < 0.5, 100.0, 2.0)            # a large transient before t* = 0.5
    P = ref + np.where(t == 0.8, 0.1, 0.0) + np.where(t == 0.1, 50.0, 0.0)
    assert monitor_error(P, ref, t, 0.5) == pytest.approx(0.1 / 2.0)
    assert monitor_error(P, ref, t, 0.0) == pytest.approx(50.0 / 100.0)


class MonitoredTwoMass(TwoMass):
    """two_mass with the coupling spring's force as its monitored history."""

    name = "two_mass_monitored"
    monitor_name = "coupling spring force [N]"
    monitor_start = 2.0

    def monitor(self, t, Y):
        return self.params["k2"] * (Y[:, 1] - Y[:, 0])


def test_records_carry_the_monitor_error(tmp_path):
    """The harness's monitor_err equals E computed here from the same run against
    the exact solution; problems without a monitor record null."""
    from integrator_bench.harness.measure import references
    from integrator_bench.harness.matrix import registry
    from integrator_bench.harness.measure.metrics import monitor_error

    registry.register(MonitoredTwoMass)
    try:
        problem = MonitoredTwoMass(c2=1000.0)
        references.save(references.compute(problem), problem, tmp_path)
        case = next(c for c in expand(problems=["two_mass_monitored:c2=1000"],
                                      integrators=["scipy-RK45"], rtols=[1e-4]))
        record = execute(case, reference_dir=tmp_path)
        assert record["status"] == CaseStatus.OK
        system = problem.formulate("ode")
        sol = registry.get_integrator("scipy-RK45")().solve(system, rtol=1e-4,
                                                            atol=system.atol(1e-4))
        exact = problem.exact(sol.t)
        E = monitor_error(problem.monitor(sol.t, sol.y), problem.monitor(sol.t, exact), sol.t, 2.0)
        assert record["monitor_err"] == pytest.approx(E, rel=1e-9) and 1e-8 < E < 1e-1
    finally:
        registry.unregister("two_mass_monitored")
    plain = execute(next(c for c in expand(problems=["two_mass:c2=1000"],
                                           integrators=["scipy-RK45"], rtols=[1e-4])))
    assert plain["status"] == CaseStatus.OK and plain["monitor_err"] is None
