"""Test problems with known solutions for ``ibench verify``.

Smooth problems for the convergence-order check and Dahlquist-type problems
for the stability check, built as :mod:`integrator_bench.problems.system` objects so that any
registered integrator can take them. They belong to the verification, not to
the benchmark, so they are not registered problems.

Order problems (``exact(t)`` gives the compared components at times ``t``);
their only output times are the two ends, so that a fixed-step ladder
``h = span / N`` steps on a uniform grid (output times inside steps change the
step pattern from one ``h`` to the next and blur the fit; the tests check
output times separately):

``nonlinear`` (ODE)
    the Kepler problem ``q'' = -q / |q|^3`` on a circular orbit beside
    ``z' = cos(t) z`` on [0, 3] (step-size ladder) or [0, 20] (tolerance ladder): ``q = (cos t, sin t)``, ``z = exp(sin t)``;
    nonlinear and non-autonomous, so stage times matter. (A first choice,
    ``y' = -2 t y^2``, had final-time errors that changed sign with ``h``,
    which made the fitted slopes erratic.)
``oscillator`` (ODE)
    ``y1' = y2``, ``y2' = -y1`` on [0, 10] or [0, 20]: ``y = (cos t, -sin t)``.
``circle`` (mechanical, index 3)
    a unit point mass on the unit circle, ``g(q) = (|q|^2 - 1)/2``, no applied
    force, started at ``q = (1, 0)`` with speed ``w = 2``: uniform rotation
    ``q = (cos wt, sin wt)``, ``lam = w^2``, on [0, 3] or [0, 10]; positions
    are compared.

Stability problems: ``y' = lam y`` (real ``lam``), the rotation
``y' = [[0, w], [-w, 0]] y`` (eigenvalues ``+-i w``) and, for mechanical
integrators, a mass with a stiff damper or a stiff spring beside a trivial
constraint ``z = 0``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from integrator_bench.problems.system import MechanicalSystem, OdeSystem, System


@dataclass(frozen=True)
class OrderProblem:
    """A smooth problem with its exact solution on the compared components.

    ``make(t_end)`` builds the system on ``[0, t_end]``; ``t_fixed`` is the
    span of step-size ladders (steppers and codes taking ``h``), ``t_adaptive``
    the longer span of tolerance ladders (enough evaluations that the counts
    of high-order codes are not coarse).
    """

    name: str
    kind: str
    make: Callable[[float], System]
    exact: Callable[[np.ndarray], np.ndarray]
    compared: slice
    t_fixed: float
    t_adaptive: float


def _nonlinear_fun(t, y):
    r3 = (y[0] ** 2 + y[1] ** 2) ** 1.5
    return np.array([y[2], y[3], -y[0] / r3, -y[1] / r3, np.cos(t) * y[4]])


def _nonlinear_jac(t, y):
    x1, x2 = y[0], y[1]
    r2 = x1 * x1 + x2 * x2
    r3, r5 = r2 ** 1.5, r2 ** 2.5
    J = np.zeros((5, 5))
    J[0, 2] = J[1, 3] = 1.0
    J[2, 0] = -1.0 / r3 + 3.0 * x1 * x1 / r5
    J[2, 1] = J[3, 0] = 3.0 * x1 * x2 / r5
    J[3, 1] = -1.0 / r3 + 3.0 * x2 * x2 / r5
    J[4, 4] = np.cos(t)
    return J


def _nonlinear(t_end) -> OdeSystem:
    return OdeSystem(
        t0=0.0, t_end=t_end, y0=np.array([1.0, 0.0, 0.0, 1.0, 1.0]),
        t_eval=np.array([0.0, t_end]), atol_scale=1.0, fun=_nonlinear_fun, jac=_nonlinear_jac)


def _nonlinear_exact(t):
    t = np.asarray(t, float)
    return np.column_stack([np.cos(t), np.sin(t), -np.sin(t), np.cos(t), np.exp(np.sin(t))])


def _oscillator(t_end) -> OdeSystem:
    A = np.array([[0.0, 1.0], [-1.0, 0.0]])
    return OdeSystem(
        t0=0.0, t_end=t_end, y0=np.array([1.0, 0.0]), t_eval=_ends(t_end),
        atol_scale=1.0, fun=lambda t, y: A @ y, jac=lambda t, y: A)


def _oscillator_exact(t):
    t = np.asarray(t, float)
    return np.column_stack([np.cos(t), -np.sin(t)])


CIRCLE_W = 2.0


def _circle(t_end) -> MechanicalSystem:
    w = CIRCLE_W
    eye = np.eye(2)
    y0 = np.array([1.0, 0.0, 0.0, w, w * w])
    return MechanicalSystem(
        t0=0.0, t_end=t_end, y0=y0, t_eval=np.array([0.0, t_end]),
        atol_scale=np.ones(5), error_mask=np.arange(5) < 2,
        output=lambda t, Y: np.atleast_2d(Y),
        nq=2, nc=1, mass=lambda q: eye, force=lambda t, q, v: np.zeros(2),
        constraint=lambda q: np.array([0.5 * (q @ q - 1.0)]),
        constraint_jac=lambda q: q.reshape(1, 2),
        accel_term=lambda q, v: np.array([v @ v]),
        tangent=lambda t, q, v, a, lam: (lam[0] * eye, np.zeros((2, 2))),
        a0=np.array([-w * w, 0.0]))


def _circle_exact(t):
    t = np.asarray(t, float)
    return np.column_stack([np.cos(CIRCLE_W * t), np.sin(CIRCLE_W * t)])


ORDER_PROBLEMS = (
    OrderProblem("nonlinear", "ode", _nonlinear, _nonlinear_exact, slice(0, 5), 3.0, 20.0),
    OrderProblem("oscillator", "ode", _oscillator, _oscillator_exact, slice(0, 2), 10.0, 20.0),
    OrderProblem("circle", "mechanical", _circle, _circle_exact, slice(0, 2), 3.0, 10.0),
)


def _ends(t_end):
    """Output times ``0, t_end/2, t_end``."""
    return np.array([0.0, t_end / 2, t_end])


def dahlquist(lam: float, t_end: float) -> OdeSystem:
    """``y' = lam y``, ``y(0) = 1`` on ``[0, t_end]``, output at 0, t_end/2, t_end."""
    return OdeSystem(
        t0=0.0, t_end=t_end, y0=np.array([1.0]), t_eval=_ends(t_end),
        atol_scale=1.0, fun=lambda t, y: lam * y, jac=lambda t, y: np.array([[lam]]))


