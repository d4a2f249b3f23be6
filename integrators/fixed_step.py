"""Classical one-step methods at a fixed step size.

Explicit Euler, classical Runge-Kutta (RK4), implicit Euler, the trapezoidal
rule and Alexander's L-stable SDIRK of order 3. Each gives a one-step function
``step(t, y, h) -> y_new`` wrapped in a :class:`OneStepper`; the shared driver
(:mod:`integrator_bench.integrators.driver`) takes the steps ``t0 + k h``,
fills output times inside a step by its interpolation of the method's order
(no extra evaluations), projects after each step when the formulation asks
for it (sound for one-step methods, which declare ``projects = True``) and
ends the run on a non-finite state or an overflow. These methods have no
error estimate: they run at a fixed ``h`` only.

Implicit steps use :class:`integrator_bench.integrators.newton.ImplicitSolver`
(simplified Newton, analytic or finite-difference Jacobian, kept over steps);
its :class:`~integrator_bench.integrators.newton.NewtonFailure` ends the run
with status ``newton_failure``.

References: Hairer, Norsett and Wanner, Solving Ordinary Differential
Equations I, 2nd ed. (1993), sect. II.1; Hairer and Wanner, Solving Ordinary
Differential Equations II, 2nd ed. (1996), sect. IV.3 and IV.6; Alexander,
SIAM J. Numer. Anal. 14 (1977) 1006-1021.
"""

from __future__ import annotations

import numpy as np

from integrator_bench.integrators.base import Integrator, Step, Stepper
from integrator_bench.integrators.newton import NEWTON_SETTINGS, newton_solver


class OneStepper(Stepper):
    """A :class:`Stepper` around a one-step function ``step(t, y, h) -> y_new``
    with no error estimate and no dense output."""

    def __init__(self, system, counts, step):
        super().__init__(system, counts)
        self.one_step = step

    def step(self, t, y, h):
        return Step(self.one_step(t, y, h))


class FixedStep(Integrator):
    """Common declarations of the fixed-step one-step methods."""

    adaptive = False
    projects = True

    def stepper(self, system, counts, rtol=None, atol=None):
        return OneStepper(system, counts, self.step_function(system, counts))

    def step_function(self, system, counts):
        """Return ``step(t, y, h) -> y_new`` for ``system``."""
        raise NotImplementedError


class ExplicitEuler(FixedStep):
    name = "euler"
    description = "Explicit Euler method, fixed step"
    reference = "Hairer, Norsett, Wanner, Solving ODEs I, 2nd ed., sect. II.1"
    order = 1
    #: R(z) = 1 + z: stable on [-2, 0] (Hairer and Wanner II, sect. IV.2)
    stability_intervals = {"": 2.0}

    def step_function(self, system, counts):
        fun = system.fun

        def step(t, y, dt):
            return y + dt * np.asarray(fun(t, y), float)
        return step


class RK4(FixedStep):
    name = "rk4"
    description = "Classical 4-stage Runge-Kutta method of order 4, fixed step"
    reference = "Kutta, Z. Math. Phys. 46 (1901) 435-453; Hairer, Norsett, Wanner I, sect. II.1"
    order = 4
    #: R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24 = -1 at z = -2.7853 (Hairer and Wanner II,
    #: sect. IV.2, Fig. 2.1; checked in tests/harness/measure/test_stiffness.py)
    stability_intervals = {"": 2.785293563405282}

    def step_function(self, system, counts):
        fun = system.fun

        def f(t, y):
            return np.asarray(fun(t, y), float)

        def step(t, y, dt):
            k1 = f(t, y)
            k2 = f(t + dt / 2, y + dt / 2 * k1)
            k3 = f(t + dt / 2, y + dt / 2 * k2)
            k4 = f(t + dt, y + dt * k3)
            return y + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return step


class ImplicitEuler(FixedStep):
    name = "implicit-euler"
    description = "Implicit (backward) Euler method with simplified Newton, fixed step"
    reference = "Hairer and Wanner, Solving ODEs II, 2nd ed., sect. IV.3"
    order = 1
    implicit = True
    uses_jacobian = True
    stability = "L"
    settings = NEWTON_SETTINGS

    def step_function(self, system, counts):
        newton = newton_solver(self, system, counts)

        def step(t, y, dt):
            return newton.solve(t + dt, y, dt, y)
        return step


class Trapezoidal(FixedStep):
    name = "trapezoidal"
    description = "Trapezoidal rule (implicit, A-stable) with simplified Newton, fixed step"
    reference = "Hairer and Wanner, Solving ODEs II, 2nd ed., sect. IV.3"
    order = 2
    implicit = True
    uses_jacobian = True
    stability = "A"
    settings = NEWTON_SETTINGS

    def step_function(self, system, counts):
        newton = newton_solver(self, system, counts)
        fun = system.fun

        def step(t, y, dt):
            r = y + dt / 2 * np.asarray(fun(t, y), float)
            return newton.solve(t + dt, y, dt / 2, r)
        return step


# Alexander (1977), 3-stage, stiffly accurate, L-stable SDIRK of order 3:
# gamma is the root of x^3 - 3x^2 + 3x/2 - 1/6 in (1/6, 1/2).
_G = 0.43586652150845899941601945
SDIRK3_A = np.array([
    [_G, 0.0, 0.0],
    [(1 - _G) / 2, _G, 0.0],
    [-(6 * _G**2 - 16 * _G + 1) / 4, (6 * _G**2 - 20 * _G + 5) / 4, _G],
])
SDIRK3_C = SDIRK3_A.sum(axis=1)


def sdirk3_step(newton, t, y, dt):
    """One step of Alexander's SDIRK3; stage slopes come from the stage equations."""
    slopes = []
    Y = y
    for i in range(3):
        r = y + dt * sum(SDIRK3_A[i, j] * slopes[j] for j in range(i))
        c = dt * _G
        Y = newton.solve(t + SDIRK3_C[i] * dt, Y, c, r)
        slopes.append((Y - r) / c)
    return Y  # stiffly accurate: the last stage is the step value


class SDIRK3(FixedStep):
    name = "sdirk3"
    description = "Alexander's 3-stage L-stable SDIRK of order 3 with simplified Newton, fixed step"
    reference = "Alexander, SIAM J. Numer. Anal. 14 (1977) 1006-1021; Hairer and Wanner II, sect. IV.6"
    order = 3
    implicit = True
    uses_jacobian = True
    stability = "L"
    settings = NEWTON_SETTINGS

    def step_function(self, system, counts):
        newton = newton_solver(self, system, counts)
        return lambda t, y, dt: sdirk3_step(newton, t, y, dt)
