"""The chain drive with bushings in place of its revolute joints: a stiff 6N-state ODE.

The compliant-joint variant of :mod:`integrator_bench.problems.models.chain_drive`:
the usual industrial alternative to constraints (Chrono's tracked
vehicles, e.g. the M113 single-pin track, join their shoes by bushings),
physically stiff. Geometry, start, contact, friction, gravity and drive are
:class:`~integrator_bench.problems.models.chain_drive.ChainDrive`'s (held as
``self.chain``); only the joints change.

Model
-----
The gap of joint j between the front pin of link j and the back pin of link
j + 1, ``g_j = F_j - B_{j+1}`` (a 2-vector; the chain drive's constraint), is
no longer held at zero but resisted by a linear bushing (a spring and a damper
between the two pins, isotropic in the plane)::

    lam_b = k_b g(q) + c_b G(q) v,      M q'' = f(t, q, v) - G(q)^T lam_b,

i.e. the chain drive's equations of motion with the multipliers replaced by
the bushing forces (a penalty formulation of the joints; as ``k_b`` grows the
solution tends to the constrained one, with joint gaps of order ``lam / k_b``).
There are no constraints: the state is ``y = (q, v)``, 2 (3N + 2) = 6N + 4
components, and the problem is an explicit ODE ``q' = v``,
``v' = M^-1 (f - G^T lam_b)`` with M diagonal. Its Jacobian is analytic and
sparse (block tridiagonal over the links, plus the sprocket rows and
columns)::

    d(G^T lam_b)/dq = (d(G^T lam)/dq)|_{lam = lam_b} + G^T (k_b G + c_b d(G v)/dq),
    d(G^T lam_b)/dv = c_b G^T G,

from the chain drive's ``gt_q``, ``constraint_jac`` and ``gv_q``. The ``ode``
system also carries the second-order form ``M q'' = f - G^T lam_b`` with no
constraints (``nc = 0``; tangent ``K = -df/dq``, ``C = -df/dv``), so that
HHT, Newmark and generalized-alpha, the methods industrial codes use on
compliant mechanisms, run beside the first-order codes. The bushing
stores ``k_b |g|^2 / 2``; with drive, load, contact damping, friction and
bushing damping off, the energy (kinetic, gravity, contact and bushing) is
conserved.

No rotational bushing: a roller chain's pin turns freely in its bushing (the
revolute joint's free rotation is kept); Chrono's track shoes add a torsional
spring of 300 N m/rad for the rubber bushing, which would give the chain a
bending stiffness and a stress-free shape, neither of which the chain drive has.

Bushing values. Chrono's M113 single-pin track: 3.5e7 N/m and
300 N m/rad for shoes of 18 kg at pitch 0.154 m. We keep
``k_b = 3.5e7 N/m`` for Exudyn's 4.32 g links: it is of the order of a steel
roller chain link's longitudinal stiffness (side plates of about
2 x 1 mm x 10 mm of steel over the 30 mm pitch: EA/p ~ 1.4e8 N/m), its
joints' highest frequency ``2 sqrt(k_b / m_l) = 1.8e5 rad/s`` (29 kHz) is
about 90 times the contact's ``sqrt(k_t / m_l) = 2.1e3 rad/s``
(``k_t = e k delta0^(e-1) = 1.9e4 N/m`` at the pretension depth) and 10^4
times the span's transverse frequencies (15-30 Hz), so the system is stiff,
and the joint gaps under the 5 N pretension, ``T / k_b = 1.4e-7 m``, are
5e-6 of the pitch. The damping ``c_b = 20 N s/m`` damps the highest joint
mode (neighbouring pins in antiphase: ``m_l x'' = -4 k_b x - 4 c_b x'``) at the
ratio ``c_b / sqrt(k_b m_l) = 0.05`` and the lower modes less (it is
stiffness-proportional, ``c_b / k_b = 5.7e-7 s``): lightly damped fast
oscillations, physical stiffness in the sense of the ADAMS seminar (seed 000;
problems/models/two_mass.py), not the overdamped numerical kind.

The start is the chain drive's: the wrapped chain in rigid motion, with
``g = 0`` and ``G v = 0`` exactly, so the bushings start unloaded and the
pretension loads them within the first contact periods.
"""

from __future__ import annotations

import numpy as np

from integrator_bench.problems.base import Parameter, ProblemError
from integrator_bench.problems.models.chain_drive import ChainDrive
from integrator_bench.problems.second_order import SecondOrderProblem

#: Chrono M113 single-pin track bushing stiffness [N/m]
BUSHING_STIFFNESS = 3.5e7
#: c_b = 0.05 sqrt(k_b m_l) for Exudyn's 4.32 g links, rounded [N s/m]
BUSHING_DAMPING = 20.0


