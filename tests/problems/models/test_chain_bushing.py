"""The chain drive with bushings (problems/models/chain_bushing.py): analytic sparse
derivatives, energy conservation, convergence to the constrained chain drive as
the bushing stiffness grows, and O(N) memory at N = 1000."""

import json
import time
import tracemalloc
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.integrate import solve_ivp

from integrator_bench.harness.matrix import registry
from integrator_bench.problems.base import ProblemError
from integrator_bench.problems.models.chain_bushing import ChainBushing
from integrator_bench.problems.models.chain_drive import ChainDrive
from integrator_bench.problems.system import convert

from test_chain_drive import pin_distances, simulate  # noqa: E402
from derivative_checks import check_model_derivatives, fd  # noqa: E402


def as_mechanical(p):
    """The bushing chain's forces with the chain drive's joint functions, in the
    shape :func:`check_model_derivatives` takes: the bushing force and its
    derivatives are built from ``constraint_jac``, ``gv_q`` and ``gt_q``, so all
    are checked at once."""
    c = p.chain
    return SimpleNamespace(constraint=c.constraint, constraint_jac=c.constraint_jac,
                           gv_q=c.gv_q, gt_q=c.gt_q, accel_term=c.accel_term, mass=p.mass,
                           mass_q=c.mass_q, force=p.force, force_q=p.force_q, force_v=p.force_v)


def random_point(p, seed):
    rng = np.random.default_rng(seed)
    q0, v0 = p.start()
    return q0 + 1e-3 * rng.standard_normal(p.nq), v0 + rng.standard_normal(p.nq), rng


def test_derivatives_match_finite_differences():
    # soft bushings so that their forces are of the size of the contact's; pins in
    # and out of contact and inside the damping ramp, moving, during the drive ramp
    p = ChainBushing(n_links=10, teeth=6, initial_speed=3.0, damping_depth=1e-3,
                     bushing_stiffness=1e4, bushing_damping=3.0)
    q, v, rng = random_point(p, 1)
    delta = p.chain.contact_radius - pin_distances(p.chain, q)
    assert np.sum((delta > 0) & (delta < 1e-3)) >= 2 and np.sum(delta >= 1e-3) >= 2
    t = 0.3 * p.params["ramp_time"]
    assert np.max(np.abs(p.bushing_force(q, v))) > 1.0            # the bushings act
    assert sp.issparse(p.force_q(t, q, v)) and sp.issparse(p.force_v(t, q, v))
    check_model_derivatives(as_mechanical(p), t, q, v, rng.standard_normal(p.nq),
                            rng.standard_normal(2 * p.n))


def test_ode_jacobian_is_sparse_and_matches_finite_differences():
    p = ChainBushing(n_links=12, teeth=8, initial_speed=2.0, bushing_stiffness=1e5)
    q, v, _ = random_point(p, 2)
    y, t = np.concatenate([q, v]), 0.02
    J = p.formulate("ode").jac(t, y)
    assert sp.issparse(J) and J.shape == (2 * p.nq, 2 * p.nq)
    numeric = fd(lambda x: p.rhs(t, x), y)
    np.testing.assert_allclose(J.toarray(), numeric, atol=1e-6 * np.max(np.abs(numeric)),
                               rtol=1e-6)


def test_no_constraints_and_the_chain_drive_start():
    p = ChainBushing()
    assert p.formulations == ("ode",) and p.dimension == 2 * p.nq == 6 * 30 + 4
    q, v = p.start()
    np.testing.assert_array_equal(p.initial_state(), np.concatenate(ChainDrive().start()))
    # unloaded bushings: the gaps are round-off (< 1e-15 m), so is the force
    assert np.max(np.abs(p.bushing_force(q, v))) < 1e-15 * p.params["bushing_stiffness"]
    with pytest.raises(ProblemError, match="chain_bushing"):
        ChainBushing(n_links=31)


def integrate(p, t_end, rtol, n_out=11):
    """The bushing chain's ODE with scipy's DOP853; (t, Q, V)."""
    system = p.formulate("ode")
    sol = solve_ivp(system.fun, (0.0, t_end), system.y0, method="DOP853", rtol=rtol,
                    atol=rtol * system.atol_scale, t_eval=np.linspace(0.0, t_end, n_out))
    assert sol.status == 0, sol.message
    return sol.t, sol.y[:p.nq].T, sol.y[p.nq:].T


def test_energy_is_conserved_without_drive_load_damping_and_friction():
    """Gravity, Hertz contact and the bushings (potential k_b |g|^2 / 2 included)
    with the chain moving at 5 rad/s; DOP853 at rtol 1e-10 over 10 ms (about 50
    periods of the fastest joint mode). Bushings of 1e6 N/m keep the explicit run
    short; their energy reaches 0.12 of the total, so leaving it out or a wrong
    sign of the bushing force would break the balance at that level. Measured
    relative drift 6.4e-10; allowed 1e-8.
    """
    p = ChainBushing(n_links=20, teeth=10, initial_speed=5.0, drive_gain=0.0,
                     load_damping=0.0, damping=0.0, friction=0.0, bushing_damping=0.0,
                     bushing_stiffness=1e6)
    assert "energy" in p.invariants()
    t, Q, V = integrate(p, 0.01, 1e-10)
    E = p.energy(Q, V)
    bushing = 0.5 * p.params["bushing_stiffness"] * np.sum(p.chain.constraint(Q) ** 2, -1)
    assert np.max(bushing) > 0.05 * abs(E[0])
    assert np.max(np.abs(E - E[0])) < 1e-8 * abs(E[0])
    Y = np.hstack([Q, V])
    np.testing.assert_allclose(p.invariants()["energy"](t, Y), E)


