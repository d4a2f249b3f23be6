"""Elastic spring pendulum (seed 002, FMNN05 Project 1).

A unit point mass on a spring of natural length 1 and stiffness ``k`` under unit
gravity, in nondimensional units (m = 1, natural length 1, g = 1)::

    y1' = y3,   y2' = y4,
    y3' = -y1 lam,   y4' = -y2 lam - 1,   lam = k (r - 1) / r,   r = |(y1, y2)|

The seed's OCR prints ``lam = k sqrt(y1^2 + y2^2 - 1) / sqrt(y1^2 + y2^2)``; the
``-1`` belongs outside the root (the spring force of a spring of natural length
1; confirmed by a public solution of the course's project, the repository
TuongL94/SimulationTools ``P1/task4.py``, which seed 002 does not name). Start ``(1, 1, 0, 0)``: the spring stretched to
r = sqrt(2), at rest, as in the report's runs. The linearised fast mode is about
``+-i sqrt(k)``: physically stiff (undamped), not overdamped. Energy
``E = (y3^2 + y4^2)/2 + y2 + k (r - 1)^2 / 2`` is conserved.
"""

import numpy as np

from integrator_bench.problems.base import Parameter, Problem


class SpringPendulum(Problem):
    name = "spring_pendulum"
    description = "Elastic spring pendulum with spring constant k (seed 002)"
    source = ("Lund FMNN05 Project 1 report (seed 002); Hairer, Lubich, Wanner, "
              "Geometric Numerical Integration, 2nd ed., sect. I.5 (stiff spring pendulum)")
    components = ("x", "y", "vx", "vy")
    parameters = (
        Parameter("k", 100.0, 1.0, 1e7, "spring constant (nondimensional)"),
        Parameter("t_end", 10.0, 0.01, 1000.0, "final time"),
    )
    benchmark_parameters = ({"k": 100.0}, {"k": 1000.0})
    error_components = ("x", "y")
    velocity_components = ("vx", "vy")
    atol_scale = 1.0

    @property
    def t_span(self):
        return (0.0, self.params["t_end"])

    def initial_state(self):
        return np.array([1.0, 1.0, 0.0, 0.0])

    def rhs(self, t, y):
        k = self.params["k"]
        r = np.hypot(y[0], y[1])
        lam = k * (r - 1.0) / r
        return np.array([y[2], y[3], -y[0] * lam, -y[1] * lam - 1.0])

    def jac(self, t, y):
        k = self.params["k"]
        x1, x2 = y[0], y[1]
        r = np.hypot(x1, x2)
        lam = k * (r - 1.0) / r
        c = k / r**3  # d lam / d y_i = c * y_i
        J = np.zeros((4, 4))
        J[0, 2] = J[1, 3] = 1.0
        J[2, 0] = -lam - c * x1 * x1
        J[2, 1] = -c * x1 * x2
        J[3, 0] = -c * x1 * x2
        J[3, 1] = -lam - c * x2 * x2
        return J

    def invariants(self):
        k = self.params["k"]

        def energy(t, Y):
            r = np.hypot(Y[:, 0], Y[:, 1])
            return 0.5 * (Y[:, 2] ** 2 + Y[:, 3] ** 2) + Y[:, 1] + 0.5 * k * (r - 1.0) ** 2

        return {"energy": energy}
