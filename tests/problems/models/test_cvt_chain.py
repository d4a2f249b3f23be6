"""The CVT-like chain (problems/models/cvt_chain.py): friction laws, analytic sparse
derivatives against finite differences, the friction eigenvalue formula and its
1/v0 scaling, the energy balance, the tension difference in steady drive, and
linear memory at 3,604 states."""

import json
import time
import tracemalloc

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.integrate import solve_ivp

from integrator_bench.harness.matrix import registry
from integrator_bench.problems.base import ProblemError
from integrator_bench.problems.models.cvt_chain import CvtChain, friction_law

from derivative_checks import fd  # noqa: E402


def test_friction_laws():
    u = np.linspace(-3, 3, 601)
    for smooth, sat in ((True, 2.0), (False, 1.0)):
        f, df = friction_law(u, smooth)
        assert friction_law(0.0, smooth)[1] == 1.0                  # f'(0) = 1
        np.testing.assert_array_equal(f[np.abs(u) >= sat], np.sign(u[np.abs(u) >= sat]))
        np.testing.assert_allclose(df, np.gradient(f, u), atol=0.02 if smooth else 1.0)
        assert np.all(np.abs(f) <= 1.0)
    # smooth law is C^1 at the joints u = +-2, the linear one has a kink at +-1
    fs, dfs = friction_law(np.array([2 - 1e-9, 2 + 1e-9]), True)
    assert abs(fs[1] - fs[0]) < 1e-8 and abs(dfs[1] - dfs[0]) < 1e-8
    fl, dfl = friction_law(np.array([1 - 1e-9, 1 + 1e-9]), False)
    assert abs(fl[1] - fl[0]) < 1e-8 and dfl[0] - dfl[1] == 1.0


def test_bad_parameters_are_refused():
    with pytest.raises(ProblemError, match=r"friction=0.5.*valid: 0 \(linear\), 1 \(smooth\)"):
        CvtChain(friction=0.5)
    with pytest.raises(ProblemError, match="n_pins=50.5"):
        CvtChain(n_pins=50.5)
    with pytest.raises(ProblemError, match="outside its range"):
        CvtChain(n_pins=39)                 # the chain must be longer than both wraps


def soft_point(friction, seed):
    """A soft chain (forces of like size) at a point with pins inside the wrap
    windows' transitions, halves in and out of contact (depths away from the
    d^(1/2) kink), both laws' linear zone and saturation in use."""
    p = CvtChain(n_pins=40, friction=friction, v0=0.3, v0_pulley=0.3, k_p=1e5,
                 k_hertz=1e7, pretension=100.0, torque=1.0, k_r=1e4)
    q, v = p.start()
    rng = np.random.default_rng(seed)
    N = p.n
    q = q.copy()
    q[:N] += rng.uniform(0, 0.01, N)
    w = rng.uniform(2e-4, 2e-3, 2 * N) * rng.choice([-1.0, 1.0], 2 * N)
    q[N:3 * N] = w
    v = v + 0.5 * rng.standard_normal(p.nq)
    s = np.arange(N) * p.pitch + q[:N]
    chi = p.window(s, 0)[0] + p.window(s, 1)[0]
    assert np.sum((chi > 0) & (chi < 1)) >= 2
    rel = (v[2 * N:3 * N] - v[N:2 * N]) / 0.3
    assert np.sum(np.abs(rel) < 1) >= 5 and np.sum(np.abs(rel) > 2) >= 5
    return p, q, v


@pytest.mark.parametrize("friction", [0, 1])
def test_force_derivatives_match_finite_differences(friction):
    p, q, v = soft_point(friction, 3)
    t = 0.001
    for analytic, numeric in ((p.force_q(t, q, v), fd(lambda x: p.force(t, x, v), q)),
                              (p.force_v(t, q, v), fd(lambda x: p.force(t, q, x), v))):
        assert sp.isspmatrix_csr(analytic)
        scale = max(1.0, np.max(np.abs(numeric)))
        np.testing.assert_allclose(analytic.toarray(), numeric, atol=1e-6 * scale, rtol=1e-6)


