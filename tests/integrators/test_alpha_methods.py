"""HHT-alpha, Newmark and generalized-alpha on index-3 mechanical systems.

Every integrator accepting the ``"mechanical"`` kind (found in the live
registry) on the Cartesian pendulum, built here as a MechanicalSystem and
checked against the minimal-coordinate pendulum solved by DOP853 at rtol 1e-12,
and on Andrews' squeezer against the project's reference.
"""

import dataclasses

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from integrator_bench.harness.measure import references

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.run.execution import counted, execute
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.integrators import alpha_methods as am
from integrator_bench.integrators.base import COUNTERS, Status
from integrator_bench.problems.system import MechanicalSystem

M_, L_, G_ = 1.0, 1.0, 9.81
DRIFT = 1e-12   # |g(q)| at outputs: step ends, or the dense output projected onto g = 0


def mechanical(adaptive=None):
    """Registered integrators taking mechanical systems: those with an error
    estimate (adaptive=True), without (False), or all (None)."""
    return [pytest.param(name, id=name) for name, cls in registry.integrators().items()
            if "mechanical" in cls.accepts and adaptive in (None, cls.adaptive)]


def fixed_step():
    """Every mechanical integrator that takes a step size h."""
    return [pytest.param(name, id=name) for name, cls in registry.integrators().items()
            if "mechanical" in cls.accepts and cls.takes_h()]


def pendulum(theta0=np.pi / 3, omega0=2.0, t_end=1.0, n_out=10, grav=G_):
    """Cartesian pendulum q = (x, y), g(q) = (x^2 + y^2 - L^2) / 2, and its reference."""
    q0 = L_ * np.array([np.sin(theta0), -np.cos(theta0)])
    v0 = L_ * omega0 * np.array([np.cos(theta0), np.sin(theta0)])
    lam0 = M_ * (v0 @ v0 - grav * q0[1]) / L_**2
    a0 = (np.array([0.0, -M_ * grav]) - q0 * lam0) / M_
    t_eval = np.linspace(0.0, t_end, n_out + 1)
    system = MechanicalSystem(
        t0=0.0, t_end=t_end, y0=np.r_[q0, v0, lam0], t_eval=t_eval, atol_scale=np.ones(5),
        error_mask=np.r_[True, True, False, False, False], nq=2, nc=1,
        mass=lambda q: M_ * np.eye(2),
        force=lambda t, q, v: np.array([0.0, -M_ * grav]),
        constraint=lambda q: np.array([(q @ q - L_**2) / 2]),
        constraint_jac=lambda q: q.reshape(1, 2).copy(),
        accel_term=lambda q, v: np.array([v @ v]),
        tangent=lambda t, q, v, a, lam: (lam[0] * np.eye(2), np.zeros((2, 2))),
        a0=a0)
    z = solve_ivp(lambda t, z: [z[1], -grav / L_ * np.sin(z[0])], (0.0, t_end), [theta0, omega0],
                  method="DOP853", rtol=1e-12, atol=1e-12, t_eval=t_eval).y
    ref = np.column_stack([L_ * np.sin(z[0]), -L_ * np.cos(z[0])])
    return system, ref


def energy(Y):
    return 0.5 * M_ * (Y[:, 2] ** 2 + Y[:, 3] ** 2) + M_ * G_ * Y[:, 1]


def position_error(sol, ref):
    return float(np.max(np.abs(sol.y[:, :2] - ref)))


def constraint_residual(sol):
    """Largest |g(q)| over the outputs, relative to L^2 / 2."""
    q = sol.y[:, :2]
    return float(np.max(np.abs(np.sum(q * q, axis=1) - L_**2)))


