"""The chain drive (problems/models/chain_drive.py): analytic sparse derivatives, the
consistent start, the O(N) memory of the model at N = 1000, and physics checks
(energy, chain speed, link-passing frequency) on short runs at N = 20-30.

The runs integrate the underlying ODE with a sparse augmented solve written
here (``[[M, G^T], [G, 0]] [a; lam] = [f; -(dGv/dq) v]``), so they do not
depend on the formulation generator's sparse support.
"""

import time
import tracemalloc

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.integrate import solve_ivp

from integrator_bench.problems.base import ProblemError
from integrator_bench.problems.models.chain_drive import ChainDrive

from derivative_checks import check_model_derivatives  # noqa: E402


def pin_distances(p, q):
    """Distances (2, N) of the back pins from the two sprocket centres."""
    B = p._pins(q, np.zeros_like(q))[0]
    return np.linalg.norm(B[None] - p.centres[:, None], axis=-1)


def simulate(p, t_end, n_out, method="DOP853", rtol=1e-9):
    q0, v0 = p.start()          # consistent to round-off (test_start_is_consistent_to_round_off)
    nq = p.nq

    def fun(t, y):
        return np.concatenate([y[nq:], p.accelerations(t, y[:nq], y[nq:])[0]])

    t_eval = np.linspace(0.0, t_end, n_out)
    sol = solve_ivp(fun, (0.0, t_end), np.concatenate([q0, v0]), method=method, rtol=rtol,
                    atol=rtol * 1e-2, t_eval=t_eval)
    assert sol.status == 0, sol.message
    return sol.t, sol.y[:nq].T, sol.y[nq:].T


def test_derivatives_match_finite_differences():
    # pins near both sprockets, some inside the damping ramp (depth 1e-3 m), moving
    p = ChainDrive(n_links=10, teeth=6, initial_speed=3.0, damping_depth=1e-3)
    rng = np.random.default_rng(1)
    q0, v0 = p.start()
    q = q0 + 1e-3 * rng.standard_normal(p.nq)
    v = v0 + rng.standard_normal(p.nq)
    a, lam = rng.standard_normal(p.nq), rng.standard_normal(p.nc)
    delta = p.contact_radius - pin_distances(p, q)
    assert np.sum((delta > 0) & (delta < 1e-3)) >= 2 and np.sum(delta >= 1e-3) >= 2
    t = 0.3 * p.params["ramp_time"]        # inside the drive ramp
    for name, args in (("constraint_jac", (q,)), ("gv_q", (q, v)), ("force_q", (t, q, v)),
                       ("force_v", (t, q, v)), ("mass_q", (q, a)), ("gt_q", (q, lam))):
        assert sp.issparse(getattr(p, name)(*args)), name
    check_model_derivatives(p, t, q, v, a, lam)
    assert p.mass(q).shape == (p.nq, p.nq) and p.force(t, q, v).shape == (p.nq,)


