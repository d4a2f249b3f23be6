"""The trapezoidal rule on the index-3 augmented Lagrangian formulation with
mass-orthogonal projections (ALI3-P).

Bayo and Ledesma (Nonlinear Dyn. 9 (1996) 113-130) and Cuadrado, Cardenal and
Bayo (Multibody Syst. Dyn. 1 (1997) 259-280): the integrator takes an
:class:`~integrator_bench.problems.system.AugmentedLagrangianSystem` (the ``al3``
formulation: ``M q'' = f - G^T lam``, ``g(q) = 0`` with a penalty ``alpha`` and
a tolerance) and advances ``y = (q, v, lam)`` at a fixed step ``h`` by the
trapezoidal rule, the Newmark member ``beta = 1/4``, ``gamma = 1/2``::

    q_{n+1} = q^ + beta h^2 a_{n+1},   q^ = q_n + h v_n + (1/2 - beta) h^2 a_n
    v_{n+1} = v^ + gamma h a_{n+1},    v^ = v_n + (1 - gamma) h a_n

Per step, Newton's method on ``q_{n+1}`` for the dynamics in augmented
Lagrangian form, scaled by ``beta h^2``::

    F(q) = M (q - q^) + beta h^2 (G^T (lam* + alpha g) - f) = 0,
    dF/dq ~ W = M + gamma h C + beta h^2 (K + alpha G^T G)

with ``K``, ``C`` from ``system.tangent`` (``K`` at the multipliers ``lam* +
alpha g``), evaluated and factored anew at every iteration; after each Newton
update the multipliers are updated, ``lam* <- lam* + alpha g(q)`` (the
iteration starts from the step's predictor ``a_{n+1} = a_n`` and ``lam* =
lam_n``). It stops when the largest position change is within ``tolerance``
of the position scale and ``|g|`` within ``tolerance`` of the scale of ``G q``;
``lam_{n+1} = lam*``. Then the velocities and accelerations are projected
mass-orthogonally, with the same ``W`` and ``P = W - beta h^2 alpha G^T G``::

    W v = P v_{n+1},            W a = P a_{n+1} - beta h^2 alpha G^T (d(G v)/dq) v

so that ``G v = 0`` and ``G a + (d(G v)/dq) v = 0`` hold in the penalty's
least-squares sense. Constraints that depend on time, ``g(q, t) = 0``, add
their driving terms: ``W v = P v_{n+1} - beta h^2 alpha G^T g_t`` for ``G v +
g_t = 0``, and the acceleration term is then ``(d(G v)/dq) v + 2 G_t v + g_tt``. ``W`` is symmetric positive definite whenever ``M`` is and
``K``, ``C`` are small, whatever the rank of ``G``: redundant constraints and
singular configurations need no special treatment (Bayo and Ledesma's point).
The penalty is ``alpha = penalty * mass_scale / (beta h^2 jacobian_scale^2)``
(the formulation's relative penalty, see the system), so that a multiplier
update contracts the violation by about ``1 / (1 + penalty)`` at any step.

A run ends with ``NEWTON_FAILURE`` when the iteration does not converge in
``max_iterations`` (a factorization that fails or a non-finite state counts
as not converging). Output times inside a step take cubic Hermite interpolation
in ``q`` (from ``q``, ``v``) and ``v`` (from ``v``, ``a``) and linear in ``lam``.

Counters: ``nsteps`` (the driver), ``nniter`` Newton iterations, ``nlu``
factorizations of ``W`` (one per iteration), ``nfev`` ``force`` calls (one per
iteration), ``njev`` ``tangent`` calls (one per iteration), ``nnfail`` failed
iterations.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from integrator_bench.integrators.base import Integrator, Status, Step, StepFailure, Stepper
from integrator_bench.integrators.interpolation import hermite
from integrator_bench.integrators.settings import Setting
from integrator_bench.integrators.sparse import factor

#: the trapezoidal rule as a Newmark member
BETA, GAMMA = 0.25, 0.5


class AugmentedLagrangianStepper(Stepper):
    """One fixed-step run of ALI3-P (see the module docstring)."""

    def __init__(self, system, counts, max_iterations, penalty=None, tolerance=None):
        super().__init__(system, counts)
        self.max_iterations = max_iterations
        self.penalty = system.penalty if penalty is None else penalty
        self.tolerance = system.tolerance if tolerance is None else tolerance
        self.a = np.array(system.a0, float)
        self.pending = None
        self.sparse = sp.issparse(system.mass(system.y0[:system.nq]))

    def step(self, t, y, h):
        s = self.system
        q, v, lam = s.split(y)
        bh2, gh = BETA * h * h, GAMMA * h
        q_hat = q + h * v + (0.5 - BETA) * h * h * self.a
        v_hat = v + (1 - GAMMA) * h * self.a
        alpha = self.penalty * s.mass_scale / (bh2 * s.jacobian_scale ** 2)
        new = self.iterate(t + h, q_hat, v_hat, bh2, gh, alpha, self.a, lam, q)
        if new is None:
            self.counts["nnfail"] += 1
            raise StepFailure(Status.NEWTON_FAILURE,
                              f"augmented Lagrangian iteration did not converge in "
                              f"{self.max_iterations} iterations at t={t + h:.6g} (h={h:.3g})")
        q1, v1, a1, lam1 = new
        self.pending = a1
        qs, vs = hermite(t, h, q, v, q1, v1), hermite(t, h, v, self.a, v1, a1)

        def dense(te):
            w = (te - t) / h
            return np.concatenate([qs(te), vs(te), (1 - w) * lam + w * lam1])
        return Step(np.concatenate([q1, v1, lam1]), dense=dense)

    def iterate(self, t1, q_hat, v_hat, bh2, gh, alpha, a0, lam0, q_old):
        """Newton with multiplier updates, then the projections: ``(q, v, a, lam)``
        at ``t1``, or None when the iteration does not converge."""
        s = self.system
        a, lam_star = a0.copy(), np.array(lam0, float)
        q = q_hat + bh2 * a
        qscale = max(1.0, float(np.max(np.abs(q_old), initial=0.0)))
        at = s.at(t1)
        for _ in range(self.max_iterations):
            self.counts["nniter"] += 1
            v = v_hat + gh * a
            g = np.asarray(s.constraint(q, *at), float)
            G, M = s.constraint_jac(q, *at), s.mass(q)
            lam = lam_star + alpha * g
            self.counts["nfev"] += 1
            F = M @ (q - q_hat) + bh2 * (G.T @ lam - s.force(t1, q, v))
            W, P = self.matrices(t1, q, v, a, lam, G, M, bh2, gh, alpha)
            dq = W(F)
            if not np.all(np.isfinite(dq)):
                return None
            q = q - dq
            a = (q - q_hat) / bh2
            g = np.asarray(s.constraint(q, *at), float)
            lam_star = lam_star + alpha * g
            if np.max(np.abs(dq), initial=0.0) <= self.tolerance * qscale:
                return self.project(t1, q, v_hat + gh * a, a, lam_star, bh2, gh, alpha)
        return None

    def matrices(self, t1, q, v, a, lam, G, M, bh2, gh, alpha):
        """``solve`` with ``W`` (factored) and ``P`` (see the module docstring)."""
        s = self.system
        self.counts["njev"] += 1
        K, C = s.tangent(t1, q, v, a, lam)
        P = M + gh * C + bh2 * K
        W = P + (bh2 * alpha) * (G.T @ G)
        self.counts["nlu"] += 1
        if self.sparse or sp.issparse(W):
            W = sp.csc_matrix(W)
        else:
            W = np.asarray(W, float)
        return factor(W), P

    def project(self, t1, q, v, a, lam, bh2, gh, alpha):
        """Mass-orthogonal projections of ``v`` and ``a`` at the converged ``q``
        (with the driving terms ``g_t`` and ``accel_term`` of constraints that
        depend on time: the same penalized least-squares problems, with ``G v +
        g_t`` in place of ``G v``)."""
        s = self.system
        at = s.at(t1)
        G, M = s.constraint_jac(q, *at), s.mass(q)
        solve, P = self.matrices(t1, q, v, a, lam, G, M, bh2, gh, alpha)
        if s.constraint_t is None:
            v = solve(P @ v)
        else:
            v = solve(P @ v - (bh2 * alpha) * (G.T @ s.velocity_term(q, t1)))
        a = solve(P @ a - (bh2 * alpha) * (G.T @ np.asarray(s.accel_term(q, v, *at), float)))
        if not (np.all(np.isfinite(v)) and np.all(np.isfinite(a))):
            return None
        return q, v, a, lam

    def accept(self, t_new, y_new):
        self.a, self.pending = self.pending, None

    def reject(self):
        self.pending = None


class AugmentedLagrangianTrapezoidal(Integrator):
    """ALI3-P: the trapezoidal rule on the ``al3`` formulation, fixed step."""

    name = "al-trapezoidal"
    description = ("Trapezoidal rule on the index-3 augmented Lagrangian formulation with "
                   "mass-orthogonal projections (ALI3-P), fixed step")
    reference = ("Bayo and Ledesma, Nonlinear Dyn. 9 (1996) 113-130; Cuadrado, Cardenal and "
                 "Bayo, Multibody Syst. Dyn. 1 (1997) 259-280")
    accepts = frozenset({"augmented_lagrangian"})
    max_index = 3
    order = 2
    implicit = True
    uses_jacobian = True
    adaptive = False
    stability = "A"
    dense_output = True
    settings = (Setting("penalty", float, None, "relative penalty (default: the "
                        "formulation's, see AugmentedLagrangianSystem)", low=0.0, positive=True),
                Setting("tolerance", float, None, "iteration tolerance on positions and "
                        "constraints, relative (default: the formulation's)", low=0.0,
                        positive=True),
                Setting("max_iterations", int, 100, "most Newton iterations (with multiplier "
                        "updates) per step", low=1, high=1000))

    def stepper(self, system, counts, rtol=None, atol=None):
        for key in ("nfev", "njev", "nlu", "nniter", "nnfail"):
            counts.setdefault(key, 0)
        return AugmentedLagrangianStepper(system, counts, self.max_iterations, self.penalty,
                                          self.tolerance)
