"""Heun's method as an integrator-bench plugin.

Heun (1900): the explicit trapezoidal rule, a two-stage Runge-Kutta method of
order 2 (Hairer, Norsett, Wanner, Solving ODEs I, 2nd ed., sect. II.1 and the
embedded pair "Heun-Euler" of sect. II.4)::

    k1 = f(t, y),  k2 = f(t + h, y + h k1),  y_new = y + h (k1 + k2) / 2

The embedded explicit Euler step ``y + h k1`` differs from ``y_new`` by
``h (k2 - k1) / 2 = O(h^2)``, the local error estimate of the Euler step
(``error_order = 1``). The step is propagated with the order-2 value (local
extrapolation), so the method runs at a step size ``h`` and, with that
estimate, under error control at ``rtol``/``atol``. The plugin writes only the
step; the harness's driver does the loop, the output times, the step-size
control and the counting of steps.

A setting: ``c2``, the second stage's node, picks one member of the two-stage
order-2 family ``k2 = f(t + c2 h, y + c2 h k1)``, ``y_new = y + h ((1 - b) k1
+ b k2)`` with ``b = 1 / (2 c2)`` (Hairer, Norsett, Wanner I, sect. II.1): 1 is
Heun, 1/2 the midpoint rule, 2/3 Ralston. ``-i heun:c2=0.5`` runs the midpoint
rule; the harness checks the value against the declared range.
"""

import numpy as np

from integrator_bench.integrators.base import Integrator, Step, Stepper
from integrator_bench.integrators.settings import Setting


class HeunStepper(Stepper):
    """One Heun step with the embedded Euler error estimate."""

    error_order = 1          # the estimate b h (k2 - k1) is O(h^2)

    def __init__(self, system, counts, rtol=None, atol=None, c2=1.0):
        super().__init__(system, counts, rtol, atol)
        self.c2 = c2

    def step(self, t, y, h):
        f, c2 = self.system.fun, self.c2
        b = 0.5 / c2
        k1 = np.asarray(f(t, y), float)
        k2 = np.asarray(f(t + c2 * h, y + c2 * h * k1), float)
        return Step(y + h * ((1 - b) * k1 + b * k2), error=b * h * (k2 - k1))


class Heun(Integrator):
    name = "heun"                       # must equal the entry-point name
    description = "Heun's method (explicit trapezoidal rule) with an embedded Euler estimate"
    reference = "Hairer, Norsett, Wanner, Solving ODEs I, 2nd ed., sect. II.1 and II.4"
    accepts = frozenset({"ode"})        # explicit ODEs y' = f(t, y)
    order = 2
    adaptive = True                     # an error estimate: runs at rtol/atol, and at h
    projects = True                     # a one-step method: projection after a step is sound
    # the controls a user may set (-i heun:c2=0.5); the instance has self.c2
    settings = (Setting("c2", float, 1.0, "node of the second stage: 1 Heun, 0.5 midpoint, "
                        "2/3 Ralston", low=0.0, high=1.0, positive=True),)

    def stepper(self, system, counts, rtol=None, atol=None):
        return HeunStepper(system, counts, rtol, atol, c2=self.c2)
