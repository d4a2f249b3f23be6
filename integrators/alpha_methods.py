"""HHT-alpha, Newmark and generalized-alpha for index-3 mechanical systems.

All four integrators take a :class:`integrator_bench.problems.system.MechanicalSystem`,
``M(q) q'' = f(t, q, v) - G(q)^T lam``, ``g(q) = 0``, and share one Newmark
machinery (Arnold and Bruls 2007). Per step the unknowns are the acceleration
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
  Negrut et al. as PROBLEMS.md section 9 recalls it (from memory),
  ``(M q'')_{n+1} / (1 + alpha) + (G^T lam - f)_{n+1}
  - alpha / (1 + alpha) (G^T lam - f)_n = 0``, with their ``q''`` our ``a``
  (up to the start value). When M depends on q they differ: that form,
  implemented first, converged only to first order on Andrews' squeezer
  (final-time position errors 3.2e-2, 1.7e-2, 8.3e-3, 4.2e-3 for 1000 to 8000
  steps), this one to second order (1.2e-3, 2.9e-4, 7.1e-5, 1.8e-5).
* Newmark (1959): am = af = 0, free (beta, gamma).
* Generalized-alpha (Chung and Hulbert 1993) with constraints as Arnold and
  Bruls: am, af, beta, gamma from rho_inf.

The start value ``a_0 = q''(t_0 + (am - af) h)`` follows Arnold and Bruls'
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
At most ``maxit`` iterations: 10 for ``hht`` (the ADAMS MAXIT), 20 for the
fixed-step methods, which cannot shorten the step and solve to 1e-10. Testing
only positions, as ADAMS does, left velocity errors of order tol / h per step
in our runs.

``hht`` controls the step with the local error estimate on the positions
``(beta - 1/6) h^2 (q''_{n+1} - q''_n)`` (PROBLEMS.md section 9, from the
seed's description; with the true accelerations ``q''``; weighted RMS over
``system.error_mask``, weights ``atol + rtol |q|``): accept when <= 1,
``h_new = h * 0.9 * err^(-1/3)`` within [0.2, 2] (at most 1 after a rejection),
and ``h`` is kept when the proposal lies in [h_used, 1.2 h]. After a failed
corrector the Jacobian is renewed, or, if it was fresh, ``h`` is divided by 4;
below ``1e-12 (t_end - t_0)`` the run stops with ``success=False``. It is a
per-step control: the global error grows with the number of steps and is not
bounded by rtol.

Output times are step ends, so that every output satisfies the constraint:
each stretch up to the next output time is split into ``ceil(remaining / h)``
equal steps (one small change of step size instead of one short last step,
which disturbed lam: on the squeezer at rtol 1e-9 the median lam error was
2.5e-2 with short last steps, 2.6e-4 with equal steps, as with fixed steps).
The fixed-step methods do the same, so their step is ``h`` wherever ``h``
divides the output spacing and slightly less elsewhere; they solve the
corrector to ``newton_tol`` = 1e-10 (relative, on ``atol_scale``), and a
corrector failure with a fresh Jacobian ends the run with ``success=False``.

Counters: ``nsteps`` accepted steps, ``nreject`` steps rejected by the error
test, ``nnfail`` failed corrector iterations (each followed by a new Jacobian
or a smaller step), ``nniter`` corrector iterations (one ``force`` call each),
``nlu`` LU factorizations, ``njev`` ``tangent`` calls, ``nfev`` ``force`` calls
(corrector iterations plus the start value).

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
import scipy.sparse.linalg as spla

from integrator_bench.integrators.base import Integrator, Solution

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
class State:
    t: float
    q: np.ndarray
    v: np.ndarray
    qdd: np.ndarray   # q'' at t
    a: np.ndarray     # auxiliary acceleration, ~ q''(t + (am - af) h) (= qdd for Newmark)
    lam: np.ndarray
    h: float | None = None           # size of the step that ended here (None at t0)


def _dense(A):
    return A.toarray() if sp.issparse(A) else np.asarray(A, dtype=float)


class _Factor:
    """LU factorization of the saddle-point matrix, dense or sparse."""

    def __init__(self, A11, G):
        if sp.issparse(A11) or sp.issparse(G):
            nc = G.shape[0]
            A = sp.bmat([[sp.csc_matrix(A11), sp.csc_matrix(G).T],
                         [sp.csc_matrix(G), sp.csc_matrix((nc, nc))]], format="csc")
            self.solve = spla.splu(A).solve
        else:
            G = np.asarray(G, float).reshape(-1, A11.shape[0])
            A = np.block([[A11, G.T], [G, np.zeros((G.shape[0], G.shape[0]))]])
            lu = la.lu_factor(A, check_finite=False)
            self.solve = lambda b: la.lu_solve(lu, b, check_finite=False)


def consistent_acceleration(system, force, t, q, v):
    """``(q'', lam)`` from ``[[M, G^T], [G, 0]] [q''; lam] = [f; -accel_term]``."""
    f = force(t, q, v)
    M, G = system.mass(q), system.constraint_jac(q)
    rhs = np.concatenate([f, -np.asarray(system.accel_term(q, v), float)])
    x = _Factor(M if sp.issparse(M) else _dense(M), G).solve(rhs)
    return x[:system.nq], x[system.nq:]


class _Stepper:
    """One integration run: the state, the iteration matrix and the counters."""

    KAPPA = 1e-2
    REFRESH = 0.3      # observed rate above which K, C are evaluated anew

    def __init__(self, system, scheme, rtol, atol, maxit):
        self.sys, self.s, self.maxit = system, scheme, maxit
        self.nq = nq = system.nq
        self.mask = np.asarray(system.error_mask[:nq], bool)
        atol = np.broadcast_to(np.asarray(atol, float), (system.n,))
        self.rtol, self.atol, self.atol_v = rtol, atol[:nq], atol[nq:2 * nq]
        self.floor = 100 * EPS / rtol   # a weighted correction at round-off level
        self.qscale = np.asarray(system.atol_scale[:nq], float)
        self.counts = dict(nfev=0, njev=0, nlu=0, nsteps=0, nreject=0, nniter=0, nnfail=0)
        self.blocks = None       # (K, C) from the last tangent evaluation
        self.fresh = False       # blocks evaluated for the current step
        self.factor_at = None    # (t, h) of the current LU
        self.factor = None
        self.rate = 0.5          # last observed contraction rate
        self.gtol = None
        self.start_values = {}

    # --------------------------------------------------------------- pieces
    def force(self, t, q, v):
        self.counts["nfev"] += 1
        return np.asarray(self.sys.force(t, q, v), float)


    def wrms(self, x, w):
        m = self.mask
        return float(np.sqrt(np.mean((x[m] / w[m]) ** 2))) if m.any() else 0.0

    def jacobian(self, t, q, v, a, lam):
        self.counts["njev"] += 1
        self.blocks = self.sys.tangent(t, q, v, a, lam)
        self.factor = None
        self.fresh = True

    def accept(self, new):
        """Count an accepted step; ask for new K, C after slow convergence."""
        self.counts["nsteps"] += 1
        self.fresh = False
        if self.rate > self.REFRESH:
            self.blocks = None
        return new

    def factorize(self, q, key, h):
        """LU of the iteration matrix: M, G at ``q``, K, C from the last tangent."""
        s = self.s
        K, C = self.blocks
        M, G = self.sys.mass(q), self.sys.constraint_jac(q)
        A11 = M + (s.beta * s.cu * h * h) * K + (s.gamma * s.cu * h) * C
        if not sp.issparse(A11):
            A11 = _dense(A11)
        self.factor = _Factor(A11, G)
        self.factor_at = key
        self.counts["nlu"] += 1
        # round-off level of g near q: 1000 eps times the size of the terms of G q
        scale = abs(G) @ np.maximum(np.abs(q), self.qscale)
        self.gtol = 1e3 * EPS * max(float(np.max(scale, initial=0.0)), EPS)

    def auxiliary(self, st, h):
        """``a_n`` for a step of size ``h`` from ``st``.

        At ``t_0``, Arnold and Bruls' start value ``q''(t_0 + (am - af) h)`` for
        the ``h`` of this first step, from the index-1 acceleration equations at
        the second-order Taylor state (one ``force`` call per first step size
        tried); afterwards the ``a`` the last step produced.
        """
        da = self.s.am - self.s.af
        if da == 0.0 or st.h is not None:
            return st.a
        if h not in self.start_values:
            dt = da * h
            q = st.q + dt * st.v + 0.5 * dt * dt * st.qdd
            v = st.v + dt * st.qdd
            self.start_values[h] = consistent_acceleration(self.sys, self.force, st.t + dt, q, v)[0]
        return self.start_values[h]

    # --------------------------------------------------------------- a step
    def step(self, st: State, h: float):
        """Corrector for one step of size ``h`` from ``st``: new State or None."""
        s, sys, nq = self.s, self.sys, self.nq
        t1 = st.t + h
        a_n = self.auxiliary(st, h)
        qp = st.q + h * st.v + h * h * (0.5 - s.beta) * a_n
        vp = st.v + h * (1 - s.gamma) * a_n
        c0 = (s.af * st.qdd - s.am * a_n) / (1 - s.am)
        bh2, gh = s.beta * s.cu * h * h, s.gamma * s.cu * h
        # index 3: round-off eps |q| in positions is round-off (gamma / beta) eps |q| / h
        # in velocities; corrections below that level are noise
        vnoise = 1e3 * EPS * s.gamma / (s.beta * h)
        u, lam = st.qdd.copy(), st.lam.copy()     # predictor: q''_{n+1} = q''_n
        q_pred = qp + h * h * s.beta * (s.cu * u + c0)
        if self.blocks is None:     # K, C at the predicted state
            self.jacobian(t1, q_pred, vp + h * s.gamma * (s.cu * u + c0), u, lam)
        if self.factor is None or self.factor_at != (st.t, h):
            self.factorize(q_pred, (st.t, h), h)
        converged, dn_old = False, None
        for k in range(self.maxit + 1):
            a1 = s.cu * u + c0
            q1 = qp + h * h * s.beta * a1
            v1 = vp + h * s.gamma * a1
            g = np.asarray(sys.constraint(q1), float)
            if converged and np.max(np.abs(g), initial=0.0) <= self.gtol:
                return State(t1, q1, v1, u, a1, lam, h)
            if k == self.maxit or not np.all(np.isfinite(q1)):
                break
            self.counts["nniter"] += 1
            f = self.force(t1, q1, v1)
            G = sys.constraint_jac(q1)
            res = np.concatenate([sys.mass(q1) @ u + G.T @ lam - f, g / bh2])
            d = self.factor.solve(res)
            u -= d[:nq]
            lam -= d[nq:]
            dn = max(self.wrms(bh2 * d[:nq], self.atol + self.rtol * np.abs(q1)),
                     self.wrms(gh * d[:nq], self.atol_v + self.rtol * np.abs(v1)
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


def _toward(remaining, h):
    """Step size toward an output time ``remaining`` away: the interval is split
    into ``ceil(remaining / h)`` equal steps (a step-size change once, small
    when many steps remain; one tiny last step would disturb lam). Returns the
    step and whether it lands on the output time."""
    n = max(1, int(np.ceil(remaining / h * (1 - 1e-9))))
    return remaining / n, n == 1


class AlphaMethod(Integrator):
    """Common driver of the Newmark family (see the module docstring)."""

    accepts = frozenset({"mechanical"})
    max_index = 3
    order = 2
    implicit = True
    uses_jacobian = True
    #: Newton tolerance (relative, on positions) of the fixed-step methods.
    newton_tol = 1e-10
    #: most corrector iterations per try
    maxit = 20
    #: step-size control of the adaptive method: safety factor, largest growth
    safety = 0.9
    growth = 2.0

    def scheme(self) -> Scheme:
        raise NotImplementedError

    def initial_state(self, stepper):
        system = stepper.sys
        q0, v0, lam0 = (np.array(x, float) for x in system.split(system.y0))
        a0 = system.a0
        if a0 is None:
            a0, lam0 = consistent_acceleration(system, stepper.force, system.t0, q0, v0)
        a0 = np.asarray(a0, float)
        return State(system.t0, q0, v0, a0.copy(), a0.copy(), lam0)

    def solve(self, system, *, rtol=None, atol=None, h=None):
        scheme = self.scheme()
        if self.adaptive:
            if rtol is None:
                raise ValueError(f"{self.name} is adaptive: give rtol")
            atol = system.atol(rtol) if atol is None else atol
            stepper = _Stepper(system, scheme, rtol, atol, self.maxit)
        else:
            if h is None or not h > 0:
                raise ValueError(f"{self.name} is a fixed-step method: give h > 0, not {h!r}")
            stepper = _Stepper(system, scheme, self.newton_tol,
                               self.newton_tol * system.atol_scale, self.maxit)
        t_eval = system.t_eval
        if h is None:   # first try of the adaptive method; the error test corrects it
            h = min(1e-3 * (system.t_end - system.t0), t_eval[1] - t_eval[0])
        st = self.initial_state(stepper)
        ys = np.empty((t_eval.size, system.n))
        ys[0] = system.y0
        drive = self._adaptive_run if self.adaptive else self._fixed_run
        reached, message = drive(stepper, st, h, ys)
        success = reached == t_eval.size
        return Solution(t_eval[:reached], ys[:reached], success, message, stepper.counts)

    @staticmethod
    def _record(ys, i, st):
        ys[i] = np.concatenate([st.q, st.v, st.lam])

    def _fixed_run(self, stepper, st, h, ys):
        t_eval = stepper.sys.t_eval
        for i in range(1, t_eval.size):
            t_out = t_eval[i]
            while st.t < t_out:
                h_use, landing = _toward(t_out - st.t, h)
                new = stepper.step(st, h_use)
                if new is None:
                    if stepper.fresh:
                        return i, (f"Newton iteration failed at t={st.t:.6g} with "
                                   f"h={h_use:.3g} (fresh Jacobian)")
                    stepper.blocks = None       # new Jacobian, same step
                    continue
                if landing:
                    new.t = t_out
                st = stepper.accept(new)
            self._record(ys, i, st)
        return t_eval.size, ""

    def _adaptive_run(self, stepper, st, h, ys):
        s = self.scheme()
        t_eval = stepper.sys.t_eval
        span = stepper.sys.t_end - stepper.sys.t0
        h_min = 1e-12 * max(span, abs(stepper.sys.t_end))
        c_err = abs(s.beta - 1.0 / 6.0)
        fac_max = self.growth
        for i in range(1, t_eval.size):
            t_out = t_eval[i]
            while st.t < t_out:
                h_use, clipped = _toward(t_out - st.t, h)
                new = stepper.step(st, h_use)
                if new is None:
                    fresh, stepper.blocks = stepper.fresh, None   # new K, C next try
                    if not fresh:
                        continue                   # same step
                    h, fac_max = 0.25 * h_use, 1.0
                    if h < h_min:
                        return i, (f"Newton iteration failed at t={st.t:.6g} with "
                                   f"h={h_use:.3g}, at the minimum step")
                    continue
                w = stepper.atol + stepper.rtol * np.maximum(np.abs(st.q), np.abs(new.q))
                err = stepper.wrms(c_err * h_use ** 2 * (new.qdd - st.qdd), w)
                fac = self.safety * err ** (-1.0 / 3.0) if err > 0 else 5.0
                if err > 1.0:
                    stepper.counts["nreject"] += 1
                    h, fac_max = h_use * max(0.2, min(fac, 0.9)), 1.0
                    if h < h_min:
                        return i, f"step size {h:.3g} below the minimum at t={st.t:.6g}"
                    continue
                if clipped:
                    new.t = t_out
                st = stepper.accept(new)
                h_new = min(h_use * max(0.2, fac), fac_max * h)
                h, fac_max = (h if h_use <= h_new <= 1.2 * h else h_new), self.growth
            self._record(ys, i, st)
        return t_eval.size, ""


class HHT(AlphaMethod):
    """HHT-alpha with error control on the positions (Negrut et al. 2007)."""

    name = "hht"
    description = "HHT-alpha for index-3 mechanical systems, adaptive step (alpha=-0.3)"
    reference = ("Negrut, Rampalli, Ottarsson, Sajdak, J. Comput. Nonlinear Dyn. 2 (2007) "
                 "73-85")
    adaptive = True
    stability = "A"
    #: alpha in [-1/3, 0]; -0.3, the ADAMS default as PROBLEMS.md section 9 recalls it.
    alpha = -0.3
    maxit = 10

    def scheme(self):
        return hht_scheme(self.alpha)


class HHTFixed(HHT):
    """HHT-alpha with a fixed step size."""

    name = "hht-fixed"
    description = "HHT-alpha for index-3 mechanical systems, fixed step (alpha=-0.3)"
    adaptive = False
    maxit = 20


class Newmark(AlphaMethod):
    """Newmark (beta, gamma) on the index-3 form.

    Defaults beta = 0.36, gamma = 0.7: the dissipative choice
    beta = (gamma + 1/2)^2 / 4 with the ADAMS values (PROBLEMS.md section 9,
    from memory). gamma > 1/2 makes it first order; gamma = 1/2 (beta = 1/4,
    the trapezoidal rule) is second order but leaves the (-1)^n oscillation of
    lam undamped on index-3 problems.
    """

    name = "newmark"
    description = "Newmark for index-3 mechanical systems, fixed step (beta=0.36, gamma=0.7)"
    reference = "Newmark, J. Eng. Mech. Div. ASCE 85 (1959) 67-94"
    adaptive = False
    stability = "A"
    beta = 0.36
    gamma = 0.7

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
    rho_inf = 0.9

    def scheme(self):
        return generalized_alpha_scheme(self.rho_inf)

