"""Transverse vibrations of a free span of the chain drive against the taut string.

The physics check "small transverse vibrations of a free span match the
taut-string frequencies (n / 2L) sqrt(T / rho)" on Exudyn's 30-link drive
(problems/models/chain_drive.py: z = 16, m = 7 links per span, pitch p = 0.03 m) with
drive, load, friction, gravity and contact damping off.

Set-up
------
* Static equilibrium: the wrapped start is not quite in equilibrium (the
  tangent pins are pushed out as hard as the wrapped ones), so Newton on
  ``f(q) - G^T lam = 0, g(q) = 0`` (link coordinates; the sprockets feel no
  torque without friction, drive and load) finds it first. The span tension T
  is then read from the multipliers of the span's joints, ``|lam_j|`` (the
  joint force), and checked against the accelerations solve at rest; it is
  5.2655 N, not the nominal pretension 5 N (the contact radius is set for
  wrapped pins of an ideal polygon; the tangent pins and the elastic arcs
  shift it). Using 5 N instead would shift the predictions by 2.6 %.
* Perturbation: the interior pins of the upper span (pins z/2 + j,
  j = 1 .. m - 1; the span runs from pin z/2 on top of sprocket 2 to pin
  z/2 + m on top of sprocket 1, length L = m p, the centre distance) get the
  transverse velocity ``A omega sin(j n pi / m)`` (A = 0.2 mm), the link
  velocities follow from the pin velocities of rigid links, then projected
  onto G v = 0 by the harness's M-weighted projection.
* Integration: the ``ggl`` formulation (the harness's own, sparse) with IDA
  from the integrator registry at rtol 1e-8, about 3.3 periods.
* Frequency: the modal coordinate ``a_n(t)``, the least-squares projection of
  the pins' transverse displacement onto ``sin(j n pi / m)`` (the mid-span
  displacement for n = 1, filtered of the other modes; for n = 2 the mid-span
  is a node), its zero crossings located by linear interpolation on 1000
  outputs; f = (crossings - 1) / (2 (t_last - t_first)).

Predictions
-----------
The continuous string: ``f_n = (n / 2L) sqrt(T / rho)``, ``rho = m_l / p``.

The discrete chain: m rigid bars between m + 1 pins, ends fixed, pin
transverse displacements u_j. A bar between u_a and u_b has centre
displacement (u_a + u_b) / 2 and rotation (u_b - u_a) / p, so its kinetic
energy ``m_l/8 (u_a' + u_b')^2 + J/(2 p^2) (u_b' - u_a')^2`` with
``J = m_l p^2 (1 + eps) / 12`` (eps = w^2 / p^2 = 0.16 for the 12 mm wide
link) gives the bar mass matrix ``(m_l/12) [[4 + eps, 2 - eps], [2 - eps,
4 + eps]]`` (the consistent mass matrix of a linear finite element for
eps = 0); under tension T a bar tilted by (u_b - u_a) / p stores
``T (u_b - u_a)^2 / (2 p)`` (the tension does work T p (1 - cos alpha)),
stiffness ``(T/p) [[1, -1], [-1, 1]]``. With ``u_j = sin(j kappa)``,
``kappa = n pi / m``, the assembled rows give::

    omega_n^2 = 12 T (1 - cos kappa) / (m_l p ((4 + eps) + (2 - eps) cos kappa)),

which tends to the string's ``(n pi / L)^2 T / rho`` as m grows. For m = 7 it
is 0.70 % (n = 1) and 2.79 % (n = 2) above the string.

Measured (IDA, rtol 1e-8): f_1 = 14.4559 Hz against 14.4988 discrete and
14.3975 string; f_2 = 29.5256 Hz against 29.5993 discrete and 28.7950 string.

Tolerance
---------
1 % of the discrete prediction for n = 1 and 2, and 1 % of the continuous
string formula for n = 1 (where the discreteness correction is 0.7 %). What
the ideal string ignores: the sprockets are no rigid supports. The tangent
pins sit on the compliant Hertz contact (tangent stiffness
k_t = e k delta^(e-1) ~ 1.9e4 N/m at the pretension depth 1.6e-4 m), so the
transverse end conditions are springs and the span acts longer by about
T / k_t at each end: a frequency lower by ~ 2 T / (k_t L) = 0.27 %, which is
what is measured (-0.30 % and -0.25 % against the discrete chain); the wrapped
arcs move with the span as well. The nonlinear tension change at 0.2 mm
amplitude is below 1e-4 relative, the integration error below 1e-6 (the same
frequencies to 4 digits with DOP853 on the underlying ODE at rtol 1e-7). 1 %
is three times the measured end effect; a link mass wrong by 20 % moves the
frequencies by 9 % (measured 13.197 Hz for n = 1) and a tension taken as the
nominal 5 N by 2.6 %, both outside it.
"""

