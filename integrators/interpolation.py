"""Interpolants of accepted steps, shared by the driver and the steppers.

* :func:`lagrange`: the polynomial through given step values (BDF's dense
  output and predictor; the driver's interpolation for steppers without a
  dense output);
* :func:`hermite`: the cubic Hermite interpolant from values and slopes at
  both ends of a step (RKC's dense output; the alpha methods' ``q`` and ``v``),
  locally ``O(h^4)``;
* :class:`Interpolation`: the driver's output values inside steps, from a
  window of accepted step values as centred on the output time as the steps
  taken allow (see :mod:`integrator_bench.integrators.driver`).

References: Hairer, Norsett and Wanner, Solving ODEs I, 2nd ed. (1993),
sect. II.6 (dense output, Hermite interpolation) and III.1 (the interpolation
polynomial of multistep methods).
"""

from __future__ import annotations

from collections import deque

import numpy as np

MAX_DEGREE = 8


def lagrange(nodes, values, t) -> np.ndarray:
    """Value at ``t`` of the polynomial through ``(nodes[i], values[i])``."""
    out = 0.0
    for j, xj in enumerate(nodes):
        w = np.prod([(t - xi) / (xj - xi) for i, xi in enumerate(nodes) if i != j])
        out = out + w * values[j]
    return out


def hermite(t0, h, x0, dx0, x1, dx1):
    """Cubic Hermite interpolant through ``(x0, dx0)`` at ``t0`` and ``(x1, dx1)``
    at ``t0 + h``, as a function of ``t``."""
    def value(t):
        s = (t - t0) / h
        h00, h10 = (1 + 2 * s) * (1 - s) ** 2, s * (1 - s) ** 2
        h01, h11 = s * s * (3 - 2 * s), s * s * (s - 1)
        return h00 * x0 + h * h10 * dx0 + h01 * x1 + h * h11 * dx1
    return value


class Interpolation:
    """The Lagrange polynomial of ``degree`` (1 to ``MAX_DEGREE``) through the
    ``degree + 1`` latest accepted step values that enclose an output time."""

    def __init__(self, degree: int):
        self.degree = max(1, min(int(degree), MAX_DEGREE))
        self.points = deque(maxlen=2 * (self.degree + 1))

    def add(self, t, y):
        self.points.append((t, y))

    def ready(self, te: float, final: bool) -> bool:
        """Whether enough step values surround ``te`` (all of them at the end)."""
        after = sum(1 for t, _ in self.points if t >= te)
        return final or after >= (self.degree + 2) // 2 and len(self.points) >= self.degree + 1

    def __call__(self, te: float) -> np.ndarray:
        ts = np.array([t for t, _ in self.points])
        m = min(self.degree + 1, ts.size)
        j = int(np.searchsorted(ts, te, side="left"))     # first point at or after te
        hi = min(ts.size, max(j + (m + 1) // 2, m))
        lo = hi - m
        return np.asarray(lagrange(ts[lo:hi], [self.points[i][1] for i in range(lo, hi)], te),
                          float)
