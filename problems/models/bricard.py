"""IFToMM benchmark A04: Bricard's mechanism, redundant constraints at every instant.

The specification (IFToMM Technical Committee for Multibody Dynamics, benchmark
library by the Laboratorio de Ingenieria Mecanica, University of A Coruna:
M. Gonzalez Castro, "Bricard mechanism", ``mbsbenchmark/dist/A04/
A04_specification.xml``, 2005; Gonzalez, Dopico, Lugris and Cuadrado, Multibody
Syst. Dyn. 16 (2006) 179-190; re-implemented in OpenSim by the repository
RehabEngGroup/MBSbenchmarksInOpenSim, ``help/benchmarks/A04_BricardsMechanism.rst``
and ``src/A04-BricardsMechanism``): five rods of 1 m and 1 kg with a square
cross-section of 0.1 m, joined to each other and to the ground by six revolute
joints; gravity 9.81 N/kg along -y; 10 s. Grubler's count gives 0 degrees of
freedom, the special directions of the axes (each perpendicular to the two rods
it joins and to the next axis along each rod) give 1 (Bricard, J. Math. Pures
Appl. 3 (1897) 113-148). The reference variables are the coordinates of the
point P3; the accuracy measure of the conservative mechanism is the variation
of its mechanical energy.

What the sources accessible here do not give (the specification's XML body was
not readable; docs/problems.md lists what was searched): its precision levels,
and an initial velocity. The start here is the OpenSim re-implementation's: the
configuration below, at rest, so that the mechanism moves under gravity alone;
the problem declares no precision levels of its own (the IFToMM table then takes
A01/A02's, and says so).

Geometry at the start (the OpenSim model's): the ground joints at P1 = (0, 0, 0)
(axis y) and P6 = (0, 0, 1) (axis x); the rods run P1 -> P2 = (1, 0, 0) (the
joint there has axis z) -> P3 = (1, -1, 0) (axis x) -> P4 = (1, -1, 1) (axis y)
-> P5 = (0, -1, 1) (axis z) -> P6. P3, the end of the second rod, is the point
the OpenSim re-implementation compares with the reference.

Model
-----
Natural coordinates (Garcia de Jalon and Bayo, Kinematic and Dynamic Simulation
of Multibody Systems, 1994, ch. 2 and 3): the moving joints' points P2..P5 and
their unit axis vectors u2..u5, each shared by the two rods it joins, so
``q = (P2, P3, P4, P5, u2, u3, u4, u5)``, nq = 24 (P1, P6, u1 = y and u6 = x are
fixed). A rod from Ps to Pe with the axes us at Ps and ue at Pe has the
orthonormal frame ``((Pe - Ps) / L, us, ue)``; its material points are ``Ps +
xi (Pe - Ps) + eta us + zeta ue`` with constant ``(xi, eta, zeta)``, so its mass
matrix is constant: ``m [[1/3, 1/6, 0, 0], [1/6, 1/3, 0, 0], [0, 0, a^2/12, 0],
[0, 0, 0, a^2/12]]`` per axis on ``(Ps, Pe, us, ue)`` for a rod of square
section a (its inertias m (L^2 + a^2) / 12 across and m a^2 / 6 along). Gravity
puts half of each rod's weight on each of its ends. The constraints are
quadratic, each a dot product of two linear expressions of q::

    |u_i|^2 = 1                          i = 2 .. 5 (4)
    |Pe - Ps|^2 = L^2, (Pe - Ps).us = 0, (Pe - Ps).ue = 0, us.ue = 0   per rod (20)

nc = 24 = nq: Grubler's count, 0 degrees of freedom; the Jacobian has rank 23
everywhere on the motion (``redundant_constraints = 1``), the mechanism moves.
"""

from __future__ import annotations

import functools

import numpy as np

from integrator_bench.problems.mechanical import MechanicalProblem

#: IFToMM A04: rod length [m], rod mass [kg], side of the square section [m], gravity [N/kg]
LENGTH, MASS, SECTION, GRAVITY = 1.0, 1.0, 0.1, 9.81

#: the joints' points and axes at the start; P1, P6, u1, u6 are fixed
START_POINTS = {1: (0, 0, 0), 2: (1, 0, 0), 3: (1, -1, 0), 4: (1, -1, 1), 5: (0, -1, 1),
                6: (0, 0, 1)}
START_AXES = {1: (0, 1, 0), 2: (0, 0, 1), 3: (1, 0, 0), 4: (0, 1, 0), 5: (0, 0, 1),
              6: (1, 0, 0)}
MOVING = (2, 3, 4, 5)
NQ = 24


def _slot(kind: str, joint: int):
    """``(A, a)`` with the vector ``A q + a``: joint ``joint``'s point (``"P"``) or
    axis (``"u"``); a fixed one has ``A = 0``."""
    A = np.zeros((3, NQ))
    if joint in MOVING:
        start = (MOVING.index(joint) + (0 if kind == "P" else 4)) * 3
        A[:, start:start + 3] = np.eye(3)
        return A, np.zeros(3)
    return A, np.array((START_POINTS if kind == "P" else START_AXES)[joint], float)


def _difference(first, second):
    return first[0] - second[0], first[1] - second[1]


