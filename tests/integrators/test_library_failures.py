"""Typed failures of the library wrappers: SUNDIALS' flags and scipy's messages
(LSODA's ``istate``) become :class:`Status` members, forced here on small ODEs
written for the purpose (a right-hand side that turns NaN, a NaN Jacobian,
tolerances beyond the working precision, a solution that blows up)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.integrators.base import Status
from integrator_bench.integrators.sundials import CVODE_FAILURES, IDA_FAILURES
from integrator_bench.problems.system import OdeSystem


def ode(fun, y0=1.0, t_end=1.0, jac=None):
    return OdeSystem(t0=0.0, t_end=t_end, y0=np.atleast_1d(np.asarray(y0, float)),
                     t_eval=np.linspace(0.0, t_end, 11), atol_scale=1.0, fun=fun, jac=jac)


def nan_after_half(t, y):
    return -y if t < 0.5 else np.full_like(y, np.nan)


def run(name, system, rtol=1e-6, atol=None):
    integrator = registry.integrators()[name]()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return integrator.solve(system, rtol=rtol, atol=system.atol(rtol) if atol is None else atol)


@pytest.mark.parametrize("name", ["scipy-RK23", "scipy-RK45", "scipy-DOP853", "scipy-Radau"])
def test_scipy_step_size_underflow(name):
    """"Required step size is less than spacing between numbers." is an underflow."""
    sol = run(name, ode(nan_after_half))
    assert sol.status is Status.STEP_SIZE_UNDERFLOW and "spacing" in sol.message
    assert 0.4 <= sol.t[-1] <= 0.5 and not sol.success      # the outputs before the NaN


def test_lsoda_reads_its_istate():
    sol = run("scipy-LSODA", ode(lambda t, y: -y), rtol=1e-20, atol=1e-30)
    assert sol.status is Status.ERROR_TEST_FAILURE
    assert sol.message.startswith("LSODA istate -2: Excess accuracy requested")


@pytest.mark.parametrize("name", ["cvode-bdf", "cvode-adams"])
def test_cvode_too_much_accuracy_is_an_error_test_failure(name):
    sol = run(name, ode(lambda t, y: -y), rtol=1e-20, atol=1e-30)
    assert sol.status is Status.ERROR_TEST_FAILURE and "accuracy" in sol.message


@pytest.mark.parametrize("name", ["cvode-bdf", "cvode-adams"])
def test_cvode_convergence_failure_is_a_newton_failure(name):
    system = ode(lambda t, y: -1e6 * (y - np.cos(t)), 0.0, jac=lambda t, y: np.array([[np.nan]]))
    sol = run(name, system)
    assert sol.status is Status.NEWTON_FAILURE and "Convergence" in sol.message


@pytest.mark.parametrize("name", ["cvode-bdf", "cvode-adams"])
def test_sundials_steps_that_no_longer_advance_are_an_underflow(name):
    """On a NaN right-hand side CVODE steps on with ``t + h = t``: stopped, not a hang."""
    sol = run(name, ode(nan_after_half))
    assert sol.status is Status.STEP_SIZE_UNDERFLOW and "t + h = t" in sol.message
    assert 0.4 <= sol.t[-1] <= 0.5


def test_lsoda_at_a_zero_step_is_an_underflow_not_a_hang():
    """Near the blow-up of y' = y^2 LSODA's step size reaches zero and its steps stop
    moving without failing (it used to loop forever there): stopped, not counted."""
    sol = run("scipy-LSODA", ode(lambda t, y: y * y, t_end=2.0))
    assert sol.status is Status.STEP_SIZE_UNDERFLOW and "t + h = t" in sol.message
    assert 0.8 <= sol.t[-1] < 1.0 and sol.counts["nsteps"] < 2000


def test_ida_too_much_accuracy_is_an_error_test_failure():
    sol = run("ida", ode(lambda t, y: -y).as_dae(), rtol=1e-20, atol=1e-30)
    assert sol.status is Status.ERROR_TEST_FAILURE


def test_the_flag_tables_keep_to_sundials_numbers():
    """CV_TOO_MUCH_WORK = IDA_TOO_MUCH_WORK = -1, ..._TOO_MUCH_ACC = -2, CV_ERR_FAILURE =
    IDA_ERR_FAIL = -3, CV_CONV_FAILURE = IDA_CONV_FAIL = -4 (cvode.h, ida.h); the
    nonlinear-solver failures differ: CV_NLS_FAIL = -16, IDA_NLS_FAIL = -17."""
    for table in (CVODE_FAILURES, IDA_FAILURES):
        assert table[-1] is Status.MAX_STEPS and table[-2] is Status.ERROR_TEST_FAILURE
        assert table[-3] is Status.ERROR_TEST_FAILURE and table[-4] is Status.NEWTON_FAILURE
        assert {table[k] for k in (-5, -6, -7)} == {Status.LINEAR_SOLVER_FAILURE}
    assert CVODE_FAILURES[-16] is IDA_FAILURES[-17] is Status.NEWTON_FAILURE


def test_fmpy_cvode_errors_are_typed_by_their_flag():
    """fmpy's CVODE wrapper raises "CVode error (code FLAG) in module ..."
    (fmpy/sundials/__init__.py, CVodeSolver.step): the flag is typed as SUNDIALS'."""
    from integrator_bench.integrators.fmpy_solvers import failure

    text = "CVode error (code {}) in module CVODE, function CVode: at t = 0.5, ..."
    assert failure(text.format(-1)) is Status.MAX_STEPS
    assert failure(text.format(-3)) is Status.ERROR_TEST_FAILURE
    assert failure(text.format(-4)) is Status.NEWTON_FAILURE
    assert failure(text.format(-8)) is Status.SOLVER_FAILURE      # the right-hand side failed
    assert failure("No samples available") is Status.SOLVER_FAILURE
