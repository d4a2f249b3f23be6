"""HHT-alpha, Newmark and generalized-alpha for index-3 mechanical systems.

All three integrators take a :class:`integrator_bench.problems.system.MechanicalSystem`,
``M(q) q'' = f(t, q, v) - G(q)^T lam``, ``g(q) = 0``, and share one Newmark
machinery (Arnold and Bruls 2007), a :class:`AlphaStepper` run by the shared
driver (:mod:`integrator_bench.integrators.driver`) on the state
``y = (q, v, lam)``. Per step the unknowns are the acceleration
``q''_{n+1}`` and ``lam_{n+1}``; an auxiliary acceleration ``a`` carries the
alpha-averaging::

    (1 - am) a_{n+1} + am a_n = (1 - af) q''_{n+1} + af q''_n
    q_{n+1} = q_n + h v_n + h^2 (1/2 - beta) a_n + h^2 beta a_{n+1}
    v_{n+1} = v_n + h (1 - gamma) a_n + h gamma a_{n+1}
    M(q_{n+1}) q''_{n+1} = f(t_{n+1}, q_{n+1}, v_{n+1}) - G(q_{n+1})^T lam_{n+1}
    g(q_{n+1}) / (beta' h^2) = 0,        beta' = beta (1 - af) / (1 - am)

* HHT-alpha (Hilber, Hughes, Taylor 1977; Negrut et al. 2007): am = 0,
  af = -alpha, alpha in [-1/3, 0], gamma = (1 - 2 alpha) / 2,
  beta = (1 - alpha)^2 / 4. When M is constant this is the discretization of
  Negrut et al. (J. Comput. Nonlinear Dyn. 2 (2007) 73-85, their scaled form),
  ``(M q'')_{n+1} / (1 + alpha) + (G^T lam - f)_{n+1}
  - alpha / (1 + alpha) (G^T lam - f)_n = 0``, with their ``q''`` our ``a``
  (up to the start value). When M depends on q they differ: that form,
  implemented first, converged only to first order on Andrews' squeezer
  (final-time position errors 3.2e-2, 1.7e-2, 8.3e-3, 4.2e-3 for 1000 to 8000
  steps), this one to second order (1.2e-3, 2.9e-4, 7.1e-5, 1.8e-5).
* Newmark (1959): am = af = 0, free (beta, gamma).
* Generalized-alpha (Chung and Hulbert 1993) with constraints as Arnold and
  Bruls: am, af, beta, gamma from rho_inf.

The stepper keeps ``q''_n`` and ``a_n`` (not part of the driver's state) and
commits them only when the driver accepts a step. The start value
``a_0 = q''(t_0 + (am - af) h)`` follows Arnold and Bruls'
remark (lam is otherwise O(h) off for a transient); it is computed for the
``h`` of the first step actually taken (one ``force`` call per first step size
tried: a start value left from a rejected first try cost the adaptive HHT its
second order in our runs, 0.85 observed instead of 2.0).

The constraint rows are scaled by ``1 / (beta' h^2)``, so the iteration matrix
``[[M + beta' h^2 K + gamma' h C, G^T], [G, 0]]`` (``gamma' = gamma (1 - af) /
(1 - am)``; ``K``, ``C`` from ``system.tangent``) stays well conditioned as
``h -> 0``. It is a quasi-Newton iteration: ``K`` and ``C`` are evaluated at a
step's predicted state (``q''_{n+1} = q''_n``), kept over the following steps,
and evaluated anew only after a convergence failure or slow convergence
(observed rate > 0.3); ``M`` and ``G`` (callables the harness does not count)
are taken at each step's predictor and the matrix is refactored once per step
(and per step-size change). The corrector stops by the convergence-rate test
``xi / (1 - xi) ||d|| <= kappa`` (kappa = 0.01, xi the observed contraction
rate, ||d|| the weighted RMS of the position *and* velocity corrections), and,
our addition so that the constraint holds to round-off as the index-3
formulation promises, once ``|g(q)| <= 1000 eps`` times the scale of ``G q``.
At most ``maxit_adaptive`` = 10 iterations under error control (the ADAMS
MAXIT), ``maxit_fixed`` = 20 at a fixed step, which cannot be shortened; there
the corrector solves to ``newton_tol`` = 1e-10 (relative, on ``atol_scale``),
under error control to ``rtol``/``atol``. Testing only positions, as ADAMS
does, left velocity errors of order tol / h per step in our runs.

``hht`` runs at a fixed step ``h`` or, given ``rtol``, under the driver's
error control with the local error estimate on the positions
``(beta - 1/6) h^2 (q''_{n+1} - q''_n)`` (Zienkiewicz and Xie, Earthquake
Eng. Struct. Dyn. 20 (1991) 871-887, the Newmark family's local error estimate;
the ADAMS seminar describes it as a dimensionless constant times the
step-to-step change of the accelerations; with the true accelerations ``q''``;
``error_order`` 2;
weighted RMS over ``system.error_mask``, weights
``atol + rtol max(|q_n|, |q_{n+1}|)``): accept when <= 1,
``h_new = h * 0.9 * err^(-1/3)`` within [0.2, 2] (at most 1 after a
rejection), and ``h`` is kept when the factor lies in [1, 1.2] (the class
attribute ``controller``, a :class:`~integrator_bench.integrators.control.PI`). A
failed corrector is retried once with new ``K``, ``C`` (unless they were new
for this step); a second failure raises ``StepFailure(NEWTON_FAILURE)``: the
driver then divides ``h`` by 4 under error control (below ``1e-12`` of the
span the run stops), and ends the run at a fixed step. It is a per-step
control: the global error grows with the number of steps and is not bounded
by rtol. Newmark and generalized-alpha declare no error estimate and run at a
fixed step only: the estimate above is derived for HHT's ``am = 0``; Newmark
with ``gamma > 1/2`` has a local error ``O(h^2)`` in ``v`` that it does not
see, and for generalized-alpha (``am != 0``) its constant is not derived here.

Output. The driver takes the steps ``t_0 + k h`` (the last one shortened to
``t_end``), or the controller's steps, without shortening them to land on
output times. An output time inside a step takes the step's continuous
extension (``dense_output``): cubic Hermite in ``q`` from ``q``, ``v`` at both
ends and in ``v`` from ``v``, ``q''`` at both ends (``O(h^4)`` locally, above
the methods' order 2), linear in ``lam`` (``O(h^2)``); the interpolated ``q``
is then projected onto ``g(q) = 0`` by simplified Gauss-Newton steps, ``G`` and the
factors of ``G G^T`` kept from the interpolated point (a correction of the
size of the interpolation error; without it ``|g|`` at such outputs was
2e-5 on the pendulum at rtol 1e-4, not round-off). The old code instead
split each stretch up to the next output time into equal steps. It did so
because one tiny last step disturbed lam (on the squeezer at rtol 1e-9 the
median lam error was 2.5e-2 with short last steps, 2.6e-4 with equal steps);
the driver may still end a run with a short step to ``t_end``, so under error
control :meth:`AlphaStepper.max_step` splits the rest of the run into equal
steps once it is shorter than three last steps (on the squeezer the relative
lam error at ``t_end`` fell from 1.3e-2 to 1.9e-3 at rtol 1e-6, where the
last step had been 0.16 of the one before, and from 7.8e-5 to 2.4e-5 at rtol
1e-9). A stepper cannot lengthen a step; the driver does: a step within 10 %
of ``t_end`` is stretched to end there, which removes the sliver left when
the controller proposes slightly less than the rest (the pendulum, i3, at
rtol 1e-6: a last step of 5.4e-6 after 3.6e-3 had lam at ``t_end`` off by
100 %; with the stretch 6e-4). At a fixed step the last step is short only
when ``h`` does not divide the span.

Counters: ``nsteps`` accepted steps and ``nreject`` steps rejected by the
error test (both kept by the driver), ``nnfail`` failed corrector iterations
(each followed by a new Jacobian or a smaller step), ``nniter`` corrector
iterations (one ``force`` call each), ``nlu`` LU factorizations, ``njev``
``tangent`` calls, ``nfev`` ``force`` calls (corrector iterations plus the
start values; the projection of dense output calls only ``constraint`` and
``constraint_jac``).

Sparse systems: when any of ``M``, ``G``, ``K``, ``C`` comes as a
``scipy.sparse`` matrix, the iteration matrix is assembled sparse (CSC) from the
blocks' stored entries, with the sorting of its structure kept over the steps
(:class:`integrator_bench.integrators.sparse.SaddlePoint`; ``bmat`` and sparse
sums cost more than the LU at 150 chain links) and factored by SuperLU
(:func:`integrator_bench.integrators.sparse.factor`), as are the consistent
accelerations; the projection of dense output factors the sparse ``G G^T``
once per output. No dense ``n x n`` matrix is formed; dense blocks take LAPACK.

References
----------
H. M. Hilber, T. J. R. Hughes, R. L. Taylor, "Improved numerical dissipation for
time integration algorithms in structural dynamics", Earthquake Eng. Struct.
Dyn. 5 (1977) 283-292.
D. Negrut, R. Rampalli, G. Ottarsson, A. Sajdak, "On an implementation of the
Hilber-Hughes-Taylor method in the context of index 3 differential-algebraic
equations of multibody dynamics", J. Comput. Nonlinear Dyn. 2 (2007) 73-85.
N. M. Newmark, "A method of computation for structural dynamics", J. Eng. Mech.
Div. ASCE 85 (1959) 67-94.
J. Chung, G. M. Hulbert, "A time integration algorithm for structural dynamics
with improved numerical dissipation: the generalized-alpha method", J. Appl.
Mech. 60 (1993) 371-375.
M. Arnold, O. Bruls, "Convergence of the generalized-alpha scheme for
constrained mechanical systems", Multibody Syst. Dyn. 18 (2007) 185-202.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

from integrator_bench.integrators.base import Integrator, Status, Step, StepFailure, Stepper
from integrator_bench.integrators.control import PI, rms
from integrator_bench.integrators.interpolation import hermite
from integrator_bench.integrators.settings import Setting
from integrator_bench.integrators.sparse import SaddlePoint, dense, factor

EPS = np.finfo(float).eps


@dataclass(frozen=True)
class Scheme:
    """Coefficients of one member of the family (see the module docstring)."""

    beta: float
    gamma: float
    am: float = 0.0
    af: float = 0.0

    @property
    def cu(self) -> float:
        """d a_{n+1} / d u."""
        return (1.0 - self.af) / (1.0 - self.am)


def hht_scheme(alpha: float) -> Scheme:
    if not -1.0 / 3.0 <= alpha <= 0.0:
        raise ValueError(f"HHT alpha={alpha!r} is outside [-1/3, 0]")
    return Scheme(beta=(1 - alpha) ** 2 / 4, gamma=(1 - 2 * alpha) / 2, am=0.0, af=-alpha)


def generalized_alpha_scheme(rho_inf: float) -> Scheme:
    if not 0.0 <= rho_inf <= 1.0:
        raise ValueError(f"generalized-alpha rho_inf={rho_inf!r} is outside [0, 1]")
    am = (2 * rho_inf - 1) / (rho_inf + 1)
    af = rho_inf / (rho_inf + 1)
    return Scheme(beta=0.25 * (1 - am + af) ** 2, gamma=0.5 - am + af, am=am, af=af)


@dataclass
class Attempt:
    """The outcome of one corrector solve: the new point and its accelerations."""

    q: np.ndarray
    v: np.ndarray
    qdd: np.ndarray   # q'' at t + h
    a: np.ndarray     # auxiliary acceleration, ~ q''(t + h + (am - af) h) (= qdd for Newmark)
    lam: np.ndarray


class _Factor:
    """LU factorization of the saddle-point matrix ``[[sum_i c_i X_i, G^T], [G, 0]]``
    (``terms`` = ``[(X_1, c_1), ...]``): assembled by ``saddle`` (a
    :class:`~integrator_bench.integrators.sparse.SaddlePoint`, a new one if
    None) and factored by SuperLU when a block is sparse (a singular matrix
    then gives NaN solutions, as LAPACK's singular factors do, and the
    corrector reports a failure), else by LAPACK."""

    def __init__(self, terms, G, saddle=None):
        nq = terms[0][0].shape[0]
        if any(sp.issparse(X) for X, _ in terms) or sp.issparse(G):
            G = G if sp.issparse(G) else np.asarray(G, float).reshape(-1, nq)
            saddle = saddle or SaddlePoint(nq, G.shape[0])
            self.solve = factor(saddle(terms, G))
        else:
            A11 = sum(c * dense(X) for X, c in terms)
            G = np.asarray(G, float).reshape(-1, nq)
            A = np.block([[A11, G.T], [G, np.zeros((G.shape[0], G.shape[0]))]])
            self.solve = factor(A)


def consistent_acceleration(system, force, t, q, v):
    """``(q'', lam)`` from ``[[M, G^T], [G, 0]] [q''; lam] = [f; -accel_term]``."""
    f = force(t, q, v)
    at = system.at(t)
    M, G = system.mass(q), system.constraint_jac(q, *at)
    rhs = np.concatenate([f, -np.asarray(system.accel_term(q, v, *at), float)])
    x = _Factor([(M, 1.0)], G).solve(rhs)
    return x[:system.nq], x[system.nq:]


class AlphaStepper(Stepper):
    """One run of a Newmark-family method: the corrector of one step, the kept
    accelerations ``q''_n`` and ``a_n``, the iteration matrix and the counters.

    ``rtol`` None (a fixed-step run): the corrector solves to ``newton_tol``
    with ``maxit_fixed`` iterations; else to ``rtol``/``atol`` with
    ``maxit_adaptive``. ``estimate``: whether :meth:`step` returns the error
    estimate on the positions (``error_order`` 2) or none.
    """

    KAPPA = 1e-2
    REFRESH = 0.3      # observed rate above which K, C are evaluated anew
    #: under error control, the rest of the run is split into equal steps once
    #: it is shorter than END_WINDOW last steps (factor_max + 1 of HHT)
    END_WINDOW = 3.0
    dense_order = 3

    def __init__(self, system, counts, rtol, atol, *, scheme, estimate, newton_tol, maxit):
        super().__init__(system, counts, rtol, atol)
        self.s, self.maxit = scheme, maxit
        self.nq = nq = system.nq
        for key in ("nfev", "njev", "nlu", "nniter", "nnfail"):
            counts.setdefault(key, 0)
        if rtol is None:
            rtol, atol = newton_tol, newton_tol * np.asarray(system.atol_scale, float)
        atol = np.broadcast_to(np.asarray(atol, float), (system.n,))
        self.tol, self.atol_q, self.atol_v = rtol, atol[:nq], atol[nq:2 * nq]
        self.floor = 100 * EPS / rtol   # a weighted correction at round-off level
        self.mask = np.asarray(system.error_mask[:nq], bool)
        self.error_order = 2 if estimate else None
        self.error_mask = np.zeros(system.n, bool)
        self.error_mask[:nq] = self.mask
        self.c_err = abs(scheme.beta - 1.0 / 6.0)
        self.qscale = np.asarray(system.atol_scale[:nq], float)
        self.blocks = None       # (K, C) from the last tangent evaluation
        self.fresh = False       # blocks evaluated for the current step
        self.factor_at = None    # (t, h) of the current LU
        self.factor = None
        self.saddle = None       # the sparse assembly of the iteration matrix, kept
        self.rate = 0.5          # last observed contraction rate
        self.gtol = None
        self.start_values = {}
        self.first = True        # no step accepted yet: a_n is the start value
        self.qdd = self.a = None
        self.pending = self.pending_h = None
        self.h_last = None       # size of the last accepted step

    # --------------------------------------------------------------- pieces
    def force(self, t, q, v):
        self.counts["nfev"] += 1
        return np.asarray(self.system.force(t, q, v), float)

    def wrms(self, x, w):
        m = self.mask
        return rms(x[m] / w[m])

    def jacobian(self, t, q, v, a, lam):
        self.counts["njev"] += 1
        self.blocks = self.system.tangent(t, q, v, a, lam)
        self.factor = None
        self.fresh = True

    def factorize(self, q, key, h):
        """LU of the iteration matrix: M, G at ``q`` (and at the step's end ``t + h``,
        ``key = (t, h)``), K, C from the last tangent."""
        s = self.s
        K, C = self.blocks
        M, G = self.system.mass(q), self.system.constraint_jac(q, *self.system.at(sum(key)))
        if self.saddle is None and any(sp.issparse(X) for X in (M, K, C, G)):
            self.saddle = SaddlePoint(self.nq, G.shape[0])   # sparse, never densified
        self.factor = _Factor([(M, 1.0), (K, s.beta * s.cu * h * h), (C, s.gamma * s.cu * h)],
                              G, self.saddle)
        self.factor_at = key
        self.counts["nlu"] += 1
        # round-off level of g near q: 1000 eps times the size of the terms of G q
        scale = abs(G) @ np.maximum(np.abs(q), self.qscale)
        self.gtol = 1e3 * EPS * max(float(np.max(scale, initial=0.0)), EPS)

    def auxiliary(self, t, q, v, h):
        """``a_n`` for a step of size ``h`` from ``t``.

        At ``t_0``, Arnold and Bruls' start value ``q''(t_0 + (am - af) h)`` for
        the ``h`` of this first step, from the index-1 acceleration equations at
        the second-order Taylor state (one ``force`` call per first step size
        tried); afterwards the ``a`` the last accepted step produced.
        """
        da = self.s.am - self.s.af
        if da == 0.0 or not self.first:
            return self.a
        if h not in self.start_values:
            dt = da * h
            qs = q + dt * v + 0.5 * dt * dt * self.qdd
            vs = v + dt * self.qdd
            self.start_values[h] = consistent_acceleration(
                self.system, self.force, t + dt, qs, vs)[0]
        return self.start_values[h]

    # --------------------------------------------------------------- the run
    def start(self, t0, y0):
        """Consistent ``q''_0`` and ``lam_0`` (or the system's ``a0`` and ``lam_0``)."""
        system = self.system
        q0, v0, lam0 = (np.array(x, float) for x in system.split(y0))
        a0 = system.a0
        if a0 is None:
            a0, lam0 = consistent_acceleration(system, self.force, t0, q0, v0)
        self.qdd = np.array(a0, float)
        self.a = self.qdd.copy()
        return np.concatenate([q0, v0, lam0])

    def initial_step(self, t0, y0, rtol, atol):
        """The old first try: ``1e-3`` of the span, at most the output spacing
        (the error test corrects it)."""
        t_eval = self.system.t_eval
        return min(1e-3 * (self.system.t_end - t0), t_eval[1] - t_eval[0])

    def max_step(self, t, y):
        """Under error control, near ``t_end``: the rest split into
        ``ceil(rest / h_last)`` equal steps, so that the run does not end with
        a step much shorter than the one before (it disturbs lam, whose
        index-3 error grows as the step shrinks; see the module docstring)."""
        rest = self.system.t_end - t
        if self.rtol is None or self.h_last is None or rest >= self.END_WINDOW * self.h_last:
            return np.inf
        return rest / max(1, int(np.ceil(rest / self.h_last * (1 - 1e-9))))

    def step(self, t, y, h):
        """One step; a corrector failure is retried once with new ``K``, ``C``
        (unless they were new), then raises :class:`StepFailure`."""
        q, v, lam = self.system.split(y)
        new = self.corrector(t, q, v, lam, h)
        if new is None and not self.fresh:
            self.blocks = None
            new = self.corrector(t, q, v, lam, h)
        if new is None:
            self.blocks = None           # new K, C for the next try
            raise StepFailure(Status.NEWTON_FAILURE,
                              f"Newton iteration failed at t={t:.6g} with h={h:.3g} "
                              "(fresh Jacobian)")
        self.pending, self.pending_h = new, h
        y_new = np.concatenate([new.q, new.v, new.lam])
        error = None
        if self.error_order is not None:
            error = np.zeros_like(y_new)
            error[:self.nq] = self.c_err * h * h * (new.qdd - self.qdd)
        return Step(y_new, error=error, dense=self.dense(t, h, q, v, lam, new))

    def dense(self, t, h, q, v, lam, new):
        """Cubic Hermite in ``q`` (from ``q``, ``v``) and in ``v`` (from ``v``,
        ``q''``) at both ends, linear in ``lam``; ``q`` then projected onto
        ``g(q) = 0`` (:meth:`onto_constraint`)."""
        qs = hermite(t, h, q, v, new.q, new.v)
        vs = hermite(t, h, v, self.qdd, new.v, new.qdd)

        def at(te):
            s = (te - t) / h
            return np.concatenate([self.onto_constraint(qs(te), te), vs(te),
                                   (1 - s) * lam + s * new.lam])
        return at

    def onto_constraint(self, q, t, maxit=5):
        """The nearest (Euclidean) ``q`` with ``g(q) = 0`` (``g(q, t) = 0`` when the
        constraints depend on time), to second order in
        the correction: simplified Gauss-Newton steps ``q -= G_0^T (G_0
        G_0^T)^-1 g(q)`` with ``G_0`` (and the factorization of ``G_0 G_0^T``)
        taken at the interpolated point, one more after ``|g|`` reaches the
        corrector's round-off level (at most ``maxit``). The interpolation
        error is ``O(h^4)``, so is the correction ``d``: the order is kept,
        and an output inside a step satisfies the constraint as a step end
        does; freezing ``G`` moves the result off the nearest point by
        ``O(|d|^2)`` only, and each step contracts ``g`` by a factor
        ``O(|d|)``. (Velocities are not projected: the step ends do not
        satisfy ``G v = 0`` exactly either.)"""
        system = self.system
        at = system.at(t)
        G = system.constraint_jac(q, *at)
        if sp.issparse(G):
            G = sp.csr_matrix(G)
            solve = factor(G @ G.T, symmetric=True)
        else:
            G = np.atleast_2d(np.asarray(G, float))
            cho = la.cho_factor(G @ G.T)
            solve = lambda g: la.cho_solve(cho, g)   # noqa: E731
        for _ in range(maxit):
            g = np.asarray(system.constraint(q, *at), float)
            done = np.max(np.abs(g), initial=0.0) <= self.gtol
            q = q - G.T @ np.atleast_1d(solve(g))
            if done:
                break
        return q

    def accept(self, t_new, y_new):
        """Commit ``q''`` and ``a``; ask for new K, C after slow convergence."""
        self.qdd, self.a, self.h_last = self.pending.qdd, self.pending.a, self.pending_h
        self.pending, self.first, self.fresh = None, False, False
        if self.rate > self.REFRESH:
            self.blocks = None

    def reject(self):
        self.pending = None

    # --------------------------------------------------------------- corrector
    def corrector(self, t, q, v, lam, h):
        """Corrector for one step of size ``h`` from ``(t, q, v, lam)``: an
        :class:`Attempt`, or None when it does not converge."""
        s, system, nq = self.s, self.system, self.nq
        t1 = t + h
        a_n = self.auxiliary(t, q, v, h)
        qp = q + h * v + h * h * (0.5 - s.beta) * a_n
        vp = v + h * (1 - s.gamma) * a_n
        c0 = (s.af * self.qdd - s.am * a_n) / (1 - s.am)
        bh2, gh = s.beta * s.cu * h * h, s.gamma * s.cu * h
        # index 3: round-off eps |q| in positions is round-off (gamma / beta) eps |q| / h
        # in velocities; corrections below that level are noise
        vnoise = 1e3 * EPS * s.gamma / (s.beta * h)
        u, lam = self.qdd.copy(), np.array(lam, float)    # predictor: q''_{n+1} = q''_n
        q_pred = qp + h * h * s.beta * (s.cu * u + c0)
        if self.blocks is None:     # K, C at the predicted state
            self.jacobian(t1, q_pred, vp + h * s.gamma * (s.cu * u + c0), u, lam)
        if self.factor is None or self.factor_at != (t, h):
            self.factorize(q_pred, (t, h), h)
        converged, dn_old = False, None
        for k in range(self.maxit + 1):
            a1 = s.cu * u + c0
            q1 = qp + h * h * s.beta * a1
            v1 = vp + h * s.gamma * a1
            g = np.asarray(system.constraint(q1, *system.at(t1)), float)
            if converged and np.max(np.abs(g), initial=0.0) <= self.gtol:
                return Attempt(q1, v1, u, a1, lam)
            if k == self.maxit or not np.isfinite(q1).all():
                break
            self.counts["nniter"] += 1
            f = self.force(t1, q1, v1)
            G = system.constraint_jac(q1, *system.at(t1))
            res = np.concatenate([system.mass(q1) @ u + G.T @ lam - f, g / bh2])
            d = self.factor.solve(res)
            u -= d[:nq]
            lam -= d[nq:]
            dn = max(self.wrms(bh2 * d[:nq], self.atol_q + self.tol * np.abs(q1)),
                     self.wrms(gh * d[:nq], self.atol_v + self.tol * np.abs(v1)
                               + vnoise * np.maximum(np.abs(q1), self.qscale)))
            if converged:
                continue                      # iterating on g only
            if dn <= self.floor:
                converged = True
                continue
            if dn_old is None:
                eta = max(self.rate, 0.1)     # rate of the last step, or 0.1
            else:
                self.rate = eta = dn / dn_old
                if eta >= 0.9:
                    if dn > 1.0:
                        break                 # diverges or stalls above the tolerance
                    converged = True          # stalls below it: round-off level
                    continue
            converged = eta / (1 - eta) * dn <= self.KAPPA
            dn_old = dn
        self.counts["nnfail"] += 1
        return None


class AlphaMethod(Integrator):
    """Common declarations of the Newmark family (see the module docstring)."""

    accepts = frozenset({"mechanical"})
    max_index = 3
    order = 2
    implicit = True
    uses_jacobian = True
    dense_output = True
    #: whether the steps carry the error estimate (the method can run at rtol)
    adaptive = False
    #: Newton tolerance (relative, on positions) at a fixed step
    newton_tol = 1e-10
    #: most corrector iterations per try under error control and at a fixed step
    maxit_adaptive = 10
    maxit_fixed = 20

    def scheme(self) -> Scheme:
        raise NotImplementedError

    def stepper(self, system, counts, rtol=None, atol=None):
        maxit = self.maxit_fixed if rtol is None else self.maxit_adaptive
        return AlphaStepper(system, counts, rtol, atol, scheme=self.scheme(),
                            estimate=self.adaptive, newton_tol=self.newton_tol, maxit=maxit)

    def solve(self, system, *, rtol=None, atol=None, h=None):
        """The shared driver; ``atol`` defaults to ``system.atol(rtol)``."""
        if h is None and rtol is not None and atol is None:
            atol = system.atol(rtol)
        return super().solve(system, rtol=rtol, atol=atol, h=h)


class HHT(AlphaMethod):
    """HHT-alpha (Negrut et al. 2007): error control on the positions at
    ``rtol``, or a fixed step ``h``."""

    name = "hht"
    description = ("HHT-alpha for index-3 mechanical systems, adaptive (rtol) or fixed (h) "
                   "step (alpha=-0.3)")
    reference = ("Negrut, Rampalli, Ottarsson, Sajdak, J. Comput. Nonlinear Dyn. 2 (2007) "
                 "73-85")
    adaptive = True
    stability = "A"
    #: alpha in [-1/3, 0] (Hilber, Hughes, Taylor 1977); -0.3, the default of ADAMS/Solver's
    #: HHT integrator (MSC Adams documentation; the seed documents do not state it).
    settings = (Setting("alpha", float, -0.3, "numerical damping: 0 none (trapezoidal), "
                        "-1/3 the most", low=-1 / 3, high=0.0),)
    #: step-size control (see the module docstring)
    controller = PI(safety=0.9, factor_min=0.2, factor_max=2.0, hold_band=(1.0, 1.2))

    def scheme(self):
        return hht_scheme(self.alpha)


class Newmark(AlphaMethod):
    """Newmark (beta, gamma) on the index-3 form.

    Defaults beta = 0.36, gamma = 0.7: the dissipative choice
    beta = (gamma + 1/2)^2 / 4 (Newmark, J. Eng. Mech. Div. ASCE 85 (1959) 67-94;
    Hilber, Hughes, Taylor, Earthquake Eng. Struct. Dyn. 5 (1977) 283-292), the values of
    ADAMS/Solver's Newmark integrator (MSC Adams documentation; the seed documents
    do not state them). gamma > 1/2 makes it first order; gamma = 1/2 (beta = 1/4,
    the trapezoidal rule) is second order but leaves the (-1)^n oscillation of
    lam undamped on index-3 problems.
    """

    name = "newmark"
    description = "Newmark for index-3 mechanical systems, fixed step (beta=0.36, gamma=0.7)"
    reference = "Newmark, J. Eng. Mech. Div. ASCE 85 (1959) 67-94"
    adaptive = False
    stability = "A"
    settings = (Setting("beta", float, 0.36, "Newmark's beta (unconditionally stable for "
                        "2 beta >= gamma >= 1/2)", low=0.0, high=1.0),
                Setting("gamma", float, 0.7, "Newmark's gamma (> 1/2 damps, first order)",
                        low=0.5, high=1.0))

    order = 1

    def scheme(self):
        if not 2 * self.beta >= self.gamma >= 0.5:
            raise ValueError(f"Newmark beta={self.beta}, gamma={self.gamma} is not "
                             "unconditionally stable (need 2 beta >= gamma >= 1/2)")
        return Scheme(beta=self.beta, gamma=self.gamma)


class GeneralizedAlpha(AlphaMethod):
    """Generalized-alpha with the Arnold-Bruls treatment of constraints.

    The auxiliary acceleration starts at ``a_0 = q''(t_0 + (am - af) h)``,
    computed from the index-1 acceleration equations at the second-order Taylor
    state at that time (one extra ``force`` call): Arnold and Bruls show that
    ``a_0 = q''(t_0)`` leaves an O(h) transient in lam.
    """

    name = "gen-alpha"
    description = "Generalized-alpha (Chung-Hulbert, Arnold-Bruls), index 3, fixed step (rho_inf=0.9)"
    reference = ("Chung and Hulbert, J. Appl. Mech. 60 (1993) 371-375; "
                 "Arnold and Bruls, Multibody Syst. Dyn. 18 (2007) 185-202")
    adaptive = False
    stability = "A"
    #: spectral radius at infinity, in [0, 1]; 0.9 is our choice (mild damping).
    settings = (Setting("rho_inf", float, 0.9, "spectral radius at infinity: 1 no damping, "
                        "0 the most", low=0.0, high=1.0),)

    def scheme(self):
        return generalized_alpha_scheme(self.rho_inf)