@pytest.mark.parametrize("friction", [0, 1])
def test_ode_jacobian_is_sparse_and_matches_finite_differences(friction):
    """Default stiffness; friction in the linear zone (v0 raised so the random
    speeds stay in it) and chain displaced along the path."""
    p = CvtChain(n_pins=40, friction=friction, v0=0.5, v0_pulley=0.5)
    y = p.initial_state().copy()
    rng = np.random.default_rng(1)
    y[:p.n] += rng.uniform(0, 0.005, p.n)
    y[p.nq:] += 0.1 * rng.standard_normal(p.nq)
    J = p.formulate("ode").jac(0.001, y)
    assert sp.issparse(J) and J.shape == (p.dimension, p.dimension)
    numeric = fd(lambda x: p.rhs(0.001, x), y, h=1e-9)
    np.testing.assert_allclose(J.toarray(), numeric, atol=1e-8 * np.max(np.abs(numeric)),
                               rtol=1e-5)


def test_most_negative_eigenvalue_follows_the_friction_formula():
    """Dense eigenvalues of the Jacobian at the start (40 pins): the most negative
    real part equals -2 mu T_max / (v0 m_h) (-1e8 at the defaults) within 1e-4
    relative (measured 2e-8 and 2e-6), and scales as 1/v0; the largest imaginary
    part (plates, about 2 sqrt(k_p / 2 m_h) = 7.1e5) does not move with v0."""
    lam, im = [], []
    for v0 in (1e-3, 1e-2):
        p = CvtChain(n_pins=40, v0=v0)
        y = p.initial_state()
        ev = np.linalg.eigvals(p.jac(0.0, y).toarray())
        formula = -2 * p.params["mu"] * np.max(p.plate_tension(y)) / (v0 * p.m_h)
        assert formula == pytest.approx(p.friction_eigenvalue(), rel=1e-3)
        assert ev.real.min() == pytest.approx(formula, rel=1e-4)
        lam.append(ev.real.min())
        im.append(np.abs(ev.imag).max())
    assert lam[0] == pytest.approx(-1e8, rel=1e-3)
    assert lam[0] / lam[1] == pytest.approx(10.0, rel=1e-4)
    assert 5e5 < im[0] < 7.1e5 and im[0] == pytest.approx(im[1], rel=1e-3)


def test_energy_balance_without_friction_damping_and_torque():
    """Friction, damping and torques off; plates softened to 1e7 N/m so that DOP853
    is quick. Then d E/dt is the power of the capstan load alone (the Hertz
    force's potential includes its window, so entering pins exchange energy with
    it correctly); over 2 ms the chain runs 2 pitches, so pins enter and leave
    the wraps. E(t) - E(0) - int power dt, integrated beside the state, must stay
    below 1e-7 of the Hertz energy (0.08 J, its swing as pins enter and leave
    0.011 J; the capstan work reaches 0.01 J; the total is 80 J, mostly kinetic).
    Measured 2.2e-9 J. A missing window gradient or capstan term breaks it by the
    size of those swings."""
    p = CvtChain(n_pins=40, mu=0.0, mu_pulley=0.0, c_p=0.0, hertz_damping=0.0, torque=0.0,
                 k_p=1e7, t_end=0.002)
    nq = p.nq

    def aug(t, z):
        y = z[:-1]
        return np.append(p.rhs(t, y), p.external_power(t, y[:nq], y[nq:])[0])

    z0 = np.append(p.initial_state(), 0.0)
    sol = solve_ivp(aug, (0, 0.002), z0, method="DOP853", rtol=1e-11, atol=1e-13,
                    t_eval=np.linspace(0, 0.002, 21))
    assert sol.status == 0, sol.message
    Y = sol.y[:-1].T
    E = p.energy(Y[:, :nq], Y[:, nq:])
    work = sol.y[-1]
    N = p.n
    s = np.arange(N) * p.pitch + Y[:, :N]
    chi = p.window(s, 0)[0] + p.window(s, 1)[0]
    w = Y[:, N:3 * N]
    e_hertz = np.sum(np.hstack([chi, chi]) * 0.4 * p.params["k_hertz"]
                     * np.maximum(-w, 0) ** 2.5, -1)
    assert np.min(e_hertz) > 0.05 and np.max(np.abs(work)) > 1e-3 * np.min(e_hertz)
    np.testing.assert_allclose(E - E[0] - work, 0.0, atol=1e-7 * np.min(e_hertz))


