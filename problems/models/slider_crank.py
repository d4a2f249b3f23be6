"""Slider-crank mechanism (Sudarsan and Keerthi 1998, Example 5.2; seed 003).

Crank of length 1 (angle phi1, inertia J1) driven by a constant torque T; a
connecting body of length 4 whose centre, 2 from the crank pin, carries angle
phi2 and inertia J2; its far end slides on the x-axis, with coordinate x2 and
mass m2::

    q = (phi1, x2, phi2),  M = diag(J1, m2, J2),  f = (T, 0, 0),
    g(q) = (cos phi1 + 2 cos phi2 - x2,  sin phi1 + 2 sin phi2)

The torque is the paper's ("A constant torque T = 10 N m is applied to body-1").
Choices where the OCR of the paper is garbled: J1 = 1 and J2 = m2 = 2 (read from "J1 = 1, J2 ~ m2 = 2"); time
span [0, 2] s rather than [0, 0.2] s, since 145 steps at TOL 1e-6 (Table 1) is
implausibly many for 0.2 s of near-quadratic motion. Start: phi1 = pi/4,
phi2 = asin(-sin(phi1)/2), x2 = cos phi1 + 2 cos phi2, at rest.
"""

import numpy as np
import sympy as sym

from integrator_bench.problems.base import Parameter
from integrator_bench.problems.symbolic import SymbolicMechanics


class SliderCrank(SymbolicMechanics):
    name = "slider_crank"
    description = "Slider-crank under constant torque (Sudarsan and Keerthi 1998, Ex. 5.2)"
    source = ("Sudarsan and Keerthi, Appl. Math. Comput. 92 (1998) 195-218, Example 5.2 "
              "(seed 003)")
    coordinates = ("phi1", "x2", "phi2")
    n_constraints = 2
    t_span = (0.0, 2.0)
    parameters = (
        Parameter("T", 10.0, 0.0, 1e4, "crank torque [N m]"),
        Parameter("J1", 1.0, 1e-6, 1e6, "crank inertia"),
        Parameter("m2", 2.0, 1e-6, 1e6, "slider mass"),
        Parameter("J2", 2.0, 1e-6, 1e6, "connecting body inertia"),
    )
    velocity_scale = 10.0
    lambda_scale = 10.0

    def model(self, t, q, v, p):
        phi1, x2, phi2 = q
        M = sym.diag(p["J1"], p["m2"], p["J2"])
        f = sym.Matrix([p["T"], 0, 0])
        g = sym.Matrix([sym.cos(phi1) + 2 * sym.cos(phi2) - x2,
                        sym.sin(phi1) + 2 * sym.sin(phi2)])
        return M, f, g

    def start(self):
        phi1 = np.pi / 4
        phi2 = np.arcsin(-np.sin(phi1) / 2)
        return np.array([phi1, np.cos(phi1) + 2 * np.cos(phi2), phi2]), np.zeros(3)
