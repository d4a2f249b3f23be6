"""The classical fixed-step integrators: order, counters, output times, blow-ups, seed 002.

Integrators are selected from the live registry by what they declare, never by
name lists: every fixed-step integrator with a declared order has its observed
order checked (``ibench verify``'s ladder), plugins included.
"""

import numpy as np
import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.run.execution import counted
from integrator_bench.harness.checks.verify import FIXED_TOL, order_on
from integrator_bench.harness.checks.verify_problems import ORDER_PROBLEMS, dahlquist
from integrator_bench.integrators import rkc as rkc_module
from integrator_bench.integrators.base import Status
from integrator_bench.integrators.bdf import BDF2, BDF3, bdf_coefficients
from integrator_bench.integrators.rkc import rkc_coefficients, rkc_step, stability_polynomial
from integrator_bench.problems.models.spring_pendulum import SpringPendulum
from integrator_bench.problems.system import OdeSystem, convert, takes

INTEGRATORS = registry.integrators()


def _select(pred):
    return sorted(name for name, cls in INTEGRATORS.items() if pred(cls))


# the order problems are ODEs, DAEs and mechanical systems; an integrator of FMUs
# only has its order checked on an FMU (tests/problems/fmu/test_fmu_problem.py)
FIXED_ORDER = _select(lambda c: not c.adaptive and c.order is not None
                      and c.accepts & {"ode", "dae", "mechanical"})
FIXED_ODE = _select(lambda c: not c.adaptive and "ode" in c.accepts)
IMPLICIT_FIXED_ODE = _select(lambda c: not c.adaptive and c.implicit and "ode" in c.accepts)
EXPLICIT_FIXED_ODE = _select(lambda c: not c.adaptive and not c.implicit and "ode" in c.accepts)
ORDER_CASES = [(name, p) for name in FIXED_ORDER for p in ORDER_PROBLEMS
               if takes(p.make(p.t_fixed), INTEGRATORS[name])]


def test_every_fixed_order_method_has_a_test_problem():
    covered = {name for name, _ in ORDER_CASES}
    assert FIXED_ORDER and set(FIXED_ORDER) == covered


@pytest.mark.parametrize("name,problem", ORDER_CASES,
                         ids=[f"{n}-{p.name}" for n, p in ORDER_CASES])
def test_observed_order_within_0_3_of_declared(name, problem):
    cls = INTEGRATORS[name]
    result = order_on(cls, problem)
    assert result.observed_order is not None, result.detail
    assert abs(result.observed_order - cls.order) <= FIXED_TOL, \
        f"{name} on {problem.name}: observed {result.observed_order:.2f}, declared {cls.order}"


def test_bdf_coefficients_are_the_classical_ones():
    """The classical BDF coefficients a_j / (h b) on the uniform grid (h = 1)
    (Hairer and Wanner, Solving ODEs II, 2nd ed., sect. III.1)."""
    table = {2: ([1, -4 / 3, 1 / 3], 2 / 3), 3: ([1, -18 / 11, 9 / 11, -2 / 11], 6 / 11),
             4: ([1, -48 / 25, 36 / 25, -16 / 25, 3 / 25], 12 / 25)}
    for k, (a, b) in table.items():
        alpha = bdf_coefficients([float(k - j) for j in range(k + 1)])
        np.testing.assert_allclose(alpha * b, a, rtol=1e-13, atol=1e-14)


@pytest.mark.parametrize("s", [2, 3, 7, 30])
def test_rkc_step_realises_its_stability_polynomial(s):
    coef = rkc_coefficients(s)
    assert coef["c"][s] == pytest.approx(1.0, abs=1e-12)
    for z in (-0.1, -0.5 * 0.653 * s * s, -0.95 * 0.653 * s * s):
        y = rkc_step(lambda t, y: z * y, 0.0, np.array([1.0]), 1.0, np.array([z]), coef)
        assert y[0] == pytest.approx(stability_polynomial(s, z).real, rel=1e-10, abs=1e-12)
    if s >= 3:  # bounded on the damped interval [-0.653 s^2 * 0.95, 0]
        z = np.linspace(-0.95 * 0.653 * s * s, 0.0, 500)
        assert np.max(np.abs(stability_polynomial(s, z))) <= 1.0 + 1e-9


