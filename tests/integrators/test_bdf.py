"""BDF2/3/4 on the shared driver: history committed only on accept, the
shortened last step, the dense output and the declarations."""

import numpy as np
import pytest

from integrator_bench.integrators.base import Status
from integrator_bench.integrators.bdf import BDF2, BDF3, BDF4, BDFStepper
from integrator_bench.integrators.interpolation import hermite, lagrange
from integrator_bench.problems.system import OdeSystem

BDFS = [BDF2, BDF3, BDF4]


def _power(p, t_end=1.0, t_eval=None):
    """``y' = p t^(p-1)``, ``y(0) = 0``: the solution ``t^p``."""
    t_eval = np.linspace(0.0, t_end, 11) if t_eval is None else t_eval
    return OdeSystem(t0=0.0, t_end=t_end, y0=np.array([0.0]), t_eval=t_eval, atol_scale=1.0,
                     fun=lambda t, y: np.array([p * t ** (p - 1)]),
                     jac=lambda t, y: np.zeros((1, 1)))


@pytest.mark.parametrize("cls,p", [(BDF2, 2), (BDF3, 3), (BDF4, 3)])
def test_exact_on_polynomials_with_a_shortened_last_step(cls, p):
    """BDFk is exact on ``y = t^p``, ``p <= k`` (SDIRK3 starts exactly for
    ``p <= 3``). h = 0.3 does not divide 1.3: the last step (0.1) is exact only
    with the variable-step coefficients; the output times inside steps are
    exact only if their interpolation has degree >= p."""
    t_eval = np.array([0.0, 0.05, 0.17, 0.45, 0.61, 0.8, 0.93, 1.1, 1.25, 1.3])
    system = _power(p, t_end=1.3, t_eval=t_eval)
    sol = cls().solve(system, h=0.3)
    assert sol.success, sol.message
    assert sol.counts["nsteps"] == 5
    np.testing.assert_allclose(sol.y[:, 0], t_eval ** p, rtol=0, atol=1e-12)


def test_uniform_coefficients_would_be_wrong_on_the_shortened_step():
    """The check above can fail: the uniform BDF2 formula applied to the short
    last step misses ``t^2``."""
    from integrator_bench.integrators.bdf import bdf_coefficients
    uniform = bdf_coefficients([0.9, 0.6, 0.3])
    actual = bdf_coefficients([1.0, 0.9, 0.6])
    y = lambda t: t * t  # noqa: E731
    assert np.dot(actual, [y(1.0), y(0.9), y(0.6)]) == pytest.approx(2.0, abs=1e-12)
    assert abs(np.dot(uniform, [y(1.0), y(0.9), y(0.6)]) - 2.0) > 0.1


@pytest.mark.parametrize("cls", BDFS)
def test_step_commits_nothing_until_accept(cls):
    system = _power(2)
    k = cls.order
    stepper = cls().stepper(system, {})
    assert isinstance(stepper, BDFStepper)
    t, y, h = 0.0, stepper.start(0.0, system.y0), 0.1
    for _ in range(k + 1):
        before = (list(stepper.hist_t), [v.copy() for v in stepper.hist_y])
        first = stepper.step(t, y, h)
        second = stepper.step(t, y, h)
        np.testing.assert_array_equal(first.y, second.y)
        assert list(stepper.hist_t) == before[0]
        for a, b in zip(stepper.hist_y, before[1]):
            np.testing.assert_array_equal(a, b)
        t, y = t + h, first.y
        stepper.accept(t, y)
        assert stepper.hist_t[-1] == t and len(stepper.hist_t) == min(len(before[0]) + 1, k + 1)


@pytest.mark.parametrize("cls", BDFS)
def test_dense_output_is_the_polynomial_through_the_k_plus_1_latest_values(cls):
    """Start steps carry the cubic Hermite interpolant of their ends; a BDF
    step's dense output passes through the new value and the k previous ones."""
    k = cls.order
    A = np.array([[0.0, 1.0], [-1.0, 0.0]])
    system = OdeSystem(t0=0.0, t_end=2.0, y0=np.array([1.0, 0.0]),
                       t_eval=np.array([0.0, 2.0]), atol_scale=1.0,
                       fun=lambda t, y: A @ y, jac=lambda t, y: A)
    stepper = cls().stepper(system, {})
    assert stepper.dense_order == k
    t, y, h = 0.0, stepper.start(0.0, system.y0), 0.1
    for m in range(1, k + 2):
        step = stepper.step(t, y, h)
        if m < k:
            te = t + 0.37 * h
            expected = hermite(t, h, y, A @ y, step.y, A @ step.y)(te)
            np.testing.assert_allclose(step.dense(te), expected, rtol=0, atol=1e-15)
            np.testing.assert_allclose(step.dense(t + h), step.y, rtol=0, atol=1e-15)
        else:
            nodes = list(stepper.hist_t)[-k:] + [t + h]
            values = list(stepper.hist_y)[-k:] + [step.y]
            for tn, yn in zip(nodes, values):
                np.testing.assert_allclose(step.dense(tn), yn, rtol=0, atol=1e-14)
            te = t + 0.37 * h
            np.testing.assert_allclose(step.dense(te), lagrange(nodes, values, te),
                                       rtol=0, atol=1e-15)
        t, y = t + h, step.y
        stepper.accept(t, y)


@pytest.mark.parametrize("cls", BDFS)
def test_output_error_inside_steps_falls_at_the_method_order(cls):
    """On y' = -y with no output time on the grid (the first one inside the
    start steps, the others inside BDF steps), the output error falls at
    order k: the output polynomials do not degrade the method's O(h^k)."""
    k = cls.order
    errs = []
    t_eval = np.concatenate([[0.0], 0.0123 + np.arange(7) / 7, [1.0]])
    for h in (0.02, 0.01):
        system = OdeSystem(t0=0.0, t_end=1.0, y0=np.array([1.0]), t_eval=t_eval,
                           atol_scale=1.0, fun=lambda t, y: -y,
                           jac=lambda t, y: -np.eye(1))
        sol = cls().solve(system, h=h)
        assert sol.success, sol.message
        errs.append(np.max(np.abs(sol.y[:, 0] - np.exp(-sol.t))))
    assert np.log2(errs[0] / errs[1]) >= k - 0.3, errs


@pytest.mark.parametrize("cls", BDFS)
def test_declarations(cls):
    assert not cls.adaptive and not cls.projects and cls.dense_output
    assert cls.takes_h() and cls.has_stepper()
    assert cls.mode_unsupported(1e-6, None) is not None
    assert cls.mode_unsupported(None, 0.1) is None


def test_newton_failure_ends_the_run_with_its_status():
    """y' = y^2 from y(0) = 1 blows up at t = 1; at h = 2 the SDIRK start has
    no real solution of its stage equation."""
    system = OdeSystem(t0=0.0, t_end=4.0, y0=np.array([1.0]), t_eval=np.array([0.0, 4.0]),
                       atol_scale=1.0, fun=lambda t, y: y * y,
                       jac=lambda t, y: np.array([[2.0 * y[0]]]))
    sol = BDF3().solve(system, h=2.0)
    assert not sol.success and sol.status is Status.NEWTON_FAILURE
    assert "Newton" in sol.message and sol.counts["nnfail"] >= 1
