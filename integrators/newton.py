"""Simplified Newton iteration for the implicit equations of fixed-step methods.

Every implicit method here (implicit Euler, trapezoidal rule, BDFk, the SDIRK
stages that start BDF) reduces a step to equations of the form

    y - c f(t, y) = r,

with a scalar ``c`` (``h``, ``h/2``, ``h b_k``, ``h gamma``). They are solved by
the simplified Newton iteration with the iteration matrix ``I - c J``, where
``J`` is the system's analytic Jacobian (``system.jac``) or, when the system
has none, a forward finite-difference Jacobian built from calls of
``system.fun`` (the harness counts those calls as function evaluations).

The Jacobian is kept over steps and re-evaluated only when an iteration fails
to converge with an old one; the LU factorization of ``I - c J`` is redone when
``J`` or ``c`` changes. The stopping rule is that of Hairer and Wanner: with the
contraction estimate ``theta_k = |d_k| / |d_{k-1}|`` the iteration stops when
``theta_k / (1 - theta_k) |d_k| <= tol`` (or ``|d_k| <= tol``), in the weighted
RMS norm ``|d| = rms(d_i / (|y_i| + scale_i))``. A fixed-step method has no
error tolerance to relate ``tol`` to, and the iteration error adds up over the
steps, so ``tol = 1e-14``: the equations are solved to about rounding level,
well below any truncation error (``tol = 1e-12`` left a floor of about
``N tol`` under the global error of SDIRK3 on a smooth problem). It is a
convergence failure when ``theta_k >= 0.9`` or after ``maxiter`` iterations,
unless the last correction is already below ``1e-10`` (rounding noise of an
ill-conditioned iteration matrix: accepted). A solve whose contraction
exceeded 0.1 with an old Jacobian marks it for re-evaluation at the next
solve, so slow convergence does not persist. When even a fresh Jacobian does
not give convergence (strongly nonlinear equations at a large step), full
Newton (Jacobian and LU renewed at every iterate, at most 20 iterations,
stopping at a correction below ``1e-10``) is tried before giving up; all of
these Jacobians, factorizations and iterations are counted.

Sparse systems: when ``jac`` returns a ``scipy.sparse`` matrix, ``I - c J``
is kept sparse and factored by SuperLU; when the system has no ``jac`` but
names its ``jac_sparsity``, the difference Jacobian is built on that pattern
with grouped columns (one call of ``fun`` per group, see
:mod:`integrator_bench.integrators.sparse`); no dense ``n x n`` matrix is then
formed. A dense Jacobian takes the dense path (LAPACK) as before.

Counters (``njev``, ``nlu``, ``nniter``, ``nnfail``) are kept in the dict
handed in. ``nnfail`` counts every convergence failure, also those recovered
by a fresh Jacobian, as CVODE counts them.

References: Hairer and Wanner, Solving Ordinary Differential Equations II,
2nd ed., Springer (1996), sect. IV.8 ("Implementation of implicit Runge-Kutta
methods", stopping criterion (8.10)-(8.13)).
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import scipy.sparse as sp

from integrator_bench.integrators.base import Status, StepFailure
from integrator_bench.integrators.control import rms
from integrator_bench.integrators.settings import JACOBIAN_EVERY, NEWTON_MAXIT
from integrator_bench.integrators.sparse import GroupedDifferences, factor, identity_minus

_EPS = np.finfo(float).eps
STALL = 1e-10  # corrections this small that stop contracting are rounding noise
FULL_MAXITER = 20
SLOW = 0.1     # contraction above which the old Jacobian is replaced after the solve


class NewtonFailure(StepFailure):
    """The iteration did not converge even with a fresh Jacobian (a smaller step may)."""

    def __init__(self, message: str):
        super().__init__(Status.NEWTON_FAILURE, message, retry=True)


def jacobian(fun, jac, scale, t, y, counts, grouped=None):
    """``J = df/dy``: the analytic ``jac`` if given (dense, or sparse as it
    comes), else forward differences of ``fun``: on the sparsity pattern of
    ``grouped`` (a :class:`~integrator_bench.integrators.sparse.GroupedDifferences`)
    when given, else dense.

    Increments ``counts["njev"]``; the difference calls of ``fun`` (``n``, or
    one per column group) are counted by the harness as function evaluations.
    """
    counts["njev"] = counts.get("njev", 0) + 1
    if jac is not None:
        J = jac(t, y)
        return sp.csc_matrix(J) if sp.issparse(J) else np.asarray(J, float)
    f0 = np.asarray(fun(t, y), float)
    if grouped is not None:
        return grouped(fun, t, y, f0, scale)
    n = y.size
    J = np.empty((n, n))
    for j in range(n):
        delta = np.sqrt(_EPS) * max(abs(y[j]), scale[j], 1e-5)
        yj = y.copy()
        yj[j] += delta
        J[:, j] = (np.asarray(fun(t, yj), float) - f0) / delta
    return J


class ImplicitSolver:
    """Solve ``y - c f(t, y) = r`` repeatedly for one system.

    Parameters
    ----------
    system : OdeSystem
        Supplies ``fun``, ``jac`` (may be None), ``jac_sparsity`` (may be None)
        and ``atol_scale``.
    counts : dict
        Counter dict updated in place (``njev``, ``nlu``, ``nniter``, ``nnfail``).
    tol : float
        Weighted RMS tolerance of the Newton corrections.
    maxiter : int
        Iterations allowed per attempt.
    jacobian_every : int
        0 (default): the Jacobian is kept until an iteration fails or
        contracts slowly; ``k`` > 0: a new Jacobian (and factorization) after
        every ``k`` iterations with the last one (ADAMS's PATTERN; 1 is full
        Newton).
    """

    def __init__(self, system, counts, tol=1e-14, maxiter=12, jacobian_every=0):
        self.fun, self.jac = system.fun, system.jac
        sparsity = getattr(system, "jac_sparsity", None)
        self.grouped = (GroupedDifferences(sparsity)
                        if system.jac is None and sparsity is not None else None)
        self.scale = np.asarray(system.atol_scale, float)
        self.n = system.n
        self.counts = counts
        for key in ("njev", "nlu", "nniter", "nnfail"):
            counts.setdefault(key, 0)
        self.tol, self.maxiter, self.every = tol, maxiter, jacobian_every
        self.age = 0             # iterations done with the current Jacobian
        self.J = None
        self.fresh = False       # J evaluated during the current solve
        self.lu = None
        self.c = None

    def jacobian(self, t, y):
        self.age = 0
        return jacobian(self.fun, self.jac, self.scale, t, y, self.counts, self.grouped)

    def _factor(self, c):
        """LU of ``I - c J``: LAPACK when ``J`` is dense, SuperLU when it is sparse."""
        self.lu = factor(identity_minus(c, self.J))
        self.c = c
        self.counts["nlu"] += 1

    def solve(self, t, guess, c, r):
        """Return ``y`` with ``y - c f(t, y) = r``, starting from ``guess``.

        Raises
        ------
        NewtonFailure
            When the iteration fails with a Jacobian evaluated in this call.
        """
        self.fresh = False
        while True:
            if self.J is None:
                self.J, self.fresh, self.lu = self.jacobian(t, guess), True, None
            if self.lu is None or c != self.c:
                self._factor(c)
            y, why, theta = self._iterate(t, guess, c, r)
            if y is not None:
                if theta > SLOW and not self.fresh:
                    self.J = None  # slow contraction: a new Jacobian for the next solve
                return y
            self.counts["nnfail"] += 1
            if self.fresh:
                break
            self.J = None  # stale Jacobian: evaluate a new one and retry
        y, why = self._full_newton(t, guess, c, r)
        if y is None:
            self.counts["nnfail"] += 1
            raise NewtonFailure(f"Newton iteration failed at t={t:.6g} ({why})")
        return y

    def _full_newton(self, t, guess, c, r):
        """Last resort: Newton with the Jacobian renewed at every iterate."""
        y = np.array(guess, dtype=float)
        weight = np.abs(y) + self.scale
        for _ in range(FULL_MAXITER):
            self.J = self.jacobian(t, y)
            self._factor(c)
            self.counts["nniter"] += 1
            g = y - c * np.asarray(self.fun(t, y), float) - r
            if not np.isfinite(g).all():
                return None, "non-finite residual"
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                d = self.lu(-g)
            if not np.isfinite(d).all():
                return None, "singular iteration matrix"
            y += d
            dnorm = rms(d / weight)
            if dnorm <= max(self.tol, STALL):
                return y, ""
        return None, f"no convergence in {FULL_MAXITER} full Newton iterations"

    def _iterate(self, t, guess, c, r):
        y = np.array(guess, dtype=float)
        weight = np.abs(y) + self.scale
        dnorm_old, theta = None, 0.0
        for _ in range(self.maxiter):
            if self.every and self.age >= self.every:   # PATTERN: a Jacobian every k iterations
                self.J, self.fresh = self.jacobian(t, y), True
                self._factor(c)
            self.age += 1
            self.counts["nniter"] += 1
            g = y - c * np.asarray(self.fun(t, y), float) - r
            if not np.isfinite(g).all():
                return None, "non-finite residual", theta
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                d = self.lu(-g)
            if not np.isfinite(d).all():
                return None, "singular iteration matrix", theta
            y += d
            dnorm = rms(d / weight)
            if dnorm <= self.tol:
                return y, "", theta
            if dnorm_old is not None:
                theta = dnorm / dnorm_old
                if theta >= 0.9:
                    if dnorm <= STALL:  # stalled at rounding level: as solved as it gets
                        return y, "", theta
                    return None, f"contraction {theta:.2g}", theta
                if theta / (1.0 - theta) * dnorm <= self.tol:
                    return y, "", theta
            dnorm_old = dnorm
        if dnorm <= STALL:
            return y, "", theta
        return None, f"no convergence in {self.maxiter} iterations", theta


#: the Newton settings of the in-house implicit methods (their :class:`ImplicitSolver`)
NEWTON_SETTINGS = (dataclasses.replace(NEWTON_MAXIT, default=12), JACOBIAN_EVERY)


def newton_solver(integrator, system, counts) -> ImplicitSolver:
    """The :class:`ImplicitSolver` of ``integrator`` (which declares
    :data:`NEWTON_SETTINGS`) for ``system``, with its settings."""
    return ImplicitSolver(system, counts, maxiter=integrator.max_newton,
                          jacobian_every=integrator.jacobian_every)
