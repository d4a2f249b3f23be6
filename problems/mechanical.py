"""Constrained mechanical systems, written once, in every formulation.

A problem gives only ``M(q) q'' = f(t, q, v) - G(q)^T lam``, ``g(q) = 0``: the mass
matrix, the applied forces, the position constraints, and the derivatives that
formulations and implicit integrators need. Every formulation is generated here
from those, never written per problem (names from ../shared/CONTRACT.md):

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
    coordinates chosen by column-pivoted QR of G; after every accepted step the
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
"""

from __future__ import annotations

import functools
from typing import ClassVar

import numpy as np
import scipy.linalg

from integrator_bench.problems.base import Problem, ProblemError
from integrator_bench.problems.system import DaeSystem, MechanicalSystem, OdeSystem

FORMULATIONS = ("i3", "i2", "i1", "ode", "ggl", "baumgarte", "projection", "partitioning")


class MechanicalProblem(Problem):
    """Base of constrained mechanical problems.

    Rules for implementers: set ``coordinates`` (names of q) and
    ``n_constraints``; implement :meth:`start` and the numeric model
    (:meth:`mass`, :meth:`force`, :meth:`constraint`, :meth:`constraint_jac`,
    :meth:`gv_q`, :meth:`force_q`, :meth:`force_v`, :meth:`mass_q`,
    :meth:`gt_q`), or derive from :class:`integrator_bench.problems.symbolic.SymbolicMechanics`
    and give the model once as sympy expressions. The tests check every
    derivative against finite differences.
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
        numpy.ndarray
            The N values stacked along a leading axis: (N, nq, nq) for
            ``mass``, (N, nc, nq) for ``constraint_jac``, (N, n) for the
            vectors.

        This default calls the function point by point; a model that
        evaluates all the points in one call overrides it
        (:class:`~integrator_bench.problems.symbolic.SymbolicMechanics` does).
        """
        return np.array([getattr(self, name)(*row) for row in zip(*args)])

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
        Lam (N, nc)."""
        rhs_c = -self.evaluate_many("accel_term", Q, V)
        if extra is not None:
            rhs_c = rhs_c - extra
        return self._augmented_solve(self.evaluate_many("mass", Q),
                                     self.evaluate_many("constraint_jac", Q),
                                     self.evaluate_many("force", t, Q, V), rhs_c)

    def _augmented_solve(self, M, G, f, rhs_c):
        """Solve ``[[M, G^T], [G, 0]] [a; lam] = [f; rhs_c]`` for one point or
        a stack of them (leading axes broadcast); returns ``(a, lam)``."""
        nq, n = self.nq, self.nq + self.nc
        K = np.zeros(M.shape[:-2] + (n, n))
        K[..., :nq, :nq], K[..., :nq, nq:], K[..., nq:, :nq] = M, np.swapaxes(G, -1, -2), G
        sol = np.linalg.solve(K, np.concatenate([f, rhs_c], axis=-1)[..., None])[..., 0]
        return sol[..., :nq], sol[..., nq:]

    def _project_positions(self, q, tol=1e-14, maxiter=20):
        """M-weighted Gauss-Newton onto g(q) = 0; returns (q, converged)."""
        for _ in range(maxiter):
            r = self.constraint(q)
            if np.max(np.abs(r)) <= tol * max(1.0, np.max(np.abs(q))):
                return q, True
            M, G = self.mass(q), self.constraint_jac(q)
            MiGt = np.linalg.solve(M, G.T)
            q = q - MiGt @ np.linalg.solve(G @ MiGt, r)
        return q, np.max(np.abs(self.constraint(q))) <= 1e-10 * max(1.0, np.max(np.abs(q)))

    def _project_velocities(self, q, v):
        M, G = self.mass(q), self.constraint_jac(q)
        MiGt = np.linalg.solve(M, G.T)
        return v - MiGt @ np.linalg.solve(G @ MiGt, G @ v)

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
        G = self.evaluate_many("constraint_jac", Q)
        return (np.linalg.norm(self.evaluate_many("constraint", Q), axis=1),
                np.linalg.norm((G @ V[..., None])[..., 0], axis=1))

    def _probe_values(self, y0):
        rng = np.random.default_rng(12345)
        q0, v0, _, _ = self._consistent
        out = []
        for _ in range(3):
            q = q0 + 0.01 * rng.standard_normal(self.nq)
            v = v0 + 0.01 * rng.standard_normal(self.nq)
            out += [np.ravel(self.mass(q)), self.force(0.5 * sum(self.t_span), q, v),
                    self.constraint(q), np.ravel(self.constraint_jac(q))]
        return out

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
            Y = np.atleast_2d(Y)
            Q, V = Y[:, :nq], Y[:, nq:2 * nq]
            _, lam = self.accelerations_many(np.broadcast_to(t, len(Y)), Q, V,
                                             extra_many(Q, V) if extra_many else None)
            return np.concatenate([Q, V, lam], axis=1)
        return output

    def _ode_system(self, q0, v0, common, extra=None, extra_many=None, project=None):
        nq = self.nq

        def fun(t, y):
            q, v = y[:nq], y[nq:]
            a, _ = self.accelerations(t, q, v, extra(q, v) if extra else None)
            return np.concatenate([v, a])

        return OdeSystem(y0=np.concatenate([q0, v0]), atol_scale=self._scales("q", "v"),
                         output=self._ode_output(extra_many), fun=fun, jac=None,
                         project=project, **common)

    def _form_ode(self, q0, v0, a0, lam0, common):
        return self._ode_system(q0, v0, common)

    def _baumgarte(self, G, g, v):
        """Baumgarte's terms ``2 alpha G v + beta^2 g``, at one point or a stack of them."""
        alpha, beta = self.baumgarte_alpha, self.baumgarte_beta
        return 2 * alpha * (G @ v[..., None])[..., 0] + beta**2 * g

    def _form_baumgarte(self, q0, v0, a0, lam0, common):
        return self._ode_system(
            q0, v0, common,
            extra=lambda q, v: self._baumgarte(self.constraint_jac(q), self.constraint(q), v),
            extra_many=lambda Q, V: self._baumgarte(self.evaluate_many("constraint_jac", Q),
                                                    self.evaluate_many("constraint", Q), V))

    def _form_projection(self, q0, v0, a0, lam0, common):
        nq = self.nq

        def project(t, y):
            q, _ = self._project_positions(y[:nq])
            return np.concatenate([q, self._project_velocities(q, y[nq:])])

        return self._ode_system(q0, v0, common, project=project)

    def _form_partitioning(self, q0, v0, a0, lam0, common):
        nq, nc = self.nq, self.nc
        chart = {}

        def conditioning(G, dep):
            # ||G|| ||G_dep^-1||: cond(G_dep) alone is 1 for any nonzero 1x1 block
            return np.linalg.norm(G, 2) / np.linalg.svd(G[:, dep], compute_uv=False)[-1]

        def choose(q):
            G = self.constraint_jac(q)
            piv = scipy.linalg.qr(G, pivoting=True, mode="r")[1]
            dep = np.sort(piv[:nc])
            chart.update(dep=dep, ind=np.setdiff1d(np.arange(nq), dep),
                         cond=conditioning(G, dep))

        def solve_dependent(q):
            dep = chart["dep"]
            for _ in range(20):
                r = self.constraint(q)
                if np.max(np.abs(r)) <= 1e-14 * max(1.0, np.max(np.abs(q))):
                    return q, True
                q[dep] -= np.linalg.solve(self.constraint_jac(q)[:, dep], r)
            return q, False

        def project(t, y):
            q, v = y[:nq].copy(), y[nq:].copy()
            if conditioning(self.constraint_jac(q), chart["dep"]) > 10 * chart["cond"]:
                choose(q)
            q_new, ok = solve_dependent(q.copy())
            if not ok:
                choose(q)
                q_new, ok = solve_dependent(q.copy())
                if not ok:  # leave it to the integrator's failure handling
                    return np.full_like(y, np.nan)
            G = self.constraint_jac(q_new)
            dep, ind = chart["dep"], chart["ind"]
            v[dep] = -np.linalg.solve(G[:, dep], G[:, ind] @ v[ind])
            return np.concatenate([q_new, v])

        choose(q0)
        return self._ode_system(q0, v0, common, project=project)

    def _dae(self, residual, jac, y0, yp0, var_index, error_parts, parts, common,
             mechanical=None):
        n = {"q": self.nq, "v": self.nq, "lam": self.nc, "mu": self.nc}
        mask = np.concatenate([np.full(n[p], p in error_parts) for p in parts])
        algebraic = np.concatenate([np.full(n[p], p in ("lam", "mu")) for p in parts])
        index = np.concatenate([np.full(n[p], var_index[p]) for p in parts])
        nq, nc = self.nq, self.nc
        return DaeSystem(
            y0=y0, atol_scale=self._scales(*parts), error_mask=mask,
            output=lambda t, Y: np.atleast_2d(Y)[:, :2 * nq + nc],
            residual=residual, jac=jac, yp0=yp0, var_index=index, algebraic=algebraic,
            mechanical=mechanical, **common)

    def _split(self, y):
        nq, nc = self.nq, self.nc
        return y[:nq], y[nq:2 * nq], y[2 * nq:2 * nq + nc], y[2 * nq + nc:]

    def _dynamics_rows(self, t, q, v, qp, vp, lam):
        return qp - v, self.mass(q) @ vp - self.force(t, q, v) + self.constraint_jac(q).T @ lam

    def _dynamics_jac(self, t, q, v, vp, lam, cj):
        """Rows of d(F1, F2)/d(q, v) + cj d/d(q', v') and the G^T block."""
        nq = self.nq
        eye = np.eye(nq)
        M, G = self.mass(q), self.constraint_jac(q)
        top = np.hstack([cj * eye, -eye])
        Kq = self.mass_q(q, vp) - self.force_q(t, q, v) + self.gt_q(q, lam)
        mid = np.hstack([Kq, cj * M - self.force_v(t, q, v)])
        return top, mid, G

    def _form_i3(self, q0, v0, a0, lam0, common):
        nq, nc = self.nq, self.nc

        def residual(t, y, yp):
            q, v, lam, _ = self._split(y)
            r1, r2 = self._dynamics_rows(t, q, v, yp[:nq], yp[nq:2 * nq], lam)
            return np.concatenate([r1, r2, self.constraint(q)])

        def jac(t, y, yp, cj):
            q, v, lam, _ = self._split(y)
            top, mid, G = self._dynamics_jac(t, q, v, yp[nq:2 * nq], lam, cj)
            z = np.zeros
            return np.block([[top, z((nq, nc))], [mid, G.T],
                             [G, z((nc, nq)), z((nc, nc))]])

        mech = MechanicalSystem(
            y0=np.concatenate([q0, v0, lam0]), atol_scale=self._scales("q", "v", "lam"),
            error_mask=np.arange(2 * nq + nc) < nq, output=lambda t, Y: np.atleast_2d(Y),
            nq=nq, nc=nc, mass=self.mass, force=self.force, constraint=self.constraint,
            constraint_jac=self.constraint_jac, accel_term=self.accel_term,
            tangent=lambda t, q, v, a, lam: (
                self.mass_q(q, a) - self.force_q(t, q, v) + self.gt_q(q, lam),
                -self.force_v(t, q, v)),
            a0=a0, **common)
        return self._dae(residual, jac, np.concatenate([q0, v0, lam0]),
                         np.concatenate([v0, a0, np.zeros(nc)]),
                         {"q": 1, "v": 2, "lam": 3}, ("q",), ("q", "v", "lam"), common,
                         mechanical=mech)

    def _form_i2(self, q0, v0, a0, lam0, common):
        nq, nc = self.nq, self.nc

        def residual(t, y, yp):
            q, v, lam, _ = self._split(y)
            r1, r2 = self._dynamics_rows(t, q, v, yp[:nq], yp[nq:2 * nq], lam)
            return np.concatenate([r1, r2, self.constraint_jac(q) @ v])

        def jac(t, y, yp, cj):
            q, v, lam, _ = self._split(y)
            top, mid, G = self._dynamics_jac(t, q, v, yp[nq:2 * nq], lam, cj)
            z = np.zeros
            return np.block([[top, z((nq, nc))], [mid, G.T],
                             [self.gv_q(q, v), G, z((nc, nc))]])

        return self._dae(residual, jac, np.concatenate([q0, v0, lam0]),
                         np.concatenate([v0, a0, np.zeros(nc)]),
                         {"q": 1, "v": 1, "lam": 2}, ("q", "v"), ("q", "v", "lam"), common)

    def _form_i1(self, q0, v0, a0, lam0, common):
        """Index 1. No analytic Jacobian: d/dq of (d(G v)/dq) v needs second
        derivatives of G, which the model does not give; integrators use
        finite differences (counted by the harness)."""
        nq = self.nq

        def residual(t, y, yp):
            q, v, lam, _ = self._split(y)
            vp = yp[nq:2 * nq]
            r1, r2 = self._dynamics_rows(t, q, v, yp[:nq], vp, lam)
            return np.concatenate([r1, r2, self.constraint_jac(q) @ vp + self.accel_term(q, v)])

        return self._dae(residual, None, np.concatenate([q0, v0, lam0]),
                         np.concatenate([v0, a0, np.zeros(self.nc)]),
                         {"q": 1, "v": 1, "lam": 1}, ("q", "v"), ("q", "v", "lam"), common)

    def _form_ggl(self, q0, v0, a0, lam0, common):
        nq, nc = self.nq, self.nc

        def residual(t, y, yp):
            q, v, lam, mu = self._split(y)
            G = self.constraint_jac(q)
            r1, r2 = self._dynamics_rows(t, q, v, yp[:nq], yp[nq:2 * nq], lam)
            return np.concatenate([r1 + G.T @ mu, r2, self.constraint(q), G @ v])

        def jac(t, y, yp, cj):
            q, v, lam, mu = self._split(y)
            top, mid, G = self._dynamics_jac(t, q, v, yp[nq:2 * nq], lam, cj)
            top = top.copy()
            top[:, :nq] += self.gt_q(q, mu)
            z = np.zeros
            return np.block([[top, z((nq, nc)), G.T], [mid, G.T, z((nq, nc))],
                             [G, z((nc, nq)), z((nc, nc)), z((nc, nc))],
                             [self.gv_q(q, v), G, z((nc, nc)), z((nc, nc))]])

        return self._dae(residual, jac, np.concatenate([q0, v0, lam0, np.zeros(nc)]),
                         np.concatenate([v0, a0, np.zeros(2 * nc)]),
                         {"q": 1, "v": 1, "lam": 2, "mu": 2}, ("q", "v"),
                         ("q", "v", "lam", "mu"), common)
