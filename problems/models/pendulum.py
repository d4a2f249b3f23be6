"""Rigid planar pendulum in Cartesian coordinates (seeds 000 and 001).

The seeds' I3/SI2 example: a point mass m on a massless rod of length L, pivoted
at the origin, under gravity g::

    m x'' = -x lam,   m y'' = -m g - y lam,   g(q) = (x^2 + y^2 - L^2) / 2 = 0

(the clean point-mass version of the seeds' rod, whose signs the OCR partly
lost; the ADAMS rod with its own inertia J differs only in M). Every formulation is
generated from this model by :mod:`integrator_bench.problems.mechanical`. Start: the rod
horizontal at rest (theta0 = pi/2 from the downward vertical), a
large-amplitude, strongly nonlinear swing over t in [0, 10]. Energy
``m (vx^2 + vy^2) / 2 + m g y`` is conserved.
"""

import sympy as sym
import numpy as np

from integrator_bench.problems.base import Parameter
from integrator_bench.problems.symbolic import SymbolicMechanics


class Pendulum(SymbolicMechanics):
    name = "pendulum"
    description = "Rigid planar pendulum in Cartesian coordinates, started horizontal (seeds 000/001)"
    source = ("MSC.ADAMS/Solver seminar (seed 000); ADAMS course sect. 7 (seed 001); "
              "Hairer and Wanner, Solving ODEs II, sect. VII.1")
    coordinates = ("x", "y")
    n_constraints = 1
    t_span = (0.0, 10.0)
    parameters = (
        Parameter("m", 1.0, 1e-6, 1e6, "mass"),
        Parameter("L", 1.0, 1e-6, 1e6, "rod length"),
        Parameter("g", 9.81, 0.0, 1e3, "gravitational acceleration"),
        Parameter("theta0", np.pi / 2, -np.pi, np.pi, "initial angle from the downward vertical"),
    )
    velocity_scale = 1.0
    lambda_scale = 10.0

    def model(self, t, q, v, p):
        x, y = q
        M = sym.diag(p["m"], p["m"])
        f = sym.Matrix([0, -p["m"] * p["g"]])
        g = sym.Matrix([(x**2 + y**2 - p["L"] ** 2) / 2])
        return M, f, g

    def start(self):
        L, th = self.params["L"], self.params["theta0"]
        return np.array([L * np.sin(th), -L * np.cos(th)]), np.zeros(2)

    def invariants(self):
        m, g = self.params["m"], self.params["g"]

        def energy(t, Y):
            return 0.5 * m * (Y[:, 2] ** 2 + Y[:, 3] ** 2) + m * g * Y[:, 1]

        return {"energy": energy}
