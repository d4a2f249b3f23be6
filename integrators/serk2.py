"""SERK2v2: Kleefeld and Martin-Vaquero's stabilized explicit Runge-Kutta method of order 2.

An ``s``-stage step (``s`` one of :data:`~integrator_bench.integrators.serk2_coefficients.MS`,
10 ... 250) runs ten blocks of ``d = s / 10`` first-order Chebyshev stages,
``alpha = 2.5 / s^2``: within a block

    u_1 = v + alpha h f(v),   u_j = 2 u_(j-1) - u_(j-2) + 2 alpha h f(u_(j-1)),  j = 2..d,

from the block's start ``v`` (``y_n``, then the previous block's last stage), so
that ``u_j = T_j(1 + alpha h J) v`` for a linear problem, and the step is the
weighted sum of all stage values

    y_(n+1) = B_0 y_n + sum_k B_k u_k

with the weights ``B`` of :mod:`~integrator_bench.integrators.serk2_coefficients`
(an extrapolation of the first-order stages to order 2 with a damped
stability polynomial). Stage ``j`` of block ``i`` lies at ``t_n + ((i - 1) d^2
+ j^2) alpha h``. The stability polynomial stays bounded on about ``[-0.8
s^2, 0]`` (``|1 + alpha z| <= 1``, ``T_d`` bounded) for s = 10 ... 100 and 200
(0.804 to 0.815 s^2, measured on the polynomial), **but for s = 150 and 250
only on ``[-0.746 s^2, 0]``**: past it ``|R|`` grows to 30 (s = 150) and 6500
(s = 250) before ``-0.8 s^2``. Which of the tabulated weights (or the
publication's) cause this was not traced. SERK2v2's stage rule ``s >= 1 +
floor(sqrt(h rho / 0.8))`` (OrdinaryDiffEq.jl's) would therefore take unstable
steps there; here the stage count is the smallest tabulated ``s`` whose measured
interval :data:`BETA` holds ``h rho``, at most 250 (``h rho <= 46601``).

SERK2v2's own error estimate is not at hand: the local error estimate is
RKC's, ``0.8 (y_n - y_(n+1)) + 0.4 h (F_n + F_(n+1))`` (``O(h^3)``), with RKC's
controller constants, spectral radius (the nonlinear power method of
:class:`~integrator_bench.integrators.rkc.SpectralRadius`, 1.2 times the
estimate, renewed every 25 accepted steps and after a rejection), output and
projection (:class:`~integrator_bench.integrators.rkc.RKCStepper`).

One registered integrator, ``serk2v2``: adaptive at ``rtol``, or at a fixed step
``h`` with stages from the spectral radius (more than 250 ends the run with
``method_limit``); the setting ``stages`` (``-i serk2v2:stages=50``) fixes the
stage count (one of :data:`STAGES`) at every step, with no spectral radius.

References: B. Kleefeld and J. Martin-Vaquero, SERK2v2: A new second-order
stabilized explicit Runge-Kutta method for stiff problems, Numer. Methods
Partial Differential Equations 29 (2013) 170-185, the revision of J.
Martin-Vaquero and B. Janssen, Comput. Phys. Commun. 180 (2009) 1802-1810;
the weights as tabulated in OrdinaryDiffEq.jl (see the coefficient module). The
2009 method's own table was not found (neither the paper's coefficients nor a
code implementing them; OrdinaryDiffEq.jl's ``SERK2`` is SERK2v2), so the
registered ``serk2v2`` is SERK2v2 only.
"""

from __future__ import annotations

import math

import numpy as np

from integrator_bench.integrators.rock2 import (Tabulated, declared, real_stability_interval,
                                               stages_setting)
from integrator_bench.integrators.serk2_coefficients import B, MS
from integrator_bench.integrators.rkc import RKCStepper

STAGES = tuple(MS)
MAX_STAGES = STAGES[-1]
_START = tuple(int(x) for x in np.concatenate(([0], np.cumsum([m + 1 for m in MS])))[:-1])


def serk2_step(fun, t, y, h, f0, s: int):
    """One SERK2v2 step of ``s`` stages (one of :data:`STAGES`) from ``(t, y)``,
    ``f0 = f(t, y)``: ``(y_new, None)`` (no embedded estimate)."""
    w = B[_START[STAGES.index(s)]:][:s + 1]
    d, alpha = s // 10, 2.5 / s**2
    total = w[0] * y
    v, k = y, 1
    for i in range(10):
        base = i * d * d
        f = f0 if i == 0 else np.asarray(fun(t + base * alpha * h, v), float)
        prev, u = v, v + (alpha * h) * f
        total = total + w[k] * u
        k += 1
        for j in range(2, d + 1):
            f = np.asarray(fun(t + (base + (j - 1) ** 2) * alpha * h, u), float)
            prev, u = u, 2 * u - prev + (2 * alpha * h) * f
            total = total + w[k] * u
            k += 1
        v = u
    return total, None


#: ``beta(s)`` of every tabulated stage count, measured on its stability polynomial.
BETA = tuple(real_stability_interval(serk2_step, s) for s in STAGES)


def stages_for(h: float, rho: float) -> int:
    """The smallest tabulated stage count with ``h rho <= beta(s)`` (:data:`BETA`);
    past the largest, the stage count of SERK2v2's rule ``1 + floor(sqrt(h rho /
    0.8))`` (which then exceeds every tabulated one)."""
    x = h * rho
    return next((s for s, b in zip(STAGES, BETA) if x <= b),
                max(MAX_STAGES + 1, 1 + int(math.sqrt(x / 0.8))))


class Serk2Stepper(RKCStepper):
    """SERK2v2 one step at a time: RKC's stepper with SERK2v2's stages."""

    hard_limit = MAX_STAGES

    def longest(self, rho):
        return BETA[-1] / rho

    def stages(self, h, rho):
        return stages_for(h, rho)

    def advance(self, t, y, h, f0, s):
        return serk2_step(self.fun, t, y, h, f0, s)


DECLARED = (10, 20, 50, 100, 150, 200, 250)


class Serk2(Tabulated):
    name = "serk2v2"
    description = ("SERK2v2, stabilized explicit RK of order 2 (Kleefeld, Martin-Vaquero), "
                   "10-250 stages from a spectral-radius estimate; adaptive (rtol) or fixed h")
    reference = "Kleefeld, Martin-Vaquero, Numer. Methods PDE 29 (2013) 170-185"
    order = 2
    #: the real stability interval per stage count, from the stability polynomial
    stability_intervals = {f"s={s}": declared(BETA[STAGES.index(s)]) for s in DECLARED}
    stability_variants = {f"s={s}": {"stages": s} for s in DECLARED}
    settings = (stages_setting(STAGES),)
    stepper_class = Serk2Stepper
