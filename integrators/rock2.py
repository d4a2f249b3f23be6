"""ROCK2: Abdulle and Medovikov's orthogonal-Runge-Kutta-Chebyshev method of order 2.

An ``s``-stage step (``s = m + 2``, ``m`` one of the 46 degrees of
:data:`~integrator_bench.integrators.rock2_coefficients.MS`, ``s = 3 ... 200``)
realizes the stability polynomial ``R_s(z) = P_m(z) w(z)``: ``P_m``, orthogonal
with respect to ``w(z)^2 / sqrt(1 - x^2)``, by the three-term recurrence

    g_0 = y_n,   g_1 = y_n + h mu_1 F_n,
    g_j = h mu_j f(g_(j-1)) + (1 + kappa_j) g_(j-1) - kappa_j g_(j-2),   j = 2..m,

and the quadratic factor ``w(z) = 1 + sigma z + tau z^2`` by a two-stage
finishing procedure,

    g_(s-1) = g_m + h sigma f(g_m),   ge_s = g_(s-1) + h sigma f(g_(s-1)),
    y_(n+1) = ge_s - h sigma (1 - sigma/tau) (f(g_(s-1)) - f(g_m)),

``mu_j, kappa_j, sigma`` and ``-sigma (1 - sigma/tau)`` from the tables of the
authors' code (:mod:`~integrator_bench.integrators.rock2_coefficients`), the
stage abscissae from the same recurrence. The embedded first-order ``ge_s``
gives the local error estimate ``y_(n+1) - ge_s`` (the code's, ``O(h^2)``), so
the step factor is ``0.8 err^(-1/2)`` limited to ``[0.1, 2]`` (at most 1
after a rejection), as rock2.f; rock2.f's predictive (Gustafsson-type) factor
is not used (the driver owns ``h``). **One addition to rock2.f:** the error is,
component by component, the larger of that estimate and RKC's endpoint estimate
``0.8 (y_n - y_(n+1)) + 0.4 h (F_n + F_(n+1))``, whose ``F_(n+1)`` is the next
step's ``F_n`` anyway (no extra evaluation). The embedded estimate compares
slopes at two interior stages only (``t_n + c_m h`` and ``t_n + (c_m + sigma)
h``), so a change of ``f`` outside them goes unseen: on a ramp ``y' = (1 +
tanh((t - 1)/0.01))/2`` at ``rtol = 1e-7`` rock2.f's estimate alone let a
doubling step jump the ramp (error 3.6e-2, no rejection), which ``ibench
check-plugin``'s accuracy check rejects. The real stability interval grows as
about ``0.81 s^2``: rock2.f takes ``s = 1 + floor(sqrt((1.5 + h rho) /
0.811))`` stages, rounded up to the next tabulated degree, for a
spectral-radius estimate ``rho`` renewed every 25 accepted steps and after a
rejection; at most 200 stages (the step is bounded by ``(0.811 * 199^2 -
1.5) / rho``).

The spectral radius is RKC's nonlinear power method
(:class:`~integrator_bench.integrators.rkc.SpectralRadius`, 1.2 times
the estimate), rock2.f's ``rocktrho`` being the same iteration. Steps, output
and projection are RKC's (:class:`~integrator_bench.integrators.rkc.RKCStepper`):
first same as last, cubic Hermite dense output, a projection after accepted
steps when the system asks for it.

One registered integrator, ``rock2``:

* given ``rtol``: adaptive step and stage number as above;
* given ``h``: the steps ``t0 + k h``, stages from the spectral radius (a step
  needing more than 200 stages ends the run, ``method_limit``);
* the setting ``stages`` (``-i rock2:stages=49``) fixes the stage count (one of
  :data:`STAGES`) at every step, with no spectral radius and no stability
  bound, at a fixed step or under error control.

References: A. Abdulle and A. A. Medovikov, Second order Chebyshev methods
based on orthogonal polynomials, Numer. Math. 90 (2001) 1-18; the Fortran
code rock2.f by A. Abdulle (April 2002), as distributed in the repository
MoisaAndrew/StabilizedMethods (file Fortran/rock2.f).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from integrator_bench.integrators.base import Intervals
from integrator_bench.integrators.control import PI
from integrator_bench.integrators.rock2_coefficients import FP1, FP2, MS, RECF
from integrator_bench.integrators.settings import Setting
from integrator_bench.integrators.rkc import RKC, RKCStepper

#: The stage counts of the tabulated polynomials (degree + 2).
STAGES = tuple(m + 2 for m in MS)
MAX_STAGES = STAGES[-1]
#: Offsets of each degree's recurrence parameters in ``RECF``.
_START = tuple(int(x) for x in np.concatenate(([0], np.cumsum([2 * m - 1 for m in MS])))[:-1])


def stages_for(h: float, rho: float) -> int:
    """rock2.f's stage count for ``h rho``, rounded up to a tabulated one."""
    s = max(3, 1 + int(math.sqrt((1.5 + h * rho) / 0.811)))
    return next((x for x in STAGES if x >= s), s)