import numpy as np
import pytest
import scipy.sparse as sp

from integrator_bench.harness.matrix import registry
from integrator_bench.problems.models.chain_drive import ChainDrive

FREE = dict(n_links=30, drive_gain=0.0, load_damping=0.0, friction=0.0, gravity=0.0,
            damping=0.0)
AMPLITUDE = 2e-4         # transverse amplitude at the antinode [m]
PERIODS = 3.3
TOLERANCE = 0.01


def static_equilibrium(p, tol=1e-11, maxiter=30):
    """Newton (least squares, small N) on ``f(q) - G^T lam = 0``, ``g(q) = 0`` over the
    link coordinates, from the wrapped start; returns (q, lam)."""
    q, _, _, lam = p.consistent_start()
    nl, zero = 3 * p.n, np.zeros(p.nq)
    for _ in range(maxiter):
        G = p.constraint_jac(q)
        r = np.concatenate([(p.force(0.0, q, zero) - G.T @ lam)[:nl], p.constraint(q)])
        if np.max(np.abs(r)) < tol:
            return q, lam
        K = (p.force_q(0.0, q, zero) - p.gt_q(q, lam))[:nl, :nl]
        J = sp.bmat([[K, -G.T[:nl]], [G[:, :nl], None]]).toarray()
        step = np.linalg.lstsq(J, -r, rcond=1e-13)[0]
        q, lam = q.copy(), lam + step[nl:]
        q[:nl] += step[:nl]
    raise AssertionError(f"no static equilibrium: residual {np.max(np.abs(r)):.3g}")


def span_pins(p):
    """Indices of the pins of the upper span, from sprocket 2 to sprocket 1 (m + 1)."""
    return p.z // 2 + np.arange(p.m + 1)


def span_tension(p, q):
    """Tension of the upper span from the multipliers at rest: ``|lam_j|`` over its
    interior joints (joint j holds pin j + 1)."""
    a, lam = p.accelerations(0.0, q, np.zeros(p.nq))
    forces = np.hypot(*lam.reshape(-1, 2)[span_pins(p)[1:-1] - 1].T)
    return forces, a


def mode_velocity(p, q, n, omega):
    """Link velocities for pin transverse velocities ``A omega sin(j n pi / m)`` on the
    upper span, projected onto G v = 0."""
    j = np.arange(p.m + 1)
    U = np.zeros((p.n, 2))
    U[span_pins(p), 1] = AMPLITUDE * omega * np.sin(j * n * np.pi / p.m)
    P = p._pins(q, np.zeros(p.nq))[0]
    d, dU = np.roll(P, -1, axis=0) - P, np.roll(U, -1, axis=0) - U
    om = (d[:, 0] * dU[:, 1] - d[:, 1] * dU[:, 0]) / p.params["pitch"] ** 2
    vc = (U + np.roll(U, -1, axis=0)) / 2
    v = np.concatenate([np.column_stack([vc, om]).ravel(), [0.0, 0.0]])
    return p._project_velocities(q, v)


