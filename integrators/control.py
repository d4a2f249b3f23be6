"""Step-size controllers of the shared driver: one interface, a constant step or PI control.

Every controller implements :class:`StepSizeController` (the model is
diffrax's ``AbstractAdaptiveStepSizeController``, whose ``adapt_step_size``
owns the error norm, the step clipping and the step-size underflow test), so
the driver has one stepping loop for fixed and adaptive runs and no step-size
arithmetic of its own:

``init(t0, t_end, estimate) -> h``
    the first step of a segment from ``t0`` (the start, or a restart after a
    reset); ``estimate()`` is the driver's initial-step estimate, called only
    by a controller that wants it (it may evaluate the right-hand side);
``attempt(t, h, cap) -> h``
    the size of the step about to be tried from ``t``: ``h`` within the
    stepper's ``max_step`` ``cap``, stretched to end at ``t_end`` when it would
    end within 10 % of its size before it (``LAST_STRETCH``, the code RKC's
    rule: no sliver of a last step, which in index-3 formulations disturbs the
    multipliers); raises :class:`StepSizeUnderflow` below ``MIN_STEP max(span,
    |t|)`` or when ``h`` is not finite;
``norm(error, y, y_new) -> err``
    the size of a step's local error estimate: the weighted RMS
    ``rms(e_i / (atol_i + rtol max(|y_n,i|, |y_n+1,i|)))`` over the stepper's
    ``error_mask``; ``inf`` when ``y_new`` is not finite; ``0`` at a
    constant step (no tolerance);
``adapt(h, err) -> (accept, h_next)``
    after a step of size ``h`` whose error is ``err``: whether the step is
    kept, and the size of the next attempt;
``failed(h, factor) -> h_next or None``
    the size to retry with after a step could not be completed (a retryable
    :class:`~integrator_bench.integrators.base.StepFailure`), None when the
    controller does not retry (a constant step) or the retry would be below
    the smallest step;
``adaptive``
    True for error control: the driver then counts attempts against the
    integrator's ``max_steps``.

:class:`ConstantStep` (``h`` given) walks the grid ``t0 + k h``, the last step
shortened to end exactly at ``t_end``, and accepts every step (a non-finite
one then ends the run). :class:`PIControl` (``rtol`` given): with the
weighted RMS error ``err_n`` of the accepted step ``n`` (``err_n <= 1``), an
error estimate of order ``q + 1`` (``O(h^(q+1))``) and the previous accepted
step ``h_{n-1}``,

    h_new = h * clip(safety * err_n^(-kI/(q+1)) * err_{n-1}^(kP/(q+1))
                     * (h / h_{n-1})^r,  factor_min, factor_max),

with ``r = 1`` for a predictive controller, else 0. ``kI = 1``, ``kP = 0`` is
the classical I controller (Hairer, Norsett and Wanner, Solving ODEs I, 2nd
ed., sect. II.4); ``kI = 0.7``, ``kP = 0.4`` Gustafsson's PI controller
(Hairer and Wanner, Solving ODEs II, 2nd ed., sect. IV.8, eq. (8.20) form;
Soderlind, Numer. Algorithms 31 (2002) 281-310); ``kI = 2``, ``kP = 1``,
``r = 1`` Gustafsson's predictive controller (Gustafsson, ACM Trans. Math.
Softw. 20 (1994) 496-517; Hairer and Wanner II, sect. IV.8, the control of
RADAU5), the one the code RKC uses with ``q + 1 = 3`` (Sommeijer, Shampine
and Verwer, J. Comput. Appl. Math. 88 (1997) 315-326). The first accepted
step of a segment has no history and takes the I controller's factor
``safety * err^(-1/(q+1))``, as RKC and RADAU5 do. After a rejected step the
next accepted step may not grow (factor at most 1), as in RKC and ADAMS. A
rejection (``err > 1``) shrinks the step by ``max(factor_min, safety *
err^(-1/(q+1)))``; a non-finite error by ``factor_min``. ``hold_band = (lo,
hi)`` keeps ``h`` when the proposed factor lies in ``[lo, hi]`` (saves
refactorizations in implicit codes).

An integrator chooses its adaptive controller's constants with its one class
attribute ``controller``, a :class:`PI` (the constants; the driver builds a
:class:`PIControl` from them with the stepper's error order, the run's
tolerances and its span), so one method keeps the control its publication
describes: RKC the predictive controller of its code, the others I control
(DUMKA3's and the alpha methods' codes choose the step from the last error
alone, and the in-house BDF, SDIRK, W-methods and extrapolation follow Hairer,
Norsett and Wanner's I control). ROCK2 and SERK2 run I control too; whether
rock2.f's own step selection is a predictive one has not been checked against
the code.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Protocol, runtime_checkable

import numpy as np

SNAP = 1e-9            # a grid point this close (relative to h) to t_end is t_end
MIN_STEP = 1e-12       # relative to max(span, |t|): step-size underflow below
LAST_STRETCH = 1.1     # a step within 10 % of t_end is stretched to end there (as RKC does)


def rms(x: np.ndarray) -> float:
    """The root mean square of the 1-D float array ``x`` (0 when empty): the
    weighted error norm of the controllers and Newton iterations, by one dot
    product (``np.sqrt(np.mean(x ** 2))`` costs four numpy calls)."""
    return math.sqrt(float(x @ x) / x.size) if x.size else 0.0


class StepSizeUnderflow(Exception):
    """The step a controller would try is below the smallest it allows."""


@runtime_checkable
class StepSizeController(Protocol):
    """What the driver asks of a step-size controller (see the module docstring)."""

    adaptive: bool

    def init(self, t0: float, t_end: float, estimate: Callable[[], float] | None) -> float:
        """The first step of a segment from ``t0``."""

    def attempt(self, t: float, h: float, cap: float) -> float:
        """The size of the step to try from ``t``; raises :class:`StepSizeUnderflow`."""

    def norm(self, error: np.ndarray | None, y: np.ndarray, y_new: np.ndarray) -> float:
        """The size of a step's local error estimate (``inf`` for a non-finite state)."""

    def adapt(self, h: float, err: float) -> tuple[bool, float]:
        """``(accept, h_next)`` after a step of size ``h`` with error ``err``."""

    def failed(self, h: float, factor: float) -> float | None:
        """The size to retry a failed step with, or None for no retry."""