@pytest.mark.parametrize("name", fixed_step())
def test_fixed_step_order_constraint_and_energy(name):
    cls = registry.get_integrator(name)
    system, ref = pendulum()
    hs = (0.02, 0.01, 0.005)
    sols = [cls().solve(system, h=h) for h in hs]
    assert all(s.success for s in sols), [s.message for s in sols]
    errors = [position_error(s, ref) for s in sols]
    orders = np.log2(np.array(errors[:-1]) / errors[1:])
    assert np.all(np.abs(orders - cls.order) < 0.25), (errors, orders)
    for s in sols:
        np.testing.assert_array_equal(s.t, system.t_eval)
        assert constraint_residual(s) < 1e-10
    drift = [float(np.max(np.abs(energy(s.y) - energy(s.y[:1])))) for s in sols]
    assert drift[-1] < 0.05 * M_ * G_ * L_
    assert drift[-1] < drift[0] / 2 ** (2 * cls.order - 1)   # shrinks with h at about the order


@pytest.mark.parametrize("beta", [0.25, 0.3])
def test_newmark_with_gamma_one_half_is_second_order(beta):
    system, ref = pendulum()
    errors = [position_error(am.Newmark(beta=beta, gamma=0.5).solve(system, h=h), ref)
              for h in (0.02, 0.01, 0.005)]
    orders = np.log2(np.array(errors[:-1]) / errors[1:])
    assert np.all(np.abs(orders - 2) < 0.2), (errors, orders)


@pytest.mark.parametrize("name", mechanical(adaptive=True))
def test_adaptive_reaches_reference(name):
    """The step-size control bounds the local error: the global error stays within
    the sum of the per-step tolerances and falls as rtol falls."""
    cls = registry.get_integrator(name)
    system, ref = pendulum(theta0=np.pi / 2, omega0=0.0, t_end=2.0, n_out=20)
    errors = []
    for rtol in (1e-4, 1e-6, 1e-8):
        sol = cls().solve(system, rtol=rtol)
        assert sol.success, sol.message
        np.testing.assert_array_equal(sol.t, system.t_eval)
        err = position_error(sol, ref)
        assert err < 5 * sol.counts["nsteps"] * rtol, (rtol, err, sol.counts)
        assert constraint_residual(sol) < 1e-10
        errors.append(err)
    assert errors[1] < errors[0] / 10 and errors[2] < errors[1] / 10, errors


@pytest.mark.parametrize("name", mechanical(adaptive=True))
def test_adaptive_on_squeezer_reaches_reference(name):
    problem = registry.get_problem_class("squeezer")()
    ref = references.load(problem, compute_missing=False)
    system = problem.formulate("i3").mechanical
    nq = system.nq
    cls = registry.get_integrator(name)
    for rtol in (1e-5, 1e-7):
        sol = cls().solve(system, rtol=rtol)
        assert sol.success, sol.message
        err = float(np.max(np.abs(sol.y[:, :nq] - ref.Y[:, :nq])))
        assert err < 5 * sol.counts["nsteps"] * rtol, (rtol, err, sol.counts)
        g = max(float(np.max(np.abs(system.constraint(y[:nq])))) for y in sol.y)
        assert g < 1e-11       # 1e-10 relative to the mechanism's lengths (0.1 m)


def runs(name):
    """The modes ``name`` runs in: rtol 1e-6 when it has an error estimate, h 0.01
    when it takes a step size."""
    cls = registry.get_integrator(name)
    return ([{"rtol": 1e-6}] if cls.adaptive else []) + ([{"h": 0.01}] if cls.takes_h() else [])


@pytest.mark.parametrize("name", mechanical())
def test_counters_present_and_consistent(name):
    cls = registry.get_integrator(name)
    system, _ = pendulum()
    for kw in runs(name):
        wrapped, calls = counted(system)
        c = cls().solve(wrapped, **kw).counts
        assert set(c) == set(COUNTERS)
        assert c["nfev"] == calls["nfev"].n and c["njev"] == calls["njev"].n
        assert c["nniter"] <= c["nfev"] <= c["nniter"] + 1   # + the start value a_0
        assert c["njev"] >= 1 and c["nlu"] >= c["nsteps"] >= 1
        if "h" in kw:   # a Newton failure at a fixed step ends the run: a success has none
            assert c["nsteps"] == 100 and c["nreject"] == 0 and c["nnfail"] == 0
        else:           # each failure cost at least one iteration
            assert isinstance(c["nnfail"], int) and 0 <= c["nnfail"] <= c["nniter"]


