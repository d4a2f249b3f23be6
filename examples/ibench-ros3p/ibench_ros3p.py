"""ROS3P, a linearly implicit (Rosenbrock) method, as an integrator-bench plugin.

ROS3P: J. Lang and J. G. Verwer, "ROS3P - an accurate third-order Rosenbrock
solver designed for parabolic problems", BIT 41 (2001) 731-738. Three stages,
order 3 (also for the Prothero-Robinson model and semi-discretized parabolic
problems), an embedded order-2 solution for the error estimate, A-stable
with ``R(inf) = 1 - sqrt(3)`` (so *not* L-stable), two evaluations of ``f``
per step (the third stage reuses the second's). The coefficients are those
of the transformed formulation of Hairer and Wanner (Solving ODEs II, 2nd
ed., sect. IV.7, eq. (7.25)), as tabulated for ROS3P in KPP's and MESA's
Rosenbrock codes, with ``gamma = 1/2 + sqrt(3)/6``::

    (I / (h gamma) - J) U_i = f(t + alpha_i h, y + sum_j a_ij U_j)
                              + sum_j (c_ij / h) U_j + h gamma_i f_t(t, y)
    y_new = y + sum_i m_i U_i,   error = sum_i e_i U_i   (O(h^3))

with ``J = df/dy`` and ``f_t = df/dt`` at ``(t, y)``. The tests verify the order
(3) and ``R(inf)`` numerically.

A property to know when reading its results: the embedded solution has the same
stability function as the propagated one, so on a linear problem with constant
coefficients (and the exact Jacobian) the estimate is zero to rounding; it sees
only nonlinearity and time dependence. On such problems its steps are too long
for the tolerance: ``two_mass:c2=1000`` (linear) at ``rtol = 1e-6`` ends with
2.8 correct digits where scipy-Radau has 7.2 (4.7 at ``rtol = 1e-8``), while on
the Kepler problem the estimate is ``O(h^3)`` as it should be.

What a Jacobian-using plugin meets, and how this one handles it:

* ``system.jac`` may be None: the Jacobian is then taken by forward
  differences of ``system.fun`` (the harness counts those calls in ``nfev``;
  ``njev`` counts every Jacobian, analytic or not), on ``system.jac_sparsity``
  when the system names one. It may return a ``scipy.sparse`` matrix: it stays
  sparse and is factored by SuperLU. Both through
  :func:`integrator_bench.integrators.newton.jacobian` and
  :func:`integrator_bench.integrators.sparse.factor`, which every built-in
  implicit method uses too.
* ``f`` may depend on ``t``: ``f_t`` is a forward difference in ``t`` (one
  more evaluation per step).
* The Jacobian is evaluated once per step *point*: after a rejection the
  driver calls :meth:`step` again from the same ``(t, y)`` with a smaller
  ``h``, so it is kept until :meth:`accept`; the iteration matrix depends on
  ``h`` and is factored at every attempt (``nlu``).
* The error test covers the components of ``system.error_mask`` (positions
  only, for a mechanical system in first-order form): the stepper copies it
  into its own ``error_mask``, which the driver reads.
"""

import math

import numpy as np

from integrator_bench.integrators.base import Integrator, Step, Stepper
from integrator_bench.integrators.newton import jacobian
from integrator_bench.integrators.sparse import GroupedDifferences, factor, identity_minus

GAMMA = 0.5 + math.sqrt(3.0) / 6.0            # 0.78867513459481287
SQRT3 = math.sqrt(3.0)
#: a_21 = a_31 = 1 / gamma (a_32 = 0: stage 3 reuses stage 2's evaluation of f)
A21 = 1.0 / GAMMA                               # 1.26794919243112270
#: c_ij of the transformed formulation
C21 = -1.0 / GAMMA ** 2                         # -1.60769515458673623
C31 = -2.0 * SQRT3                              # -3.46410161513775459
C32 = -SQRT3                                    # -1.73205080756887729
#: m_i (the order-3 solution) and m_i - mhat_i (the estimate, mhat of order 2)
M = np.array([2.0, 1.0 / SQRT3, 1.0 - 1.0 / SQRT3])       # 2, 0.57735.., 0.42264..
MHAT = np.array([5.0 * (1.0 - 1.0 / SQRT3), 1.0, 1.0 - 1.0 / SQRT3])   # 2.11324.., 1, 0.42264..
E = M - MHAT
#: gamma_i = sum_j gamma_ij: the coefficients of h f_t
GAMMA_I = np.array([GAMMA, GAMMA - 1.0, 0.5 - 2.0 * GAMMA])   # 0.78867.., -0.21132.., -1.07735..


class ROS3PStepper(Stepper):
    """One ROS3P step; the Jacobian at ``(t, y)`` is kept over rejected attempts."""

    error_order = 2          # the embedded estimate is O(h^3)

    def __init__(self, system, counts, rtol=None, atol=None):
        super().__init__(system, counts, rtol, atol)
        self.error_mask = system.error_mask       # not inherited from the system: copy it
        sparsity = getattr(system, "jac_sparsity", None)
        self.grouped = (GroupedDifferences(sparsity)
                        if system.jac is None and sparsity is not None else None)
        self.scale = np.asarray(system.atol_scale, float)
        for key in ("njev", "nlu"):
            counts.setdefault(key, 0)
        self.J = None

    def step(self, t, y, h):
        f = self.system.fun
        if self.J is None:                        # first attempt from this point
            self.J = jacobian(f, self.system.jac, self.scale, t, y, self.counts, self.grouped)
        f0 = np.asarray(f(t, y), float)
        dt = math.sqrt(np.finfo(float).eps) * max(abs(t), 1.0)
        ft = (np.asarray(f(t + dt, y), float) - f0) / dt
        # (I / (h gamma) - J) U = r  <=>  (I - h gamma J) U = h gamma r
        solve = factor(identity_minus(h * GAMMA, self.J))
        self.counts["nlu"] += 1
        hg = h * GAMMA
        u1 = solve(hg * (f0 + h * GAMMA_I[0] * ft))
        f2 = np.asarray(f(t + h, y + A21 * u1), float)
        u2 = solve(hg * (f2 + (C21 / h) * u1 + h * GAMMA_I[1] * ft))
        u3 = solve(hg * (f2 + (C31 * u1 + C32 * u2) / h + h * GAMMA_I[2] * ft))
        return Step(y + M[0] * u1 + M[1] * u2 + M[2] * u3,
                    error=self.estimate(u1, u2, u3))

    def estimate(self, u1, u2, u3):
        """The local error estimate ``sum_i e_i U_i`` (``O(h^3)``)."""
        return E[0] * u1 + E[1] * u2 + E[2] * u3

    def accept(self, t_new, y_new):
        self.J = None                             # a new point: a new Jacobian


class ROS3P(Integrator):
    name = "ros3p"                      # must equal the entry-point name
    description = "ROS3P: 3-stage Rosenbrock method of order 3 with an embedded order-2 estimate"
    reference = "J. Lang, J. G. Verwer, BIT 41 (2001) 731-738"
    accepts = frozenset({"ode"})        # explicit ODEs y' = f(t, y)
    order = 3
    implicit = True                     # solves linear systems with I - h gamma J
    uses_jacobian = True                # calls system.jac (finite differences when None)
    stability = "A"                     # R(inf) = 1 - sqrt(3): A-stable, not L-stable
    adaptive = True                     # an embedded estimate: runs at rtol/atol, and at h
    projects = True                     # a one-step method: projection after a step is sound

    def stepper(self, system, counts, rtol=None, atol=None):
        return ROS3PStepper(system, counts, rtol, atol)
