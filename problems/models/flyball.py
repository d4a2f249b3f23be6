"""IFToMM benchmark A05: the stiff flyball governor.

The specification (IFToMM Technical Committee for Multibody Dynamics, benchmark
library by the Laboratorio de Ingenieria Mecanica, University of A Coruna:
M. Gonzalez Castro, "Stiff flyball governor", ``mbsbenchmark/dist/A05/
A05_specification.xml``, 2005; re-implemented in OpenSim by the repository
RehabEngGroup/MBSbenchmarksInOpenSim, ``help/benchmarks/A05_FlyballGovernor.rst``
and ``src/A05-FlyballGovernor``): Watt's governor whose couplers are replaced by
stiff spring-dampers. A vertical shaft (1 m x 0.01 m x 0.01 m) turns about its
axis on a pivot at the ground; at its top, 0.05 m either side of the axis, two
rods (1 m x 0.01 m x 0.01 m) are hinged, each carrying a point mass of 5 kg at
its tip; a slider (0.1 m cube) runs on the shaft at height ``s``; a
spring-damper (K = 8e5 N/m, C = 4e4 N s/m, rest length 0.5 m) joins the slider,
0.05 m either side of the axis, to each rod's midpoint. Density 3000 kg/m^3
(shaft and rods 0.3 kg, slider 3 kg); gravity 9.81 N/kg along the shaft,
downwards. At the start ``s = 0.5 m``, the rods make 30 degrees with the
horizontal (the springs at their rest length), everything at rest in the
shaft's frame, which turns at 2 pi rad/s. The reference variable is ``s``.

What the sources accessible here do not give (the specification's XML body was
not readable; docs/problems.md lists what was searched): its time span and
precision levels. The span here is the 10 s of the OpenSim re-implementation's
comparison; the problem declares no precision levels of its own (the IFToMM
table then takes A01/A02's, and says so). The shaft turns freely (no drive
torque), as in the OpenSim model.

Model
-----
Coordinates in the shaft's turning frame: the shaft's angle ``phi``, the
slider's height ``s`` and the tips ``(x1, y1)``, ``(x2, y2)`` of the rods in the
plane of the shaft (``x`` radial, ``y`` up), q = (phi, s, x1, y1, x2, y2), with
the rods' lengths as the two constraints::

    ((x1 - d)^2 + (y1 - H)^2 - L^2) / 2 = 0,   ((x2 + d)^2 + (y2 - H)^2 - L^2) / 2 = 0

(d = 0.05 m, H = 1 m the hinges' height). M(q) and f(t, q, v) follow from
Lagrange's equations of the kinetic energy (the bodies' translations in the
plane, the turning ``phi'`` at each point's distance from the axis, the
rods' and slider's rotational inertias of their boxes) and the potential of
gravity and the springs, with the dampers' forces ``-C l' dl/dq``; sympy
differentiates them once (:class:`~integrator_bench.problems.symbolic.SymbolicMechanics`).
The fast modes (the linearized ODE at the start has eigenvalues near -8100 and
-1450 1/s, the slider and the rods on the spring-dampers) make it stiff; the
governor's own swing (``s`` between 0.5 and 0.74 m, about 4 s a period) is
barely damped, since the springs hardly deform (the energy falls by 3.1e-3 J of
237 J in 10 s).
"""

from __future__ import annotations

import numpy as np
import sympy as sym

from integrator_bench.problems.symbolic import SymbolicMechanics

#: IFToMM A05 (and its OpenSim re-implementation): SI units
DENSITY, POINT_MASS, STIFFNESS, DAMPING, REST = 3000.0, 5.0, 8e5, 4e4, 0.5
GRAVITY, SPEED, ANGLE, S0 = 9.81, 2 * np.pi, np.pi / 6, 0.5
ROD, SIDE, SLIDER = 1.0, 0.01, 0.1          # rod/shaft length and section, slider side
HINGE_HEIGHT, OFFSET = 1.0, 0.05            # hinges at the shaft's top, 0.05 m off its axis
ROD_MASS, SLIDER_MASS = DENSITY * ROD * SIDE**2, DENSITY * SLIDER**3