@pytest.mark.parametrize("name", mechanical())
def test_newton_failure_is_returned_not_raised(name):
    cls = registry.get_integrator(name)
    system, _ = pendulum()

    def force(t, q, v):
        return np.array([0.0, -M_ * G_]) if t < 0.45 else np.full(2, np.nan)

    broken = dataclasses.replace(system, force=force)
    for kw in runs(name):
        sol = cls().solve(broken, **kw)
        assert not sol.success and sol.status is Status.NEWTON_FAILURE, sol.message
        assert "Newton" in sol.message
        assert 1 <= len(sol.t) <= 5 and np.all(np.isfinite(sol.y))
        np.testing.assert_array_equal(sol.t, system.t_eval[:len(sol.t)])
        assert sol.counts["nnfail"] >= 1


@pytest.mark.parametrize("name", mechanical())
def test_runs_in_the_matrix_on_the_i3_pendulum(name):
    cases = expand(problems=["pendulum"], formulations=["i3"], integrators=[name],
                   rtols=[1e-6], hs=[0.01])
    cases = [case for case in cases if case.unsupported is None]
    assert len(cases) == len(runs(name))
    order = registry.get_integrator(name).order
    for case in cases:
        record = execute(case)
        assert record["status"] == CaseStatus.OK, record["message"]
        assert record["nfev"] > 0 and record["cpu_s"] > 0
        assert record["drift_pos"] < DRIFT, (case, record["drift_pos"])
        assert record["scd"] > (1.0 if order >= 2 else -1.0)   # first-order Newmark: coarse h
        for key in ("nsteps", "nlu", "nreject", "nniter", "nnfail", "njev"):
            assert record[key] == record["solver_counts"][key]
        assert record["nfev"] == record["solver_counts"]["nfev"]


def test_bad_parameters_name_the_value_and_the_range():
    system, _ = pendulum()

    for cls, values, text in ((am.HHT, {"alpha": -0.5}, r"alpha=-0\.5 .*\[-0\.333333, 0\]"),
                              (am.Newmark, {"beta": 0.2, "gamma": 0.6},
                               r"beta=0\.2, gamma=0\.6"),
                              (am.GeneralizedAlpha, {"rho_inf": 1.5}, r"rho_inf=1\.5 .*\[0, 1\]")):
        with pytest.raises(ValueError, match=text):
            cls(**values).solve(system, h=0.01)
    assert am.Newmark.mode_unsupported(1e-6, None) and am.HHT.mode_unsupported(1e-6, None) is None
    with pytest.raises(ValueError, match="no error estimate"):
        am.GeneralizedAlpha().solve(system, rtol=1e-6)


@pytest.mark.parametrize("name", mechanical(adaptive=True))
def test_variable_steps_keep_the_order(name):
    """Error against accepted steps over a tolerance ladder falls as nsteps^-order
    (the start value a_0 must belong to the first step actually taken, not to a
    rejected try). Uniform circular motion: the pendulum without gravity."""
    cls = registry.get_integrator(name)
    system, ref = pendulum(theta0=np.pi / 2, omega0=2.0, t_end=10.0, n_out=1, grav=0.0)
    steps, errors = [], []
    for rtol in (1e-5, 1e-6, 1e-7, 1e-8):
        sol = cls().solve(system, rtol=rtol)
        steps.append(sol.counts["nsteps"])
        errors.append(position_error(sol, ref))
    constant = np.array(errors) * np.array(steps, float) ** cls.order   # err = C nsteps^-p
    assert constant.max() < 2 * constant.min(), (steps, errors)