def _stiff_decay(lam, t_end=1.0, n_out=11):
    """y1' = -lam (y1 - cos t) (stiff, spectral radius lam), y2' = -y2 (y2 = e^-t).

    y1(0) = 0 starts a transient, so f(y0) has a component along the stiff
    direction and the power method finds lam (from y1(0) = 1 it would see -1 only).
    """
    return OdeSystem(t0=0.0, t_end=t_end, y0=np.array([0.0, 1.0]),
                     t_eval=np.linspace(0.0, t_end, n_out), atol_scale=1.0,
                     fun=lambda t, y: np.array([-lam * (y[0] - np.cos(t)), -y[1]]))


@pytest.mark.parametrize("mode", [{"h": 0.013}, {"h": 0.0065}, {"rtol": 1e-6, "atol": 1e-6}],
                         ids=["h=0.013", "h=0.0065", "rtol=1e-6"])
def test_rkc_runs_at_a_fixed_step_and_under_error_control(mode):
    """One integrator, two modes: h = 0.013 needs 5 stages at lam = 1000
    (explicit Euler would need h < 0.002); output times fall inside steps and are
    met by the Hermite dense output at second order, whose end slope is the next
    step's F_n: they cost no evaluation (same nfev as with no output inside)."""
    nfev = []
    for n_out in (2, 11):   # the last run, with outputs inside steps, is measured
        system, counters = counted(_stiff_decay(1000.0, n_out=n_out))
        sol = INTEGRATORS["rkc"]().solve(system, **mode)
        assert sol.success, sol.message
        np.testing.assert_array_equal(sol.t, system.t_eval)
        nfev.append(counters["nfev"].n)
    assert nfev[0] == nfev[1]
    err = np.max(np.abs(sol.y[:, 1] - np.exp(-sol.t)))
    assert err < 2e-5
    if "h" in mode:
        assert sol.counts["nsteps"] == int(np.ceil(1.0 / mode["h"]))
        assert err > 1e-9                  # not exact: the error is the method's
        assert err < 0.3 * mode["h"] ** 2  # second order in h
    else:
        assert sol.counts["nsteps"] + sol.counts["nreject"] > 0


def test_rkc_stage_limit_at_a_fixed_step_and_under_error_control(monkeypatch):
    """lam = 1e6 at h = 1 needs about 1360 stages (> 1000): a method limit at a
    fixed step; under error control the step is cut to keep s <= 250."""
    sol = INTEGRATORS["rkc"]().solve(_stiff_decay(1e6), h=1.0)
    assert sol.status is Status.METHOD_LIMIT and "stages" in sol.message
    used = []
    real = rkc_module.stages_for
    monkeypatch.setattr(rkc_module, "stages_for", lambda h, rho: used.append(real(h, rho)) or used[-1])
    sol = INTEGRATORS["rkc"]().solve(_stiff_decay(1e6, t_end=0.5), rtol=1e-3, atol=1e-3)
    assert sol.success, sol.message
    # the cap binds (h rho rounding may give 249) and holds, but for the last
    # step, stretched by up to 10 % to end at t_end
    assert 240 <= max(used[:-1]) <= 250 and used[-1] <= 262


def _oscillator(t_end=2.0, n_out=7, with_jac=True):
    A = np.array([[0.0, 1.0], [-1.0, 0.0]])
    return OdeSystem(t0=0.0, t_end=t_end, y0=np.array([1.0, 0.0]),
                     t_eval=np.linspace(0.0, t_end, n_out), atol_scale=1.0,
                     fun=lambda t, y: A @ y, jac=(lambda t, y: A) if with_jac else None)


def _exact(t):
    return np.column_stack([np.cos(t), -np.sin(t)])


