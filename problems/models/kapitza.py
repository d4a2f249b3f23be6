"""Kapitza's pendulum: a pendulum whose support oscillates vertically, as a driven
(rheonomic) constrained mechanical system.

A point mass m on a massless rod of length L whose upper end, the support, is
moved on the prescribed path ``(0, s(t))``, ``s(t) = A cos(omega t)``, under gravity
g. In Cartesian coordinates ``q = (x, y)``::

    m x'' = -x lam,   m y'' = -m g - (y - s(t)) lam,
    g(q, t) = (x^2 + (y - s(t))^2 - L^2) / 2 = 0

The constraint depends on time (``driven``): the velocity constraint is ``G v +
g_t = 0`` with ``g_t = -(y - s) s'``, and every formulation takes its driving
terms (:mod:`integrator_bench.problems.mechanical`). In the angle ``theta`` from
the downward vertical (``x = L sin theta``, ``y = s - L cos theta``) the
multiplier drops out and the motion is the one-degree-of-freedom ODE::

    theta'' = -(g + s''(t)) sin(theta) / L = -(g - A omega^2 cos(omega t)) sin(theta) / L

(the tests check the reference against it, solved by another integrator).

With a fast drive the inverted position is stable: Landau and Lifshitz
(Mechanics, 3rd ed., sect. 30, problem 1) average the fast motion into the
effective potential ``m g L (-cos theta + (A^2 omega^2 / (4 g L)) sin^2 theta)``,
whose upper equilibrium ``theta = pi`` is stable when ``A^2 omega^2 > 2 g L``
(P. L. Kapitza, Zh. Eksp. Teor. Fiz. 21 (1951) 588). Its small oscillations about
``theta = pi`` then have the angular frequency ``Omega`` with ``Omega^2 = A^2
omega^2 / (2 L^2) - g / L`` (the second derivative of that potential). The
default parameters (A = 0.1 L, omega = 100 rad/s: ``A^2 omega^2 / (2 g L)`` = 5.1)
start the pendulum 0.3 rad from upright, at rest, the support at its highest:
it swings slowly about the inverted position (``2 pi / Omega`` = 0.99 s) while
jittering at the drive's period (0.063 s), over t in [0, 2].
"""

import numpy as np
import sympy as sym

from integrator_bench.problems.base import Parameter
from integrator_bench.problems.symbolic import SymbolicMechanics


class Kapitza(SymbolicMechanics):
    name = "kapitza"
    description = ("Kapitza's pendulum: the support driven vertically, A cos(omega t), "
                   "a driven constraint g(q, t) = 0; upright and stable")
    source = ("P. L. Kapitza, Zh. Eksp. Teor. Fiz. 21 (1951) 588; Landau and Lifshitz, "
              "Mechanics, 3rd ed., sect. 30, problem 1")
    coordinates = ("x", "y")
    n_constraints = 1
    t_span = (0.0, 2.0)
    n_output = 200
    parameters = (
        Parameter("m", 1.0, 1e-6, 1e6, "mass"),
        Parameter("L", 1.0, 1e-6, 1e6, "rod length"),
        Parameter("g", 9.81, 0.0, 1e3, "gravitational acceleration"),
        Parameter("A", 0.1, 0.0, 1e3, "amplitude of the support's vertical motion"),
        Parameter("omega", 100.0, 0.0, 1e5, "angular frequency of the support's motion"),
        Parameter("theta0", np.pi - 0.3, -np.pi, np.pi,
                  "initial angle from the downward vertical (at rest relative to the support)"),
    )
    velocity_scale = 1.0
    lambda_scale = 100.0
    #: the support at rest: the same pendulum and start, falling from 0.3 rad off upright
    undriven = {"A": 0.0}

    def model(self, t, q, v, p):
        x, y = q
        s = p["A"] * sym.cos(p["omega"] * t)
        M = sym.diag(p["m"], p["m"])
        f = sym.Matrix([0, -p["m"] * p["g"]])
        g = sym.Matrix([(x**2 + (y - s) ** 2 - p["L"] ** 2) / 2])
        return M, f, g

    def support(self, t):
        """``(s, s', s'')`` of the support's height at times ``t``."""
        A, w = self.params["A"], self.params["omega"]
        t = np.asarray(t, float)
        return A * np.cos(w * t), -A * w * np.sin(w * t), -A * w * w * np.cos(w * t)

    def start(self):
        L, th = self.params["L"], self.params["theta0"]
        s, ds, _ = self.support(self.t_span[0])
        return np.array([L * np.sin(th), s - L * np.cos(th)]), np.array([0.0, ds])

    def angle(self, t, Y):
        """theta from the downward vertical of the canonical rows ``Y`` at ``t``."""
        s = self.support(t)[0]
        return np.arctan2(Y[:, 0], s - Y[:, 1])