def test_sparse_matrices_give_the_dense_result():
    import scipy.sparse as sp
    system, _ = pendulum()
    sparse = dataclasses.replace(
        system, mass=lambda q: sp.csr_matrix(M_ * np.eye(2)),
        constraint_jac=lambda q: sp.csr_matrix(q.reshape(1, 2)),
        tangent=lambda t, q, v, a, lam: (sp.csr_matrix(lam[0] * np.eye(2)), sp.csr_matrix((2, 2))))
    for cls, kw, cols, tol in ((am.HHT, {"rtol": 1e-6}, slice(0, 2), 1e-7),   # Newton to 1e-8
                               (am.GeneralizedAlpha, {"h": 0.01}, slice(None), 1e-8)):
        dense_sol, sparse_sol = cls().solve(system, **kw), cls().solve(sparse, **kw)
        assert sparse_sol.success
        np.testing.assert_allclose(sparse_sol.y[:, cols], dense_sol.y[:, cols], rtol=0, atol=tol)


@pytest.mark.parametrize("name", fixed_step())
def test_outputs_inside_steps_come_from_the_dense_output(name):
    """h = 0.03 does not divide the output spacing 0.1: the steps are t0 + k h
    (33 of them, and a last one of 0.01 to t_end); the outputs at 0.3, 0.6, 0.9
    are step ends, the others come from the cubic Hermite extension projected
    onto g = 0: all satisfy the constraint to round-off, with a position error
    no larger than at a step size that lands on every output time."""
    cls = registry.get_integrator(name)
    system, ref = pendulum()
    sol = cls().solve(system, h=0.03)
    assert sol.success and sol.counts["nsteps"] == 34
    np.testing.assert_array_equal(sol.t, system.t_eval)
    assert constraint_residual(sol) < 1e-10
    landing = position_error(cls().solve(system, h=0.025), ref)
    assert position_error(sol, ref) < 2 * (0.03 / 0.025) ** cls.order * landing


def test_dense_output_interpolates_the_step_and_has_order_three():
    """The step's continuous extension meets both step values, and its error
    at the midpoint against a step of half the size falls as h^3 or faster
    (q, v; lam is linear: h^2); its positions satisfy the constraint."""
    system, _ = pendulum(theta0=np.pi / 2, omega0=0.0)
    cls = am.HHT
    errs = []
    for h in (0.02, 0.01, 0.005):
        counts = {}
        st = cls().stepper(system, counts)
        y0 = st.start(0.0, system.y0)
        step = st.step(0.0, y0, h)
        np.testing.assert_allclose(step.dense(0.0), y0, rtol=0, atol=1e-15)
        np.testing.assert_allclose(step.dense(h), step.y, rtol=0, atol=1e-15)
        half = cls().stepper(system, {})
        half.start(0.0, system.y0)
        mid = step.dense(h / 2)
        assert abs(mid[:2] @ mid[:2] - L_**2) < 1e-12
        errs.append(np.abs(mid - half.step(0.0, y0, h / 2).y))
    errs = np.array(errs)
    qv = errs[:, :4].max(axis=1)
    assert np.all(np.log2(qv[:-1] / qv[1:]) > 2.7), qv
    assert np.all(np.log2(errs[:-1, 4] / errs[1:, 4]) > 1.7), errs[:, 4]


def test_rest_of_an_adaptive_run_is_split_into_equal_steps():
    """Near t_end the step is bounded so that the run ends with equal steps no
    longer than the last one, not with one much shorter than the one before (it
    disturbs lam); a run at a fixed step keeps the driver's grid."""
    system, _ = pendulum()            # t_end = 1
    for kw in ({"rtol": 1e-6, "atol": 1e-6 * system.atol_scale}, {}):
        stepper = am.HHT().stepper(system, {}, **kw)
        y0 = stepper.start(0.0, system.y0)
        assert stepper.max_step(0.0, y0) == np.inf          # no step accepted yet
        step = stepper.step(0.0, y0, 0.2)
        stepper.accept(0.2, step.y)
        bounds = [stepper.max_step(t, step.y) for t in (0.2, 0.5, 0.6, 0.85)]
        if kw:   # rest 0.8 >= 3 h_last; 0.5 in 3 steps, 0.4 in 2, 0.15 in 1
            np.testing.assert_allclose(bounds, [np.inf, 0.5 / 3, 0.2, 0.15], rtol=1e-12)
        else:
            assert bounds == [np.inf] * 4