class Flyball(SymbolicMechanics):
    name = "flyball"
    description = ("IFToMM A05: the stiff flyball governor (couplers replaced by spring-dampers "
                   "K = 8e5 N/m, C = 4e4 N s/m); scored on the slider's height s")
    source = ("IFToMM multibody benchmark A05 (M. Gonzalez Castro, Univ. A Coruna, "
              "mbsbenchmark A05_specification.xml, 2005); RehabEngGroup/MBSbenchmarksInOpenSim "
              "help/benchmarks/A05_FlyballGovernor.rst and src/A05-FlyballGovernor "
              "(dimensions, masses, spring-dampers, start, 10 s)")
    coordinates = ("phi", "s", "x1", "y1", "x2", "y2")
    error_coordinates = ("s",)
    n_constraints = 2
    t_span = (0.0, 10.0)
    n_output = 400
    position_scale = 1.0
    velocity_scale = 10.0
    lambda_scale = 100.0
    baumgarte_alpha = 50.0
    baumgarte_beta = 50.0

    def model(self, t, q, v, p):
        phi, s, x1, y1, x2, y2 = q
        w, sd, *tips_v = v
        d, H, L = OFFSET, HINGE_HEIGHT, ROD
        # the rods' boxes: across the rod (beyond the thin rod) and along it
        across, along = ROD_MASS * (SIDE / 2) ** 2 / 3, ROD_MASS * 2 * (SIDE / 2) ** 2 / 3
        kinetic = (SLIDER_MASS * sd**2 / 2
                   + (ROD_MASS * 2 * (SIDE / 2) ** 2 / 3) * w**2 / 2      # the shaft's own turning
                   + (SLIDER_MASS * 2 * (SLIDER / 2) ** 2 / 3) * w**2 / 2)  # the slider's
        potential = GRAVITY * SLIDER_MASS * s
        damping = sym.zeros(6, 1)
        tips = ((x1, y1, tips_v[0], tips_v[1], d), (x2, y2, tips_v[2], tips_v[3], -d))
        for x, y, xd, yd, hinge in tips:
            rx, ry = x - hinge, y - H                     # the rod, hinge to tip
            speed2 = xd**2 + yd**2
            # thin rod: in-plane m |tip'|^2 / 3 ... of a rod turning about its hinge,
            # out of plane the turning at distance hinge + xi rx from the axis
            kinetic += ROD_MASS * speed2 / 6 + ROD_MASS * w**2 / 2 * (
                hinge**2 + hinge * rx + rx**2 / 3)
            kinetic += (across * speed2 / L**2
                        + w**2 * (across * rx**2 + along * ry**2) / L**2) / 2
            kinetic += POINT_MASS * (speed2 + x**2 * w**2) / 2
            potential += GRAVITY * (ROD_MASS * (H + y) / 2 + POINT_MASS * y)
            # the spring-damper from the slider (hinge, s) to the rod's midpoint
            lx, ly = (hinge + x) / 2 - hinge, (H + y) / 2 - s
            length = sym.sqrt(lx**2 + ly**2)
            potential += STIFFNESS * (length - REST) ** 2 / 2
            grad = sym.Matrix([length]).jacobian(q).T
            rate = (grad.T * sym.Matrix(v))[0]
            damping += -DAMPING * rate * grad
        vq = sym.Matrix(v)
        M = sym.hessian(kinetic, v)
        dTdv = sym.Matrix([kinetic]).jacobian(v).T
        f = (sym.Matrix([kinetic - potential]).jacobian(q).T - dTdv.jacobian(q) * vq + damping)
        g = sym.Matrix([((x1 - d)**2 + (y1 - H)**2 - L**2) / 2,
                        ((x2 + d)**2 + (y2 - H)**2 - L**2) / 2])
        return M, f, g

    def start(self):
        dx, dy = ROD * np.cos(ANGLE), ROD * np.sin(ANGLE)
        q = np.array([0.0, S0, OFFSET + dx, HINGE_HEIGHT - dy, -OFFSET - dx, HINGE_HEIGHT - dy])
        v = np.zeros(6)
        v[0] = SPEED
        return q, v
