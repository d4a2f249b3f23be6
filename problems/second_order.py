"""Mechanisms without constraints: ``M q'' = f(t, q, v)`` with a constant diagonal M.

A compliant mechanism (bushings in place of joints, springs in place of
contacts held by constraints) is an explicit second-order ODE. A subclass of
:class:`SecondOrderProblem` gives, after ``Problem.__init__``:

* ``self.nq`` (coordinates) and ``self._inv_m`` (the inverse diagonal of M);
* :meth:`start` -> ``(q0, v0)``;
* :meth:`force` ``(t, q, v) -> f`` and :meth:`_jacobians` ``(t, q, v) ->
  (df/dq, df/dv)`` as scipy.sparse matrices (analytic, vectorized);

and gets the rest once: the canonical state ``y = (q, v)``, the first-order
ODE ``y' = (v, M^-1 f)`` with its sparse Jacobian ``[[0, I], [M^-1 df/dq,
M^-1 df/dv]]``, and the same problem in second-order form (``nc = 0``,
tangent ``K = -df/dq``, ``C = -df/dv``) carried by the ``ode`` system for
integrators accepting the ``"mechanical"`` kind (HHT-alpha, Newmark,
generalized-alpha), as industrial codes integrate such models.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from integrator_bench.problems.base import Problem
from integrator_bench.problems.system import MechanicalSystem


class SecondOrderProblem(Problem):
    """``M q'' = f(t, q, v)``, M constant and diagonal, no constraints; see the module
    docstring for what a subclass gives."""

    formulations = ("ode",)
    nq: int = 0
    _inv_m: np.ndarray = None

    def start(self) -> tuple[np.ndarray, np.ndarray]:
        """Initial positions and velocities ``(q0, v0)``."""
        raise NotImplementedError

    def force(self, t, q, v) -> np.ndarray:
        """Applied forces ``f(t, q, v)``, (nq,)."""
        raise NotImplementedError

    def _jacobians(self, t, q, v):
        """``(df/dq, df/dv)``, sparse (nq, nq) each."""
        raise NotImplementedError

    def initial_state(self):
        return np.concatenate(self.start())

    def mass(self, q):
        """The constant diagonal mass matrix (sparse)."""
        return sp.diags(1.0 / self._inv_m, format="csr")

    def force_q(self, t, q, v):
        """d(force)/dq, sparse."""
        return self._jacobians(t, q, v)[0]

    def force_v(self, t, q, v):
        """d(force)/dv, sparse."""
        return self._jacobians(t, q, v)[1]

    def rhs(self, t, y):
        nq = self.nq
        return np.concatenate([y[nq:], self._inv_m * self.force(t, y[:nq], y[nq:])])

    def jac(self, t, y):
        """``[[0, I], [M^-1 df/dq, M^-1 df/dv]]`` in CSR."""
        nq = self.nq
        fq, fv = self._jacobians(t, y[:nq], y[nq:])
        Minv = sp.diags(self._inv_m)
        return sp.bmat([[None, sp.identity(nq)], [Minv @ fq, Minv @ fv]], format="csr")

    def formulate(self, formulation: str = "ode"):
        """The ODE ``y' = (v, M^-1 f)``, carrying its second-order form (no
        constraints) for HHT, Newmark and generalized-alpha."""
        system = super().formulate(formulation)
        q0, v0 = self.start()
        nq = self.nq
        no_constraints = sp.csr_matrix((0, nq))
        system.mechanical = MechanicalSystem(
            t0=system.t0, t_end=system.t_end, y0=system.y0, t_eval=system.t_eval,
            atol_scale=system.atol_scale, error_mask=np.arange(2 * nq) < nq,
            nq=nq, nc=0, mass=self.mass, force=self.force,
            constraint=lambda q: np.zeros(0), constraint_jac=lambda q: no_constraints,
            accel_term=lambda q, v: np.zeros(0), tangent=self._tangent,
            a0=self._inv_m * self.force(system.t0, q0, v0))
        return system

    def _tangent(self, t, q, v, a, lam):
        """``(K, C) = (-df/dq, -df/dv)``: M is constant and there are no multipliers."""
        fq, fv = self._jacobians(t, q, v)
        return -fq, -fv