def test_tension_grows_from_slack_to_tight_span_in_steady_drive():
    """The default chain (smooth law) driven at 175 N m over 5 ms: CVODE BDF at
    rtol 1e-6. At the end the mean plate tension in the tight span (entering the
    driving pulley) exceeds the slack span's by M / R = 3500 N within 2 %
    (measured 3496 N), both spans nearly uniform (std below 1 % of the
    difference), and the chain keeps its speed (10 m/s within 1 %)."""
    p = CvtChain()
    system = p.formulate("ode")
    sol = registry.integrators()["cvode-bdf"]().solve(system, rtol=1e-6, atol=system.atol(1e-6))
    assert sol.success, sol.message
    y = sol.y[-1]
    N = p.n
    T = p.plate_tension(y)[0]
    s = np.mod((np.arange(N) + 0.5) * p.pitch + y[:N], p.L)
    (a1, b1), (a2, b2) = p.wraps
    slack = (s > b1 + 0.01) & (s < a2 - 0.01)
    tight = (s > b2 + 0.01) & (s < p.L - 0.01)
    assert slack.sum() >= 5 and tight.sum() >= 5
    diff = T[tight].mean() - T[slack].mean()
    M_over_R = p.params["torque"] / p.radius
    assert diff == pytest.approx(M_over_R, rel=0.02)
    assert max(T[tight].std(), T[slack].std()) < 0.01 * diff
    assert np.mean(y[p.nq:p.nq + N]) == pytest.approx(p.params["speed"], rel=0.01)
    P = p.pin_force(sol.t, sol.y)
    assert P.shape == sol.t.shape and np.max(P) > 100.0        # the monitored pin is gripped
    assert p.monitor_start == 0.001 < p.t_span[1]


def test_3604_states_build_and_evaluate_in_linear_memory():
    p = CvtChain(n_pins=600)
    system = p.formulate("ode")
    y, n = system.y0, system.n
    assert n == 3604
    dense_bytes = 8 * n * n                 # 104 MB for one dense n x n matrix
    tracemalloc.start()
    try:
        f = system.fun(0.001, y)
        J = system.jac(0.001, y)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < dense_bytes / 50, peak
    assert f.shape == (n,) and sp.issparse(J) and J.nnz <= 20 * n
    t0 = time.process_time()
    system.fun(0.001, y)
    system.jac(0.001, y)
    assert time.process_time() - t0 < 1.0


def test_registered_and_describes_itself():
    p = registry.problems()["cvt_chain"]()
    d = json.loads(json.dumps(p.describe(), allow_nan=False))
    assert d["formulations"] == ["ode"] and d["dimension"] == 298
    assert len(p.fingerprint()) == 16
    assert CvtChain.benchmark_parameters == ({"friction": 1}, {"friction": 0})
    Y = np.tile(p.initial_state(), (3, 1))
    assert p.pin_force(np.zeros(3), Y).shape == (3,)
    np.testing.assert_array_equal(p.monitor(np.zeros(3), Y), p.pin_force(np.zeros(3), Y))
    assert p.monitor_name and 0 < p.monitor_start < p.t_span[1]


@pytest.mark.parametrize("params", [{"pretension": 0.0}, {"torque": 1e4}])
def test_a_slack_side_in_compression_is_refused_with_its_reason(params):
    """T0 - M/2R < 0 (the range's ends pretension=0, torque=1e4) would give a chain in
    compression and a non-finite start: a ProblemError naming both, not NaN."""
    with pytest.raises(ProblemError, match="slack side's tension"):
        CvtChain(**params)