@dataclass
class ConstantStep:
    """A fixed step size ``h`` on the grid ``t0 + k h``; only the last step is
    shortened, to end exactly at ``t_end``."""

    h: float

    adaptive = False

    def __post_init__(self):
        if not (isinstance(self.h, (int, float)) and math.isfinite(self.h) and self.h > 0):
            raise ValueError(f"step size h={self.h!r} must be a positive finite number")
        self.grid, self.k = np.empty(0), 0

    def init(self, t0: float, t_end: float, estimate=None) -> float:
        """The grid from ``t0``; the first step (``estimate`` is not used)."""
        h = self.h
        n = int(math.floor((t_end - t0) / h + SNAP))
        times = t0 + h * np.arange(1, n + 1)
        if times.size == 0 or t_end - times[-1] > SNAP * h:
            times = np.append(times, t_end)
        else:
            times[-1] = t_end
        self.grid, self.k, self.t = times, 0, t0
        return self._to(times[0])

    def _to(self, target: float) -> float:
        """The step from the current grid point whose end, ``t + h`` in floating
        point, is exactly ``target``."""
        h = target - self.t
        while self.t + h < target:
            h = math.nextafter(h, math.inf)
        while self.t + h > target:
            h = math.nextafter(h, -math.inf)
        return h

    def attempt(self, t: float, h: float, cap: float) -> float:
        """The grid's step, unchanged (no bound, no stretch, no underflow)."""
        return h

    def norm(self, error, y, y_new) -> float:
        """0, or ``inf`` when ``y_new`` is not finite (the end of the run)."""
        return 0.0 if np.isfinite(y_new).all() else math.inf

    def adapt(self, h: float, err: float) -> tuple[bool, float]:
        """Every step is kept; the next one goes to the next grid point."""
        self.t = self.grid[self.k]
        self.k += 1
        return True, (self._to(self.grid[self.k]) if self.k < self.grid.size else h)

    def failed(self, h: float, factor: float) -> None:
        """No retry: a failed step ends a run at a fixed step."""
        return None


@dataclass(frozen=True)
class PI:
    """The constants of :class:`PIControl`: an integrator's ``controller``
    attribute (the defaults: I control as in Hairer, Norsett and Wanner I)."""

    safety: float = 0.9
    factor_min: float = 0.2
    factor_max: float = 5.0
    k_i: float = 1.0
    k_p: float = 0.0
    hold_band: tuple | None = None
    #: multiply by ``h_n / h_{n-1}`` (Gustafsson's predictive controller)
    predictive: bool = False

    def __call__(self, order: int, *, rtol: float = 1.0, atol=0.0, mask=None,
                 span: tuple[float, float] = (0.0, 1.0)) -> PIControl:
        """A fresh controller for an error estimate ``O(h^(order+1))``, weighing
        errors with ``rtol`` and ``atol`` over ``mask`` on a run over ``span``."""
        return PIControl(order, self, rtol=rtol, atol=atol, mask=mask, span=span)


