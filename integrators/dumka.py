"""DUMKA3: Medovikov's stabilized explicit Runge-Kutta method of order 3.

Each of 14 stability polynomials ``R_k`` (degrees 3, 6, ..., 324) is optimal
for order 3 on the negative real axis: ``|R_k(z)|`` stays small on ``[-beta_k,
0]``. They are labelled as Orlov labels them: P0 (degree 3), P1 (degree 6), ...,
P13 (degree 324), ``k`` counting from 0 (earlier versions of this project counted from 1:
its "P1" was P0, its "P4"-"P7" Orlov's P3-P6). A step of polynomial ``k`` is a
chain of ``n_k / 3`` three-stage sub-steps;
sub-step ``j`` from ``(t_j, Y_j)`` with ``F_j = f(t_j, Y_j)`` is

    K1 = f(t_j + a21 h, Y_j + a21 h F_j),
    K2 = f(t_j + (a31 + a32) h, U),   U = Y_j + h (a31 F_j + a32 K1),
    Y_{j+1} = U + a43 h K2,   t_{j+1} = t_j + (a31 + a32 + a43) h,

with ``a21 = a31`` except in the last sub-step (the interior sub-steps are the
factors ``(1 + a31 z)(1 + a32 z)(1 + a43 z)`` of ``R_k``). Every sub-step ends
with ``f(Y_{j+1})``, so a step costs ``n_k`` evaluations and its end slope is
the next step's first (first same as last). The local error estimate (of the
last sub-step, ``c2 = a21``, ``c3 = a31 + a32``, ``c4 = c3 + a43``) is

    err = h [c3/2 (K1 - F_end) + (c4 - c2)/2 (K2 - F_last)],

``F_last`` the slope at the start of the last sub-step, ``F_end = f(y_{n+1})``.

One registered integrator, ``dumka3``, on the shared driver
(:mod:`integrator_bench.integrators.driver`):

* given ``rtol``: the driver weighs the error estimate (RMS, as the C code)
  and proposes ``h`` with DUMKA3's constants: factor ``0.8 err^(-1/3)`` limited
  to ``[0.1, 2]`` (at most 1 after a rejection). The spectral radius ``rho``
  comes from RKC's power method (:class:`~.stabilized.SpectralRadius`, 1.2
  times the estimate, as the C code; its first direction is ``f(y0)`` plus a
  small fixed pseudo-random vector, see :meth:`DumkaStepper.start`), renewed
  every 20 accepted steps and after a rejection; the step is bounded by
  ``beta_12 / rho`` and each step takes the smallest polynomial with
  ``h rho <= beta_k``. Not done here (the
  driver owns ``h``): the C code's switch to the next smaller polynomial with
  a shortened step when that costs fewer evaluations, and its predictive
  (Gustafsson-type) factor after accepted steps; the first step is the
  driver's estimate instead of the user's ``h0``.
* given ``h``: at each step the smallest polynomial with ``h rho <= beta_k``;
  a step beyond the largest interval ends the run with ``method_limit``.

The setting ``polynomial`` (``-i dumka3:polynomial=P5``: one of ``auto``,
``P0`` ... ``P12``) always takes one polynomial (no spectral radius), as Orlov
compared them; ``auto`` (the default) chooses it per step. A bare number (the
project's former 1-based setting) is refused with a one-line error naming the
valid values. :func:`with_polynomial` makes the same variant as a registrable
class of its own (``dumka3-P5``).

**P13 is not used.** The coefficients of the degree-324 polynomial in the
source below are defective: two of its 108 sub-step factors repeat factors of
other sub-steps (``0.1973979727999e-4`` and ``0.22391321547766630e-4``), so
``R_13(z) = 1 + (1 - 1.7e-5) z + ...`` is not even consistent and ``|R_13(-x)|
<= 1`` holds only up to ``x = 7587``, not 50667. The table
(:mod:`~integrator_bench.integrators.dumka_coefficients`) keeps P13 as
transcribed, but the method stops at P12 (degree 243, ``beta = 29376``):
larger ``h rho`` is a ``method_limit``.

Output times inside a step take the cubic Hermite interpolant of the end
values and slopes (``O(h^4)``). DUMKA3 is a one-step method: it projects
after accepted steps when the system asks for it. It is not A-stable (only a
thin strip around the negative real axis is stable).

The damped polynomials P1-P7 keep ``|R_k| <= 0.1`` on the band that ends at
the published ``beta_k``; their ``|R_k| <= 1`` interval is 7 % (P1) to 0.1 %
(P7) longer. P0 and P8-P12 are undamped: ``beta_k`` is their ``|R_k| <= 1``
interval.

References: A. A. Medovikov, High order explicit methods for parabolic
equations, BIT 38 (1998) 372-390 (the method, the intervals ``beta_k``);
coefficients and the step, error estimate and degree choice of the C code
``dumka3.c`` by A. A. Medovikov, as distributed in the repository
MoisaAndrew/StabilizedMethods (file C/dumka3.c, commit 28a486bd).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from integrator_bench.integrators.base import Integrator, Status, Step, StepFailure, Stepper
from integrator_bench.integrators.control import PI, rms
from integrator_bench.integrators.dumka_coefficients import LAST_A21, N_DEG, STAB_REG, SUBSTEPS
from integrator_bench.integrators.interpolation import hermite
from integrator_bench.integrators.settings import Setting
from integrator_bench.integrators.rkc import SpectralRadius

#: Published real stability intervals (Medovikov 1998), one per polynomial.
PUBLISHED_BETA = (2.50, 9.78, 23.8, 68.9, 136.6, 226.9, 404.7, 720.7, 1337.1, 3266.0, 9072.0,
                  17785.0, 29376.0, 50667.0)
USABLE = 13               # P0-P12; P13 is defective in the source (see the module docstring)
RHO_EVERY = 20            # accepted steps between spectral-radius estimates (as dumka3.c)


#: The setting ``polynomial``'s values: ``auto`` and Orlov's labels of the usable ones.
CHOICES = ("auto",) + tuple(f"P{k}" for k in range(USABLE))


def label(k: int) -> str:
    """The name of polynomial ``k`` (Orlov's, from 0) in ``stability_intervals``."""
    return f"P{k} (degree {N_DEG[k]})"


def dumka_step(fun, t, y, h, f0, k: int):
    """One step of polynomial ``k`` (Orlov's label, from 0) from ``(t, y)`` with
    ``f0 = f(t, y)``.

    Returns
    -------
    y_new, f_new : ndarray
        The state at ``t + h`` and ``f(t + h, y_new)``.
    error : ndarray
        The local error estimate (see the module docstring).
    """
    subs = SUBSTEPS[k]
    tj, f = t, f0
    for j, (a31, a32, a43) in enumerate(subs):
        last = j == len(subs) - 1
        a21 = LAST_A21[k] if last else a31
        c3 = a31 + a32
        k1 = fun(tj + a21 * h, y + (a21 * h) * f)
        u = y + (a31 * h) * f + (a32 * h) * k1
        k2 = fun(tj + c3 * h, u)
        y = u + (a43 * h) * k2
        f_start, tj = f, (t + h if last else tj + (c3 + a43) * h)
        f = fun(tj, y)
    c2, c4 = a21, c3 + a43
    error = h * (0.5 * c3 * (k1 - f) + 0.5 * (c4 - c2) * (k2 - f_start))
    return y, f, error


def stability_function(k: int, z):
    """``R_k(z)``: one step of polynomial ``k`` with ``h = 1`` on ``y' = z y``, ``y_0 = 1``
    (``z`` real or complex, scalar or array)."""
    z = np.asarray(z, dtype=complex)
    y0 = np.ones_like(z)
    return dumka_step(lambda t, y: z * y, 0.0, y0, 1.0, z * y0, k)[0]


def polynomial_for(h_rho: float) -> int | None:
    """The smallest usable polynomial with ``h rho <= beta_k``, or None."""
    for k in range(USABLE):
        if h_rho <= STAB_REG[k]:
            return k
    return None


class DumkaStepper(Stepper):
    """DUMKA3 one step at a time (see the module docstring).

    ``polynomial`` fixes the polynomial (no spectral radius is estimated);
    None chooses it per step from ``h rho``. ``used`` counts the steps
    attempted with each polynomial.
    """

    error_order = 2          # the controller's exponent is 1/3, as in dumka3.c
    dense_order = 3

    def __init__(self, system, counts, rtol=None, atol=None, polynomial=None):
        super().__init__(system, counts, rtol, atol)
        self.polynomial = polynomial
        self.radius = SpectralRadius(self._f, system.n)
        self.f = self.rho = None
        self.age = 0
        self.last = None
        self.used: dict[int, int] = {}

    def _f(self, t, y) -> np.ndarray:
        return np.asarray(self.system.fun(t, y), float)

    def start(self, t0, y0):
        """Evaluate ``f(y0)``; seed the power method with ``f(y0)`` plus a fixed
        pseudo-random vector of 1e-3 its RMS size, so that smooth data (``f(y0)``
        a combination of a few slow modes, where RKC's start would stay) still
        reach the fastest mode."""
        self.f = self._f(t0, y0)
        n = self.system.n
        scale = rms(self.f) or 1.0
        self.radius.v = self.f + 1e-3 * scale * np.random.default_rng(1998).standard_normal(n)
        return y0

    def _rho(self, t, y) -> float:
        if self.f is None:
            self.f = self._f(t, y)
        if self.rho is None or self.age >= RHO_EVERY:
            self.rho, self.age = self.radius(t, y, self.f), 0
        return self.rho

    def max_step(self, t, y):
        if self.polynomial is not None or self.rtol is None:
            return math.inf
        rho = self._rho(t, y)
        return STAB_REG[USABLE - 1] / rho if np.isfinite(rho) and rho > 0 else math.inf

    def _choose(self, t, y, h) -> int:
        if self.polynomial is not None:
            return self.polynomial
        rho = self._rho(t, y)
        if not np.isfinite(rho):
            raise StepFailure(Status.METHOD_LIMIT,
                              f"spectral radius estimate is not finite at t={t:.6g}", retry=False)
        k = polynomial_for(h * rho)
        if k is None:
            raise StepFailure(Status.METHOD_LIMIT, (
                f"h={h:.3g} with {self.radius.describe(rho)}: h*rho={h * rho:.4g} exceeds the "
                f"largest stability interval {STAB_REG[USABLE - 1]:.6g} (P{USABLE - 1}, degree "
                f"{N_DEG[USABLE - 1]}); take h <= {STAB_REG[USABLE - 1] / rho:.3g}"),
                retry=self.rtol is not None)
        return k

    def step(self, t, y, h):
        k = self._choose(t, y, h)
        self.used[k] = self.used.get(k, 0) + 1
        if self.f is None:
            self.f = self._f(t, y)
        f0 = self.f
        y_new, f_new, error = dumka_step(self._f, t, y, h, f0, k)
        self.last = (y_new, f_new)
        if not np.isfinite(y_new).all():
            return Step(y_new, error=np.full(y_new.shape, math.inf))
        return Step(y_new, error=error if self.rtol is not None else None,
                    dense=hermite(t, h, y, f0, y_new, f_new))

    def accept(self, t_new, y_new):
        """Keep ``f(y_new)`` unless a projection moved ``y_new``."""
        y_last, f_last = self.last
        same = y_new is y_last or np.array_equal(y_new, y_last)
        self.f, self.last = (f_last if same else None), None
        self.age += 1

    def reject(self):
        self.last, self.rho = None, None


class Dumka3(Integrator):
    name = "dumka3"
    description = ("DUMKA3, stabilized explicit RK of order 3 (Medovikov), polynomial degree "
                   "3-243 from a spectral-radius estimate; adaptive (rtol) or fixed step h")
    reference = "A. A. Medovikov, BIT 38 (1998) 372-390"
    order = 3
    projects = True
    dense_output = True
    events = True          # located on the Hermite interpolant by the driver
    stability_intervals = {label(k): PUBLISHED_BETA[k] for k in range(USABLE)}
    controller = PI(safety=0.8, factor_min=0.1, factor_max=2.0)
    settings = (Setting("polynomial", str, "auto", "a fixed stability polynomial (Orlov's "
                        "labels: P0 degree 3 ... P12 degree 243) at every step, no spectral "
                        "radius and no stability bound (as Orlov compared them); auto: the "
                        "smallest with h rho <= beta_k", choices=CHOICES),)

    def stepper(self, system, counts, rtol=None, atol=None):
        k = None if self.polynomial == "auto" else int(self.polynomial[1:])
        return DumkaStepper(system, counts, rtol, atol, polynomial=k)


def with_polynomial(k: int) -> type[Dumka3]:
    """A fixed-step variant that always takes polynomial ``k`` (Orlov's label, P0 =
    degree 3; registry name ``dumka3-P{k}``); it checks no stability bound."""
    if not (isinstance(k, int) and 0 <= k < USABLE):
        raise ValueError(f"polynomial k={k!r} is not one of 0..{USABLE - 1}"
                         + (" (P13's coefficients are defective)" if k == USABLE else ""))
    return type(f"Dumka3P{k}", (Dumka3,), {
        "name": f"dumka3-P{k}", "adaptive": False, "fixed_step": True,
        "settings": (dataclasses.replace(Dumka3.settings[0], default=f"P{k}"),),
        "stability_intervals": {label(k): PUBLISHED_BETA[k]},
        "description": (f"DUMKA3 with polynomial P{k} only (Orlov's label; degree {N_DEG[k]}, "
                        f"beta={PUBLISHED_BETA[k]:g}), fixed step h"),
        "__module__": __name__})
