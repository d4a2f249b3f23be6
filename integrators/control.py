"""Step-size controllers for the shared driver: a constant step, or I/PI control.

A controller is chosen per run (as diffrax's ``ConstantStepSize`` and
``PIDController``): :class:`ConstantStep` for a run at ``h``, :class:`PIControl`
for a run at ``rtol``. The integrator's class attributes ``safety``,
``factor_min``, ``factor_max`` and ``hold_band`` set the adaptive controller's
constants, so one method keeps the control its publication describes.

With the weighted RMS error ``err`` of the accepted step ``n`` (``err <= 1``)
and an error estimate of order ``q + 1`` (``O(h^(q+1))``),

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
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass
class ConstantStep:
    """A fixed step size ``h``; the driver shortens only the last step to ``t_end``."""

    h: float

    def __post_init__(self):
        if not (isinstance(self.h, (int, float)) and math.isfinite(self.h) and self.h > 0):
            raise ValueError(f"step size h={self.h!r} must be a positive finite number")

    adaptive = False


@dataclass
class PIControl:
    """I (``k_p = 0``) or PI step-size control on a weighted RMS error."""

    order: int                      # q: the error estimate is O(h^(q+1))
    safety: float = 0.9
    factor_min: float = 0.2
    factor_max: float = 5.0
    k_i: float = 1.0
    k_p: float = 0.0
    hold_band: tuple | None = None

    adaptive = True

    def __post_init__(self):
        self.err_old = 1.0
        self.after_reject = False

    def accept(self, h: float, err: float) -> float:
        """The next step size after an accepted step of size ``h`` with error ``err``."""
        q1 = self.order + 1
        if err == 0.0:
            fac = self.factor_max
        else:
            fac = self.safety * err ** (-self.k_i / q1) * self.err_old ** (self.k_p / q1)
        fac = min(self.factor_max, max(self.factor_min, fac))
        if self.after_reject:
            fac = min(fac, 1.0)
        if self.hold_band is not None and self.hold_band[0] <= fac <= self.hold_band[1]:
            fac = 1.0
        self.err_old = max(err, 1e-4)
        self.after_reject = False
        return h * fac

    def reject(self, h: float, err: float) -> float:
        """The step size to retry with after a step of size ``h`` was rejected."""
        self.after_reject = True
        if not math.isfinite(err):
            return h * self.factor_min
        return h * max(self.factor_min, min(1.0, self.safety * err ** (-1.0 / (self.order + 1))))

    def failed(self, h: float, factor: float) -> float:
        """The step size to retry with after a step could not be completed."""
        self.after_reject = True
        return h * factor
