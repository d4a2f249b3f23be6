"""Andrews' squeezer mechanism: seven rigid bodies, six constraints.

The planar seven-body mechanism of Manning (1981) as set by Schiehlen and used
as a DAE test problem by Hairer and Wanner (Solving ODEs II, 2nd ed., sect.
VII.7) and the IVP Test Set (problem ``andrews``). q = (beta, Theta, gamma,
Phi, delta, Omega, epsilon); a drive torque mom acts on the first body and a
spring (c0, l0) on the third. Constants, mass matrix, forces and constraints
as in the IVP Test Set's andrews.f (Mazzia and Magherini, release 2.4). The
start is the test set's consistent one, at rest; t in [0, 0.03]. As in the
test set, the error is scored on the positions only: the test set's reference
values of the velocities and multipliers disagree with a converged
recomputation by 2e-8 to 1e-6 relative, its positions to at most 3e-10. Seed 002 (Table 5) runs it in IDA at index 3
and 2.
"""

import numpy as np
import sympy as sym

from integrator_bench.problems.symbolic import SymbolicMechanics

# IVP Test Set, andrews.f (Mazzia and Magherini, release 2.4): masses, inertias,
# fixed points, spring, lengths and the drive torque, in SI units.
C = dict(
    m1=.04325, m2=.00365, m3=.02373, m4=.00706, m5=.07050, m6=.00706, m7=.05498,
    I1=2.194e-6, I2=4.410e-7, I3=5.255e-6, I4=5.667e-7, I5=1.169e-5, I6=5.667e-7,
    I7=1.912e-5, xa=-.06934, ya=-.00227, xb=-.03635, yb=.03273, xc=.014, yc=.072,
    c0=4530.0, l0=.07785, d=28e-3, da=115e-4, e=2e-2, ea=1421e-5, rr=7e-3, ra=92e-5,
    ss=35e-3, sa=1874e-5, sb=1043e-5, sc=18e-3, sd=2e-2, ta=2308e-5, tb=916e-5,
    u=4e-2, ua=1228e-5, ub=449e-5, zf=2e-2, zt=4e-2, fa=1421e-5, mom=0.033,
)

Q0 = (-0.0617138900142764496358948458001, 0.0, 0.455279819163070380255912382449,
      0.222668390165885884674473185609, 0.487364979543842550225598953530,
      -0.222668390165885884674473185609, 1.23054744454982119249735015568)


class Squeezer(SymbolicMechanics):
    name = "squeezer"
    description = "Andrews' squeezer mechanism, seven bodies (IVP Test Set 'andrews')"
    source = ("Hairer and Wanner, Solving ODEs II, 2nd ed. (1996), sect. VII.7; "
              "Mazzia and Magherini, IVP Test Set 2.4, problem andrews; seed 002")
    coordinates = ("beta", "Theta", "gamma", "Phi", "delta", "Omega", "epsilon")
    n_constraints = 6
    t_span = (0.0, 0.03)
    velocity_scale = 1.0
    lambda_scale = 1.0
    baumgarte_alpha = 300.0  # the motion takes place in milliseconds
    baumgarte_beta = 300.0

    def model(self, t, q, v, p):
        b, Th, ga, Ph, de, Om, ep = q
        bp, Thp, gap, Php, dep, Omp, epp = v
        c = C
        cos, sin = sym.cos, sym.sin
        M = sym.zeros(7, 7)
        M[0, 0] = (c["m1"] * c["ra"]**2 + c["m2"] * (c["rr"]**2 - 2 * c["da"] * c["rr"] * cos(Th)
                   + c["da"]**2) + c["I1"] + c["I2"])
        M[0, 1] = M[1, 0] = c["m2"] * (c["da"]**2 - c["da"] * c["rr"] * cos(Th)) + c["I2"]
        M[1, 1] = c["m2"] * c["da"]**2 + c["I2"]
        M[2, 2] = c["m3"] * (c["sa"]**2 + c["sb"]**2) + c["I3"]
        eea = c["e"] - c["ea"]
        M[3, 3] = c["m4"] * eea**2 + c["I4"]
        M[3, 4] = M[4, 3] = c["m4"] * (eea**2 + c["zt"] * eea * sin(Ph)) + c["I4"]
        M[4, 4] = (c["m4"] * (c["zt"]**2 + 2 * c["zt"] * eea * sin(Ph) + eea**2)
                   + c["m5"] * (c["ta"]**2 + c["tb"]**2) + c["I4"] + c["I5"])
        zfa = c["zf"] - c["fa"]
        M[5, 5] = c["m6"] * zfa**2 + c["I6"]
        M[5, 6] = M[6, 5] = c["m6"] * (zfa**2 - c["u"] * zfa * sin(Om)) + c["I6"]
        M[6, 6] = (c["m6"] * (zfa**2 - 2 * c["u"] * zfa * sin(Om) + c["u"]**2)
                   + c["m7"] * (c["ua"]**2 + c["ub"]**2) + c["I6"] + c["I7"])

        xd = c["sd"] * cos(ga) + c["sc"] * sin(ga) + c["xb"]
        yd = c["sd"] * sin(ga) - c["sc"] * cos(ga) + c["yb"]
        Ls = sym.sqrt((xd - c["xc"])**2 + (yd - c["yc"])**2)
        F = -c["c0"] * (Ls - c["l0"]) / Ls
        Fx, Fy = F * (xd - c["xc"]), F * (yd - c["yc"])
        f = sym.Matrix([
            c["mom"] - c["m2"] * c["da"] * c["rr"] * Thp * (Thp + 2 * bp) * sin(Th),
            c["m2"] * c["da"] * c["rr"] * bp**2 * sin(Th),
            Fx * (c["sc"] * cos(ga) - c["sd"] * sin(ga)) + Fy * (c["sd"] * cos(ga) + c["sc"] * sin(ga)),
            c["m4"] * c["zt"] * eea * dep**2 * cos(Ph),
            -c["m4"] * c["zt"] * eea * Php * (Php + 2 * dep) * cos(Ph),
            -c["m6"] * c["u"] * zfa * epp**2 * cos(Om),
            c["m6"] * c["u"] * zfa * Omp * (Omp + 2 * epp) * cos(Om),
        ])
        Cc = c["rr"] * cos(b) - c["d"] * cos(b + Th)
        Sc = c["rr"] * sin(b) - c["d"] * sin(b + Th)
        g = sym.Matrix([
            Cc - c["ss"] * sin(ga) - c["xb"],
            Sc + c["ss"] * cos(ga) - c["yb"],
            Cc - c["e"] * sin(Ph + de) - c["zt"] * cos(de) - c["xa"],
            Sc + c["e"] * cos(Ph + de) - c["zt"] * sin(de) - c["ya"],
            Cc - c["zf"] * cos(Om + ep) - c["u"] * sin(ep) - c["xa"],
            Sc - c["zf"] * sin(Om + ep) + c["u"] * cos(ep) - c["ya"],
        ])
        return M, f, g

    def start(self):
        return np.array(Q0), np.zeros(7)
