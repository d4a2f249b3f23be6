"""IFToMM benchmark A02: the N-four-bar mechanism, a singular configuration.

The specification (IFToMM Technical Committee for Multibody Dynamics, benchmark
library by the Laboratorio de Ingenieria Mecanica, University of A Coruna:
M. Gonzalez Castro, "N four-bar mechanism", ``mbsbenchmark/dist/A02/
A02_specification.xml``, 2005; re-implemented in OpenSim by the repository
RehabEngGroup/MBSbenchmarksInOpenSim, ``help/benchmarks/A02_N_FourBarMechanism.rst``):
2N+1 bars of 1 m and a uniformly distributed mass of 1 kg; N+1 cranks pinned to
the ground 1 m apart, their tips joined by N couplers; gravity 9.81 N/kg along
-y; at the start the cranks stand upright and the tip of the first crank, B0,
moves along +x at 1 m/s; 20 s; N = 40. The reference variables are the
position and velocity of B0 (x and y); the precision levels are a maximum error
of 1e-1 (low) and 1e-3 (high) over 400 output steps. When the bars lie
horizontal the mechanism passes a singular configuration: its degrees of freedom
jump from 1 to N+1 (the constraint Jacobian loses N rows of rank).

Model
-----
Natural coordinates (Garcia de Jalon and Bayo, Kinematic and Dynamic
Simulation of Multibody Systems, 1994, ch. 2): the tips ``B_i = (x_i, y_i)``,
i = 0 .. N, of the cranks, whose pivots ``P_i = (i, 0)`` are fixed, so
``q = (x_0, y_0, ..., x_N, y_N)``, nq = 2N + 2. A bar of mass m and length L
between points r1, r2 has the constant mass matrix ``m/6 [[2 I, I], [I, 2 I]]``
and carries half its weight at each end; a crank's pivot is fixed, so it adds
``m/3 I`` at its tip. The constraints keep the lengths, halved squares::

    crank i:    ((x_i - i)^2 + y_i^2 - L^2) / 2 = 0,              i = 0 .. N
    coupler i:  ((x_i - x_{i-1})^2 + (y_i - y_{i-1})^2 - L^2) / 2 = 0, i = 1 .. N

nc = 2N + 1, one degree of freedom. M is constant, the forces are constant
(gravity), the constraints quadratic: ``G(q)`` is linear in q and
``d(G v)/dq = G_0(v)``, its homogeneous part at v.

The physical motion (the parallelogram motion)
---------------------------------------------
All cranks turn together at the angle phi from the x-axis, ``B_i = (i + L cos
phi, L sin phi)``, and the couplers translate. Its kinetic and potential energy
are ``I phi'^2 / 2`` and ``C sin phi`` with ``I = (N + 1) m L^2 / 3 + N m L^2``
and ``C = g m L ((N + 1) / 2 + N)``: a pendulum in ``theta = phi + pi / 2``. The
start (phi = pi/2, phi' = -v0 / L) has energy above the top, so the mechanism
turns over and over, through the singular configurations phi = 0 and pi twice a
turn. In closed form (Jacobi's amplitude, Byrd and Friedman, Handbook of
Elliptic Integrals, 2nd ed. (1971), 121.00; Abramowitz and Stegun 16.1)::

    theta / 2 = am(K(k) - Omega t | k^2),   k^2 = 2 C / (E + C),   Omega = sqrt((E + C) / (2 I))

with ``E = I phi'(0)^2 / 2 + C``; :meth:`NFourBar.exact` gives it (positions,
velocities and the multipliers of that motion, the latter NaN where sin phi = 0).
It is the problem's reference solution, and the tests check it against the
one-coordinate equation ``I theta'' = -C sin theta`` integrated numerically and
against the full model's equations.
"""

from __future__ import annotations

import functools

import numpy as np
import scipy.sparse as sp
from scipy.special import ellipj, ellipk

from integrator_bench.problems.base import Parameter, ProblemError
from integrator_bench.problems.mechanical import MechanicalProblem

