"""Constrained mechanical systems, written once, in every formulation.

A problem gives only ``M(q) q'' = f(t, q, v) - G(q)^T lam``, ``g(q) = 0``: the mass
matrix, the applied forces, the position constraints, and the derivatives that
formulations and implicit integrators need. Every formulation is generated here
from those, never written per problem (the names are the project's, docs/layout.md):

``i3``
    index-3 DAE in ``(q, v, lam)``: ``q' = v``, ``M v' = f - G^T lam``, ``g = 0``;
    integrators accepting the ``"mechanical"`` kind (HHT-alpha, Newmark,
    generalized-alpha) get it as a :class:`~integrator_bench.problems.system.MechanicalSystem`.
``i2``
    index 2: the position constraint replaced by ``G v = 0``.
``i1``
    index 1: ``G v' + (d(G v)/dq) v = 0`` (lam algebraic of index 1).
``ggl``
    stabilized index 2 (Gear, Gupta and Leimkuhler 1985; ADAMS's SI2):
    ``q' = v - G^T mu``, ``M v' = f - G^T lam``, ``g = 0``, ``G v = 0``.
``ode``
    the underlying ODE in ``(q, v)``: lam eliminated through the augmented
    system ``[[M, G^T], [G, 0]] [a; lam] = [f; -(d(G v)/dq) v]``.
``baumgarte``
    the same with the stabilized acceleration constraint
    ``G a + (d(G v)/dq) v + 2 alpha G v + beta^2 g = 0`` (Baumgarte 1972).
``projection``
    the ``ode`` form plus a projection applied after every accepted step:
    positions onto ``g = 0`` by M-weighted Gauss-Newton, then velocities onto
    ``G v = 0`` (Sudarsan and Keerthi's perturbation approach, sect. 4.3; only
    integrators declaring ``projects = True`` take it).
``partitioning``
    coordinate partitioning (Wehage and Haug 1982): nq - nc independent
    coordinates chosen by column-pivoted QR of G (by sparse elimination with
    column pivoting for a sparse problem); after every accepted step the
    dependent coordinates are recomputed from the independent ones by Newton
    on ``g = 0`` and the dependent velocities from ``G v = 0``, so what is
    integrated are the independent coordinates. The partition is renewed when
    ``||G|| ||G_dep^-1||`` (the dependent block's condition measured against the
    scale of the whole of G, so that a single constraint's 1x1 block going
    singular counts too) grows tenfold past its value at selection, or when the
    Newton solve fails. Unlike the textbook method, the
    integrator advances (and error-tests) all of (q, v) and the dependent part
    is overwritten; it runs with the integrators that project.

Each generated DAE declares the index of every variable in the RADAU5 convention
(positions 1, velocities 2 in index 3, multipliers 3) and which variables take
part in the error test: positions in ``i3`` (the velocities and multipliers of
an index-3 DAE cannot be error-controlled, Hairer and Wanner II sect. VII.3),
positions and velocities otherwise.

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
  column choice of Wehage and Haug 1982, see :class:`_SparsePartition`) and
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
import scipy.linalg
from scipy.linalg.lapack import dgesv as _gesv
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from integrator_bench.problems.base import Problem, ProblemError
from integrator_bench.problems.system import DaeSystem, MechanicalSystem, OdeSystem

FORMULATIONS = ("i3", "i2", "i1", "ode", "ggl", "baumgarte", "projection", "partitioning")


def _kkt(M, G):
    """The augmented matrix ``[[M, G^T], [G, 0]]`` of sparse ``M`` and ``G``, in CSC."""
    return sp.bmat([[M, G.T], [G, None]], format="csc")


def _solve(A, b, overwrite: bool = False):
    """``A^-1 b`` for a dense ``A`` by LAPACK's ``gesv``, without numpy's generic
    wrapping (a few microseconds a call on a small system); ``LinAlgError``
    when ``A`` is singular, as ``numpy.linalg.solve`` raises. ``overwrite``:
    ``A`` and ``b`` may be factored and solved in place (no copy when they are
    Fortran-contiguous)."""
    _, _, x, info = _gesv(A, b, overwrite_a=overwrite, overwrite_b=overwrite)
    if info > 0:
        raise np.linalg.LinAlgError("Singular matrix")
    return x


def _splu(A):
    """SuperLU's factors of the sparse ``A``; ``LinAlgError`` (as LAPACK's dense
    solvers raise) where SuperLU finds it exactly singular."""
    try:
        return spla.splu(A)
    except RuntimeError as exc:   # SuperLU: "Factor is exactly singular"
        raise np.linalg.LinAlgError(str(exc)) from None


def _ones(*blocks):
    """Union of the stored entries of sparse matrices of one shape, explicit zeros
    included, as ones (CSR): every block's stored values are set to one before
    the sum, so that nothing cancels and no stored zero is dropped."""
    total = None
    for b in blocks:
        b = sp.csr_matrix(b, dtype=float, copy=True)
        b.data[:] = 1.0
        total = b if total is None else total + b
    return total


class MechanicalProblem(Problem):
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
    """

    coordinates: ClassVar[tuple[str, ...]] = ()
    error_coordinates: ClassVar[tuple[str, ...] | None] = None  # None: all coordinates
    n_constraints: ClassVar[int] = 0
    formulations = FORMULATIONS
    baumgarte_alpha: ClassVar[float] = 10.0
    baumgarte_beta: ClassVar[float] = 10.0
    position_scale: ClassVar[float] = 1.0
    velocity_scale: ClassVar[float] = 1.0
    lambda_scale: ClassVar[float] = 1.0
    start_tolerance: ClassVar[float] = 1e-3
    reference_methods = (("ode", "scipy-Radau", 1e-13), ("baumgarte", "scipy-DOP853", 1e-13))
    #: the matrix methods return scipy.sparse matrices (large problems)
    sparse: ClassVar[bool] = False

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
        """g(q)."""
        raise NotImplementedError

    def constraint_jac(self, q):
        """G(q) = dg/dq."""
        raise NotImplementedError

    def gv_q(self, q, v):
        """d(G(q) v)/dq for fixed v; ``gv_q(q, v) @ v`` is the acceleration term."""
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
        """d(G(q)^T lam)/dq for fixed lam."""
        raise NotImplementedError

    # ------------------------------------------------------------ derived
    @property
    def nq(self) -> int:
        return len(self.coordinates)

    @property
    def nc(self) -> int:
        return self.n_constraints

    def accel_term(self, q, v):
        """(d(G v)/dq) v."""
        return self.gv_q(q, v) @ v

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
        rhs_c = -self.accel_term(q, v)
        if extra is not None:
            rhs_c = rhs_c - extra
        return self._augmented_solve(self.mass(q), self.constraint_jac(q), self.force(t, q, v),
                                     rhs_c)

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
        rhs_c = -self.evaluate_many("accel_term", Q, V)
        if extra is not None:
            rhs_c = rhs_c - extra
        return self._augmented_solve(self.evaluate_many("mass", Q),
                                     self.evaluate_many("constraint_jac", Q),
                                     self.evaluate_many("force", t, Q, V), rhs_c)

    def _augmented_solve(self, M, G, f, rhs_c):
        """Solve ``[[M, G^T], [G, 0]] [a; lam] = [f; rhs_c]`` for one point or
        a stack of them (leading axes broadcast); returns ``(a, lam)``. For a
        sparse problem, one point, by sparse LU of the CSC matrix."""
        if self.sparse:
            sol = _splu(_kkt(M, G)).solve(np.concatenate([f, rhs_c]))
            return sol[:self.nq], sol[self.nq:]
        nq, n = self.nq, self.nq + self.nc
        K = np.zeros(M.shape[:-2] + (n, n))
        K[..., :nq, :nq], K[..., :nq, nq:], K[..., nq:, :nq] = M, np.swapaxes(G, -1, -2), G
        rhs = np.concatenate([f, rhs_c], axis=-1)
        if K.ndim == 2:     # one point: LAPACK's gesv without numpy's generic wrapping
            sol = _solve(K, rhs)
        else:
            sol = np.linalg.solve(K, rhs[..., None])[..., 0]
        return sol[..., :nq], sol[..., nq:]

    def _project_positions(self, q, tol=1e-14, maxiter=20):
        """M-weighted Gauss-Newton onto g(q) = 0; returns (q, converged)."""
        for _ in range(maxiter):
            r = self.constraint(q)
            if np.max(np.abs(r)) <= tol * max(1.0, np.max(np.abs(q))):
                return q, True
            q = q - self._m_correction(self.mass(q), self.constraint_jac(q), r)
        return q, np.max(np.abs(self.constraint(q))) <= 1e-10 * max(1.0, np.max(np.abs(q)))

    def _project_velocities(self, q, v):
        M, G = self.mass(q), self.constraint_jac(q)
        return v - self._m_correction(M, G, G @ v)

    def _m_correction(self, M, G, r):
        """The M-weighted least-norm ``d`` with ``G d = r``: ``M^-1 G^T (G M^-1 G^T)^-1 r``.

        For a sparse problem it is the first block of the solution of
        ``[[M, G^T], [G, 0]] [d; mu] = [0; r]`` (the same vector, since
        ``M d = -G^T mu``), by sparse LU, so that M is never inverted.
        """
        if self.sparse:
            return _splu(_kkt(M, G)).solve(np.concatenate([np.zeros(self.nq), r]))[:self.nq]
        MiGt = _solve(M, G.T)
        return MiGt @ _solve(G @ MiGt, r)

    @functools.cached_property
    def _consistent(self):
        q_start, v_start = (np.asarray(x, float) for x in self.start())
        q, ok = self._project_positions(q_start)
        moved = np.max(np.abs(q - q_start))
        if not ok or moved > self.start_tolerance * max(1.0, np.max(np.abs(q_start))):
            raise ProblemError(
                f"{self.name}: start too far from consistent (positions moved by {moved:.3g}, "
                f"constraint residual {np.max(np.abs(self.constraint(q))):.3g})")
        v = self._project_velocities(q, v_start)
        a, lam = self.accelerations(self.t_span[0], q, v)
        return q, v, a, lam

    def consistent_start(self):
        """Consistent (q, v, a, lam) from :meth:`start`: positions by Newton on g,
        velocities by projection onto G v = 0, a and lam from the augmented system."""
        return tuple(x.copy() for x in self._consistent)

    def initial_state(self):
        q, v, a, lam = self._consistent
        return np.concatenate([q, v, lam])

    def constraint_residuals(self, t, Y):
        nq, Y = self.nq, np.atleast_2d(Y)
        if not len(Y):
            return np.empty(0), np.empty(0)
        Q, V = Y[:, :nq], Y[:, nq:2 * nq]
        return (np.linalg.norm(self.evaluate_many("constraint", Q), axis=1),
                np.linalg.norm(self._gv_many(Q, V), axis=1))

    def _gv_many(self, Q, V):
        """``G(q) v`` at N points, (N, nc); point by point for a sparse problem."""
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
            M, G = self._probe_matrices(q)
            out += [M, self.force(0.5 * sum(self.t_span), q, v), self.constraint(q), G]
        return out

    def _probe_matrices(self, q):
        """M(q) and G(q) as probed into the fingerprint: their entries, or for a
        sparse problem their products with a fixed pseudo-random vector."""
        M, G = self.mass(q), self.constraint_jac(q)
        if self.sparse:
            w = np.random.default_rng(54321).standard_normal(self.nq)
            return M @ w, G @ w
        return np.ravel(M), np.ravel(G)

    # ------------------------------------------------------------ formulations
    def formulate(self, formulation: str = "ode"):
        if formulation not in self.formulations:
            raise ProblemError(
                f"problem {self.name} has no formulation {formulation!r}; "
                f"valid: {', '.join(self.formulations)}")
        q0, v0, a0, lam0 = self._consistent
        common = dict(t0=self.t_span[0], t_end=self.t_span[1], t_eval=self.t_eval)
        return getattr(self, f"_form_{formulation}")(q0, v0, a0, lam0, common)

    def _scales(self, *parts):
        sizes = {"q": self.nq, "v": self.nq, "lam": self.nc, "mu": self.nc}
        scale = {"q": self.position_scale, "v": self.velocity_scale,
                 "lam": self.lambda_scale, "mu": self.position_scale}
        return np.concatenate([np.full(sizes[p], scale[p]) for p in parts])

    def _ode_output(self, extra_many=None):
        nq = self.nq

        def output(t, Y):
            """The canonical rows ``(q, v, lam)``; ``lam`` NaN at a state where the
            augmented matrix is singular (a failed run's last, diverged outputs)."""
            Y = np.atleast_2d(Y)
            Q, V = Y[:, :nq], Y[:, nq:2 * nq]
            t = np.broadcast_to(t, len(Y))
            extra = extra_many(Q, V) if extra_many else None
            try:
                _, lam = self.accelerations_many(t, Q, V, extra)
            except np.linalg.LinAlgError:
                lam = np.array([self._multipliers(t[i], Q[i], V[i],
                                                  None if extra is None else extra[i])
                                for i in range(len(Y))]).reshape(len(Y), self.nc)
            return np.concatenate([Q, V, lam], axis=1)
        return output

    def _multipliers(self, t, q, v, extra):
        """The multipliers at one point; NaN where the augmented matrix is singular."""
        try:
            return self.accelerations(t, q, v, extra)[1]
        except np.linalg.LinAlgError:
            return np.full(self.nc, np.nan)

    def _ode_system(self, q0, v0, common, extra=None, extra_many=None, project=None):
        nq = self.nq

        def fun(t, y):
            """``(v, a)``; NaN, left to the integrator's failure handling, where the
            augmented matrix is singular (a state far off the constraint manifolds,
            as a diverging step leaves): the ODE has no derivative there."""
            q, v = y[:nq], y[nq:]
            try:
                a, _ = self.accelerations(t, q, v, extra(q, v) if extra else None)
            except np.linalg.LinAlgError:
                return np.full_like(y, np.nan)
            return np.concatenate([v, a])

        return OdeSystem(y0=np.concatenate([q0, v0]), atol_scale=self._scales("q", "v"),
                         output=self._ode_output(extra_many), fun=fun, jac=None,
                         project=project, **common)

    def _form_ode(self, q0, v0, a0, lam0, common):
        return self._ode_system(q0, v0, common)

    def _baumgarte(self, Gv, g):
        """Baumgarte's terms ``2 alpha G v + beta^2 g`` from ``G v`` and ``g``, at one
        point or a stack of them."""
        alpha, beta = self.baumgarte_alpha, self.baumgarte_beta
        return 2 * alpha * Gv + beta**2 * g

    def _form_baumgarte(self, q0, v0, a0, lam0, common):
        return self._ode_system(
            q0, v0, common,
            extra=lambda q, v: self._baumgarte(self.constraint_jac(q) @ v, self.constraint(q)),
            extra_many=lambda Q, V: self._baumgarte(self._gv_many(Q, V),
                                                    self.evaluate_many("constraint", Q)))

    def _form_projection(self, q0, v0, a0, lam0, common):
        nq = self.nq

        def project(t, y):
            """``y`` on the constraint manifolds; NaN, left to the integrator's failure
            handling, where the projection's matrix is singular (a diverged state)."""
            try:
                q, _ = self._project_positions(y[:nq])
                return np.concatenate([q, self._project_velocities(q, y[nq:])])
            except np.linalg.LinAlgError:
                return np.full_like(y, np.nan)

        return self._ode_system(q0, v0, common, project=project)

    def _form_partitioning(self, q0, v0, a0, lam0, common):
        nq, nc = self.nq, self.nc
        chart = {}
        part = _SparsePartition if self.sparse else _DensePartition
        conditioning = part.conditioning

        def choose(q):
            G = self.constraint_jac(q)
            dep = part.dependent(G, nc)
            if dep.size != nc:
                raise ProblemError(f"{self.name}: the constraint Jacobian has rank "
                                   f"{dep.size} < {nc}; no coordinate partition")
            chart.update(dep=dep, ind=np.setdiff1d(np.arange(nq), dep),
                         cond=conditioning(G, dep))

        def solve_dependent(q):
            dep = chart["dep"]
            for _ in range(20):
                r = self.constraint(q)
                if np.max(np.abs(r)) <= 1e-14 * max(1.0, np.max(np.abs(q))):
                    return q, True
                q[dep] -= part.solve(self.constraint_jac(q), dep, r)
            return q, False

        def project(t, y):
            """``y`` on the constraint manifolds; NaN, left to the integrator's
            failure handling, where no partition reaches them (a state far off
            them, as a diverging explicit step leaves: a singular ``G_dep``)."""
            try:
                return _project(y)
            except (np.linalg.LinAlgError, ProblemError):
                return np.full_like(y, np.nan)

        def _project(y):
            q, v = y[:nq].copy(), y[nq:].copy()
            if conditioning(self.constraint_jac(q), chart["dep"]) > 10 * chart["cond"]:
                choose(q)
            q_new, ok = solve_dependent(q.copy())
            if not ok:
                choose(q)
                q_new, ok = solve_dependent(q.copy())
                if not ok:
                    return np.full_like(y, np.nan)
            G = self.constraint_jac(q_new)
            dep, ind = chart["dep"], chart["ind"]
            v[dep] = -part.solve(G, dep, part.columns(G, ind) @ v[ind])
            return np.concatenate([q_new, v])

        choose(q0)
        return self._ode_system(q0, v0, common, project=project)

    def _dae(self, residual, jac, y0, yp0, var_index, error_parts, parts, common,
             mechanical=None, jac_sparsity=None):
        n = {"q": self.nq, "v": self.nq, "lam": self.nc, "mu": self.nc}
        mask = np.concatenate([np.full(n[p], p in error_parts) for p in parts])
        algebraic = np.concatenate([np.full(n[p], p in ("lam", "mu")) for p in parts])
        index = np.concatenate([np.full(n[p], var_index[p]) for p in parts])
        nq, nc = self.nq, self.nc
        return DaeSystem(
            y0=y0, atol_scale=self._scales(*parts), error_mask=mask,
            output=lambda t, Y: np.atleast_2d(Y)[:, :2 * nq + nc],
            residual=residual, jac=jac, yp0=yp0, var_index=index, algebraic=algebraic,
            mechanical=mechanical, jac_sparsity=jac_sparsity, **common)

    def _split(self, y):
        nq, nc = self.nq, self.nc
        return y[:nq], y[nq:2 * nq], y[2 * nq:2 * nq + nc], y[2 * nq + nc:]

    def _dynamics_rows(self, t, q, v, qp, vp, lam):
        return qp - v, self.mass(q) @ vp - self.force(t, q, v) + self.constraint_jac(q).T @ lam

    def _dynamics_jac(self, t, q, v, vp, lam, cj):
        """The blocks ``[[cj I, -I], [K, cj M - df/dv]]`` of d(F1, F2)/d(q, v) +
        cj d/d(q', v'), with ``K = d(M a - f + G^T lam)/dq`` at ``a = v'``, and G."""
        eye = sp.identity(self.nq, format="csr") if self.sparse else np.eye(self.nq)
        M, G = self.mass(q), self.constraint_jac(q)
        fq, fv = self.force_derivatives(t, q, v)
        Kq = self.mass_q(q, vp) - fq + self.gt_q(q, lam)
        return [[cj * eye, -eye], [Kq, cj * M - fv]], G

    def _assemble(self, blocks, parts):
        """The block matrix ``blocks`` (None for a zero block; block rows and
        columns sized by ``parts``): a dense array, or CSC for a sparse problem."""
        if self.sparse:
            return sp.bmat(blocks, format="csc")
        n = [self.nq if p in ("q", "v") else self.nc for p in parts]
        return np.block([[np.zeros((n[i], n[j])) if b is None else b for j, b in enumerate(row)]
                         for i, row in enumerate(blocks)])

    def _tangent(self, t, q, v, a, lam):
        """``(K, C)`` of the ``mechanical`` form: ``K = d(M a - f + G^T lam)/dq``,
        ``C = -df/dv``."""
        fq, fv = self.force_derivatives(t, q, v)
        return self.mass_q(q, a) - fq + self.gt_q(q, lam), -fv

    def _form_i3(self, q0, v0, a0, lam0, common):
        nq, nc = self.nq, self.nc

        def residual(t, y, yp):
            q, v, lam, _ = self._split(y)
            r1, r2 = self._dynamics_rows(t, q, v, yp[:nq], yp[nq:2 * nq], lam)
            return np.concatenate([r1, r2, self.constraint(q)])

        def jac(t, y, yp, cj):
            q, v, lam, _ = self._split(y)
            (top, mid), G = self._dynamics_jac(t, q, v, yp[nq:2 * nq], lam, cj)
            return self._assemble([top + [None], mid + [G.T], [G, None, None]],
                                  ("q", "v", "lam"))

        mech = MechanicalSystem(
            y0=np.concatenate([q0, v0, lam0]), atol_scale=self._scales("q", "v", "lam"),
            error_mask=np.arange(2 * nq + nc) < nq, output=lambda t, Y: np.atleast_2d(Y),
            nq=nq, nc=nc, mass=self.mass, force=self.force, constraint=self.constraint,
            constraint_jac=self.constraint_jac, accel_term=self.accel_term,
            tangent=self._tangent,   # sparse blocks for a sparse problem
            a0=a0, **common)
        return self._dae(residual, jac, np.concatenate([q0, v0, lam0]),
                         np.concatenate([v0, a0, np.zeros(nc)]),
                         {"q": 1, "v": 2, "lam": 3}, ("q",), ("q", "v", "lam"), common,
                         mechanical=mech, jac_sparsity=self._dae_sparsity(q0, v0, "i3"))

    def _form_i2(self, q0, v0, a0, lam0, common):
        nq, nc = self.nq, self.nc

        def residual(t, y, yp):
            q, v, lam, _ = self._split(y)
            r1, r2 = self._dynamics_rows(t, q, v, yp[:nq], yp[nq:2 * nq], lam)
            return np.concatenate([r1, r2, self.constraint_jac(q) @ v])

        def jac(t, y, yp, cj):
            q, v, lam, _ = self._split(y)
            (top, mid), G = self._dynamics_jac(t, q, v, yp[nq:2 * nq], lam, cj)
            return self._assemble([top + [None], mid + [G.T], [self.gv_q(q, v), G, None]],
                                  ("q", "v", "lam"))

        return self._dae(residual, jac, np.concatenate([q0, v0, lam0]),
                         np.concatenate([v0, a0, np.zeros(nc)]),
                         {"q": 1, "v": 1, "lam": 2}, ("q", "v"), ("q", "v", "lam"), common,
                         jac_sparsity=self._dae_sparsity(q0, v0, "i2"))

    def _form_i1(self, q0, v0, a0, lam0, common):
        """Index 1. No analytic Jacobian: d/dq of (d(G v)/dq) v needs second
        derivatives of G, which the model does not give; integrators use
        finite differences (counted by the harness). A sparse problem declares
        the Jacobian's structure (:meth:`_i1_sparsity`) so that they can be
        grouped."""
        nq = self.nq

        def residual(t, y, yp):
            q, v, lam, _ = self._split(y)
            vp = yp[nq:2 * nq]
            r1, r2 = self._dynamics_rows(t, q, v, yp[:nq], vp, lam)
            return np.concatenate([r1, r2, self.constraint_jac(q) @ vp + self.accel_term(q, v)])

        return self._dae(residual, None, np.concatenate([q0, v0, lam0]),
                         np.concatenate([v0, a0, np.zeros(self.nc)]),
                         {"q": 1, "v": 1, "lam": 1}, ("q", "v"), ("q", "v", "lam"), common,
                         jac_sparsity=self._i1_sparsity(q0, v0) if self.sparse else None)

    def _i1_sparsity(self, q0, v0):
        """Structural non-zeros of the ``i1`` residual's ``dF/dy + cj dF/dy'``.

        Rows ``q' - v``: ``[I, I, 0]``; rows ``M v' - f + G^T lam``:
        ``[d(M a)/dq + df/dq + d(G^T lam)/dq, M + df/dv, G^T]``; rows
        ``G v' + (d(G v)/dq) v``: ``[G + d(G a)/dq, G + d(G v)/dq, 0]``, since
        the derivatives of g_i (first, second, third) involve only the
        coordinates g_i depends on, the non-zeros of row i of G, and
        ``d((d(G v)/dq) v)/dv = 2 d(G v)/dq`` (the Hessians of g are
        symmetric). The model's matrices are taken at :meth:`_probe_point`,
        their stored entries counted as non-zeros (:func:`_ones`).
        """
        t, q, v, a, lam = self._probe_point(q0, v0)
        eye, G = sp.identity(self.nq, format="csr"), _ones(self.constraint_jac(q))
        fq, fv = self.force_derivatives(t, q, v)
        Kq = _ones(self.mass_q(q, a), fq, self.gt_q(q, lam))
        return sp.bmat([[eye, eye, None],
                        [Kq, _ones(self.mass(q), fv), G.T],
                        [_ones(G, self.gv_q(q, a)), _ones(G, self.gv_q(q, v)), None]],
                       format="csc").astype(bool)

    def _probe_point(self, q0, v0):
        """``(t, q, v, a, lam)``: a fixed pseudo-random point near the start at
        which the structural patterns are read, so that no entry vanishes by
        accident (open contacts, zero velocities and multipliers at the start)."""
        rng = np.random.default_rng(7)
        q = q0 + 1e-3 * (1 + np.abs(q0)) * rng.standard_normal(self.nq)
        v, a = v0 + rng.standard_normal(self.nq), rng.standard_normal(self.nq)
        return self.t_span[0], q, v, a, rng.standard_normal(self.nc)

    def _form_ggl(self, q0, v0, a0, lam0, common):
        nq, nc = self.nq, self.nc

        def residual(t, y, yp):
            q, v, lam, mu = self._split(y)
            G = self.constraint_jac(q)
            r1, r2 = self._dynamics_rows(t, q, v, yp[:nq], yp[nq:2 * nq], lam)
            return np.concatenate([r1 + G.T @ mu, r2, self.constraint(q), G @ v])

        def jac(t, y, yp, cj):
            q, v, lam, mu = self._split(y)
            (top, mid), G = self._dynamics_jac(t, q, v, yp[nq:2 * nq], lam, cj)
            return self._assemble([[top[0] + self.gt_q(q, mu), top[1], None, G.T],
                                   mid + [G.T, None], [G, None, None, None],
                                   [self.gv_q(q, v), G, None, None]], ("q", "v", "lam", "mu"))

        return self._dae(residual, jac, np.concatenate([q0, v0, lam0, np.zeros(nc)]),
                         np.concatenate([v0, a0, np.zeros(2 * nc)]),
                         {"q": 1, "v": 1, "lam": 2, "mu": 2}, ("q", "v"),
                         ("q", "v", "lam", "mu"), common,
                         jac_sparsity=self._dae_sparsity(q0, v0, "ggl"))

    def _dae_sparsity(self, q0, v0, form):
        """Structural non-zeros of the ``i3``, ``i2`` or ``ggl`` (``form``) residual's
        ``dF/dy + cj dF/dy'`` for a sparse problem; None for a dense one.

        The blocks of the analytic Jacobians above: rows ``q' - v`` (``ggl``:
        ``+ G^T mu``) ``[I (+ d(G^T mu)/dq), I, 0 (, G^T)]``; rows ``M v' - f +
        G^T lam`` ``[d(M a)/dq + df/dq + d(G^T lam)/dq, M + df/dv, G^T (, 0)]``;
        then ``g``: ``[G, 0, 0]`` (``i3``, ``ggl``), ``G v``: ``[d(G v)/dq, G,
        0 (, 0)]`` (``i2``, ``ggl``). Declared so that the structure is not
        read from one Jacobian, whose sparse sums drop the entries that are
        zero there (open contacts, zero multipliers at the start; SUNDIALS'
        sparse solver then fails at the first larger one). The model's
        matrices are taken at :meth:`_probe_point`, and their stored entries,
        explicit zeros too, count as non-zeros (:func:`_ones`), so that
        nothing vanishes by accident or cancels.
        """
        if not self.sparse:
            return None
        t, q, v, a, lam = self._probe_point(q0, v0)
        eye, G = sp.identity(self.nq, format="csr"), _ones(self.constraint_jac(q))
        fq, fv = self.force_derivatives(t, q, v)
        K, D = _ones(self.mass_q(q, a), fq, self.gt_q(q, lam)), _ones(self.mass(q), fv)
        Gv = _ones(self.gv_q(q, v))
        if form == "ggl":
            blocks = [[_ones(eye, self.gt_q(q, lam)), eye, None, G.T], [K, D, G.T, None],
                      [G, None, None, None], [Gv, G, None, None]]
        else:
            blocks = [[eye, eye, None], [K, D, G.T],
                      [G, None, None] if form == "i3" else [Gv, G, None]]
        return sp.bmat(blocks, format="csc").astype(bool)