class PIControl:
    """I, PI or predictive step-size control on a weighted RMS error (see the
    module docstring), with the constants of ``constants``.

    Parameters
    ----------
    order : int
        ``q``, for an error estimate ``O(h^(q+1))``.
    constants : PI
        The controller's constants.
    rtol, atol : float, float or ndarray
        The weights of the error norm.
    mask : ndarray of bool, optional
        The components the error estimate covers (None: all).
    span : (float, float)
        ``(t0, t_end)`` of the run: the last-step stretch aims at ``t_end``,
        and the smallest step is ``MIN_STEP max(t_end - t0, |t|)``.
    """

    adaptive = True

    def __init__(self, order: int, constants: PI = PI(), *, rtol: float = 1.0, atol=0.0,
                 mask=None, span: tuple[float, float] = (0.0, 1.0)):
        self.order, self.c = order, constants
        self.rtol, self.atol, self.mask = rtol, atol, mask
        self.t_end, self.span = span[1], span[1] - span[0]
        self.err_old, self.h_old, self.after_reject = None, None, False
        self.t = span[0]              # start of the step under way

    def init(self, t0: float, t_end: float, estimate) -> float:
        """A new segment from ``t0``: no error history; the estimated first step."""
        self.err_old, self.h_old, self.after_reject = None, None, False
        return estimate()

    def attempt(self, t: float, h: float, cap: float) -> float:
        """``h`` within ``cap``, stretched to end at ``t_end`` when it would end
        within 10 % of its size before it; :class:`StepSizeUnderflow` below the
        smallest step or when ``h`` is not finite."""
        self.t = t
        h = min(h, cap)
        if t + LAST_STRETCH * h >= self.t_end and self.t_end - t <= cap:
            h = self.t_end - t
        if not math.isfinite(h):  # a NaN start (the model's NaN in the first
            # step's estimate) would otherwise pass every comparison below, forever
            raise StepSizeUnderflow(f"step size {h} not finite at t={t:.6g}")
        if h < MIN_STEP * max(self.span, abs(t)):
            raise StepSizeUnderflow(f"step size {h:.3g} too small at t={t:.6g}")
        return h

    def norm(self, error, y, y_new) -> float:
        """The weighted RMS of ``error`` (``inf`` when ``y_new`` is not finite)."""
        if not np.isfinite(y_new).all():
            return math.inf
        r = error / (self.atol + self.rtol * np.maximum(np.abs(y), np.abs(y_new)))
        return rms(r if self.mask is None else r[self.mask])

    def adapt(self, h: float, err: float) -> tuple[bool, float]:
        """``(accept, h_next)`` after a step of size ``h`` with error ``err``."""
        if err <= 1.0:
            return True, self._accepted(h, err)
        return False, self._rejected(h, err)

    def _accepted(self, h, err):
        c, q1 = self.c, self.order + 1
        if err == 0.0:
            fac = c.factor_max
        elif self.err_old is None:        # no history: the I controller's factor
            fac = c.safety * err ** (-1.0 / q1)
        else:
            fac = c.safety * err ** (-c.k_i / q1) * self.err_old ** (c.k_p / q1)
            if c.predictive:
                fac *= h / self.h_old
        fac = min(c.factor_max, max(c.factor_min, fac))
        if self.after_reject:
            fac = min(fac, 1.0)
        if c.hold_band is not None and c.hold_band[0] <= fac <= c.hold_band[1]:
            fac = 1.0
        self.err_old, self.h_old = max(err, 1e-4), h
        self.after_reject = False
        return h * fac

    def _rejected(self, h, err):
        self.after_reject = True
        if not math.isfinite(err):
            return h * self.c.factor_min
        return h * max(self.c.factor_min,
                       min(1.0, self.c.safety * err ** (-1.0 / (self.order + 1))))

    def failed(self, h: float, factor: float) -> float | None:
        """The step size to retry with after a step could not be completed (None
        when that is below the smallest step)."""
        self.after_reject = True
        h *= factor
        return h if h >= MIN_STEP * max(self.span, abs(self.t)) else None