#: IFToMM A02: bar length [m], bar mass [kg], gravity [N/kg], start speed of B0 [m/s]
LENGTH, MASS, GRAVITY, SPEED = 1.0, 1.0, 9.81, 1.0


#: the consistent start of each N (see NFourBar._consistent)
_STARTS: dict = {}


@functools.lru_cache(maxsize=None)
def mass_matrix(n: int) -> np.ndarray:
    """The constant mass matrix of N loops (read-only): each crank ``m/3`` at its
    tip, each coupler ``m/6 [[2, 1], [1, 2]]`` on its two ends, per axis."""
    M = np.zeros((2 * n + 2, 2 * n + 2))
    idx = np.arange(2 * n + 2)
    M[idx, idx] = MASS / 3                      # the cranks, pivots fixed
    a, b = idx[:-2], idx[2:]                    # the couplers' ends B_{i-1}, B_i, per axis
    M[a, a] += MASS / 3
    M[b, b] += MASS / 3
    M[a, b] += MASS / 6
    M[b, a] += MASS / 6
    M.setflags(write=False)
    return M


@functools.lru_cache(maxsize=None)
def zero_matrix(nq: int) -> np.ndarray:
    """The ``nq x nq`` zero matrix (read-only): the derivatives of the constant
    forces and mass matrix."""
    Z = np.zeros((nq, nq))
    Z.setflags(write=False)
    return Z


@functools.lru_cache(maxsize=None)
def hessians(n: int):
    """The constant Hessians of the ``2n + 1`` constraints as the columns of one
    sparse ``(nq * nq, nc)`` matrix: crank k has the identity on its tip, coupler i
    ``[[I, -I], [-I, I]]`` on its two ends (per axis)."""
    nq = 2 * n + 2
    rows, cols, vals = [], [], []
    for k in range(n + 1):                       # crank k: tip B_k
        for c in range(2):
            j = 2 * k + c
            rows.append(j * nq + j), cols.append(k), vals.append(1.0)
    for i in range(1, n + 1):                    # coupler i: B_{i-1}, B_i
        for c in range(2):
            a, b = 2 * (i - 1) + c, 2 * i + c
            for r, s, v in ((a, a, 1.0), (b, b, 1.0), (a, b, -1.0), (b, a, -1.0)):
                rows.append(r * nq + s), cols.append(n + i), vals.append(v)
    return sp.csr_matrix((vals, (rows, cols)), shape=(nq * nq, 2 * n + 1))