class _DensePartition:
    """Coordinate partition of a dense G: dependent columns by column-pivoted QR
    (Businger and Golub 1965), conditioning ``||G||_2 ||G_dep^-1||_2`` by SVD."""

    @staticmethod
    def dependent(G, nc):
        return np.sort(scipy.linalg.qr(G, pivoting=True, mode="r")[1][:nc])

    @staticmethod
    def conditioning(G, dep):
        # ||G|| ||G_dep^-1||: cond(G_dep) alone is 1 for any nonzero 1x1 block
        return np.linalg.norm(G, 2) / np.linalg.svd(G[:, dep], compute_uv=False)[-1]

    @staticmethod
    def solve(G, dep, r):
        """``G_dep^-1 r``."""
        return np.linalg.solve(G[:, dep], r)

    @staticmethod
    def columns(G, idx):
        return G[:, idx]


class _SparsePartition:
    """Coordinate partition of a sparse G without a dense matrix.

    The dependent columns come from Gaussian elimination of G, constraint row
    by constraint row, with column pivoting: each row, reduced by the pivots
    before it, takes the column of largest magnitude as its pivot, and that
    column is eliminated from the rows below that hold it (LU with partial
    pivoting of ``G^T``; Wehage and Haug 1982 pivot fully, also reordering the
    constraints; either gives a non-singular ``G_dep`` when G has full row
    rank). A row without a pivot above 1e-12 of G's largest entry stops the
    choice short (G rank deficient). The reduced rows fill in: for a chain the
    dependent positions hang on every angle before them, so the reduced row
    of joint i holds all earlier angles, and a stored LU holds O(nc^2)
    entries (SuperLU on ``G^T`` completed to the square ``[[G^T, I], [eps I,
    0]]``: 1.5 million in each of L and U for a 1000-link chain). Only
    the pivots are needed, so each row is kept as a dense vector from the
    moment an elimination first touches it until it has given its pivot, and
    then dropped: the memory is that of the rows touched and not yet
    reduced (a few for constraints numbered along a chain), the work
    O(nc nq) in vector operations. The conditioning is
    ``||G||_1 ||G_dep^-1||_1`` with the inverse's norm estimated by Higham and
    Tisseur's block 1-norm estimator (SIAM J. Matrix Anal. Appl. 21 (2000)
    1185-1201; ``onenormest`` with one column, deterministic) from the sparse
    LU of ``G_dep``.
    """

    @staticmethod
    def dependent(G, nc):
        G, nq = sp.csr_matrix(G), G.shape[1]
        holders = sp.csc_matrix(G)         # original rows holding each column
        tol = 1e-12 * abs(G).max()
        touched, dep = {}, []

        def dense_row(i):
            row = np.zeros(nq)
            row[G.indices[G.indptr[i]:G.indptr[i + 1]]] = G.data[G.indptr[i]:G.indptr[i + 1]]
            return row

        for i in range(nc):
            row = touched.pop(i, None)
            if row is None:
                row = dense_row(i)
            j = int(np.argmax(np.abs(row)))
            if abs(row[j]) <= tol:
                break
            dep.append(j)
            below = holders.indices[holders.indptr[j]:holders.indptr[j + 1]]
            for r in set(below[below > i].tolist()) | {r for r in touched if touched[r][j]}:
                target = touched.get(r)
                if target is None:
                    target = touched[r] = dense_row(r)
                target -= (target[j] / row[j]) * row
                target[j] = 0.0
        return np.sort(np.array(dep, dtype=int))

    @staticmethod
    def _factor(G, dep):
        return _splu(sp.csc_matrix(G)[:, dep])

    @staticmethod
    def conditioning(G, dep):
        lu = _SparsePartition._factor(G, dep)
        inverse = spla.LinearOperator(lu.shape, matvec=lu.solve, dtype=float,
                                      rmatvec=lambda x: lu.solve(x, trans="T"))
        return spla.norm(G, 1) * spla.onenormest(inverse, t=1)

    @staticmethod
    def solve(G, dep, r):
        """``G_dep^-1 r`` by sparse LU."""
        return _SparsePartition._factor(G, dep).solve(r)

    @staticmethod
    def columns(G, idx):
        return sp.csc_matrix(G)[:, idx]
