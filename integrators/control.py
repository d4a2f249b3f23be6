"""Step-size controllers of the shared driver: one interface, a constant step or I/PI control.

Every controller offers the same two calls (the model is diffrax's
``AbstractStepSizeController.init`` and ``adapt_step_size``), so the driver
has one stepping loop for fixed and adaptive runs:

``init(t0, t_end, estimate) -> h``
    the first step of a segment from ``t0`` (the start, or a restart after a
    reset); ``estimate()`` is the driver's initial-step estimate, called only
    by a controller that wants it (it may evaluate the right-hand side);
``adapt(h, err) -> (accept, h_next)``
    after a step of size ``h`` whose weighted RMS error is ``err`` (``inf``
    for a non-finite state, ``0`` when the run has no tolerance): whether the
    step is kept, and the size of the next attempt;
``failed(h, factor) -> h_next or None``
    the size to retry with after a step could not be completed (a retryable
    :class:`~integrator_bench.integrators.base.StepFailure`), None when the
    controller does not retry;
``adaptive``
    True for error control: the driver then applies the stepper's
    ``max_step``, the last-step stretch, the step-size underflow test and the
    step limit.

:class:`ConstantStep` (``h`` given) walks the grid ``t0 + k h``, the last step
shortened to end exactly at ``t_end``, and accepts every step (a non-finite
one then ends the run). :class:`PIControl` (``rtol`` given): with the weighted
RMS error ``err_n`` of the accepted step ``n`` (``err_n <= 1``) and an error
estimate of order ``q + 1`` (``O(h^(q+1))``),

    h_new = h * clip(safety * err_n^(-kI/(q+1)) * err_{n-1}^(kP/(q+1)),
                     factor_min, factor_max),

with ``kI = 1``, ``kP = 0`` the classical I controller (Hairer, Norsett and
Wanner, Solving ODEs I, 2nd ed., sect. II.4) and ``kI = 0.7``, ``kP = 0.4``
Gustafsson's PI controller (Hairer and Wanner, Solving ODEs II, 2nd ed.,
sect. IV.8, eq. (8.20) form; Soderlind, Numer. Algorithms 31 (2002) 281-310).
After a rejected step the next accepted step may not grow (factor at most 1),
as in RKC and ADAMS. A rejection (``err > 1``) shrinks the step by
``max(factor_min, safety * err^(-1/(q+1)))``; a non-finite error by
``factor_min``. ``hold_band = (lo, hi)`` keeps ``h`` when the proposed factor
lies in ``[lo, hi]`` (saves refactorizations in implicit codes).

An integrator chooses its adaptive controller's constants with its one class
attribute ``controller``, a :class:`PI` (the constants; the driver builds a
:class:`PIControl` from them with the stepper's error order), so one method
keeps the control its publication describes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SNAP = 1e-9  # a grid point this close (relative to h) to t_end is t_end


def rms(x: np.ndarray) -> float:
    """The root mean square of the 1-D float array ``x`` (0 when empty): the
    weighted error norm of the controllers and Newton iterations, by one dot
    product (``np.sqrt(np.mean(x ** 2))`` costs four numpy calls)."""
    return math.sqrt(float(x @ x) / x.size) if x.size else 0.0


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

    def __call__(self, order: int) -> PIControl:
        """A fresh controller for an error estimate ``O(h^(order+1))``."""
        return PIControl(order, self)


class PIControl:
    """I (``k_p = 0``) or PI step-size control on a weighted RMS error (see the
    module docstring), with the constants of ``constants``."""

    adaptive = True

    def __init__(self, order: int, constants: PI = PI()):
        self.order, self.c = order, constants
        self.err_old, self.after_reject = 1.0, False

    def init(self, t0: float, t_end: float, estimate) -> float:
        """A new segment from ``t0``: no error history; the estimated first step."""
        self.err_old, self.after_reject = 1.0, False
        return estimate()

    def adapt(self, h: float, err: float) -> tuple[bool, float]:
        """``(accept, h_next)`` after a step of size ``h`` with error ``err``."""
        if err <= 1.0:
            return True, self._accepted(h, err)
        return False, self._rejected(h, err)

    def _accepted(self, h, err):
        c, q1 = self.c, self.order + 1
        if err == 0.0:
            fac = c.factor_max
        else:
            fac = c.safety * err ** (-c.k_i / q1) * self.err_old ** (c.k_p / q1)
        fac = min(c.factor_max, max(c.factor_min, fac))
        if self.after_reject:
            fac = min(fac, 1.0)
        if c.hold_band is not None and c.hold_band[0] <= fac <= c.hold_band[1]:
            fac = 1.0
        self.err_old = max(err, 1e-4)
        self.after_reject = False
        return h * fac

    def _rejected(self, h, err):
        self.after_reject = True
        if not math.isfinite(err):
            return h * self.c.factor_min
        return h * max(self.c.factor_min,
                       min(1.0, self.c.safety * err ** (-1.0 / (self.order + 1))))

    def failed(self, h: float, factor: float) -> float:
        """The step size to retry with after a step could not be completed."""
        self.after_reject = True
        return h * factor
