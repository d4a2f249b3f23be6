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
"""

import numpy as np

from integrator_bench.integrators.base import Integrator, Step, Stepper


class HeunStepper(Stepper):
    """One Heun step with the embedded Euler error estimate."""

    error_order = 1          # the estimate h (k2 - k1) / 2 is O(h^2)

    def step(self, t, y, h):
        f = self.system.fun
        k1 = np.asarray(f(t, y), float)
        k2 = np.asarray(f(t + h, y + h * k1), float)
        return Step(y + 0.5 * h * (k1 + k2), error=0.5 * h * (k2 - k1))


class Heun(Integrator):
    name = "heun"                       # must equal the entry-point name
    description = "Heun's method (explicit trapezoidal rule) with an embedded Euler estimate"
    reference = "Hairer, Norsett, Wanner, Solving ODEs I, 2nd ed., sect. II.1 and II.4"
    accepts = frozenset({"ode"})        # explicit ODEs y' = f(t, y)
    order = 2
    adaptive = True                     # an error estimate: runs at rtol/atol, and at h
    projects = True                     # a one-step method: projection after a step is sound

    def stepper(self, system, counts, rtol=None, atol=None):
        return HeunStepper(system, counts, rtol, atol)
