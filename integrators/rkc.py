"""Runge-Kutta-Chebyshev (RKC): a stabilized explicit method of order 2.

The s-stage, second-order, damped RKC scheme of van der Houwen and Sommeijer
with the recurrence coefficients of Verwer, Hundsdorfer and Sommeijer (1990) as
used by the code RKC (Sommeijer, Shampine and Verwer 1997): with damping
``eps = 2/13``, ``w0 = 1 + eps/s^2``, ``w1 = T_s'(w0)/T_s''(w0)``,
``b_j = T_j''(w0)/T_j'(w0)^2`` (``b_0 = b_1 = b_2``),

    Y_0 = y_n,   Y_1 = Y_0 + mu~_1 h F_0,   mu~_1 = b_1 w1,
    Y_j = (1 - mu_j - nu_j) Y_0 + mu_j Y_{j-1} + nu_j Y_{j-2}
          + mu~_j h F_{j-1} + gamma~_j h F_0,                j = 2..s,
    mu_j = 2 b_j w0 / b_{j-1},  nu_j = -b_j / b_{j-2},  mu~_j = 2 b_j w1 / b_{j-1},
    gamma~_j = -(1 - b_{j-1} T_{j-1}(w0)) mu~_j,   y_{n+1} = Y_s,

with ``F_j = f(t_n + c_j h, Y_j)`` and the stage abscissae ``c_j`` from the same
recurrence. Its stability polynomial ``R_s(z) = 1 - b_s T_s(w0) + b_s T_s(w0 +
w1 z)`` stays bounded by about 1 on ``[-beta(s), 0]`` with ``beta(s) ~ 0.653
s^2``; the stage count is ``s = 1 + floor(sqrt(1 + 1.54 h rho))`` for a
spectral-radius estimate ``rho``, obtained as in RKC by a nonlinear power
method on differences of ``f`` (every such call is a counted evaluation),
increased by 20 % and renewed every 25 accepted steps (and after a rejected step).

One registered integrator, ``rkc``, whose :class:`RKCStepper` runs on the
shared driver (:mod:`integrator_bench.integrators.driver`):

* given ``rtol``: adaptive step and stage number with RKC's control. The
  local error estimate ``0.8 (y_n - y_{n+1}) + 0.4 h (F_n + F_{n+1})``
  (``O(h^3)``) is weighed by the driver's controller; the step factor is
  the code RKC's predictive one, ``0.8 (h_n / h_{n-1}) err_{n-1}^{1/3} /
  err_n^{2/3}`` (``0.8 err_n^{-1/3}`` on a segment's first accepted step),
  limited to [0.1, 10] and to at most 1 after a rejection; a rejected step
  shrinks by ``0.8 err^{-1/3}`` (the integrator's controller constants, see
  :mod:`~integrator_bench.integrators.control`). RKC's initial step:
  ``h = min(span, 1/rho)``, cut to ``0.1 / sqrt(est)`` when ``h^2 est > 0.01`` with ``est``
  the weighted RMS of ``F(y_0 + h F_0) - F_0`` (one evaluation). At most 250
  stages: the step is bounded so that ``s <= 250`` (the last step, which the
  driver stretches by up to 10 % to end at ``t_end``, up to 262).
* given ``h``: the steps ``t0 + k h``, stages from the spectral-radius
  estimate; a step needing more than 1000 stages ends the run
  (``method_limit``).

``F(y_{n+1})``, computed for the error estimate, is the next step's ``F_n``
(first same as last), unless a projection moved ``y_{n+1}``. Output times
inside a step take the cubic Hermite interpolant of the end values and slopes
(``O(h^4)``, adequate for order 2); at a fixed step, where no error estimate
needs ``F(y_{n+1})``, it is evaluated only when an output time falls inside
the step, and reused by the next step. A non-finite spectral-radius estimate
ends the run (``method_limit``).

RKC is a one-step method: it projects after every accepted step when the
system asks for it. It is not A-stable: its stability region is a thin strip
around the negative real axis, so undamped oscillations (imaginary
eigenvalues) are not stabilized.

References: Sommeijer, Shampine and Verwer, J. Comput. Appl. Math. 88 (1997)
315-326; Verwer, Hundsdorfer and Sommeijer, Numer. Math. 57 (1990) 157-178;
Hairer and Wanner, Solving ODEs II, 2nd ed., sect. IV.2.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from integrator_bench.integrators.base import (Integrator, Intervals, Status, Step, StepFailure,
                                               Stepper)
from integrator_bench.integrators.control import PI, rms
from integrator_bench.integrators.interpolation import hermite
from integrator_bench.integrators.settings import Setting

EPS_DAMPING = 2.0 / 13.0
RHO_EVERY = 25            # accepted steps between spectral-radius estimates
MAX_STAGES_ADAPTIVE = 250
MAX_STAGES_FIXED = 1000


def rkc_coefficients(s: int, eps: float = EPS_DAMPING) -> dict:
    """Recurrence coefficients of the s-stage second-order RKC method (s >= 2)."""
    if s < 2:
        raise ValueError(f"RKC needs at least 2 stages, got s={s}")
    w0 = 1.0 + eps / s**2
    T, dT, d2T = np.zeros(s + 1), np.zeros(s + 1), np.zeros(s + 1)
    T[0], T[1], dT[1] = 1.0, w0, 1.0
    for j in range(2, s + 1):
        T[j] = 2 * w0 * T[j - 1] - T[j - 2]
        dT[j] = 2 * T[j - 1] + 2 * w0 * dT[j - 1] - dT[j - 2]
        d2T[j] = 4 * dT[j - 1] + 2 * w0 * d2T[j - 1] - d2T[j - 2]
    w1 = dT[s] / d2T[s]
    b = np.empty(s + 1)
    b[2:] = d2T[2:] / dT[2:] ** 2
    b[0] = b[1] = b[2]
    mu, nu, mut, gam = (np.zeros(s + 1) for _ in range(4))
    mut[1] = b[1] * w1
    for j in range(2, s + 1):
        mu[j] = 2 * w0 * b[j] / b[j - 1]
        nu[j] = -b[j] / b[j - 2]
        mut[j] = 2 * w1 * b[j] / b[j - 1]
        gam[j] = -(1 - b[j - 1] * T[j - 1]) * mut[j]
    c = np.zeros(s + 1)
    c[1] = mut[1]
    for j in range(2, s + 1):
        c[j] = mu[j] * c[j - 1] + nu[j] * c[j - 2] + mut[j] + gam[j]
    return {"s": s, "w0": w0, "w1": w1, "b": b, "T": T, "mu": mu, "nu": nu,
            "mut": mut, "gam": gam, "c": c}


def stability_polynomial(s: int, z) -> np.ndarray:
    """``R_s(z) = 1 - b_s T_s(w0) + b_s T_s(w0 + w1 z)``."""
    k = rkc_coefficients(s)
    x = k["w0"] + k["w1"] * np.asarray(z, dtype=complex)
    return 1 - k["b"][s] * k["T"][s] + k["b"][s] * np.polynomial.chebyshev.chebval(
        x, [0] * s + [1])


def real_stability_interval(s: int) -> float:
    """``beta(s)``: the length of the real stability interval ``[-beta, 0]`` of
    the s-stage RKC method, by bisection on :func:`stability_polynomial`.

    On ``w0 + w1 z`` in ``[-1, w0]`` the polynomial stays within ``[1 - b_s
    (T_s(w0) + 1), 1]``, inside ``[-1, 1]``; left of ``-1`` ``|T_s|`` grows
    monotonically, so the boundary lies beyond ``z = -(1 + w0) / w1`` and is
    bracketed by doubling. About ``0.653 s^2`` (Sommeijer, Shampine and Verwer
    1997, sect. 2).
    """
    k = rkc_coefficients(s)

    def stable(z):
        return abs(stability_polynomial(s, z)) <= 1.0

    good = -(1.0 + k["w0"]) / k["w1"]
    bad = 1.01 * good
    while stable(bad):
        good, bad = bad, 2.0 * bad
    while bad - good < -1e-12 * abs(good):
        mid = 0.5 * (good + bad)
        good, bad = (mid, bad) if stable(mid) else (good, mid)
    return -good


def stages_for(h: float, rho: float) -> int:
    """Stages needed for ``h rho`` inside the stability interval (RKC's rule)."""
    return max(2, 1 + int(math.sqrt(1.0 + 1.54 * h * rho)))


def rkc_step(fun, t, y, h, f0, coef):
    """One RKC step from ``(t, y)`` with ``f0 = f(t, y)``."""
    mu, nu, mut, gam, c = coef["mu"], coef["nu"], coef["mut"], coef["gam"], coef["c"]
    y_prev2, y_prev = y, y + mut[1] * h * f0
    for j in range(2, coef["s"] + 1):
        fj = np.asarray(fun(t + c[j - 1] * h, y_prev), float)
        y_new = ((1 - mu[j] - nu[j]) * y + mu[j] * y_prev + nu[j] * y_prev2
                 + mut[j] * h * fj + gam[j] * h * f0)
        y_prev2, y_prev = y_prev, y_new
    return y_prev


def _norm2(x: np.ndarray) -> float:
    """The Euclidean norm of the 1-D float array ``x`` (one dot product)."""
    return math.sqrt(float(x @ x))


class SpectralRadius:
    """Nonlinear power method on ``f`` differences, as in RKC's ``rkcrho``.

    Returns 1.2 times the estimate; the last direction starts the next call.
    Keeps where the last estimate was made (``at``, ``size``: the time and the
    state's 2-norm) and the first one (``first``), which :meth:`describe` names.
    """

    def __init__(self, fun, n):
        self.fun, self.v = fun, None
        self.n = n
        self.first = self.at = self.size = None

    def describe(self, rho: float) -> str:
        """``"spectral radius 2.5e+18 (its estimate at t=3.1, where |y| = 1e+09; 15 at
        the first)"``: the radius a step used, where it was estimated, and the first
        estimate (the start's, as ``ibench stiffness`` gives it there): a run that
        blows up estimates at its blown-up state."""
        where = "" if self.at is None else f"its estimate at t={self.at:.6g}, where |y| = " \
                                            f"{self.size:.3g}; "
        first = "" if self.first is None else f"{self.first:.3g} at the first"
        return f"spectral radius {rho:.3g} ({where}{first})"

    def __call__(self, t, y, f0) -> float:
        ynorm = _norm2(y)
        self.at, self.size = float(t), float(ynorm)
        dy = math.sqrt(np.finfo(float).eps) * max(ynorm, 1.0)
        v = self.v if self.v is not None else np.asarray(f0, float)
        if not np.any(v):
            v = np.ones(self.n)
        z = y + v * (dy / _norm2(v))
        sigma = 0.0
        for it in range(50):
            d = np.asarray(self.fun(t, z), float) - f0
            dn = _norm2(d)
            if dn == 0.0:  # f locally constant along v: try another direction
                d, dn = np.ones(self.n), 0.0
            sigma_old, sigma = sigma, dn / dy
            z = y + d * (dy / max(_norm2(d), 1e-300))
            if it > 0 and abs(sigma - sigma_old) <= 0.01 * max(sigma, sigma_old):
                break
        self.v = z - y
        if self.first is None:
            self.first = 1.2 * sigma
        return 1.2 * sigma


class RKCStepper(Stepper):
    """One RKC step at a time, for the shared driver (see the module docstring).

    Keeps ``F_n = f(t_n, y_n)`` (None until needed) and the spectral-radius
    estimate, renewed every ``RHO_EVERY`` accepted steps and after a rejected
    step, as RKC does.
    """

    error_order = 2          # the error estimate is O(h^3): controller exponent 1/3
    dense_order = 3

    hard_limit = MAX_STAGES_FIXED     # more stages end an adaptive run
    #: with an embedded estimate of its own (:meth:`advance`), take the larger of it
    #: and RKC's endpoint estimate, component by component
    endpoint_check = False

    def __init__(self, system, counts, rtol=None, atol=None, max_stages=None, stages=None):
        super().__init__(system, counts, rtol, atol)
        self.fun = system.fun
        self.radius = SpectralRadius(system.fun, system.n)
        default = MAX_STAGES_FIXED if rtol is None else MAX_STAGES_ADAPTIVE
        self.max_stages = max_stages or default   # bounds max_step
        self.fixed_stages = stages                # None: from the spectral radius
        self.coefficients: dict = {}
        self.f = self.rho = None
        self.age = 0
        self.last: dict | None = None    # the last attempt: y_new and F(y_new) if known
        self.end: dict | None = None     # the accepted attempt, whose F the dense output may add

    def _f(self, t, y) -> np.ndarray:
        return np.asarray(self.fun(t, y), float)

    def start(self, t0, y0):
        self.f = self._f(t0, y0)
        if not self.fixed_stages:
            self.rho = self.radius(t0, y0, self.f)
        return y0

    def _fn(self, t, y) -> np.ndarray:
        """``F_n = f(t_n, y_n)``: kept, found by the last step's dense output, or evaluated."""
        if self.f is None:
            known = self.end["f"] if self.end is not None else None
            self.f = known if known is not None else self._f(t, y)
        self.end = None
        return self.f

    def _spectral_radius(self, t, y) -> float:
        self._fn(t, y)
        if self.rho is None or self.age >= RHO_EVERY:
            self.rho, self.age = self.radius(t, y, self.f), 0
        return self.rho

    def initial_step(self, t0, y0, rtol, atol):
        """RKC's first step (see the module docstring); one evaluation of ``f``."""
        span = self.system.t_end - t0
        h = min(span, 1.0 / self.rho) if self.rho else span    # no rho at fixed stages
        w = atol + rtol * np.abs(y0)
        f1 = self._f(t0 + h, y0 + h * self.f)
        est = rms((f1 - self.f) / w)
        return 0.1 / math.sqrt(est) if h * h * est > 0.01 else h

    def longest(self, rho: float) -> float:
        """The longest step ``s <= max_stages`` stages keep stable at spectral
        radius ``rho`` (the inverse of :meth:`stages`)."""
        return ((self.max_stages - 1) ** 2 - 1) / (1.54 * rho)

    def stages(self, h: float, rho: float) -> int:
        """The stage count for a step ``h`` at spectral radius ``rho`` (:func:`stages_for`)."""
        return stages_for(h, rho)

    def advance(self, t, y, h, f0, s):
        """One step of ``s`` stages: ``(y_new, error)``, ``error`` None when the
        method has no embedded estimate (then :meth:`step` forms RKC's)."""
        coef = self.coefficients.get(s) or self.coefficients.setdefault(s, rkc_coefficients(s))
        return rkc_step(self.fun, t, y, h, f0, coef), None

    def max_step(self, t, y):
        """The longest step with at most ``max_stages`` stages (``s`` from
        :meth:`stages`); the driver may stretch the last step by up to 10 %
        to reach ``t_end``, which then takes up to 262 stages (RKC)."""
        if self.fixed_stages:
            return math.inf
        rho = self._spectral_radius(t, y)
        if not (np.isfinite(rho) and rho > 0):
            return math.inf
        return self.longest(rho)

    def _stage_count(self, t, y, h) -> int:
        if self.fixed_stages:
            return self.fixed_stages
        rho = self._spectral_radius(t, y)
        if not np.isfinite(rho):
            raise StepFailure(Status.METHOD_LIMIT,
                              f"spectral radius estimate is not finite at t={t:.6g}", retry=False)
        s = self.stages(h, rho)
        # at a fixed step the bound is max_stages; under error control max_step keeps
        # s <= max_stages (but see below) and the step fails only past the hard limit
        limit = self.max_stages if self.rtol is None else self.hard_limit
        if s > limit:
            raise StepFailure(Status.METHOD_LIMIT, f"h={h:.3g} with "
                              f"{self.radius.describe(rho)} needs {s} stages (> {limit})",
                              retry=False)
        return s

    def step(self, t, y, h):
        s = self._stage_count(t, y, h)
        self._fn(t, y)
        f0 = self.f
        y_new, error = self.advance(t, y, h, f0, s)
        last = self.last = {"y": y_new, "f": None}
        if not np.isfinite(y_new).all():
            return Step(y_new, error=np.full(y_new.shape, math.inf))
        if self.rtol is None:
            error = None
        elif error is None or self.endpoint_check:
            last["f"] = self._f(t + h, y_new)
            rkc = 0.8 * (y - y_new) + 0.4 * h * (f0 + last["f"])
            error = rkc if error is None else np.maximum(np.abs(error), np.abs(rkc))

        def dense(te):
            if last["f"] is None:
                last["f"] = self._f(t + h, y_new)
            return hermite(t, h, y, f0, y_new, last["f"])(te)
        return Step(y_new, error=error, dense=dense)

    def accept(self, t_new, y_new):
        """Keep ``F(y_new)`` when ``y_new`` is the step's value (first same as
        last); after a projection moved it, evaluate it anew (under error
        control) or when the next step needs it (at a fixed step)."""
        last, self.last = self.last, None
        same = y_new is last["y"] or np.array_equal(y_new, last["y"])
        if same:
            self.f, self.end = last["f"], last
        else:
            self.end = None
            self.f = self._f(t_new, y_new) if self.rtol is not None else None
        self.age += 1

    def reject(self):
        self.last, self.rho = None, None


class RKC(Integrator):
    name = "rkc"
    description = ("Runge-Kutta-Chebyshev, order 2, stages from a spectral-radius estimate; "
                   "adaptive step and stage number (RKC 1997) at rtol, or fixed step h")
    reference = "Sommeijer, Shampine, Verwer, J. Comput. Appl. Math. 88 (1997) 315-326"
    order = 2
    projects = True
    dense_output = True
    events = True          # located on the Hermite interpolant by the driver
    #: RKC's own control (Sommeijer, Shampine, Verwer 1997, and their code rkc.f)
    controller = PI(safety=0.8, factor_min=0.1, factor_max=10.0, k_i=2.0, k_p=1.0,
                    predictive=True)
    max_steps = 500_000
    #: the real stability interval per stage count, from the stability polynomial
    stability_intervals = Intervals({f"s={s}": functools.partial(real_stability_interval, s)
                                     for s in (2, 5, 10, 20, 50, 100, 250)})

    settings = (Setting("max_stages", int, 0, "most stages per step (bounds the step under "
                        "error control); 0: 250 at rtol, 1000 at a fixed step", low=0,
                        high=MAX_STAGES_FIXED),)

    def stepper(self, system, counts, rtol=None, atol=None):
        return RKCStepper(system, counts, rtol, atol, max_stages=self.max_stages or None)