def test_vectors_at_many_points_equal_the_model_point_by_point():
    p = ChainDrive(n_links=12, teeth=8, initial_speed=2.0)
    rng = np.random.default_rng(2)
    q0, v0 = p.start()
    Q = q0 + 1e-3 * rng.standard_normal((5, p.nq))
    V = v0 + rng.standard_normal((5, p.nq))
    t = rng.uniform(0, 0.1, 5)
    for name, args in (("force", (t, Q, V)), ("constraint", (Q,)), ("accel_term", (Q, V))):
        one = np.array([getattr(p, name)(*row) for row in zip(*args)])
        np.testing.assert_allclose(p.evaluate_many(name, *args), one, rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("speed", [0.0, 5.0])
def test_start_is_consistent_to_round_off(speed):
    p = ChainDrive(n_links=30, initial_speed=speed)
    q_start, v_start = p.start()
    assert np.max(np.abs(p.constraint(q_start))) < 1e-15
    assert np.max(np.abs(p.constraint_jac(q_start) @ v_start)) < 1e-14 * max(1.0, speed)
    q, v, _, _ = p.consistent_start()        # the projection moves nothing noticeable
    assert np.max(np.abs(q - q_start)) < 1e-15 and np.max(np.abs(v - v_start)) < 1e-14
    # pins on the pitch circles: the wrapped ones penetrate the contact circle by the pretension depth
    rho = pin_distances(p, q)
    assert np.sum(np.isclose(rho, p.radius, rtol=1e-14)) == p.z + 2   # z/2 + 1 pins on each sprocket


def test_parameters_that_do_not_close_the_chain_are_rejected():
    with pytest.raises(ProblemError):
        ChainDrive(n_links=31)               # 31 - 16 odd: spans unequal
    with pytest.raises(ProblemError):
        ChainDrive(n_links=30, teeth=15)     # odd teeth: no half wrap


def test_energy_is_conserved_without_drive_load_damping_and_friction():
    """Gravity, contact (pretension 5 N, Hertz 1.5) and the chain moving at 5 rad/s.

    The energy drifts only by the integration error: DOP853 at rtol 1e-10 over
    0.03 s gives a relative error measured at 1.8e-11 (3e-9 over 0.1 s at N = 30);
    we allow 1e-8, room for another platform's step sequence, and still far
    below what a wrong contact potential or force sign would give (the contact
    potential, 1e-2 of the total here, varies by O(1) of itself).
    """
    p = ChainDrive(n_links=20, teeth=10, initial_speed=5.0, drive_gain=0.0, load_damping=0.0,
                   damping=0.0, friction=0.0)
    t, Q, V = simulate(p, 0.03, 31, rtol=1e-10)
    E = p.energy(Q, V)
    assert np.max(np.abs(E - E[0])) < 1e-8 * abs(E[0])
    assert np.max(np.abs(p.evaluate_many("constraint", Q))) < 1e-9   # stays on g = 0
    assert "energy" in p.invariants()


def _steady_drive(speed, t_end, n_out):
    """The 30-link drive started in rigid motion at the servo's speed (ramp 1 us)."""
    p = ChainDrive(n_links=30, drive_speed=speed, initial_speed=speed, ramp_time=1e-6,
                   gravity=0.0)
    return p, *simulate(p, t_end, n_out, rtol=1e-7)


def test_chain_speed_is_pitch_radius_times_sprocket_speed():
    """Mean span speed = R omega sin(pi/z)/(pi/z) (a polygon on a circle moves one
    pitch p = 2 R sin(pi/z) per tooth period 2 pi / (z omega)), within the friction creep.

    The pins slip on the sprocket by v_slip = v_eps artanh(F_t / (mu N)) < a few
    v_eps; we allow 2 v_eps / (R omega) (1.3 % at 20 rad/s) on top of the exact
    chordal factor (0.64 % for z = 16), averaging over whole tooth periods.
    Measured: ratio 0.99218 against the driver, 0.99936 against the driven
    sprocket (expected 0.99359 without creep).
    """
    speed = 20.0
    period = 2 * np.pi / (16 * speed)
    p, t, Q, V = _steady_drive(speed, 2 * period, 201)
    x, _, _ = p._links(Q)
    vx, vy, _ = p._links(V)
    span = (x > 0.25 * p.centres[1, 0]) & (x < 0.75 * p.centres[1, 0])
    chain_speed = np.array([np.mean(np.hypot(a[s], b[s])) for a, b, s in zip(vx, vy, span)])
    omega = V[:, -2:]
    z = p.z
    for k in range(2):
        ratio = np.mean(chain_speed) / (p.radius * np.mean(omega[:, k]))
        creep = 2 * p.params["friction_velocity"] / (p.radius * np.mean(omega[:, k]))
        assert abs(ratio - np.sin(np.pi / z) / (np.pi / z)) < creep, (k, ratio)


def test_link_passing_frequency_in_the_joint_forces():
    """The sum of the joint force magnitudes is periodic with the tooth (link-passing)
    period 2 pi / (z omega): the configuration repeats up to relabelling of links.

    Over 0.05 s (5 tooth periods at 40 rad/s; FFT bins 20 Hz), above half the
    link-passing frequency f_pass (below it lie the slow modes excited by the
    start, which is not in equilibrium), the largest spectral peak lies within
    one bin of a harmonic k f_pass, k = 1 or 2. With both sprockets in mirror
    phase the second harmonic is the largest. Only 42 % of the whole
    fluctuation's energy lies at the harmonics over this short window, so the
    check is on the peak, not on the energy fraction.
    """
    speed = 40.0
    p, t, Q, V = _steady_drive(speed, 0.05, 201)
    lam = np.array([p.accelerations(ti, q, v)[1] for ti, q, v in zip(t, Q, V)])
    total = np.linalg.norm(lam.reshape(len(t), -1, 2), axis=2).sum(1)
    power = np.abs(np.fft.rfft((total - total.mean()) * np.hanning(len(t)))) ** 2
    freq = np.fft.rfftfreq(len(t), t[1] - t[0])
    f_pass = np.mean(V[:, -2]) * p.z / (2 * np.pi)
    above = freq > f_pass / 2
    f_peak = freq[above][np.argmax(power[above])]
    k = np.round(f_peak / f_pass)
    assert k in (1, 2) and abs(f_peak - k * f_pass) <= freq[1], (f_peak, f_pass)


def test_thousand_links_build_and_evaluate_in_linear_memory():
    p = ChainDrive(n_links=1000)
    q, v, = p.start()
    assert p.nq == 3002 and p.nc == 2000
    dense_bytes = 8 * p.nq * p.nq          # 72 MB for one dense nq x nq matrix
    tracemalloc.start()
    try:
        f, g = p.force(0.01, q, v), p.constraint(q)
        G, M = p.constraint_jac(q), p.mass(q)
        Fq, Fv = p.force_q(0.01, q, v), p.force_v(0.01, q, v)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < dense_bytes / 20, peak
    assert f.shape == (p.nq,) and g.shape == (p.nc,)
    for A in (G, M, Fq, Fv):
        assert sp.issparse(A) and A.nnz <= 20 * p.nq
    t0 = time.process_time()
    p.force(0.01, q, v)
    p.constraint_jac(q)
    assert time.process_time() - t0 < 0.5