def rotation(w: float, t_end: float) -> OdeSystem:
    """``y' = [[0, w], [-w, 0]] y`` (eigenvalues ``+-i w``), ``y(0) = (1, 0)``."""
    A = np.array([[0.0, w], [-w, 0.0]])
    return OdeSystem(
        t0=0.0, t_end=t_end, y0=np.array([1.0, 0.0]), t_eval=_ends(t_end),
        atol_scale=1.0, fun=lambda t, y: A @ y, jac=lambda t, y: A)


def mechanical_oscillator(k: float, c: float, t_end: float, v0: float = 0.0,
                          x0: float = 1.0) -> MechanicalSystem:
    """``x'' = -k x - c x'`` beside the trivial constraint ``z = 0``.

    State ``(x, z, vx, vz, lam)``; the constraint only makes the system a
    genuine constrained one (``nc = 1``).
    """
    eye = np.eye(2)
    K = np.array([[k, 0.0], [0.0, 0.0]])
    C = np.array([[c, 0.0], [0.0, 0.0]])
    return MechanicalSystem(
        t0=0.0, t_end=t_end, y0=np.array([x0, 0.0, v0, 0.0, 0.0]),
        t_eval=_ends(t_end), atol_scale=np.ones(5),
        error_mask=np.arange(5) < 2, output=lambda t, Y: np.atleast_2d(Y),
        nq=2, nc=1, mass=lambda q: eye,
        force=lambda t, q, v: -K @ q - C @ v,
        constraint=lambda q: q[1:2].copy(),
        constraint_jac=lambda q: np.array([[0.0, 1.0]]),
        accel_term=lambda q, v: np.zeros(1),
        tangent=lambda t, q, v, a, lam: (K, C),
        a0=np.array([-k * x0 - c * v0, 0.0]))
