"""A planar closed chain of N rigid links around two sprockets (seed 000).

The belt/chain problem of the Advanced ADAMS/Solver seminar (MSC.ADAMS 2005,
after D. Negrut; seed 000, "Numerical Results": belt of 150 bodies, generic
chain and belt of 3759-7242 equations) as a scalable index-3 system. The
seminar gives only the models' sizes and CPU times, so the design is ours (N
rigid links in Cartesian coordinates, revolute joints, sprocket contact with
ADAMS's IMPACT force), and the numbers are Exudyn's chain drive example
(jgerstmayr/EXUDYN ``main/pythonDev/Examples/chainDriveExample.py``).

Model
-----
Link ``i`` (i = 0 .. N-1) is a bar of length p (the pitch) with centre
``(x_i, y_i)`` and angle ``theta_i``; its back pin is
``B_i = (x_i - h cos theta_i, y_i - h sin theta_i)`` and its front pin
``F_i = (x_i + h cos theta_i, y_i + h sin theta_i)``, ``h = p / 2``. Two
sprockets of pitch radius ``R = p / (2 sin(pi / z))`` (z teeth) turn about fixed
centres ``c_1 = (0, 0)`` (driven) and ``c_2 = (m p, 0)`` (loaded) with angles
``phi_1, phi_2``. Coordinates, link by link, then the sprockets::

    q = (x_0, y_0, theta_0, ..., x_{N-1}, y_{N-1}, theta_{N-1}, phi_1, phi_2),  nq = 3N + 2

Revolute joints close the loop, constraint pair ``j`` joining link j to link
j + 1 (mod N), so that G is block bidiagonal (plus one corner block)::

    g_j = F_j - B_{j+1} = (x_j - x_{j+1} + h (cos theta_j + cos theta_{j+1}),
                           y_j - y_{j+1} + h (sin theta_j + sin theta_{j+1})),   nc = 2N

``M = diag(m_l, m_l, J_l, ..., J_s, J_s)`` is constant. Applied forces:

* gravity ``-m_l g`` on every link (along -y; the centres lie on the x-axis);
* contact of every pin ``B_i`` with each sprocket k (the sprocket is a disc of
  contact radius ``R_c``; the pin a point): penetration
  ``delta = R_c - |B_i - c_k|``, normal ``n = (B_i - c_k) / |B_i - c_k|``,
  normal force on the pin (ADAMS IMPACT, the seminar's Appendix A, with
  STEP the cubic Heaviside step of ADAMS)::

      F_n = k delta_+^e + c_max STEP(delta, 0, 0, d, 1) delta',
      STEP(x, x0, h0, x1, h1) = h0 + (h1 - h0) s^2 (3 - 2 s),  s = (x - x0) / (x1 - x0) clipped to [0, 1]

  (zero for ``delta <= 0``; as in ADAMS the total is not clipped, so a fast
  separation can pull slightly). Regularized Coulomb friction along the
  tangent ``t = (-n_y, n_x)``, proportional to the elastic part of the normal
  force, as the CVT chain model does (Orlov, Kuzin and Shabrov, "Two
  approaches to speeding up dynamics simulation", Russian Supercomputing Days
  2017: ``R = -f(v_r) N_el``)::

      F_t = -mu k delta_+^e tanh(v_slip / v_eps),   v_slip = t . B_i' - rho phi_k'

  with ``rho = |B_i - c_k|``: the slip of the pin against the material point of
  the sprocket under it, so the pair is exactly dissipative, and the sprocket
  feels the torque ``-rho F_t``. The sprockets carry no teeth: the drive is
  friction-driven (a belt-like model), the pins seated on the pitch circle by
  the chain's tension.
* drive on sprocket 1, a velocity servo with a smooth ramp
  ``S(t) = STEP(t, 0, 0, t_ramp, 1)``:
  ``tau_1 = S(t) (T_d + c_d omega_ref) - c_d phi_1'``;
  viscous load on sprocket 2: ``tau_2 = -c_l phi_2'``.

Smoothness at contact opening (what Newton in implicit integrators sees): the
elastic term ``k delta_+^e`` has derivative ``e k delta_+^(e-1)``, continuous
at ``delta = 0`` for ``e > 1``; the damping coefficient ``c_max STEP`` has
derivative ``6 c_max s (1 - s) / d``, zero at both ends, so it is C^1 in
``delta``; friction is ``mu k delta_+^e`` times a smooth function. Hence the
force is C^1 in (q, v) for every ``e > 1`` (the exponent's range), with a
Hoelder-continuous (exponent ``min(1, e - 1)``) Jacobian for ``1 < e < 2`` and
a Lipschitz one for ``e >= 2``; the Jacobian of the damping term jumps in its
second derivative (the cubic STEP is C^1, not C^2). ``e = 1`` (Exudyn's linear
contact) would put a kink at opening and is excluded. The Hertz default
``e = 1.5`` gives a C^1 force whose Jacobian is continuous but not Lipschitz
at opening.

Pretension: with rigid links the tension is set by the geometry, so the
contact radius is the pitch radius plus the penetration at which a wrapped pin
carries the pin force ``2 T0 sin(pi / z)`` of a chain under tension ``T0``:
``R_c = R + (2 T0 sin(pi / z) / k)^(1 / e)``.

Start (:meth:`ChainDrive.start`): ``z/2`` links wrapped on each sprocket (z even),
straight spans of ``m = (N - z) / 2`` links tangent to the pitch circles, pins
exactly on the pitch circles, so ``g(q) = 0`` to round-off; in rigid motion at
sprocket speed ``omega0`` (arc links rotate about their sprocket centre, span
links translate at ``R omega0``), so ``G v = 0`` to round-off.

Parameter values (``benchmark_parameters[0]`` is Exudyn's 30-link drive;
``[1]`` the seed's 150 bodies with the same links): from chainDriveExample.py,
z = 16 teeth, pitch 0.03 m, 7 free links per span (N = 16 + 2 * 7 = 30), link a
steel-density (1000 there) cuboid 0.03 x 0.012 x 0.012 m: mass 4.32e-3 kg,
inertia 4.32e-3 (0.03^2 + 0.012^2) / 12 = 3.758e-7 kg m^2; sprocket a cylinder of
density 100, width 0.95 * 0.012 m, radius R = 0.0769 m: J = 6.26e-5 kg m^2;
contact damping 10 N s/m; drive speed pi rad/s; load damper 0.01 N m s/rad;
gravity 9.81. Exudyn's contact is linear (1e4 N/m); ours is Hertzian
(e = 1.5) with k = 1e6 N/m^1.5, whose tangent stiffness at the pretension
penetration (1.5e4 N/m at T0 = 5 N) is of the same order. Our choices: the
horizontal layout, pretension 5 N, damping depth 1e-4 m, mu = 0.3,
v_eps = 0.01 m/s, drive gain 1 N m s/rad, ramp 0.05 s (Exudyn: 0.5 s), and
t_end = 0.1 s.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from integrator_bench.problems.base import Parameter, ProblemError
from integrator_bench.problems.mechanical import MechanicalProblem

# Exudyn chainDriveExample.py: link cuboid of density 1000, 0.03 x 0.012 x 0.012 m
_LINK_MASS = 1000 * 0.03 * 0.012 * 0.012
_LINK_INERTIA = _LINK_MASS * (0.03**2 + 0.012**2) / 12
# sprocket: cylinder of density 100, width 0.95 * 0.012 m, radius p / (2 sin(pi/16))
_R16 = 0.03 / (2 * np.sin(np.pi / 16))
_SPROCKET_MASS = 100 * np.pi * _R16**2 * 0.95 * 0.012
_SPROCKET_INERTIA = _SPROCKET_MASS * _R16**2 / 2


def step(x, x0, h0, x1, h1):
    """ADAMS's cubic STEP and its derivative in x (seed 000, Appendix A).

    ``h0 + (h1 - h0) s^2 (3 - 2 s)`` with ``s = (x - x0) / (x1 - x0)`` clipped
    to [0, 1]; C^1 in x.
    """
    s = np.clip((np.asarray(x, float) - x0) / (x1 - x0), 0.0, 1.0)
    return h0 + (h1 - h0) * s * s * (3 - 2 * s), (h1 - h0) * 6 * s * (1 - s) / (x1 - x0)


class ChainDrive(MechanicalProblem):
    """Closed chain of rigid links on two friction-driven sprockets; see the module docstring."""

    name = "chain_drive"
    description = "Planar closed chain of N rigid links on two sprockets (belt/chain, seed 000)"
    source = ("MSC.ADAMS/Solver seminar (seed 000), belt and chain results and Appendix A "
              "(IMPACT); parameters from Exudyn's chainDriveExample.py (jgerstmayr/EXUDYN)")
    sparse = True
    parameters = (
        Parameter("n_links", 30, 10, 100000, "number of links N = teeth + 2 * span links"),
        Parameter("teeth", 16, 4, 400, "teeth z per sprocket (even); pitch radius p / (2 sin(pi/z))"),
        Parameter("pitch", 0.03, 1e-3, 1.0, "link length p [m]"),
        Parameter("link_mass", _LINK_MASS, 1e-6, 1e3, "link mass [kg]"),
        Parameter("link_inertia", _LINK_INERTIA, 1e-12, 1e3, "link inertia about its centre [kg m^2]"),
        Parameter("sprocket_inertia", _SPROCKET_INERTIA, 1e-9, 1e4, "sprocket inertia [kg m^2]"),
        Parameter("pretension", 5.0, 0.0, 1e6, "chain tension T0 the contact radius is set for [N]"),
        Parameter("stiffness", 1e6, 1.0, 1e15, "contact stiffness k [N / m^e]"),
        Parameter("exponent", 1.5, 1.1, 4.0, "contact exponent e (> 1: force C^1 at opening)"),
        Parameter("damping", 10.0, 0.0, 1e6, "contact damping c_max [N s / m]"),
        Parameter("damping_depth", 1e-4, 1e-9, 1.0, "penetration d of full damping [m]"),
        Parameter("friction", 0.3, 0.0, 2.0, "friction coefficient mu"),
        Parameter("friction_velocity", 0.01, 1e-6, 10.0, "friction regularization v_eps [m/s]"),
        Parameter("gravity", 9.81, 0.0, 100.0, "gravitational acceleration (along -y) [m/s^2]"),
        Parameter("drive_speed", np.pi, 0.0, 1e4, "servo target speed omega_ref of sprocket 1 [rad/s]"),
        Parameter("drive_gain", 1.0, 0.0, 1e6, "servo gain c_d [N m s / rad]"),
        Parameter("drive_torque", 0.0, -1e6, 1e6, "feed-forward torque T_d on sprocket 1 [N m]"),
        Parameter("ramp_time", 0.05, 1e-6, 1e3, "duration of the smooth drive ramp [s]"),
        Parameter("load_damping", 0.01, 0.0, 1e6, "viscous load c_l on sprocket 2 [N m s / rad]"),
        Parameter("initial_speed", 0.0, -1e4, 1e4, "sprocket speed omega0 of the rigid start [rad/s]"),
        Parameter("t_end", 0.1, 1e-6, 1e3, "end of the time span [s]"),
    )
    benchmark_parameters = ({"n_links": 30}, {"n_links": 150})
    # DOP853 on the underlying ODE (at 30 links it agrees with itself at rtol 1e-13
    # to 11.3 digits) checked by IDA on the stabilized index-2 form: independent
    # formulations and methods (explicit RK of order 8, implicit BDF); IDA at
    # rtol 1e-13 is the less accurate of the two and bounds the claim
    reference_methods = (("ode", "scipy-DOP853", 1e-12), ("ggl", "ida", 1e-13))
    position_scale = 0.1
    velocity_scale = 1.0
    lambda_scale = 1.0

    def __init__(self, **params):
        super().__init__(**params)
        p = self.params
        n, z = int(round(p["n_links"])), int(round(p["teeth"]))
        if n != p["n_links"] or z != p["teeth"] or z % 2:
            raise ProblemError("chain_drive: n_links must be an integer and teeth an even integer")
        if (n - z) % 2 or n - z < 2:
            raise ProblemError(f"chain_drive: n_links - teeth = {n - z} must be even and >= 2 "
                               "(two straight spans of (n_links - teeth) / 2 links)")
        self.n, self.z, self.m = n, z, (n - z) // 2
        self.h = p["pitch"] / 2
        self.radius = p["pitch"] / (2 * np.sin(np.pi / z))
        self.contact_radius = self.radius + (2 * p["pretension"] * np.sin(np.pi / z)
                                             / p["stiffness"]) ** (1 / p["exponent"])
        self.centres = np.array([[0.0, 0.0], [self.m * p["pitch"], 0.0]])
        self.t_span = (0.0, p["t_end"])
        self._set_components()
        self._structure()

    def _set_components(self):
        coords = tuple(f"{c}{i}" for i in range(self.n) for c in ("x", "y", "th")) + ("phi1", "phi2")
        self.coordinates = coords
        self.n_constraints = 2 * self.n
        self.components = (coords + tuple(f"v_{c}" for c in coords)
                           + tuple(f"lam{i + 1}" for i in range(self.n_constraints)))
        self.error_components = coords
        self.velocity_components = tuple(f"v_{c}" for c in coords)
        self.lambda_components = tuple(f"lam{i + 1}" for i in range(self.n_constraints))
        self.atol_scale = ((self.position_scale,) * len(coords) + (self.velocity_scale,) * len(coords)
                           + (self.lambda_scale,) * self.n_constraints)

    # ------------------------------------------------------------ sparsity
    def _structure(self):
        """Row and column indices of the sparse matrices (fixed pattern)."""
        n = self.n
        i = np.arange(n)
        j = (i + 1) % n
        # G: row 2i (x) at x_i, th_i, x_j, th_j; row 2i+1 (y) at y_i, th_i, y_j, th_j
        self._g_rows = np.repeat(np.stack([2 * i, 2 * i + 1], 1), 4, axis=1).ravel()
        self._g_cols = np.stack([3 * i, 3 * i + 2, 3 * j, 3 * j + 2,
                                 3 * i + 1, 3 * i + 2, 3 * j + 1, 3 * j + 2], 1).ravel()
        a = 3 * i[:, None, None] + np.arange(3)[None, :, None]
        b = 3 * i[:, None, None] + np.arange(3)[None, None, :]
        self._blk_rows = np.broadcast_to(a, (n, 3, 3)).ravel()
        self._blk_cols = np.broadcast_to(b, (n, 3, 3)).ravel()
        k = np.arange(2)[:, None, None]
        link_dofs = np.broadcast_to(3 * i[None, :, None] + np.arange(3)[None, None, :], (2, n, 3))
        sprocket = np.broadcast_to(3 * n + k, (2, n, 3))
        self._tq_rows, self._tq_cols = sprocket.ravel(), link_dofs.ravel()
        self._diag_m = np.concatenate([np.tile([self.params["link_mass"]] * 2
                                               + [self.params["link_inertia"]], n),
                                       [self.params["sprocket_inertia"]] * 2])
        self._mass = sp.diags(self._diag_m, format="csr")

    def _csr(self, rows, cols, data):
        nq = self.nq
        return sp.csr_matrix((data, (rows, cols)), shape=(nq, nq))

    # ------------------------------------------------------------ geometry
    def _links(self, q):
        """x, y, theta of the links, each (..., N)."""
        L = np.asarray(q, float)[..., :3 * self.n].reshape(np.shape(q)[:-1] + (self.n, 3))
        return L[..., 0], L[..., 1], L[..., 2]

    def _pins(self, q, v):
        """Back pins B (..., N, 2), their velocities U, cos and sin of theta, omega."""
        x, y, th = self._links(q)
        vx, vy, om = self._links(v)
        c, s = np.cos(th), np.sin(th)
        h = self.h
        B = np.stack([x - h * c, y - h * s], -1)
        U = np.stack([vx + h * s * om, vy - h * c * om], -1)
        return B, U, c, s, om

    def _contact(self, B, U, omega_s):
        """Per (sprocket, pin) contact quantities, arrays of shape (..., 2, N).

        ``omega_s`` is (..., 2), the sprocket speeds.
        """
        p = self.params
        r = B[..., None, :, :] - self.centres[:, None, :]
        rho = np.hypot(r[..., 0], r[..., 1])
        n = r / rho[..., None]
        t = np.stack([-n[..., 1], n[..., 0]], -1)
        u = U[..., None, :, :]
        delta = self.contact_radius - rho
        dp = np.maximum(delta, 0.0)
        k, e = p["stiffness"], p["exponent"]
        nel = k * dp**e
        dnel = e * k * dp ** (e - 1)
        stp, dstp = step(delta, 0.0, 0.0, p["damping_depth"], 1.0)
        ddelta = -np.einsum("...i,...i->...", n, u)
        ut = np.einsum("...i,...i->...", t, u)
        vslip = ut - rho * omega_s[..., :, None]
        phi = np.tanh(vslip / p["friction_velocity"])
        fn = nel + p["damping"] * stp * ddelta
        ft = -p["friction"] * nel * phi
        return dict(rho=rho, n=n, t=t, u=u, nel=nel, dnel=dnel, stp=stp, dstp=dstp,
                    ddelta=ddelta, ut=ut, phi=phi, fn=fn, ft=ft)

    # ------------------------------------------------------------ the model
    def start(self):
        """Wrapped chain (pins on the pitch circles) in rigid motion at ``initial_speed``."""
        P, U = self._start_pins()
        d = np.roll(P, -1, axis=0) - P
        centre = P + d / 2
        th = np.arctan2(d[:, 1], d[:, 0])
        dU = np.roll(U, -1, axis=0) - U
        om = (d[:, 0] * dU[:, 1] - d[:, 1] * dU[:, 0]) / self.params["pitch"] ** 2
        vc = (U + np.roll(U, -1, axis=0)) / 2
        w0 = self.params["initial_speed"]
        q = np.concatenate([np.column_stack([centre, th]).ravel(), [0.0, 0.0]])
        v = np.concatenate([np.column_stack([vc, om]).ravel(), [w0, w0]])
        return q, v

    def _start_pins(self):
        """Pins counter-clockwise from the bottom of sprocket 2, and their velocities."""
        z, m, R, p = self.z, self.m, self.radius, self.params["pitch"]
        w0 = self.params["initial_speed"]
        a = 2 * np.pi * np.arange(z // 2) / z
        arc2 = self.centres[1] + R * np.column_stack([np.cos(a - np.pi / 2), np.sin(a - np.pi / 2)])
        top = np.column_stack([self.centres[1, 0] - p * np.arange(m), np.full(m, R)])
        arc1 = R * np.column_stack([np.cos(a + np.pi / 2), np.sin(a + np.pi / 2)])
        bottom = np.column_stack([p * np.arange(m), np.full(m, -R)])
        P = np.vstack([arc2, top, arc1, bottom])
        rel = np.vstack([arc2 - self.centres[1], np.zeros((m, 2)), arc1, np.zeros((m, 2))])
        U = w0 * np.column_stack([-rel[:, 1], rel[:, 0]])
        U[z // 2:z // 2 + m] = [-R * w0, 0.0]
        U[z + m:] = [R * w0, 0.0]
        return P, U

    def mass(self, q):
        """The constant diagonal mass matrix (one CSR matrix, built once: callers
        must not modify it)."""
        return self._mass


    def mass_q(self, q, a):
        return sp.csr_matrix((self.nq, self.nq))

    def constraint(self, q):
        x, y, th = self._links(q)
        h = self.h
        c, s = np.cos(th), np.sin(th)
        roll = lambda w: np.roll(w, -1, axis=-1)  # noqa: E731
        gx = x - roll(x) + h * (c + roll(c))
        gy = y - roll(y) + h * (s + roll(s))
        return np.stack([gx, gy], -1).reshape(np.shape(q)[:-1] + (2 * self.n,))

    def constraint_jac(self, q):
        _, _, th = self._links(q)
        h = self.h
        c, s = np.cos(th), np.sin(th)
        cj, sj = np.roll(c, -1), np.roll(s, -1)
        one = np.ones(self.n)
        data = np.stack([one, -h * s, -one, -h * sj, one, h * c, -one, h * cj], 1).ravel()
        return sp.csr_matrix((data, (self._g_rows, self._g_cols)), shape=(self.nc, self.nq))

    def gv_q(self, q, v):
        _, _, th = self._links(q)
        _, _, om = self._links(v)
        h = self.h
        c, s = np.cos(th), np.sin(th)
        zero = np.zeros(self.n)
        co, so = c * om, s * om
        data = np.stack([zero, -h * co, zero, -h * np.roll(co, -1),
                         zero, -h * so, zero, -h * np.roll(so, -1)], 1).ravel()
        return sp.csr_matrix((data, (self._g_rows, self._g_cols)), shape=(self.nc, self.nq))

    def accel_term(self, q, v):
        _, _, th = self._links(q)
        _, _, om = self._links(v)
        h = self.h
        cw, sw = np.cos(th) * om**2, np.sin(th) * om**2
        ax = -h * (cw + np.roll(cw, -1, axis=-1))
        ay = -h * (sw + np.roll(sw, -1, axis=-1))
        return np.stack([ax, ay], -1).reshape(np.shape(q)[:-1] + (2 * self.n,))

    def gt_q(self, q, lam):
        _, _, th = self._links(q)
        lam = np.asarray(lam, float).reshape(self.n, 2)
        both = lam + np.roll(lam, 1, axis=0)      # constraint i (front) and i - 1 (back)
        diag = -self.h * (np.cos(th) * both[:, 0] + np.sin(th) * both[:, 1])
        blocks = np.zeros((self.n, 3, 3))
        blocks[:, 2, 2] = diag
        return self._csr(self._blk_rows, self._blk_cols, blocks.ravel())

    def _drive(self, t, omega_s):
        """Torques (drive, load) on the sprockets; ``omega_s`` (..., 2)."""
        p = self.params
        ramp, _ = step(t, 0.0, 0.0, p["ramp_time"], 1.0)
        tau1 = ramp * (p["drive_torque"] + p["drive_gain"] * p["drive_speed"]) \
            - p["drive_gain"] * omega_s[..., 0]
        return np.stack([tau1, -p["load_damping"] * omega_s[..., 1]], -1)

    def force(self, t, q, v):
        q, v = np.asarray(q, float), np.asarray(v, float)
        B, U, c, s, _ = self._pins(q, v)
        omega_s = v[..., 3 * self.n:]
        ct = self._contact(B, U, omega_s)
        F = (ct["fn"][..., None] * ct["n"] + ct["ft"][..., None] * ct["t"]).sum(-3)   # (..., N, 2)
        h = self.h
        f_links = np.stack([F[..., 0], F[..., 1] - self.params["link_mass"] * self.params["gravity"],
                            h * (s * F[..., 0] - c * F[..., 1])], -1)
        tau = -(ct["rho"] * ct["ft"]).sum(-1) + self._drive(np.asarray(t, float), omega_s)
        return np.concatenate([f_links.reshape(q.shape[:-1] + (3 * self.n,)), tau], -1)

    def _contact_derivatives(self, ct, omega_s):
        """dF/dP, dF/du (2, N, 2, 2), dF/domega (2, N, 2) of the pin force and
        dtau/dP, dtau/du (2, N, 2), dtau/domega (2, N) of the sprocket torque."""
        p = self.params
        mu, c_max, veps = p["friction"], p["damping"], p["friction_velocity"]
        n, t, rho = ct["n"], ct["t"], ct["rho"]
        ut, un = ct["ut"], -ct["ddelta"]
        nt = n[..., :, None] * t[..., None, :]
        tt = t[..., :, None] * t[..., None, :]
        dphi = (1 - ct["phi"] ** 2) / veps
        # scalar gradients, each (..., 2) over P or u
        ddelta_dP = -n
        dddelta_dP = -(ut / rho)[..., None] * t
        dvslip_dP = -(un / rho)[..., None] * t - omega_s[:, None, None] * n
        dnel_dP = ct["dnel"][..., None] * ddelta_dP
        dfn_dP = dnel_dP + c_max * (ct["dstp"] * ct["ddelta"])[..., None] * ddelta_dP \
            + c_max * ct["stp"][..., None] * dddelta_dP
        dft_dP = -mu * (dnel_dP * ct["phi"][..., None]
                        + (ct["nel"] * dphi)[..., None] * dvslip_dP)
        dfn_du = -c_max * ct["stp"][..., None] * n
        dft_du = -mu * (ct["nel"] * dphi)[..., None] * t
        dft_dw = mu * ct["nel"] * dphi * rho
        outer = lambda a, b: a[..., :, None] * b[..., None, :]  # noqa: E731
        dF_dP = (outer(n, dfn_dP) + (ct["fn"] / rho)[..., None, None] * tt
                 + outer(t, dft_dP) - (ct["ft"] / rho)[..., None, None] * nt)
        dF_du = outer(n, dfn_du) + outer(t, dft_du)
        dF_dw = t * dft_dw[..., None]
        dtau_dP = -(n * ct["ft"][..., None] + rho[..., None] * dft_dP)
        dtau_du = -rho[..., None] * dft_du
        dtau_dw = -rho * dft_dw
        return dF_dP, dF_du, dF_dw, dtau_dP, dtau_du, dtau_dw

    def _jacobians(self, t, q, v):
        """force_q and force_v."""
        q, v = np.asarray(q, float), np.asarray(v, float)
        B, U, c, s, om = self._pins(q, v)
        omega_s = v[3 * self.n:]
        ct = self._contact(B, U, omega_s)
        dF_dP, dF_du, dF_dw, dtau_dP, dtau_du, dtau_dw = self._contact_derivatives(ct, omega_s)
        h, n = self.h, self.n
        Bm = np.zeros((n, 2, 3))            # dB/d(x, y, theta) = du/d(vx, vy, omega)
        Bm[:, 0, 0] = Bm[:, 1, 1] = 1.0
        Bm[:, 0, 2], Bm[:, 1, 2] = h * s, -h * c
        W = np.zeros((n, 2, 3))             # du/d(x, y, theta): theta column only
        W[:, 0, 2], W[:, 1, 2] = h * c * om, h * s * om
        dFq = np.einsum("knab,nbc->knac", dF_dP, Bm) + np.einsum("knab,nbc->knac", dF_du, W)
        F = (ct["fn"][..., None] * ct["n"] + ct["ft"][..., None] * ct["t"]).sum(0)
        blk_q = np.einsum("nai,nac->nic", Bm, dFq.sum(0))
        blk_q[:, 2, 2] += h * (c * F[:, 0] + s * F[:, 1])
        blk_v = np.einsum("nai,nac->nic", Bm, np.einsum("knab,nbc->nac", dF_du, Bm))
        tq = np.einsum("kna,nac->knc", dtau_dP, Bm) + np.einsum("kna,nac->knc", dtau_du, W)
        tv = np.einsum("kna,nac->knc", dtau_du, Bm)
        cpl = np.einsum("nai,kna->kni", Bm, dF_dw)        # link force rows, sprocket columns
        p = self.params
        diag = dtau_dw.sum(1) - np.array([p["drive_gain"], p["load_damping"]])
        sprock = 3 * n + np.arange(2)
        fq = self._csr(np.concatenate([self._blk_rows, self._tq_rows]),
                       np.concatenate([self._blk_cols, self._tq_cols]),
                       np.concatenate([blk_q.ravel(), tq.ravel()]))
        fv = self._csr(np.concatenate([self._blk_rows, self._tq_rows, self._tq_cols, sprock]),
                       np.concatenate([self._blk_cols, self._tq_cols, self._tq_rows, sprock]),
                       np.concatenate([blk_v.ravel(), tv.ravel(), cpl.ravel(), diag]))
        return fq, fv

    def force_derivatives(self, t, q, v):
        """``(force_q, force_v)`` from one evaluation of the contact quantities."""
        return self._jacobians(t, q, v)

    def force_q(self, t, q, v):
        return self._jacobians(t, q, v)[0]

    def force_v(self, t, q, v):
        return self._jacobians(t, q, v)[1]

    def evaluate_many(self, name, *args):
        """Vectors (``force``, ``constraint``, ``accel_term``) at many points in one
        vectorized call, shape (npoints, n); matrices as a list of sparse matrices
        (:meth:`MechanicalProblem.evaluate_many`)."""
        if name in ("force", "constraint", "accel_term"):
            return getattr(self, name)(*(np.asarray(a, float) for a in args))
        return super().evaluate_many(name, *args)

    # ------------------------------------------------------------ physics
    def energy(self, q, v):
        """Kinetic + gravity + contact potential ``k delta_+^(e+1) / (e+1)``; q, v (..., nq)."""
        p = self.params
        q, v = np.asarray(q, float), np.asarray(v, float)
        kinetic = 0.5 * np.sum(self._diag_m * v * v, -1)
        _, y, _ = self._links(q)
        B, _, _, _, _ = self._pins(q, v)
        r = B[..., None, :, :] - self.centres[:, None, :]
        dp = np.maximum(self.contact_radius - np.hypot(r[..., 0], r[..., 1]), 0.0)
        e = p["exponent"]
        contact = p["stiffness"] * np.sum(dp ** (e + 1), (-1, -2)) / (e + 1)
        return kinetic + p["link_mass"] * p["gravity"] * np.sum(y, -1) + contact

    def invariants(self):
        """Energy, conserved only with drive, load, damping and friction off."""
        p = self.params
        if p["drive_gain"] or p["drive_torque"] or p["load_damping"] or p["damping"] \
                or p["friction"]:
            return {}
        nq = self.nq
        return {"energy": lambda t, Y: self.energy(np.atleast_2d(Y)[:, :nq],
                                                   np.atleast_2d(Y)[:, nq:2 * nq])}
