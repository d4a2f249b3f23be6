"""Rigid planar pendulum (seeds 000 and 001).

A point mass m on a massless rod of length L under gravity g, pivoted at the
origin. The canonical components are Cartesian, ``(x, y, vx, vy)`` with
``x = L sin(theta)``, ``y = -L cos(theta)``, so that every formulation of the
constrained form (index 3 in the seeds' I3/SI2 example) is measured against one
reference. The ``ode`` formulation here is the minimal-coordinate (recursive)
form of the seeds, ``theta'' = -(g / L) sin(theta)``. Start: horizontal, at rest
(theta0 = pi/2), a large-amplitude, strongly nonlinear swing. Energy
``m (vx^2 + vy^2) / 2 + m g y`` is conserved; the position constraint
``x^2 + y^2 - L^2`` and velocity constraint ``x vx + y vy`` vanish.
"""

import numpy as np

from problems.base import Parameter, Problem
from problems.system import OdeSystem


class Pendulum(Problem):
    name = "pendulum"
    description = "Rigid planar pendulum, started horizontal (seeds 000/001)"
    source = "MSC.ADAMS/Solver seminar (seed 000); ADAMS course sect. 7 (seed 001)"
    components = ("x", "y", "vx", "vy")
    t_span = (0.0, 10.0)
    parameters = (
        Parameter("m", 1.0, 1e-6, 1e6, "mass"),
        Parameter("L", 1.0, 1e-6, 1e6, "rod length"),
        Parameter("g", 9.81, 0.0, 1e3, "gravitational acceleration"),
        Parameter("theta0", np.pi / 2, -np.pi, np.pi, "initial angle from the downward vertical"),
    )
    error_components = ("x", "y")
    velocity_components = ("vx", "vy")
    atol_scale = 1.0

    def initial_state(self):
        return self._cartesian(np.array([[self.params["theta0"], 0.0]]))[0]

    def _cartesian(self, Z):
        L = self.params["L"]
        th, om = Z[:, 0], Z[:, 1]
        s, c = np.sin(th), np.cos(th)
        return np.column_stack([L * s, -L * c, L * c * om, L * s * om])

    def minimal_rhs(self, t, z):
        return np.array([z[1], -self.params["g"] / self.params["L"] * np.sin(z[0])])

    def minimal_jac(self, t, z):
        return np.array([[0.0, 1.0], [-self.params["g"] / self.params["L"] * np.cos(z[0]), 0.0]])

    def formulate(self, formulation="ode"):
        super().formulate(formulation)  # validates the name
        return OdeSystem(
            t0=self.t_span[0], t_end=self.t_span[1],
            y0=np.array([self.params["theta0"], 0.0]), t_eval=self.t_eval,
            atol_scale=np.array([1.0, 1.0]),
            output=lambda t, Z: self._cartesian(np.atleast_2d(Z)),
            fun=self.minimal_rhs, jac=self.minimal_jac)

    def invariants(self):
        m, g = self.params["m"], self.params["g"]

        def energy(t, Y):
            return 0.5 * m * (Y[:, 2] ** 2 + Y[:, 3] ** 2) + m * g * Y[:, 1]

        return {"energy": energy}

    def constraint_residuals(self, t, Y):
        L = self.params["L"]
        pos = np.abs(Y[:, 0] ** 2 + Y[:, 1] ** 2 - L**2) / 2
        vel = np.abs(Y[:, 0] * Y[:, 2] + Y[:, 1] * Y[:, 3])
        return pos, vel