class ChainBushing(SecondOrderProblem):
    """Closed chain of rigid links joined by linear bushings; see the module docstring."""

    name = "chain_bushing"
    description = "Chain drive with bushings in place of the revolute joints (stiff 6N-state ODE)"
    source = ("chain_drive (MSC.ADAMS/Solver seminar, seed 000; Exudyn chainDriveExample.py) "
              "with bushings after Chrono's M113 single-pin track (projectchrono/chrono)")
    sparse = True
    parameters = ChainDrive.parameters + (
        Parameter("bushing_stiffness", BUSHING_STIFFNESS, 1.0, 1e15,
                  "bushing stiffness k_b on the joint gap [N/m]"),
        Parameter("bushing_damping", BUSHING_DAMPING, 0.0, 1e9,
                  "bushing damping c_b on the joint gap rate [N s/m]"),
    )
    benchmark_parameters = ({"n_links": 30}, {"n_links": 150})
    # variable-order BDF (CVODE, analytic sparse Jacobian) checked by explicit RK of
    # order 8 (DOP853): independent methods and codes. CVODE at 1e-12 agrees worse than
    # at 1e-11 (round-off in its BDF history), and the lightly damped 29 kHz joint modes
    # must be resolved, so each tighter decade costs much more (docs/study-chains.md,
    # "Compliant joints", has the digits and CPU times measured)
    reference_methods = (("ode", "cvode-bdf", 1e-11), ("ode", "scipy-DOP853", 1e-9))
    # what the pair reaches on the link angles, the worst positions (docs/study-chains.md)
    reference_digits = 9

    def __init__(self, **params):
        super().__init__(**params)
        chain_names = {p.name for p in ChainDrive.parameters}
        try:
            self.chain = ChainDrive(**{k: v for k, v in self.params.items() if k in chain_names})
        except ProblemError as exc:
            raise ProblemError(str(exc).replace(ChainDrive.name, self.name)) from None
        c = self.chain
        self.n, self.nq = c.n, c.nq
        self.t_span = c.t_span
        coords = c.coordinates
        self.coordinates = coords
        self.components = coords + tuple(f"v_{x}" for x in coords)
        self.error_components = coords
        self.velocity_components = tuple(f"v_{x}" for x in coords)
        self.atol_scale = ((c.position_scale,) * len(coords) + (c.velocity_scale,) * len(coords))
        self._inv_m = 1.0 / c._diag_m

    # ------------------------------------------------------------ the model
    def start(self):
        """The chain drive's wrapped start: bushings unloaded (g = 0, G v = 0)."""
        return self.chain.start()

    def bushing_force(self, q, v):
        """``lam_b = k_b g + c_b G v``, (2N,): the force of bushing j on the front pin
        of link j is ``-lam_b[2j:2j+2]``."""
        p = self.params
        return p["bushing_stiffness"] * self.chain.constraint(q) \
            + p["bushing_damping"] * (self.chain.constraint_jac(q) @ v)

    def force(self, t, q, v):
        """Applied forces of the chain drive plus the bushings, ``f - G^T lam_b``."""
        q, v = np.asarray(q, float), np.asarray(v, float)
        return self.chain.force(t, q, v) - self.chain.constraint_jac(q).T @ self.bushing_force(q, v)

    def _jacobians(self, t, q, v):
        c, p = self.chain, self.params
        kb, cb = p["bushing_stiffness"], p["bushing_damping"]
        fq, fv = c._jacobians(t, q, v)
        G = c.constraint_jac(q)
        Gt = G.T.tocsr()
        fq = fq - c.gt_q(q, self.bushing_force(q, v)) - Gt @ (kb * G + cb * c.gv_q(q, v))
        fv = fv - cb * (Gt @ G)
        return fq.tocsr(), fv.tocsr()

    # ------------------------------------------------------------ physics
    def joint_gaps(self, Q):
        """|g_j| of every joint, (..., N)."""
        g = self.chain.constraint(np.asarray(Q, float))
        return np.linalg.norm(g.reshape(g.shape[:-1] + (self.n, 2)), axis=-1)

    def energy(self, q, v):
        """The chain drive's energy plus the bushings' ``k_b |g|^2 / 2``; q, v (..., nq)."""
        q = np.asarray(q, float)
        g = self.chain.constraint(q)
        return self.chain.energy(q, v) + 0.5 * self.params["bushing_stiffness"] * np.sum(g * g, -1)

    def invariants(self):
        """Energy, conserved only with drive, load, all damping and friction off."""
        p = self.params
        if p["drive_gain"] or p["drive_torque"] or p["load_damping"] or p["damping"] \
                or p["friction"] or p["bushing_damping"]:
            return {}
        nq = self.nq
        return {"energy": lambda t, Y: self.energy(np.atleast_2d(Y)[:, :nq],
                                                   np.atleast_2d(Y)[:, nq:2 * nq])}
