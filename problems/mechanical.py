"""Constrained mechanical systems, written once, in every formulation.

A problem gives only ``M(q) q'' = f(t, q, v) - G(q)^T lam``, ``g(q) = 0``: the mass
matrix, the applied forces, the position constraints, and the derivatives that
formulations and implicit integrators need. Every formulation is generated from
those by :mod:`integrator_bench.problems.formulations`, never written per problem.

Canonical components, against which all formulations are measured, are
``q``, ``v_q`` and ``lam1..lam_nc``; the error components are the positions, as
the IVP Test Set scores Andrews' squeezer.

Large sparse problems
---------------------
A problem with ``sparse = True`` returns scipy.sparse matrices from
:meth:`~MechanicalProblem.mass`, :meth:`~MechanicalProblem.constraint_jac`,
:meth:`~MechanicalProblem.gv_q`, :meth:`~MechanicalProblem.force_q`,
:meth:`~MechanicalProblem.force_v`, :meth:`~MechanicalProblem.mass_q` and
:meth:`~MechanicalProblem.gt_q` (vectors stay 1-D arrays), and every
formulation is then generated without a dense ``nq x nq`` matrix:

* the augmented system ``[[M, G^T], [G, 0]]`` is assembled in CSC and
  factored by SuperLU (``scipy.sparse.linalg.splu``), once per point, for the
  accelerations and multipliers, the output at many points and the
  M-weighted projections (whose Gauss-Newton step is the same saddle-point
  solve with right-hand side ``[0; r]``, so M is never inverted);
* the DAE residual Jacobians of ``i3``, ``i2`` and ``ggl`` are CSC matrices
  (``scipy.sparse.bmat``), and every DAE form declares its structural
  pattern in ``DaeSystem.jac_sparsity`` (``i1``, which has no analytic
  Jacobian, for grouped differences; ``i3``, ``i2``, ``ggl`` for the
  solvers that fix the structure before the run); the ``mechanical``
  form's ``tangent`` returns the model's sparse blocks;
* ``partitioning`` picks the dependent coordinates by sparse LU with partial
  pivoting of ``G^T`` (Gaussian elimination with row pivoting of ``G^T``, the
  column choice of Wehage and Haug 1982, see
  :class:`~integrator_bench.problems.partitioning.SparsePartition`) and
  measures the dependent block's conditioning with Higham and Tisseur's
  1-norm estimate (2000) instead of an SVD;
* the ``ode``, ``baumgarte`` and ``projection`` forms give no Jacobian: for a
  closed chain every acceleration depends on every coordinate, so it is
  structurally dense; :func:`~integrator_bench.problems.system.convert`
  refuses such systems above ``DENSE_JACOBIAN_LIMIT`` states to integrators
  that would form it by finite differences.
"""

from __future__ import annotations

import functools
from typing import ClassVar

import numpy as np

from integrator_bench.problems.base import Parameter, Problem, ProblemError
from integrator_bench.problems.formulations import FORMULATIONS, Formulations
from integrator_bench.problems.linalg import kkt, solve, solve_dropping_dependent, splu

__all__ = ["FORMULATIONS", "MechanicalProblem"]

#: pivots of ``G M^-1 G^T`` below this share of its largest diagonal entry count as
#: zero in the solves of a mechanism with redundant constraints
RANK_RCOND = 1e-10