@pytest.mark.parametrize("name", FIXED_ODE)
def test_output_times_inside_steps_are_met_at_the_method_order(name):
    """h does not divide the span and no output time is on the grid: every output
    time is returned exactly, the final time is reached, and the error at the
    output times falls with h at (nearly) the declared order."""
    cls = INTEGRATORS[name]
    errs = []
    for h in (0.11, 0.055):
        system = _oscillator()
        sol = cls().solve(system, h=h)
        assert sol.success, sol.message
        np.testing.assert_array_equal(sol.t, system.t_eval)
        errs.append(np.max(np.abs(sol.y - _exact(sol.t))))
    if cls.order is not None and errs[1] > 1e-12:
        assert np.log2(errs[0] / errs[1]) >= cls.order - 0.5, errs


@pytest.mark.parametrize("name", IMPLICIT_FIXED_ODE)
@pytest.mark.parametrize("with_jac", [True, False], ids=["analytic-jac", "fd-jac"])
def test_newton_and_jacobian_counters_are_consistent(name, with_jac):
    system, counters = counted(_oscillator(t_end=1.0, n_out=2, with_jac=with_jac))
    sol = INTEGRATORS[name]().solve(system, h=0.05)
    assert sol.success, sol.message
    c = sol.counts
    assert c["nsteps"] == 20 and c.get("nreject", 0) == 0
    assert c["njev"] >= 1 and c["nlu"] >= 1
    nfev = counters["nfev"].n
    if with_jac:
        assert counters["njev"].n == c["njev"]       # every Jacobian is an analytic call
    else:
        assert counters["njev"] is None
        assert nfev >= (system.n + 1) * c["njev"]    # each FD Jacobian costs n + 1 calls
    if "nniter" in c:                                 # Newton-based methods
        assert c["nniter"] >= c["nsteps"]             # at least one iteration per step
        assert 0 <= c["nnfail"] <= c["nniter"]
        extra = 0 if with_jac else (system.n + 1) * c["njev"]
        assert nfev >= c["nniter"] + extra            # every iteration evaluates f once


def test_newton_failure_is_a_failed_solution_not_an_exception():
    """y' = y^2 from y(0) = 1 blows up at t = 1: implicit Euler with h = 2 has no
    real solution of y - 2 y^2 = 1, so Newton must fail and say so."""
    system = OdeSystem(t0=0.0, t_end=2.0, y0=np.array([1.0]), t_eval=np.array([0.0, 2.0]),
                       atol_scale=1.0, fun=lambda t, y: y * y,
                       jac=lambda t, y: np.array([[2.0 * y[0]]]))
    sol = INTEGRATORS["implicit-euler"]().solve(system, h=2.0)
    assert not sol.success and "Newton" in sol.message
    assert sol.counts["nnfail"] >= 1


@pytest.mark.parametrize("name", EXPLICIT_FIXED_ODE)
def test_explicit_blow_up_ends_as_failure_quickly(name):
    """y' = -1e6 y at h = 1 is far outside every explicit stability region."""
    system = dahlquist(-1e6, 1000.0)
    sol = INTEGRATORS[name]().solve(system, h=1.0)
    assert not sol.success
    assert sol.message


def _energy_ratio(cls):
    problem = SpringPendulum(k=1000.0, t_end=8.0)
    system = problem.formulate("ode")
    sol = cls().solve(system, h=0.01)
    assert sol.success, sol.message
    energy = problem.invariants()["energy"](sol.t, sol.y)
    return energy[-1] / energy[0]


def test_seed_002_bdf3_grows_while_bdf2_damps_on_the_spring_pendulum():
    """Seed 002 (k = 1000, h = 0.01, t = 8): BDF3 misbehaves, BDF2 does not.

    The fast mode (about +-i sqrt(k)) has, at z = 0.316i, largest root 0.998 for
    BDF2 and 1.0022 for BDF3 (recomputed from their characteristic roots): over t = 8 the energy
    measured here falls to about 0.05 of its start with BDF2 and grows about
    20-fold with BDF3.
    """
    assert _energy_ratio(BDF2) < 0.2
    assert _energy_ratio(BDF3) > 5.0
