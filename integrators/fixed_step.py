"""Classical one-step methods at a fixed step size.

Explicit Euler, classical Runge-Kutta (RK4), implicit Euler, the trapezoidal
rule and Alexander's L-stable SDIRK of order 3, each driven by ``h``.

Step grid and output times (shared by every one-step method in this package,
see :func:`step_points`): the steps end at ``t0 + n h``; an output time of
``system.t_eval`` that falls inside a step splits that step in two (the method
steps to the output time and on to the grid point), so every output value is
the method's own step value, of the method's order, with no interpolation. A
grid point closer than ``1e-9 h`` to an output time is replaced by it, and the
last step ends exactly at ``t_end`` (shortened when ``t_end - t0`` is not a
multiple of ``h``). A non-finite state ends the run at once with
``success=False``, and so does an ``OverflowError`` raised by the right-hand
side on a state that has grown out of range. A system with ``project`` (the projection formulation) is
projected after every step, which is sound for one-step methods; they declare
``projects = True``.

Implicit steps use :class:`integrator_bench.integrators.newton.ImplicitSolver` (simplified
Newton, analytic or finite-difference Jacobian, kept over steps).

References: Hairer, Norsett and Wanner, Solving Ordinary Differential
Equations I, 2nd ed. (1993), sect. II.1; Hairer and Wanner, Solving Ordinary
Differential Equations II, 2nd ed. (1996), sect. IV.3 and IV.6; Alexander,
SIAM J. Numer. Anal. 14 (1977) 1006-1021.
"""

from __future__ import annotations

import numpy as np

from integrator_bench.integrators.base import Integrator, Solution
from integrator_bench.integrators.newton import ImplicitSolver, NewtonFailure


class StepFailure(Exception):
    """A step could not be completed (the message says why)."""


def step_points(t0: float, t_end: float, h: float, t_eval: np.ndarray) -> np.ndarray:
    """Ends of the steps: the grid ``t0 + n h`` merged with the output times.

    Grid points within ``1e-9 h`` of an output time (or of ``t_end``) are
    dropped in favour of the output time, so no step is shorter than that.
    """
    if not (np.isfinite(h) and h > 0):
        raise ValueError(f"step size h={h!r} must be a positive finite number")
    n = int(np.floor((t_end - t0) / h + 1e-9))
    grid = t0 + h * np.arange(1, n + 1)
    outs = np.asarray(t_eval, float)
    outs = outs[outs > t0]
    if outs.size == 0 or outs[-1] != t_end:
        outs = np.append(outs, t_end)
    tol = 1e-9 * h
    i = np.clip(np.searchsorted(outs, grid), 1, outs.size - 1) if outs.size > 1 else \
        np.zeros(grid.size, int)
    near = np.abs(outs[i] - grid) <= tol
    if outs.size > 1:
        near |= np.abs(outs[i - 1] - grid) <= tol
    grid = grid[~near & (grid < t_end)]
    return np.union1d(grid, outs)


def march(system, h, step, counts) -> Solution:
    """Drive a one-step method ``step(t, y, dt) -> y_new`` over the step points.

    ``step`` raises :class:`StepFailure` (or ``NewtonFailure``) to give up.
    """
    t_eval = system.t_eval
    ys = np.empty((t_eval.size, system.n))
    ys[0] = system.y0
    out = 1
    t, y = system.t0, np.array(system.y0, dtype=float)
    project = getattr(system, "project", None)
    counts.setdefault("nsteps", 0)
    counts.setdefault("nreject", 0)
    try:
        for t_new in step_points(system.t0, system.t_end, h, t_eval):
            y = step(t, y, t_new - t)
            if not np.all(np.isfinite(y)):
                raise StepFailure(f"non-finite state at t={t_new:.6g}")
            if project is not None:
                y = np.asarray(project(t_new, y), float)
            counts["nsteps"] += 1
            t = t_new
            if out < t_eval.size and t == t_eval[out]:
                ys[out] = y
                out += 1
    except (StepFailure, NewtonFailure) as exc:
        return Solution(t_eval[:out], ys[:out], False, str(exc), counts)
    except OverflowError as exc:  # the right-hand side overflowed: the solution blew up
        return Solution(t_eval[:out], ys[:out], False, blow_up_message(t, exc), counts)
    return Solution(t_eval[:out], ys[:out], True, "", counts)


def blow_up_message(t, exc) -> str:
    """The failure message when ``f`` raised OverflowError on a blown-up state."""
    return f"overflow in the step from t={t:.6g} ({exc}): the solution blew up"


class FixedStep(Integrator):
    """Common declarations of the fixed-step one-step methods."""

    adaptive = False
    projects = True

    def solve(self, system, *, rtol=None, atol=None, h=None):
        if h is None:
            raise ValueError(f"{self.name} is a fixed-step method and needs h")
        counts = {}
        return march(system, h, self.stepper(system, counts), counts)

    def stepper(self, system, counts):
        """Return ``step(t, y, dt) -> y_new`` for ``system``."""
        raise NotImplementedError


class ExplicitEuler(FixedStep):
    name = "euler"
    description = "Explicit Euler method, fixed step"
    reference = "Hairer, Norsett, Wanner, Solving ODEs I, 2nd ed., sect. II.1"
    order = 1

    def stepper(self, system, counts):
        fun = system.fun

        def step(t, y, dt):
            return y + dt * np.asarray(fun(t, y), float)
        return step


class RK4(FixedStep):
    name = "rk4"
    description = "Classical 4-stage Runge-Kutta method of order 4, fixed step"
    reference = "Kutta, Z. Math. Phys. 46 (1901) 435-453; Hairer, Norsett, Wanner I, sect. II.1"
    order = 4

    def stepper(self, system, counts):
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

    def stepper(self, system, counts):
        newton = ImplicitSolver(system, counts)

        def step(t, y, dt):
            return newton.solve(t + dt, y, dt, y)
        return step


class Trapezoidal(FixedStep):
    name = "trapezoidal"
    description = "Trapezoidal rule (implicit, A-stable) with simplified Newton, fixed step"
    reference = "Hairer and Wanner, Solving ODEs II, 2nd ed., sect. IV.3; PROBLEMS.md sect. 9"
    order = 2
    implicit = True
    uses_jacobian = True
    stability = "A"

    def stepper(self, system, counts):
        newton = ImplicitSolver(system, counts)
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

    def stepper(self, system, counts):
        newton = ImplicitSolver(system, counts)
        return lambda t, y, dt: sdirk3_step(newton, t, y, dt)