def test_stiff_bushings_converge_to_the_constrained_chain():
    """Over 5 ms of the 20-link chain in steady drive at 5 rad/s, the link centres
    of the bushing chain (CVODE BDF at rtol 1e-9 with the sparse Jacobian) differ
    from the constrained chain drive's (DOP853 on its underlying ODE, rtol 1e-10)
    by the joint gaps ~ T / k_b accumulated along the chain: measured max
    difference 2.24e-5, 2.50e-6 and 2.53e-7 m at k_b = 1e6, 1e7 and 1e8 N/m,
    i.e. 4.5, 5.0 and 5.1 T0 / k_b (T0 = 5 N; the same to 8 digits at rtol
    1e-11). We require the difference below 10 T0 / k_b at each stiffness and
    shrinking at least fivefold per decade of k_b.
    """
    common = dict(n_links=20, teeth=10, initial_speed=5.0, drive_speed=5.0, ramp_time=1e-6,
                  t_end=0.005)
    _, Qc, _ = simulate(ChainDrive(**common), common["t_end"], 11, rtol=1e-10)
    T0 = ChainDrive().params["pretension"]
    cvode = registry.integrators()["cvode-bdf"]()
    errs = []
    for kb in (1e6, 1e7, 1e8):
        p = ChainBushing(**common, bushing_stiffness=kb)
        p.n_output = 10                    # the 11 output times of simulate()
        system = p.formulate("ode")
        sol = cvode.solve(system, rtol=1e-9, atol=1e-9 * system.atol_scale)
        assert sol.success, sol.message
        xy = np.ones(p.nq, bool)
        xy[2::3] = False                   # x, y of the link centres (metres)
        xy[3 * p.n:] = False               # not the sprocket angles
        errs.append(np.max(np.abs(sol.y[:, :p.nq][:, xy] - Qc[:, xy])))
        assert errs[-1] < 10 * T0 / kb, (kb, errs)
    assert errs[1] < errs[0] / 5 and errs[2] < errs[1] / 5, errs


def test_thousand_links_build_and_evaluate_in_linear_memory():
    p = ChainBushing(n_links=1000)
    system = p.formulate("ode")
    y, t = system.y0, 0.01
    n = system.n
    assert n == 6004
    dense_bytes = 8 * n * n                 # 288 MB for one dense n x n matrix
    tracemalloc.start()
    try:
        f = system.fun(t, y)
        J = system.jac(t, y)
        Fq, Fv = p.force_q(t, y[:p.nq], y[p.nq:]), p.force_v(t, y[:p.nq], y[p.nq:])
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < dense_bytes / 50, peak
    assert f.shape == (n,)
    for A in (J, Fq, Fv):
        assert sp.issparse(A) and A.nnz <= 20 * n
    t0 = time.process_time()
    system.fun(t, y)
    system.jac(t, y)
    assert time.process_time() - t0 < 1.0


def test_registered_and_describes_itself():
    p = registry.problems()["chain_bushing"](n_links=20, teeth=10)
    d = json.loads(json.dumps(p.describe(), allow_nan=False))
    assert d["formulations"] == ["ode"] and d["dimension"] == 2 * p.nq
    assert len(p.fingerprint()) == 16


def test_second_order_form_for_the_alpha_methods():
    """The ODE carries its unconstrained second-order form: same start, the
    consistent acceleration, K and C from the force derivatives; HHT takes it
    and converges to the ODE's solution (CVODE at rtol 1e-10) over 5 ms of the
    stiff chain, with an error that falls with rtol."""
    p = ChainBushing(n_links=20, teeth=10, initial_speed=5.0, t_end=0.005)
    p.n_output = 10
    system = p.formulate("ode")
    mech = system.mechanical
    assert mech.kind == "mechanical" and (mech.nq, mech.nc) == (p.nq, 0)
    np.testing.assert_array_equal(mech.y0, system.y0)
    np.testing.assert_allclose(mech.a0, system.fun(0.0, system.y0)[p.nq:], rtol=1e-14)
    q, v, rng = random_point(p, 3)
    K, C = mech.tangent(0.001, q, v, None, np.zeros(0))
    np.testing.assert_allclose(K.toarray(), -p.force_q(0.001, q, v).toarray())
    np.testing.assert_allclose(C.toarray(), -p.force_v(0.001, q, v).toarray())
    integrators = registry.integrators()
    ref = integrators["cvode-bdf"]().solve(system, rtol=1e-10, atol=system.atol(1e-10))
    assert ref.success, ref.message
    hht = integrators["hht"]
    assert convert(system, hht) is mech
    errors = []
    for rtol in (1e-5, 1e-7):
        sol = hht().solve(mech, rtol=rtol, atol=mech.atol(rtol))
        assert sol.success, sol.message
        assert sol.y.shape == ref.y.shape
        errors.append(np.max(np.abs(sol.y[:, :p.nq] - ref.y[:, :p.nq])))
    # measured 1.8e-5 and 2.0e-6 m: HHT's order 2 under per-step control gains
    # about half a digit per decade of rtol (as on chain_drive)
    assert errors[1] < errors[0] / 5 and errors[1] < 1e-5, errors