def measured_frequency(q_eq, n, f_guess, **params):
    """Integrate the perturbed span (ggl, IDA) and return the frequency of mode n."""
    q_eq = q_eq.copy()

    class Perturbed(ChainDrive):
        def start(self):
            return q_eq, mode_velocity(self, q_eq, n, 2 * np.pi * f_guess)

    p = Perturbed(**FREE, t_end=PERIODS / f_guess, **params)
    p.n_output = 1000
    system = p.formulate("ggl")
    sol = registry.integrators()["ida"]().solve(system, rtol=1e-8, atol=1e-8 * system.atol_scale)
    assert sol.success, sol.message
    pins = span_pins(p)
    y = p._pins(sol.y[:, :p.nq], np.zeros((len(sol.t), p.nq)))[0][:, pins, 1]
    y_eq = p._pins(q_eq, np.zeros(p.nq))[0][pins, 1]
    shape = np.sin(np.arange(p.m + 1) * n * np.pi / p.m)
    a = (y - y_eq) @ shape / (shape @ shape)
    assert 0.5 * AMPLITUDE < np.max(np.abs(a)) < 2 * AMPLITUDE       # the mode was excited
    i = np.flatnonzero(np.sign(a[:-1]) * np.sign(a[1:]) < 0)
    t = sol.t
    tz = t[i] - a[i] * (t[i + 1] - t[i]) / (a[i + 1] - a[i])
    assert len(tz) >= 5, len(tz)
    return (len(tz) - 1) / (2 * (tz[-1] - tz[0]))


@pytest.fixture(scope="module")
def equilibrium():
    p = ChainDrive(**FREE)
    q, _ = static_equilibrium(p)
    forces, a = span_tension(p, q)
    return p, q, forces, a


def test_span_tension_from_the_multipliers(equilibrium):
    """At rest in equilibrium the span's joint forces are one tension T, horizontal,
    near (not equal to) the pretension T0 = 5 N the contact radius was set for."""
    p, q, forces, a = equilibrium
    assert np.max(np.abs(a[:3 * p.n])) < 1e-6          # at rest: in equilibrium
    T = forces.mean()
    assert np.ptp(forces) < 1e-9 * T
    assert 0.9 * p.params["pretension"] < T < 1.2 * p.params["pretension"]


def string_frequencies(p, T, n):
    """(continuous string, discrete chain of m rigid bars) frequencies of mode n [Hz]."""
    ml, pitch, m = p.params["link_mass"], p.params["pitch"], p.m
    f_string = n / (2 * m * pitch) * np.sqrt(T / (ml / pitch))
    eps = 12 * p.params["link_inertia"] / (ml * pitch**2) - 1     # w^2 / p^2
    c = np.cos(n * np.pi / m)
    f_chain = np.sqrt(12 * T * (1 - c) / (ml * pitch * ((4 + eps) + (2 - eps) * c))) / (2 * np.pi)
    return f_string, f_chain


def test_discrete_chain_formula_tends_to_the_string():
    p = ChainDrive(n_links=16 + 2 * 400)
    f_string, f_chain = string_frequencies(p, 5.0, 1)
    assert abs(f_chain / f_string - 1) < 1e-5


@pytest.mark.parametrize("n", [1, 2])
def test_span_frequencies_match_the_taut_string(equilibrium, n):
    """Mode n of the upper span within 1 % of the discrete-chain prediction, and for
    n = 1 also of the continuous string (n / 2L) sqrt(T / rho); see the module docstring."""
    p, q, forces, _ = equilibrium
    f_string, f_chain = string_frequencies(p, forces.mean(), n)
    f = measured_frequency(q, n, f_chain)
    assert abs(f / f_chain - 1) < TOLERANCE, (f, f_chain, f_string)
    if n == 1:
        assert abs(f / f_string - 1) < TOLERANCE, (f, f_string)