class NFourBar(MechanicalProblem):
    name = "n_four_bar"
    description = ("IFToMM A02: N four-bar linkages in a row (2N+1 bars), through singular "
                   "configurations; scored on the first crank's tip B0")
    source = ("IFToMM multibody benchmark A02 (M. Gonzalez Castro, Univ. A Coruna, "
              "mbsbenchmark A02_specification.xml, 2005); RehabEngGroup/MBSbenchmarksInOpenSim "
              "help/benchmarks/A02_N_FourBarMechanism.rst; Bayo and Avello, Nonlinear Dyn. 5 "
              "(1994) 209-231 (the two four-bar mechanism)")
    t_span = (0.0, 20.0)
    n_output = 400          # the specification's 400 output steps
    parameters = (
        Parameter("n", 40, 1, 100, "number N of four-bar loops (2N+1 bars, N+1 cranks)"),
    )
    # the specification's N = 40, and N = 2 (OpenSim's re-implementation) for quick runs
    benchmark_parameters = ({"n": 40}, {"n": 2})
    position_scale = 1.0
    velocity_scale = 1.0
    lambda_scale = 100.0
    # the closed form is the reference (exact()); the run that checks it must follow the
    # physical branch through 40 singular passages: the projected ODE with DOP853 does,
    # to 1.6e-7 in B0's position at rtol 1e-10 (N = 2 and 40; at 1e-11 and tighter it stops
    # with a step-size underflow at a singular passage, as does Radau; the plain ODE form
    # leaves the branch at the first passage), so the reference claims 6 digits
    exact_check = ("projection", "scipy-DOP853", 1e-10)
    reference_digits = 6
    #: IFToMM A02's precision levels: maximum error of B0's position and velocity
    precision_levels = {"low": 1e-1, "high": 1e-3}

    def __init__(self, **params):
        super().__init__(**params)
        n = self.params["n"]
        if n != int(n):
            raise ProblemError(f"parameter n={n:g} is not a whole number")
        self.n = int(n)
        self.coordinates = tuple(f"{c}B{i}" for i in range(self.n + 1) for c in ("x", "y"))
        self.n_constraints = 2 * self.n + 1
        coords = self.coordinates
        self.components = (coords + tuple(f"v_{c}" for c in coords)
                           + tuple(f"lam{i + 1}" for i in range(self.n_constraints)))
        # IFToMM's reference variables: B0's position (scored) and velocity
        self.error_components = ("xB0", "yB0")
        self.velocity_components = ("v_xB0", "v_yB0")
        self.lambda_components = tuple(f"lam{i + 1}" for i in range(self.n_constraints))
        self.atol_scale = ((self.position_scale,) * len(coords)
                           + (self.velocity_scale,) * len(coords)
                           + (self.lambda_scale,) * self.n_constraints)
        self._mass = mass_matrix(self.n)
        self._pivots = np.arange(self.n + 1, dtype=float)

    @property
    def _consistent(self):
        """The consistent start, computed once per N (the registry-wide tests and
        the matrix's expansion build the problem thousands of times); read-only."""
        if self.n not in _STARTS:
            start = MechanicalProblem._consistent.func(self)
            for x in start:
                x.setflags(write=False)
            _STARTS[self.n] = start
        return _STARTS[self.n]

    def start(self):
        n = self.n
        q = np.zeros(2 * n + 2)
        q[0::2] = np.arange(n + 1)
        q[1::2] = LENGTH
        v = np.zeros(2 * n + 2)
        v[0::2] = SPEED                           # every tip moves with B0
        return q, v

    def mass(self, q):
        return self._mass

    def force(self, t, q, v):
        f = np.zeros(2 * self.n + 2)
        # half of each bar's weight at each of its moving ends: a crank's tip
        # carries m g / 2, each end of a coupler m g / 2
        per_tip = np.full(self.n + 1, MASS * GRAVITY / 2)
        per_tip[:-1] += MASS * GRAVITY / 2
        per_tip[1:] += MASS * GRAVITY / 2
        f[1::2] = -per_tip
        return f

    def _jac_of(self, q, pivots):
        """The rows of G at ``q`` with the cranks' pivots at ``pivots`` (zeros: the
        homogeneous part, d(G v)/dq at q = v)."""
        n = self.n
        G = np.zeros((2 * n + 1, 2 * n + 2))
        k = np.arange(n + 1)
        G[k, 2 * k] = q[0::2] - pivots
        G[k, 2 * k + 1] = q[1::2]
        i = np.arange(1, n + 1)
        d = q.reshape(-1, 2)[1:] - q.reshape(-1, 2)[:-1]
        rows = n + i
        G[rows, 2 * i], G[rows, 2 * i + 1] = d[:, 0], d[:, 1]
        G[rows, 2 * i - 2], G[rows, 2 * i - 1] = -d[:, 0], -d[:, 1]
        return G

    def constraint(self, q):
        B = q.reshape(-1, 2)
        crank = ((B[:, 0] - self._pivots) ** 2 + B[:, 1] ** 2 - LENGTH ** 2) / 2
        d = B[1:] - B[:-1]
        coupler = (np.sum(d * d, axis=1) - LENGTH ** 2) / 2
        return np.concatenate([crank, coupler])

    def constraint_jac(self, q):
        return self._jac_of(q, self._pivots)

    def gv_q(self, q, v):
        return self._jac_of(v, 0.0)

    def accel_term(self, q, v):
        return self._jac_of(v, 0.0) @ v

    def force_q(self, t, q, v):
        return zero_matrix(self.nq)

    force_v = force_q

    def mass_q(self, q, a):
        return zero_matrix(self.nq)

    def gt_q(self, q, lam):
        """d(G^T lam)/dq = sum_k lam_k H_k, H_k the constant Hessian of constraint k
        (:func:`hessians`, one sparse product)."""
        return (hessians(self.n) @ lam).reshape(self.nq, self.nq)

    # ------------------------------------------------------------ the physical motion
    def pendulum(self):
        """``(I, C)``: the parallelogram motion's inertia ``I`` about the crank
        angle and the amplitude ``C`` of its potential energy ``C sin phi``."""
        n, m, L = self.n, MASS, LENGTH
        return (n + 1) * m * L**2 / 3 + n * m * L**2, GRAVITY * m * L * ((n + 1) / 2 + n)

    def crank_angle(self, t):
        """``(phi, phi', phi'')`` of the parallelogram motion at times ``t``, in
        closed form (see the module docstring)."""
        inertia, C = self.pendulum()
        rate0 = -SPEED / LENGTH
        energy = inertia * rate0**2 / 2 + C
        m = 2 * C / (energy + C)
        omega = np.sqrt((energy + C) / (2 * inertia))
        _, _, dn, amplitude = ellipj(ellipk(m) - omega * np.asarray(t, float), m)
        theta = 2 * amplitude
        return theta - np.pi / 2, -2 * omega * dn, -C * np.sin(theta) / inertia

    def exact(self, t):
        """The parallelogram motion at ``t``: positions, velocities and the
        multipliers that hold it (``G^T lam = f - M a`` solved in closed form:
        each crank's multiplier from the vertical balance of its tip, the
        couplers' from the horizontal ones; NaN where sin phi = 0, at the
        singular configurations, where they are not unique)."""
        phi, rate, accel = self.crank_angle(t)
        n, L = self.n, LENGTH
        c, s = np.cos(phi)[:, None], np.sin(phi)[:, None]
        Q = np.empty((len(phi), 2 * n + 2))
        Q[:, 0::2], Q[:, 1::2] = self._pivots + L * c, L * s
        V = np.empty_like(Q)
        V[:, 0::2], V[:, 1::2] = -L * s * rate[:, None], L * c * rate[:, None]
        A = np.empty_like(Q)
        A[:, 0::2] = -L * (s * accel[:, None] + c * rate[:, None] ** 2)
        A[:, 1::2] = L * (c * accel[:, None] - s * rate[:, None] ** 2)
        R = self.force(0.0, Q[0], V[0])[None, :] - A @ self._mass      # = G^T lam
        with np.errstate(divide="ignore", invalid="ignore"):
            crank = np.where(s != 0, R[:, 1::2] / (L * s), np.nan)
        # tip i, x: crank_i L cos phi + mu_i - mu_{i+1} = R_ix, mu_0 = 0; coupler rows
        # have gradient +-(L, 0) at their ends
        rest = R[:, 0::2] - crank * L * c
        coupler = -np.cumsum(rest, axis=1)[:, :-1] / L
        return np.concatenate([Q, V, crank, coupler], axis=1)

    #: the monitored history: its error (``monitor_err``) against the reference's
    #: constant energy is IFToMM's accuracy measure of the conservative A02, the
    #: largest variation of the mechanical energy, here relative to the energy
    monitor_name = "mechanical energy [J], potential from y = 0"

    def energy(self, t, Y):
        """The mechanical energy at the canonical rows ``Y``: kinetic plus the
        potential of gravity from ``y = 0``."""
        Y = np.atleast_2d(Y)
        Q, V = Y[:, :self.nq], Y[:, self.nq:2 * self.nq]
        kinetic = 0.5 * np.einsum("ij,jk,ik->i", V, self._mass, V)
        return kinetic - Q @ self.force(0.0, Q[0], V[0])

    def invariants(self):
        return {"energy": self.energy}

    def monitor(self, t, Y):
        return self.energy(t, Y)
