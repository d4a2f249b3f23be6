"""Every formulation of a constrained mechanical system, generated from its
physics (:class:`~integrator_bench.problems.mechanical.MechanicalProblem`), never
written per problem (the names are the project's, docs/layout.md):

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
``al3``
    the index-3 augmented Lagrangian formulation with mass-orthogonal
    projections of velocities and accelerations (Bayo and Ledesma, Nonlinear
    Dyn. 9 (1996) 113-130; Cuadrado, Cardenal and Bayo, Multibody Syst. Dyn. 1
    (1997) 259-280), as an
    :class:`~integrator_bench.problems.system.AugmentedLagrangianSystem`: the
    index-3 equations with the formulation's penalty and tolerance
    (the problem's ``al_penalty`` and ``al_tolerance``), for the integrators
    that solve them in that form (``al-trapezoidal``). It never inverts the
    saddle-point matrix, so it takes redundant constraints and singular
    configurations.
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
``tangent``
    tangent parametrization as Sudarsan and Keerthi specialize it (Appl. Math.
    Comput. 92 (1998) 195-218, Procedure TP-CMS): the ``2 (nq - nc)`` coordinates
    of a chart on the tangent plane (QR of ``G^T`` at the chart's point) are
    integrated, the normal ones solved from the constraints at every evaluation,
    and a new chart is taken, restarting the integration, when ``||y'|| / ||v||``
    falls below 0.5 (a state event with a reset; :mod:`~integrator_bench.problems.tangent`).
    Dense problems only; any integrator that locates events takes it.

Each generated DAE declares the index of every variable in the RADAU5 convention
(positions 1, velocities 2 in index 3, multipliers 3) and which variables take
part in the error test: positions in ``i3`` (the velocities and multipliers of
an index-3 DAE cannot be error-controlled, Hairer and Wanner II sect. VII.3),
positions and velocities otherwise.

Canonical components, against which all formulations are measured, are
``q``, ``v_q`` and ``lam1..lam_nc``; the error components are the positions, as
the IVP Test Set scores Andrews' squeezer.

Driven constraints. A problem whose constraints depend on time, ``g(q, t) = 0``
(``driven``, :class:`~integrator_bench.problems.mechanical.MechanicalProblem`), gets
every form with its driving terms: ``i3`` and ``ggl`` hold ``g(q, t) = 0``; the
velocity constraint of ``i2`` and ``ggl`` is ``G v + g_t = 0`` (its Jacobian
``d(G v)/dq + G_t``); the acceleration constraint of ``i1``, ``ode`` and
``baumgarte`` is ``G a + (d(G v)/dq) v + 2 G_t v + g_tt = 0`` (Baumgarte's terms
``2 alpha (G v + g_t) + beta^2 g``); ``projection`` projects the positions onto
``g(q, t) = 0`` and the velocities onto ``G v = -g_t`` at the step's time;
``partitioning`` solves the dependent coordinates from ``g(q, t) = 0`` and their
velocities from ``G_dep v_dep = -(G_ind v_ind + g_t)``; ``tangent`` lifts through
``g(q, t) = 0`` and ``G V z' = -(G U y' + g_t)`` and measures its chart criterion
on the velocity's tangential part (:func:`~integrator_bench.problems.tangent.tangential_ratio`);
the ``mechanical`` and ``al3`` systems carry ``constraint_t`` and constraint
functions that take the time. The consistent start is projected the same way at
the first time.

The generators are methods of :class:`Formulations`, which
:class:`~integrator_bench.problems.mechanical.MechanicalProblem` inherits: they read
the physics through its methods (``mass``, ``force``, ``constraint_jac``, ...).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from integrator_bench.problems.base import ProblemError
from integrator_bench.problems.linalg import ones_pattern
from integrator_bench.problems.partitioning import DensePartition, SparsePartition
from integrator_bench.problems.system import (AugmentedLagrangianSystem, DaeSystem,
                                              MechanicalSystem, OdeSystem)
from integrator_bench.problems.tangent import tangent_system

FORMULATIONS = ("i3", "i2", "i1", "ode", "ggl", "baumgarte", "projection", "partitioning",
                "al3", "tangent")
#: the formulations that need a constraint Jacobian of full row rank: the DAE forms,
#: whose Newton matrices hold the saddle-point block ``[[., G^T], [G, 0]]``, singular
#: for a rank-deficient G (as are their multipliers, not unique), and coordinate
#: partitioning, which needs ``nc`` independent dependent coordinates. A mechanism
#: with redundant constraints gets them refused with that reason (:meth:`Formulations.formulate`).
FULL_RANK = ("i3", "i2", "i1", "ggl", "partitioning", "tangent")
#: ``(kind, index)`` of the system each formulation gives, known without building it
FACTS = {"i3": ("dae", 3), "i2": ("dae", 2), "i1": ("dae", 1), "ggl": ("dae", 2),
         "al3": ("augmented_lagrangian", 3),
         **dict.fromkeys(("ode", "baumgarte", "projection", "partitioning", "tangent"),
                         ("ode", 0))}


class Formulations:
    """The formulation generators of a mechanical problem: :meth:`formulate` and
    the ``_form_<name>`` method of each name in :data:`FORMULATIONS`."""

    @classmethod
    def formulation_facts(cls, formulation: str) -> tuple | None:
        """``(kind, index)`` of the system ``formulation`` gives (:data:`FACTS`),
        without building the problem; None when it offers no such formulation."""
        return FACTS.get(formulation) if formulation in cls.formulations else None

    def formulate(self, formulation: str = "ode"):
        if formulation not in self.formulations:
            raise ProblemError(
                f"problem {self.name} has no formulation {formulation!r}; "
                f"valid: {', '.join(self.formulations)}")
        q0, v0, a0, lam0 = self._consistent
        common = dict(t0=self.t_span[0], t_end=self.t_span[1], t_eval=self.t_eval)
        redundant = getattr(self, "redundant_constraints", 0)
        if redundant and formulation in FULL_RANK:
            return self._refused(formulation, redundant, q0, v0, a0, lam0, common)
        return getattr(self, f"_form_{formulation}")(q0, v0, a0, lam0, common)

    def _refused(self, formulation, redundant, q0, v0, a0, lam0, common):
        """The system of a formulation that needs a Jacobian of full row rank, on
        a mechanism with ``redundant`` dependent constraints, carrying why no
        integrator can run it (``unsupported``); partitioning, which would choose
        its coordinates at the start, as the ODE it integrates."""
        why = (f"this formulation needs a constraint Jacobian of full row rank; {self.name}'s "
               f"has rank {self.nc - redundant} < {self.nc} at every instant ({redundant} "
               f"redundant constraint{'s' if redundant > 1 else ''}: the multipliers are not "
               f"unique and the Newton matrix is singular); the ode, baumgarte, projection "
               f"and al3 forms take it")
        system = (self._ode_system(q0, v0, common) if formulation in ("partitioning", "tangent")
                  else getattr(self, f"_form_{formulation}")(q0, v0, a0, lam0, common))
        system.unsupported = why
        return system

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
            extra = extra_many(t, Q, V) if extra_many else None
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
                a, _ = self.accelerations(t, q, v, extra(t, q, v) if extra else None)
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
            extra=lambda t, q, v: self._baumgarte(self.velocity_constraint(t, q, v),
                                                  self.constraint(q, *self.at(t))),
            extra_many=lambda t, Q, V: self._baumgarte(
                self._gv_many(Q, V, t), self.evaluate_many("constraint", Q,
                                                          *self.at_many(t, len(Q)))))

    def _form_projection(self, q0, v0, a0, lam0, common):
        nq = self.nq

        def project(t, y):
            """``y`` on the constraint manifolds; NaN, left to the integrator's failure
            handling, where the projection's matrix is singular (a diverged state)."""
            try:
                q, _ = self._project_positions(y[:nq], t=t)
                return np.concatenate([q, self._project_velocities(q, y[nq:], t=t)])
            except np.linalg.LinAlgError:
                return np.full_like(y, np.nan)

        return self._ode_system(q0, v0, common, project=project)

    def _form_partitioning(self, q0, v0, a0, lam0, common):
        nq, nc = self.nq, self.nc
        chart = {}
        part = SparsePartition if self.sparse else DensePartition
        conditioning = part.conditioning

        def choose(t, q):
            G = self.constraint_jac(q, *self.at(t))
            dep = part.dependent(G, nc)
            if dep.size != nc:
                raise ProblemError(f"{self.name}: the constraint Jacobian has rank "
                                   f"{dep.size} < {nc}; no coordinate partition")
            chart.update(dep=dep, ind=np.setdiff1d(np.arange(nq), dep),
                         cond=conditioning(G, dep))

        def solve_dependent(t, q):
            dep, at = chart["dep"], self.at(t)
            for _ in range(20):
                r = self.constraint(q, *at)
                if np.max(np.abs(r)) <= 1e-14 * max(1.0, np.max(np.abs(q))):
                    return q, True
                q[dep] -= part.solve(self.constraint_jac(q, *at), dep, r)
            return q, False

        def project(t, y):
            """``y`` on the constraint manifolds; NaN, left to the integrator's
            failure handling, where no partition reaches them (a state far off
            them, as a diverging explicit step leaves: a singular ``G_dep``)."""
            try:
                return _project(t, y)
            except (np.linalg.LinAlgError, ProblemError):
                return np.full_like(y, np.nan)

        def _project(t, y):
            q, v = y[:nq].copy(), y[nq:].copy()
            if conditioning(self.constraint_jac(q, *self.at(t)), chart["dep"]) > 10 * chart["cond"]:
                choose(t, q)
            q_new, ok = solve_dependent(t, q.copy())
            if not ok:
                choose(t, q)
                q_new, ok = solve_dependent(t, q.copy())
                if not ok:
                    return np.full_like(y, np.nan)
            G = self.constraint_jac(q_new, *self.at(t))
            dep, ind = chart["dep"], chart["ind"]
            r = part.columns(G, ind) @ v[ind]
            if self.driven:        # G_dep v_dep = -(G_ind v_ind + g_t)
                r = r + self.constraint_t(q_new, t)
            v[dep] = -part.solve(G, dep, r)
            return np.concatenate([q_new, v])

        choose(common["t0"], q0)
        return self._ode_system(q0, v0, common, project=project)

    def _form_tangent(self, q0, v0, a0, lam0, common):
        """Tangent parametrization (:mod:`integrator_bench.problems.tangent`); a sparse
        problem gets the ``ode`` system refused with why (its charts are dense QRs)."""
        if self.sparse:
            system = self._ode_system(q0, v0, common)
            system.unsupported = (f"the tangent formulation takes a dense QR of the "
                                  f"constraint Jacobian ({self.nq} x {self.nc}) at every "
                                  f"chart; {self.name} is a sparse problem")
            return system
        return tangent_system(self, q0, v0, common)

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
        return qp - v, (self.mass(q) @ vp - self.force(t, q, v)
                        + self.constraint_jac(q, *self.at(t)).T @ lam)

    def _dynamics_jac(self, t, q, v, vp, lam, cj):
        """The blocks ``[[cj I, -I], [K, cj M - df/dv]]`` of d(F1, F2)/d(q, v) +
        cj d/d(q', v'), with ``K = d(M a - f + G^T lam)/dq`` at ``a = v'``, and G."""
        eye = sp.identity(self.nq, format="csr") if self.sparse else np.eye(self.nq)
        M, G = self.mass(q), self.constraint_jac(q, *self.at(t))
        fq, fv = self.force_derivatives(t, q, v)
        Kq = self.mass_q(q, vp) - fq + self.gt_q(q, lam, *self.at(t))
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
        return self.mass_q(q, a) - fq + self.gt_q(q, lam, *self.at(t)), -fv

    def _form_i3(self, q0, v0, a0, lam0, common):
        nq, nc = self.nq, self.nc

        def residual(t, y, yp):
            q, v, lam, _ = self._split(y)
            r1, r2 = self._dynamics_rows(t, q, v, yp[:nq], yp[nq:2 * nq], lam)
            return np.concatenate([r1, r2, self.constraint(q, *self.at(t))])

        def jac(t, y, yp, cj):
            q, v, lam, _ = self._split(y)
            (top, mid), G = self._dynamics_jac(t, q, v, yp[nq:2 * nq], lam, cj)
            return self._assemble([top + [None], mid + [G.T], [G, None, None]],
                                  ("q", "v", "lam"))

        mech = MechanicalSystem(**self._mechanical_fields(q0, v0, a0, lam0), **common)
        return self._dae(residual, jac, np.concatenate([q0, v0, lam0]),
                         np.concatenate([v0, a0, np.zeros(nc)]),
                         {"q": 1, "v": 2, "lam": 3}, ("q",), ("q", "v", "lam"), common,
                         mechanical=mech, jac_sparsity=self._dae_sparsity(q0, v0, "i3"))

    def _mechanical_fields(self, q0, v0, a0, lam0):
        """The fields of the index-3 second-order form at the consistent start (a
        driven problem's constraint functions take the time, with ``constraint_t``)."""
        nq, nc = self.nq, self.nc
        return dict(
            y0=np.concatenate([q0, v0, lam0]), atol_scale=self._scales("q", "v", "lam"),
            error_mask=np.arange(2 * nq + nc) < nq, output=lambda t, Y: np.atleast_2d(Y),
            nq=nq, nc=nc, mass=self.mass, force=self.force, constraint=self.constraint,
            constraint_jac=self.constraint_jac, accel_term=self.accel_term,
            tangent=self._tangent,   # sparse blocks for a sparse problem
            constraint_t=self.constraint_t if self.driven else None, a0=a0)

    def _form_al3(self, q0, v0, a0, lam0, common):
        M, G = self.mass(q0), self.constraint_jac(q0, *self.at(common["t0"]))
        mass_scale = float(abs(M.diagonal()).max()) if self.nq else 1.0
        jacobian_scale = float(abs(G).max()) if self.nc else 1.0
        return AugmentedLagrangianSystem(
            **self._mechanical_fields(q0, v0, a0, lam0), penalty=self.al_penalty,
            tolerance=self.al_tolerance, mass_scale=mass_scale,
            jacobian_scale=jacobian_scale or 1.0, **common)

    def _form_i2(self, q0, v0, a0, lam0, common):
        nq, nc = self.nq, self.nc

        def residual(t, y, yp):
            q, v, lam, _ = self._split(y)
            r1, r2 = self._dynamics_rows(t, q, v, yp[:nq], yp[nq:2 * nq], lam)
            return np.concatenate([r1, r2, self.velocity_constraint(t, q, v)])

        def jac(t, y, yp, cj):
            q, v, lam, _ = self._split(y)
            (top, mid), G = self._dynamics_jac(t, q, v, yp[nq:2 * nq], lam, cj)
            return self._assemble([top + [None], mid + [G.T],
                                   [self.velocity_constraint_q(t, q, v), G, None]],
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
            at = self.at(t)
            return np.concatenate([r1, r2, self.constraint_jac(q, *at) @ vp
                                   + self.accel_term(q, v, *at)])

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
        at = self.at(t)
        eye, G = sp.identity(self.nq, format="csr"), ones_pattern(self.constraint_jac(q, *at))
        fq, fv = self.force_derivatives(t, q, v)
        Kq = ones_pattern(self.mass_q(q, a), fq, self.gt_q(q, lam, *at))
        Gt = (self.constraint_jac_t(q, t),) if self.driven else ()
        return sp.bmat([[eye, eye, None],
                        [Kq, ones_pattern(self.mass(q), fv), G.T],
                        [ones_pattern(G, self.gv_q(q, a, *at), *Gt),
                         ones_pattern(G, self.gv_q(q, v, *at), *Gt), None]],
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
            at = self.at(t)
            G = self.constraint_jac(q, *at)
            r1, r2 = self._dynamics_rows(t, q, v, yp[:nq], yp[nq:2 * nq], lam)
            gv = G @ v + self.constraint_t(q, t) if self.driven else G @ v
            return np.concatenate([r1 + G.T @ mu, r2, self.constraint(q, *at), gv])

        def jac(t, y, yp, cj):
            q, v, lam, mu = self._split(y)
            (top, mid), G = self._dynamics_jac(t, q, v, yp[nq:2 * nq], lam, cj)
            return self._assemble([[top[0] + self.gt_q(q, mu, *self.at(t)), top[1], None, G.T],
                                   mid + [G.T, None], [G, None, None, None],
                                   [self.velocity_constraint_q(t, q, v), G, None, None]],
                                  ("q", "v", "lam", "mu"))

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
        at = self.at(t)
        eye, G = sp.identity(self.nq, format="csr"), ones_pattern(self.constraint_jac(q, *at))
        fq, fv = self.force_derivatives(t, q, v)
        K = ones_pattern(self.mass_q(q, a), fq, self.gt_q(q, lam, *at))
        D = ones_pattern(self.mass(q), fv)
        Gv = ones_pattern(self.gv_q(q, v, *at), *((self.constraint_jac_t(q, t),) if self.driven
                                                  else ()))
        if form == "ggl":
            blocks = [[ones_pattern(eye, self.gt_q(q, lam, *at)), eye, None, G.T], [K, D, G.T, None],
                      [G, None, None, None], [Gv, G, None, None]]
        else:
            blocks = [[eye, eye, None], [K, D, G.T],
                      [G, None, None] if form == "i3" else [Gv, G, None]]
        return sp.bmat(blocks, format="csc").astype(bool)
