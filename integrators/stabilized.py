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
increased by 20 % and renewed every 25 steps (and after a rejected step).

Two registered variants:

* ``rkc``: adaptive step and stage number; the local error estimate of RKC,
  ``0.8 (y_n - y_{n+1}) + 0.4 h (F(y_n) + F(y_{n+1}))``, in the weighted RMS
  norm, step factor ``0.8 err^{-1/3}`` limited to [0.1, 10]; at most 250
  stages (the step is cut to respect it). Output times inside a step are
  filled with cubic Hermite interpolation from the end values and slopes
  (``O(h^4)``, adequate for order 2; the end slopes are computed anyway).
* ``rkc-fixed``: fixed ``h`` (steps split at output times, see
  :mod:`integrator_bench.integrators.fixed_step`), stages from the spectral-radius estimate; it
  gives up when more than 1000 stages would be needed.

Both project after every step when the system asks for it (one-step
methods). RKC is not A-stable: its stability region is a thin strip around the negative
real axis, so undamped oscillations (imaginary eigenvalues) are not
stabilized.

References: Sommeijer, Shampine and Verwer, J. Comput. Appl. Math. 88 (1997)
315-326; Verwer, Hundsdorfer and Sommeijer, Numer. Math. 57 (1990) 157-178;
Hairer and Wanner, Solving ODEs II, 2nd ed., sect. IV.2.
"""

from __future__ import annotations

import math

import numpy as np

from integrator_bench.integrators.base import Integrator, Solution, outputs_between
from integrator_bench.integrators.fixed_step import StepFailure, blow_up_message, march

EPS_DAMPING = 2.0 / 13.0
RHO_EVERY = 25


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


class SpectralRadius:
    """Nonlinear power method on ``f`` differences, as in RKC's ``rkcrho``.

    Returns 1.2 times the estimate; the last direction starts the next call.
    """

    def __init__(self, fun, n):
        self.fun, self.v = fun, None
        self.n = n

    def __call__(self, t, y, f0) -> float:
        ynorm = float(np.linalg.norm(y))
        dy = math.sqrt(np.finfo(float).eps) * max(ynorm, 1.0)
        v = self.v if self.v is not None else np.asarray(f0, float)
        if not np.any(v):
            v = np.ones(self.n)
        z = y + v * (dy / np.linalg.norm(v))
        sigma = 0.0
        for it in range(50):
            d = np.asarray(self.fun(t, z), float) - f0
            dn = float(np.linalg.norm(d))
            if dn == 0.0:  # f locally constant along v: try another direction
                d, dn = np.ones(self.n), 0.0
            sigma_old, sigma = sigma, dn / dy
            z = y + d * (dy / max(np.linalg.norm(d), 1e-300))
            if it > 0 and abs(sigma - sigma_old) <= 0.01 * max(sigma, sigma_old):
                break
        self.v = z - y
        return 1.2 * sigma


class RKCFixed(Integrator):
    name = "rkc-fixed"
    description = "Runge-Kutta-Chebyshev, order 2, fixed step, stages from a spectral-radius estimate"
    reference = "Sommeijer, Shampine, Verwer, J. Comput. Appl. Math. 88 (1997) 315-326"
    order = 2
    adaptive = False
    projects = True
    max_stages = 1000

    def solve(self, system, *, rtol=None, atol=None, h=None):
        if h is None:
            raise ValueError(f"{self.name} is a fixed-step method and needs h")
        fun = system.fun
        radius = SpectralRadius(fun, system.n)
        counts = {"nreject": 0}
        state = {"rho": None, "age": 0}

        def step(t, y, dt):
            f0 = np.asarray(fun(t, y), float)
            if state["rho"] is None or state["age"] >= RHO_EVERY:
                state["rho"], state["age"] = radius(t, y, f0), 0
            state["age"] += 1
            if not np.isfinite(state["rho"]):
                raise StepFailure(f"spectral radius estimate is not finite at t={t:.6g}")
            s = stages_for(dt, state["rho"])
            if s > self.max_stages:
                raise StepFailure(f"h={dt:.3g} with spectral radius {state['rho']:.3g} needs "
                                  f"{s} stages (> {self.max_stages})")
            return rkc_step(fun, t, y, dt, f0, rkc_coefficients(s))

        return march(system, h, step, counts)


class RKC(Integrator):
    name = "rkc"
    description = "Runge-Kutta-Chebyshev, order 2, adaptive step and stage number (RKC 1997)"
    reference = "Sommeijer, Shampine, Verwer, J. Comput. Appl. Math. 88 (1997) 315-326"
    order = 2
    projects = True
    max_stages = 250
    max_steps = 500_000

    def solve(self, system, *, rtol=None, atol=None, h=None):
        try:
            return self._solve(system, rtol, atol)
        except OverflowError as exc:  # f overflowed on a blown-up state: outputs are lost
            return Solution(system.t_eval[:1], np.asarray(system.y0, float)[None, :], False,
                            blow_up_message(system.t0, exc), {})

    def _solve(self, system, rtol, atol):
        fun, project = system.fun, getattr(system, "project", None)
        t0, t_end, t_eval = system.t0, system.t_end, system.t_eval
        atol = np.broadcast_to(np.asarray(atol, float), (system.n,))
        radius = SpectralRadius(fun, system.n)
        counts = {"nsteps": 0, "nreject": 0}
        ys = np.empty((t_eval.size, system.n))
        ys[0] = system.y0
        out = 1
        t, y = t0, np.array(system.y0, float)
        f0 = np.asarray(fun(t, y), float)
        rho, age = radius(t, y, f0), 0
        span = t_end - t0
        h = min(span, 1.0 / rho) if rho > 0 else span
        w = atol + rtol * np.abs(y)
        f1 = np.asarray(fun(t + h, y + h * f0), float)
        est = float(np.sqrt(np.mean(((f1 - f0) / w) ** 2)))
        if h * h * est > 0.01:
            h = 0.1 / math.sqrt(est)
        cache: dict = {}
        last_rejected = False
        while t < t_end:
            if counts["nsteps"] + counts["nreject"] >= self.max_steps:
                return self._done(t_eval, ys, out, counts, f"more than {self.max_steps} steps")
            if age >= RHO_EVERY:
                rho, age = radius(t, y, f0), 0
            if not np.isfinite(rho):
                return self._done(t_eval, ys, out, counts,
                                  f"spectral radius estimate is not finite at t={t:.6g}")
            h_cap = ((self.max_stages - 1) ** 2 - 1) / (1.54 * rho) if rho > 0 else math.inf
            h = min(h, h_cap, t_end - t)
            if t + h >= t_end - 1e-12 * abs(t_end):
                h = t_end - t
            if h <= 1e-14 * max(abs(t), 1.0):
                return self._done(t_eval, ys, out, counts, f"step size {h:.3g} too small at t={t:.6g}")
            s = stages_for(h, rho)
            coef = cache.get(s) or cache.setdefault(s, rkc_coefficients(s))
            y_new = rkc_step(fun, t, y, h, f0, coef)
            t_new = t_end if h == t_end - t else t + h
            if not np.all(np.isfinite(y_new)):
                err, f_new = math.inf, None
            else:
                f_new = np.asarray(fun(t_new, y_new), float)
                wt = atol + rtol * np.maximum(np.abs(y), np.abs(y_new))
                e = 0.8 * (y - y_new) + 0.4 * h * (f0 + f_new)
                err = float(np.sqrt(np.mean((e / wt) ** 2)))
            if err > 1.0:
                counts["nreject"] += 1
                h *= 0.1 if not np.isfinite(err) else max(0.1, 0.8 * err ** (-1 / 3))
                rho, age, last_rejected = radius(t, y, f0), 0, True
                continue
            counts["nsteps"] += 1
            age += 1
            idx = outputs_between(t_eval, t, t_new)
            for i in idx:
                if t_eval[i] != t_new:
                    ys[i] = _hermite(t, t_new, y, y_new, f0, f_new, t_eval[i])
                    if project is not None:
                        ys[i] = project(t_eval[i], ys[i])
            if project is not None:  # one-step method: projecting the step end is sound
                y_new = np.asarray(project(t_new, y_new), float)
                f_new = np.asarray(fun(t_new, y_new), float)
            if idx.size and t_eval[idx[-1]] == t_new:
                ys[idx[-1]] = y_new
            out += idx.size
            t, y, f0 = t_new, y_new, f_new
            fac = 10.0 if err == 0 else min(10.0, max(0.1, 0.8 * err ** (-1 / 3)))
            if last_rejected:
                fac = min(fac, 1.0)
            last_rejected = False
            h *= fac
        return Solution(t_eval[:out], ys[:out], True, "", counts)

    @staticmethod
    def _done(t_eval, ys, out, counts, message):
        return Solution(t_eval[:out], ys[:out], False, message, counts)


def _hermite(t0, t1, y0, y1, f0, f1, t):
    """Cubic Hermite interpolant of the step ``[t0, t1]`` at ``t``."""
    h = t1 - t0
    th = (t - t0) / h
    h00 = (1 + 2 * th) * (1 - th) ** 2
    h10 = th * (1 - th) ** 2
    h01 = th**2 * (3 - 2 * th)
    h11 = th**2 * (th - 1)
    return h00 * y0 + h10 * h * f0 + h01 * y1 + h11 * h * f1