@functools.lru_cache(maxsize=None)
def constraint_terms():
    """The constraints as ``(A1, a1, A2, a2, c)`` stacked over the 24 rows: row k
    is ``(A1 q + a1) . (A2 q + a2) - c`` (read-only arrays)."""
    rows = [(_slot("u", j), _slot("u", j), 1.0) for j in MOVING]
    for s in range(1, 6):
        rod = _difference(_slot("P", s + 1), _slot("P", s))
        us, ue = _slot("u", s), _slot("u", s + 1)
        rows += [(rod, rod, LENGTH ** 2), (rod, us, 0.0), (rod, ue, 0.0), (us, ue, 0.0)]
    A1 = np.array([r[0][0] for r in rows])
    a1 = np.array([r[0][1] for r in rows])
    A2 = np.array([r[1][0] for r in rows])
    a2 = np.array([r[1][1] for r in rows])
    c = np.array([r[2] for r in rows])
    H = np.einsum("kij,kil->kjl", A1, A2)
    H = H + np.swapaxes(H, 1, 2)                 # the constant Hessian of each row
    out = (A1, a1, A2, a2, c, H)
    for x in out:
        x.setflags(write=False)
    return out


@functools.lru_cache(maxsize=None)
def mass_and_force():
    """The constant mass matrix and gravity force on q (read-only)."""
    M, f = np.zeros((NQ, NQ)), np.zeros(NQ)
    block = MASS * np.array([[1 / 3, 1 / 6, 0, 0], [1 / 6, 1 / 3, 0, 0],
                             [0, 0, SECTION ** 2 / 12, 0], [0, 0, 0, SECTION ** 2 / 12]])
    for s in range(1, 6):
        slots = [_slot("P", s)[0], _slot("P", s + 1)[0], _slot("u", s)[0], _slot("u", s + 1)[0]]
        for i, Ai in enumerate(slots):
            for j, Aj in enumerate(slots):
                M += block[i, j] * Ai.T @ Aj
        for end in slots[:2]:                     # half the rod's weight at each end
            f += end.T @ np.array([0.0, -MASS * GRAVITY / 2, 0.0])
    M.setflags(write=False)
    f.setflags(write=False)
    return M, f


class Bricard(MechanicalProblem):
    name = "bricard"
    description = ("IFToMM A04: Bricard's mechanism, five rods and six revolute joints; "
                   "Gruebler's count 0 degrees of freedom, 1 in fact: a rank-deficient "
                   "constraint Jacobian at every instant; scored on the point P3")
    source = ("IFToMM multibody benchmark A04 (M. Gonzalez Castro, Univ. A Coruna, "
              "mbsbenchmark A04_specification.xml, 2005; Gonzalez et al., Multibody Syst. "
              "Dyn. 16 (2006) 179-190); RehabEngGroup/MBSbenchmarksInOpenSim "
              "help/benchmarks/A04_BricardsMechanism.rst (geometry, start at rest); "
              "Bricard, J. Math. Pures Appl. 3 (1897) 113-148")
    coordinates = tuple(f"{c}P{j}" for j in MOVING for c in "xyz") + \
        tuple(f"{c}u{j}" for j in MOVING for c in "xyz")
    error_coordinates = ("xP3", "yP3", "zP3")
    n_constraints = 24
    redundant_constraints = 1
    t_span = (0.0, 10.0)
    n_output = 400
    position_scale = 1.0
    velocity_scale = 1.0
    lambda_scale = 10.0
    # the underlying ODE drifts off the constraints (7 digits between Radau on it
    # and DOP853 on Baumgarte's form); projected after every step, DOP853 and Radau
    # (both one-step methods) hold them
    reference_methods = (("projection", "scipy-DOP853", 1e-13),
                         ("projection", "scipy-Radau", 1e-12))

    def __init__(self, **params):
        super().__init__(**params)
        # the multipliers of a rank-deficient Jacobian are not unique: not scored
        self.lambda_components = ()

    def start(self):
        q = np.concatenate([START_POINTS[j] for j in MOVING] + [START_AXES[j] for j in MOVING])
        return q.astype(float), np.zeros(NQ)

    def mass(self, q):
        return mass_and_force()[0]

    def force(self, t, q, v):
        return mass_and_force()[1].copy()

    def _vectors(self, q):
        A1, a1, A2, a2, c, _ = constraint_terms()
        return A1 @ q + a1, A2 @ q + a2

    def constraint(self, q):
        e1, e2 = self._vectors(q)
        return np.sum(e1 * e2, axis=1) - constraint_terms()[4]

    def constraint_jac(self, q):
        A1, _, A2, _, _, _ = constraint_terms()
        e1, e2 = self._vectors(q)
        return np.einsum("ki,kij->kj", e2, A1) + np.einsum("ki,kij->kj", e1, A2)

    def gv_q(self, q, v):
        return constraint_terms()[5] @ v

    def accel_term(self, q, v):
        return self.gv_q(q, v) @ v

    def force_q(self, t, q, v):
        return np.zeros((NQ, NQ))

    force_v = force_q

    def mass_q(self, q, a):
        return np.zeros((NQ, NQ))

    def gt_q(self, q, lam):
        return np.einsum("k,kij->ij", lam, constraint_terms()[5])

    #: the monitored history: IFToMM's accuracy measure of the conservative A04
    monitor_name = "mechanical energy [J], potential from y = 0"

    def energy(self, t, Y):
        """The mechanical energy at the canonical rows ``Y``: kinetic plus the
        potential of gravity from ``y = 0``."""
        Y = np.atleast_2d(Y)
        Q, V = Y[:, :NQ], Y[:, NQ:2 * NQ]
        M, f = mass_and_force()
        return 0.5 * np.einsum("ij,jk,ik->i", V, M, V) - Q @ f

    def invariants(self):
        return {"energy": self.energy}

    def monitor(self, t, Y):
        return self.energy(t, Y)