class MechanicalProblem(Formulations, Problem):
    """Base of constrained mechanical problems.

    Rules for implementers: set ``coordinates`` (names of q) and
    ``n_constraints``; implement :meth:`start` and the numeric model
    (:meth:`mass`, :meth:`force`, :meth:`constraint`, :meth:`constraint_jac`,
    :meth:`gv_q`, :meth:`force_q`, :meth:`force_v`, :meth:`mass_q`,
    :meth:`gt_q`), or derive from :class:`integrator_bench.problems.symbolic.SymbolicMechanics`
    and give the model once as sympy expressions. The tests check every
    derivative against finite differences. :meth:`force_derivatives` gives
    ``force_q`` and ``force_v`` together; override it when they share work.

    A large problem sets ``sparse = True`` and returns scipy.sparse matrices
    from the matrix-valued methods (see the module docstring); the vectors
    (:meth:`force`, :meth:`constraint`, :meth:`accel_term`) stay 1-D arrays.

    A mechanism whose constraints are dependent at every instant (Bricard's)
    says how many in ``redundant_constraints``: its augmented solves then drop
    that many dependent constraints and the formulations that need a Jacobian of full
    row rank are refused with that reason (dense problems only).

    A driven mechanism (a constraint that depends on time, ``g(q, t) = 0``: a
    crank turned at a prescribed angle, a support moved on a prescribed path)
    sets ``driven = True``; its constraint functions then take the time as
    their last argument, :meth:`constraint` ``(q, t)``, :meth:`constraint_jac`
    ``(q, t)``, :meth:`gv_q` ``(q, v, t)``, :meth:`accel_term` ``(q, v, t)``,
    :meth:`gt_q` ``(q, lam, t)``, and it gives the time derivatives
    :meth:`constraint_t` (``g_t``) and :meth:`constraint_jac_t` (``G_t = d g_t / dq``).
    The velocity constraint is then ``G v + g_t = 0``, the acceleration
    constraint ``G a + (d(G v)/dq) v + 2 G_t v + g_tt = 0`` (:meth:`accel_term`
    is all of it but ``G a``). A problem whose constraints do not depend on
    time (``driven = False``) is called with no time, as before.
    """

    coordinates: ClassVar[tuple[str, ...]] = ()
    error_coordinates: ClassVar[tuple[str, ...] | None] = None  # None: all coordinates
    n_constraints: ClassVar[int] = 0
    formulations = FORMULATIONS
    #: Baumgarte's ``alpha`` and ``beta`` of the ``baumgarte`` formulation (its
    #: acceleration constraint ``G a + (d(G v)/dq) v + 2 alpha G v + beta^2 g = 0``),
    #: both also options (``slider_crank:baumgarte_alpha=3``, :meth:`set_form_options`)
    baumgarte_alpha: ClassVar[float] = 10.0
    baumgarte_beta: ClassVar[float] = 10.0
    form_options = (
        Parameter("baumgarte_alpha", 10.0, 0.0, 1e6, "Baumgarte's alpha (the baumgarte "
                  "formulation's damping of G v); beta follows it unless given"),
        Parameter("baumgarte_beta", 10.0, 0.0, 1e6, "Baumgarte's beta (the baumgarte "
                  "formulation's stiffness of g)"),
    )
    #: the ``al3`` formulation's penalty, relative to the problem's scales (see
    #: :class:`~integrator_bench.problems.system.AugmentedLagrangianSystem`), and
    #: the tolerance of its iteration
    al_penalty: ClassVar[float] = 1e4
    al_tolerance: ClassVar[float] = 1e-8
    position_scale: ClassVar[float] = 1.0
    velocity_scale: ClassVar[float] = 1.0
    lambda_scale: ClassVar[float] = 1.0
    start_tolerance: ClassVar[float] = 1e-3
    reference_methods = (("ode", "scipy-Radau", 1e-13), ("baumgarte", "scipy-DOP853", 1e-13))
    #: how many of the constraints are dependent on the others at every instant
    #: (a mechanism whose special geometry keeps it mobile where Gruebler's count
    #: says it is rigid: Bricard's). The constraint Jacobian then has rank
    #: ``nc - redundant_constraints``: the multipliers are not unique, the
    #: accelerations and projections are computed with the dependent constraints
    #: dropped (:meth:`_least_squares_solve`), and the formulations that need a Jacobian of
    #: full row rank (:data:`~integrator_bench.problems.formulations.FULL_RANK`)
    #: are refused with that reason.
    redundant_constraints: ClassVar[int] = 0
    #: the matrix methods return scipy.sparse matrices (large problems)
    sparse: ClassVar[bool] = False
    #: the constraints depend on time, g(q, t) = 0 (a driven, rheonomic mechanism):
    #: the constraint functions take the time as their last argument (class docstring)
    driven: ClassVar[bool] = False
    #: a driven problem's undriven twin: the parameter values that stop its drive
    #: (an amplitude of zero), the same model, start and time span with constraints
    #: that stand still in effect. A bare name runs the twin beside each of the
    #: problem's sets, and the report compares the two (what the driving costs each
    #: formulation). None: no twin declared.
    undriven: ClassVar[dict | None] = None

    def __init_subclass__(cls, **kw):
        super().__init_subclass__(**kw)
        if cls.coordinates:
            cls.components = (tuple(cls.coordinates) + tuple(f"v_{c}" for c in cls.coordinates)
                              + tuple(f"lam{i + 1}" for i in range(cls.n_constraints)))
            cls.error_components = tuple(cls.error_coordinates or cls.coordinates)
            cls.velocity_components = tuple(f"v_{c}" for c in cls.coordinates)
            cls.lambda_components = tuple(f"lam{i + 1}" for i in range(cls.n_constraints))
            cls.atol_scale = ((cls.position_scale,) * len(cls.coordinates)
                              + (cls.velocity_scale,) * len(cls.coordinates)
                              + (cls.lambda_scale,) * cls.n_constraints)

    def set_form_options(self, values: dict) -> None:
        """:meth:`Problem.set_form_options`; ``baumgarte_alpha`` alone sets ``beta``
        to the same value (both roots of ``s^2 + 2 alpha s + beta^2`` at ``-alpha``,
        critical damping), so that one number sweeps the stabilization from
        ``alpha = 0``, the underlying ODE, as Sudarsan and Keerthi tune it (Appl.
        Math. Comput. 92 (1998) 195-218, Remark 5.1)."""
        if "baumgarte_alpha" in values and "baumgarte_beta" not in values:
            values = {**values, "baumgarte_beta": values["baumgarte_alpha"]}
        super().set_form_options(values)

    # ------------------------------------------------------------ the model
    def start(self) -> tuple[np.ndarray, np.ndarray]:
        """An approximately consistent start (q, v); made consistent by :meth:`consistent_start`."""
        raise NotImplementedError

    def mass(self, q):
        """M(q)."""
        raise NotImplementedError

    def force(self, t, q, v):
        """f(t, q, v): applied, gyroscopic and control forces."""
        raise NotImplementedError

    def constraint(self, q):
        """g(q); ``constraint(q, t)`` for a driven problem."""
        raise NotImplementedError

    def constraint_jac(self, q):
        """G(q) = dg/dq; ``constraint_jac(q, t)`` for a driven problem."""
        raise NotImplementedError

    def gv_q(self, q, v):
        """d(G(q) v)/dq for fixed v (``gv_q(q, v, t)`` for a driven problem);
        ``gv_q(q, v) @ v`` is the acceleration term of a problem not driven."""
        raise NotImplementedError

    def constraint_t(self, q, t):
        """g_t(q, t) = dg/dt of a driven problem (:attr:`driven`)."""
        raise NotImplementedError

    def constraint_jac_t(self, q, t):
        """G_t(q, t) = d(g_t)/dq = dG/dt of a driven problem (:attr:`driven`)."""
        raise NotImplementedError

    def force_q(self, t, q, v):
        raise NotImplementedError

    def force_v(self, t, q, v):
        raise NotImplementedError

    def force_derivatives(self, t, q, v):
        """``(force_q, force_v)`` at one point, as the Newton matrices need them
        both. This default makes the two calls; a model that computes both
        from shared intermediate quantities (contact geometry, say) overrides
        it to compute them once."""
        return self.force_q(t, q, v), self.force_v(t, q, v)

    def mass_q(self, q, a):
        """d(M(q) a)/dq for fixed a."""
        raise NotImplementedError

    def gt_q(self, q, lam):
        """d(G(q)^T lam)/dq for fixed lam; ``gt_q(q, lam, t)`` for a driven problem."""
        raise NotImplementedError

    # ------------------------------------------------------------ derived
    @property
    def nq(self) -> int:
        return len(self.coordinates)

    @property
    def nc(self) -> int:
        return self.n_constraints

    def accel_term(self, q, v, *t):
        """(d(G v)/dq) v; for a driven problem ``accel_term(q, v, t)``, (d(G v)/dq) v
        + 2 G_t v + g_tt, whose default here needs g_tt: a driven problem overrides
        it (:class:`~integrator_bench.problems.symbolic.SymbolicMechanics` does)."""
        if t:
            raise NotImplementedError(f"{self.name}: a driven problem gives accel_term(q, v, t)")
        return self.gv_q(q, v) @ v

    def at(self, t) -> tuple:
        """The time as the constraint functions take it: ``(t,)`` for a driven
        problem, ``()`` otherwise, so ``self.constraint(q, *self.at(t))`` serves both."""
        return (t,) if self.driven else ()

    def at_many(self, t, n: int) -> tuple:
        """:meth:`at` for :meth:`evaluate_many` at ``n`` points: ``t`` as a column."""
        return (np.broadcast_to(np.asarray(t, float), (n,)),) if self.driven else ()

    def velocity_constraint(self, t, q, v):
        """``G v + g_t``, the velocity constraint's residual (``G v`` when not driven)."""
        Gv = self.constraint_jac(q, *self.at(t)) @ v
        return Gv + self.constraint_t(q, t) if self.driven else Gv

    def velocity_constraint_q(self, t, q, v):
        """``d(G v + g_t)/dq`` at fixed ``v``: ``d(G v)/dq + G_t`` (``d(G v)/dq`` when
        not driven)."""
        Gv_q = self.gv_q(q, v, *self.at(t))
        return Gv_q + self.constraint_jac_t(q, t) if self.driven else Gv_q

    def evaluate_many(self, name: str, *args) -> np.ndarray:
        """The model function ``name`` at many points at once.

        Parameters
        ----------
        name : {"mass", "force", "constraint", "constraint_jac", "accel_term"}
        *args
            The function's arguments with one row per point: ``t`` a vector of
            N times, ``q`` and ``v`` arrays of shape (N, nq).

        Returns
        -------
        numpy.ndarray or list
            The N values stacked along a leading axis: (N, nq, nq) for
            ``mass``, (N, nc, nq) for ``constraint_jac``, (N, n) for the
            vectors. A sparse problem's matrices are not stacked: they come
            as a list of N sparse matrices.

        This default calls the function point by point; a model that
        evaluates all the points in one call overrides it
        (:class:`~integrator_bench.problems.symbolic.SymbolicMechanics` does).
        Sparse problems' matrices are used point by point
        (:meth:`accelerations_many`, :meth:`constraint_residuals`).
        """
        values = [getattr(self, name)(*row) for row in zip(*args)]
        return values if self.sparse and name in ("mass", "constraint_jac") else np.array(values)

    def accelerations(self, t, q, v, extra=None):
        """Solve the augmented system for (a, lam); ``extra`` is added to the
        acceleration-level constraint's right-hand side (Baumgarte terms)."""
        at = self.at(t)
        rhs_c = -self.accel_term(q, v, *at)
        if extra is not None:
            rhs_c = rhs_c - extra
        return self._augmented_solve(self.mass(q), self.constraint_jac(q, *at),
                                     self.force(t, q, v), rhs_c)

    def accelerations_many(self, t, Q, V, extra=None):
        """:meth:`accelerations` at N points at once: ``t`` (N,), ``Q`` and
        ``V`` (N, nq), ``extra`` None or (N, nc); returns A (N, nq) and
        Lam (N, nc). A sparse problem solves its sparse augmented system
        point by point."""
        if self.sparse:
            pairs = [self.accelerations(t[i], Q[i], V[i], None if extra is None else extra[i])
                     for i in range(len(Q))]
            return (np.array([a for a, _ in pairs]).reshape(len(Q), self.nq),
                    np.array([lam for _, lam in pairs]).reshape(len(Q), self.nc))
        at = self.at_many(t, len(Q))
        rhs_c = -self.evaluate_many("accel_term", Q, V, *at)
        if extra is not None:
            rhs_c = rhs_c - extra
        return self._augmented_solve(self.evaluate_many("mass", Q),
                                     self.evaluate_many("constraint_jac", Q, *at),
                                     self.evaluate_many("force", t, Q, V), rhs_c)

    def _augmented_solve(self, M, G, f, rhs_c):
        """Solve ``[[M, G^T], [G, 0]] [a; lam] = [f; rhs_c]`` for one point or
        a stack of them (leading axes broadcast); returns ``(a, lam)``. For a
        sparse problem, one point, by sparse LU of the CSC matrix."""
        if self.sparse:
            sol = splu(kkt(M, G)).solve(np.concatenate([f, rhs_c]))
            return sol[:self.nq], sol[self.nq:]
        if self.redundant_constraints:
            return self._least_squares_solve(M, G, f, rhs_c)
        nq, n = self.nq, self.nq + self.nc
        K = np.zeros(M.shape[:-2] + (n, n))
        K[..., :nq, :nq], K[..., :nq, nq:], K[..., nq:, :nq] = M, np.swapaxes(G, -1, -2), G
        rhs = np.concatenate([f, rhs_c], axis=-1)
        if K.ndim == 2:     # one point: LAPACK's gesv without numpy's generic wrapping
            sol = solve(K, rhs)
        else:
            sol = np.linalg.solve(K, rhs[..., None])[..., 0]
        return sol[..., :nq], sol[..., nq:]

    def _least_squares_solve(self, M, G, f, rhs_c):
        """:meth:`_augmented_solve` for a rank-deficient ``G`` (redundant
        constraints): ``a = M^-1 (f - G^T lam)`` with the
        multipliers of ``(G M^-1 G^T) lam = G M^-1 f - rhs_c`` with the
        ``redundant_constraints`` most dependent constraints dropped (their
        multipliers zero), chosen by the pivots of a Cholesky factorization
        with complete pivoting (:func:`~integrator_bench.problems.linalg.solve_dropping_dependent`;
        pivots below :data:`RANK_RCOND` of the largest drop more). The
        accelerations are unique; the multipliers are one of the many sets that
        hold the mechanism (Garcia de Jalon and Bayo, Kinematic and Dynamic
        Simulation of Multibody Systems, 1994, sect. 5.4; Wojtyra and Fraczek,
        Multibody Syst. Dyn. 30 (2013) 153-171), not scored. One point or a
        stack of them."""
        if M.ndim > 2:
            pairs = [self._least_squares_solve(*parts) for parts in zip(M, G, f, rhs_c)]
            return np.array([a for a, _ in pairs]), np.array([lam for _, lam in pairs])
        MiGt, Mif = solve(M, G.T), solve(M, f)
        lam = self._dependent_dropped(G @ MiGt, G @ Mif - rhs_c)
        return Mif - MiGt @ lam, lam

    def _dependent_dropped(self, A, b):
        """``A^-1 b`` for ``A = G M^-1 G^T`` of a mechanism with redundant
        constraints, the dependent ones dropped (:meth:`_least_squares_solve`)."""
        return solve_dropping_dependent(A, b, self.nc - self.redundant_constraints,
                                        RANK_RCOND)

    def _project_positions(self, q, tol=1e-14, maxiter=20, t=None):
        """M-weighted Gauss-Newton onto g(q) = 0 (g(q, t) = 0 of a driven problem
        at ``t``); returns (q, converged)."""
        at = self.at(t)
        for _ in range(maxiter):
            r = self.constraint(q, *at)
            if np.max(np.abs(r)) <= tol * max(1.0, np.max(np.abs(q))):
                return q, True
            q = q - self._m_correction(self.mass(q), self.constraint_jac(q, *at), r)
        return q, np.max(np.abs(self.constraint(q, *at))) <= 1e-10 * max(1.0, np.max(np.abs(q)))

    def _project_velocities(self, q, v, t=None):
        """The M-weighted projection of ``v`` onto G v = 0 (G v + g_t = 0 of a
        driven problem at ``t``)."""
        M, G = self.mass(q), self.constraint_jac(q, *self.at(t))
        r = G @ v
        if self.driven:
            r = r + self.constraint_t(q, t)
        return v - self._m_correction(M, G, r)

    def _m_correction(self, M, G, r):
        """The M-weighted least-norm ``d`` with ``G d = r``: ``M^-1 G^T (G M^-1 G^T)^-1 r``.

        For a sparse problem it is the first block of the solution of
        ``[[M, G^T], [G, 0]] [d; mu] = [0; r]`` (the same vector, since
        ``M d = -G^T mu``), by sparse LU, so that M is never inverted.
        """
        if self.sparse:
            return splu(kkt(M, G)).solve(np.concatenate([np.zeros(self.nq), r]))[:self.nq]
        MiGt = solve(M, G.T)
        if self.redundant_constraints:
            return MiGt @ self._dependent_dropped(G @ MiGt, r)
        return MiGt @ solve(G @ MiGt, r)

    @functools.cached_property
    def _consistent(self):
        q_start, v_start = (np.asarray(x, float) for x in self.start())
        t0 = self.t_span[0]
        q, ok = self._project_positions(q_start, t=t0)
        moved = np.max(np.abs(q - q_start))
        if not ok or moved > self.start_tolerance * max(1.0, np.max(np.abs(q_start))):
            raise ProblemError(
                f"{self.name}: start too far from consistent (positions moved by {moved:.3g}, "
                f"constraint residual {np.max(np.abs(self.constraint(q, *self.at(t0)))):.3g})")
        v = self._project_velocities(q, v_start, t=t0)
        a, lam = self.accelerations(t0, q, v)
        return q, v, a, lam

    def consistent_start(self):
        """Consistent (q, v, a, lam) from :meth:`start` at the first time: positions
        by Newton on g, velocities by projection onto G v = 0 (G v + g_t = 0 when
        driven), a and lam from the augmented system."""
        return tuple(x.copy() for x in self._consistent)

    def initial_state(self):
        q, v, a, lam = self._consistent
        return np.concatenate([q, v, lam])

    def constraint_residuals(self, t, Y):
        nq, Y = self.nq, np.atleast_2d(Y)
        if not len(Y):
            return np.empty(0), np.empty(0)
        Q, V = Y[:, :nq], Y[:, nq:2 * nq]
        return (np.linalg.norm(self.evaluate_many("constraint", Q, *self.at_many(t, len(Q))),
                               axis=1),
                np.linalg.norm(self._gv_many(Q, V, t), axis=1))

    def _gv_many(self, Q, V, t=None):
        """``G(q) v`` at N points, (N, nc) (``G v + g_t`` at the times ``t`` of a
        driven problem); point by point for a sparse problem."""
        if self.driven:
            ts = np.broadcast_to(np.asarray(t, float), (len(Q),))
            return np.array([self.velocity_constraint(ti, q, v)
                             for ti, q, v in zip(ts, Q, V)]).reshape(len(Q), self.nc)
        if self.sparse:
            return np.array([self.constraint_jac(q) @ v for q, v in zip(Q, V)]).reshape(
                len(Q), self.nc)
        return (self.evaluate_many("constraint_jac", Q) @ V[..., None])[..., 0]

    def _probe_values(self, y0):
        rng = np.random.default_rng(12345)
        q0, v0, _, _ = self._consistent
        out = []
        for _ in range(3):
            q = q0 + 0.01 * rng.standard_normal(self.nq)
            v = v0 + 0.01 * rng.standard_normal(self.nq)
            t = 0.5 * sum(self.t_span)
            M, G = self._probe_matrices(q, t)
            out += [M, self.force(t, q, v), self.constraint(q, *self.at(t)), G]
        return out

    def _probe_matrices(self, q, t=None):
        """M(q) and G(q) as probed into the fingerprint: their entries, or for a
        sparse problem their products with a fixed pseudo-random vector."""
        M, G = self.mass(q), self.constraint_jac(q, *self.at(t))
        if self.sparse:
            w = np.random.default_rng(54321).standard_normal(self.nq)
            return M @ w, G @ w
        return np.ravel(M), np.ravel(G)

    # ------------------------------------------------------------ formulations