def rock2_step(fun, t, y, h, f0, s: int):
    """One ROCK2 step of ``s`` stages (one of :data:`STAGES`) from ``(t, y)``,
    ``f0 = f(t, y)``: ``(y_new, error)`` with the embedded estimate ``y_new - ge_s``."""
    i = STAGES.index(s)
    m, r = MS[i], _START[i]
    mu1 = RECF[r]
    g2, g1 = y, y + (h * mu1) * f0
    c1 = c2 = mu1
    c3 = 0.0
    for j in range(2, m + 1):
        mu, kappa = RECF[r + 2 * (j - 2) + 1], RECF[r + 2 * (j - 2) + 2]
        g = (h * mu) * np.asarray(fun(t + c1 * h, g1), float) + (1 + kappa) * g1 - kappa * g2
        c1 = mu + (1 + kappa) * c2 - kappa * c3
        g2, g1, c3, c2 = g1, g, c2, c1
    sigma, tail = FP1[i], FP2[i]
    fm = np.asarray(fun(t + c1 * h, g1), float)
    g_s1 = g1 + (h * sigma) * fm
    f_s1 = np.asarray(fun(t + (c1 + sigma) * h, g_s1), float)
    correction = (h * tail) * (f_s1 - fm)
    return g_s1 + (h * sigma) * f_s1 + correction, correction


class Rock2Stepper(RKCStepper):
    """ROCK2 one step at a time: RKC's stepper with ROCK2's stages and estimate."""

    error_order = 1          # the embedded estimate is O(h^2): controller exponent 1/2
    hard_limit = MAX_STAGES
    endpoint_check = True

    def longest(self, rho):
        return (0.811 * (min(self.max_stages, MAX_STAGES) - 1) ** 2 - 1.5) / rho

    def stages(self, h, rho):
        return stages_for(h, rho)

    def advance(self, t, y, h, f0, s):
        return rock2_step(self.fun, t, y, h, f0, s)


def real_stability_interval(step, s: int, scan: int = 20_000) -> float:
    """``beta(s)``: the ``x`` where ``|R_s(-x)|`` first exceeds 1, ``R_s`` one step
    of ``step(fun, t, y, h, f0, s)`` with ``h = 1`` on ``y' = z y``: a scan of
    ``[0, 1.5 s^2]`` in ``scan`` points, then bisection; ``|R| <= 1 + 1e-9``
    counts as stable (rounding lifts ``|R(0)|`` above 1)."""
    def r(x):
        z = -np.asarray(x, float)
        return np.abs(step(lambda t, y: z * y, 0.0, np.ones_like(z), 1.0, z, s)[0])

    x = np.linspace(0.0, 1.5 * s * s, scan)
    out = np.nonzero(r(x) > 1.0 + 1e-9)[0]
    if not out.size:
        return float(x[-1])
    lo, hi = float(x[out[0] - 1]), float(x[out[0]])
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if r(mid) <= 1.0 + 1e-9 else (lo, mid)
    return lo


def declared(beta: float, digits: int = 4) -> float:
    """``beta`` rounded down to ``digits`` significant digits: a declared interval a
    little inside the measured boundary, where ``|R| = 1`` only to rounding."""
    scale = 10.0 ** (math.floor(math.log10(beta)) - digits + 1)
    return math.floor(beta / scale) * scale


#: Stage counts whose stability intervals are declared.
DECLARED = (3, 5, 10, 20, 49, 104, 200)


def _declared_interval(s: int) -> float:
    """ROCK2's declared interval for ``s`` stages (measured on first use)."""
    return declared(real_stability_interval(rock2_step, s))


class Tabulated(RKC):
    """A stabilized method with tabulated stage counts on RKC's stepper: its
    ``stepper_class`` (an :class:`~integrator_bench.integrators.rkc.RKCStepper`
    whose ``hard_limit`` is the largest tabulated count) and the setting
    ``stages`` (:func:`stages_setting`)."""

    stepper_class: type[RKCStepper] = RKCStepper

    def stepper(self, system, counts, rtol=None, atol=None):
        make = self.stepper_class
        return make(system, counts, rtol, atol, max_stages=make.hard_limit,
                    stages=self.stages or None)


def stages_setting(stages: tuple) -> Setting:
    """The setting ``stages``: 0 (from the spectral radius) or one of ``stages``."""
    return Setting("stages", int, 0, "a fixed stage count at every step (no spectral radius, "
                   "no stability bound); 0: from the spectral radius", choices=(0,) + stages)


class Rock2(Tabulated):
    name = "rock2"
    description = ("ROCK2, orthogonal Runge-Kutta-Chebyshev of order 2 (Abdulle-Medovikov), "
                   "3-200 stages from a spectral-radius estimate; adaptive (rtol) or fixed h")
    reference = "Abdulle, Medovikov, Numer. Math. 90 (2001) 1-18"
    order = 2
    controller = PI(safety=0.8, factor_min=0.1, factor_max=2.0)
    #: the real stability interval per stage count, from the stability polynomial (about
    #: 0.81 s^2, 0.1 % below rock2.f's stage rule ``0.811 s^2 - 1.5`` from s = 10 on)
    stability_intervals = Intervals({f"s={s}": functools.partial(_declared_interval, s)
                                     for s in DECLARED})
    stability_variants = {f"s={s}": {"stages": s} for s in DECLARED}
    settings = (stages_setting(STAGES),)
    stepper_class = Rock2Stepper
