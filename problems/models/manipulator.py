"""Three-link cylindrical manipulator under a control law (Sudarsan and Keerthi
1998, Example 5.3; seed 003).

q = (q1 rotation about the vertical axis, q2 height, q3 radial extension),
r = q3 + l3. The end effector is held on a circle: r sin q1 = 0.169 and
r^2 cos^2 q1 + q2^2 = d::

    M = diag(J1 + J2 + J3 + m3 r^2, m2 + m3, m3)
    f = (-2 m3 r q1' q3', -(m2 + m3) g, m3 r q1'^2) + u(q, q')

with the linear state-feedback law u of the paper stabilising
q_e = (0.436, 0.3, 0.2). Choices where the OCR of the paper lost signs and
digits: the Lagrangian signs of the Coriolis/centrifugal terms, which make u an
equilibrium at q_e (checked: the controlled motion converges to q_e); g = 9.8,
not 9.81, implied by u2's constant 29.4 = (m2 + m3) g; d = 0.221423, the value
that puts q_e on the circle. The paper's start
(0.48607, 0.34512, 0.16176) violates g by about 5e-6 and is projected onto
the constraints; at rest; t in [0, 4] s.
"""

import numpy as np
import sympy as sym

from integrator_bench.problems.base import Parameter
from integrator_bench.problems.symbolic import SymbolicMechanics

GAIN = (  # u = u0 + K1 e + K2 q', rows u1, u2, u3 (Sudarsan and Keerthi, Example 5.3)
    (0.363, (-3.655, -4.181, 3.136), (-0.455, -2.167, 1.083)),
    (29.4, (-15.938, -18.229, 13.672), (-2.167, -10.325, 5.163)),
    (0.423, (8.267, 9.455, -7.091), (1.083, 5.163, -2.581)),
)
EQUILIBRIUM = (0.436, 0.3, 0.2)


class Manipulator(SymbolicMechanics):
    name = "manipulator"
    description = "Controlled three-link cylindrical manipulator (Sudarsan and Keerthi 1998, Ex. 5.3)"
    source = ("Sudarsan and Keerthi, Appl. Math. Comput. 92 (1998) 195-218, Example 5.3 "
              "(seed 003)")
    coordinates = ("q1", "q2", "q3")
    n_constraints = 2
    t_span = (0.0, 4.0)
    parameters = (
        Parameter("m2", 1.0, 1e-6, 1e6, "mass of link 2 [kg]"),
        Parameter("m3", 2.0, 1e-6, 1e6, "mass of link 3 [kg]"),
        Parameter("J1", 0.1, 0.0, 1e6, "inertia of link 1"),
        Parameter("J2", 0.2, 0.0, 1e6, "inertia of link 2"),
        Parameter("J3", 0.1, 0.0, 1e6, "inertia of link 3"),
        Parameter("l3", 0.2, 0.0, 10.0, "length offset of link 3 [m]"),
        Parameter("g", 9.8, 0.0, 1e3, "gravitational acceleration"),
    )

    def model(self, t, q, v, p):
        q1, q2, q3 = q
        r = q3 + p["l3"]
        m2, m3 = p["m2"], p["m3"]
        M = sym.diag(p["J1"] + p["J2"] + p["J3"] + m3 * r**2, m2 + m3, m3)
        e = [qi - qe for qi, qe in zip(q, EQUILIBRIUM)]
        u = [u0 + sum(k * ei for k, ei in zip(ke, e)) + sum(k * vi for k, vi in zip(kv, v))
             for u0, ke, kv in GAIN]
        f = sym.Matrix([-2 * m3 * r * v[0] * v[2] + u[0],
                        -(m2 + m3) * p["g"] + u[1],
                        m3 * r * v[0] ** 2 + u[2]])
        g = sym.Matrix([r * sym.sin(q1) - 0.169,
                        r**2 * sym.cos(q1) ** 2 + q2**2 - 0.221423])
        return M, f, g

    def start(self):
        return np.array([0.48607, 0.34512, 0.16176]), np.zeros(3)
