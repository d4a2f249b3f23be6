"""IFToMM A02, the N-four-bar mechanism: its closed-form reference against the
one-coordinate reduction and the full model, its singular configurations, and
what the formulations do at the singular passage."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from integrator_bench.harness.measure import references
from integrator_bench.harness.matrix import registry
from integrator_bench.problems.models.n_four_bar import NFourBar
from integrator_bench.problems.system import convert


@pytest.mark.parametrize("n", [1, 2, 40])
def test_closed_form_agrees_with_the_one_coordinate_reduction_integrated(n):
    """The crank angle from Jacobi's amplitude against ``I phi'' = -C cos phi``
    integrated by DOP853 (an independent computation of the parallelogram motion)."""
    p = NFourBar(n=n)
    inertia, C = p.pendulum()
    t = p.t_eval
    sol = solve_ivp(lambda t, y: [y[1], -C * np.cos(y[0]) / inertia], p.t_span,
                    [np.pi / 2, -1.0], t_eval=t, rtol=1e-12, atol=1e-12, method="DOP853")
    phi, rate, _ = p.crank_angle(t)
    assert np.max(np.abs(phi - sol.y[0])) < 1e-8
    assert np.max(np.abs(rate - sol.y[1])) < 1e-8
    assert phi[-1] < -9 * 2 * np.pi          # about ten turns: 40 singular passages


@pytest.mark.parametrize("n", [2, 40])
def test_closed_form_satisfies_the_model(n):
    """At the output times the closed form holds every constraint (positions and
    velocities), starts at the specification's state, and with its multipliers
    satisfies ``M a + G^T lam = f``, ``a`` from the closed-form crank angle."""
    p = NFourBar(n=n)
    t = p.t_eval
    Y = p.exact(t)
    nq = p.nq
    pos, vel = p.constraint_residuals(t, Y)
    assert pos.max() < 1e-13 and vel.max() < 1e-12
    q0, v0 = Y[0, :nq], Y[0, nq:2 * nq]
    np.testing.assert_allclose(q0[:2], [0.0, 1.0], atol=1e-15)     # B0 above its pivot (0, 0)
    np.testing.assert_allclose(v0[:2], [1.0, 0.0], atol=1e-15)     # B0 moves along +x at 1 m/s
    np.testing.assert_allclose(Y[0], p.initial_state(), atol=1e-12)
    phi, rate, accel = p.crank_angle(t)
    for k in range(1, len(t), 37):
        q, v, lam = Y[k, :nq], Y[k, nq:2 * nq], Y[k, 2 * nq:]
        a = np.empty(nq)
        a[0::2] = -np.sin(phi[k]) * accel[k] - np.cos(phi[k]) * rate[k] ** 2
        a[1::2] = np.cos(phi[k]) * accel[k] - np.sin(phi[k]) * rate[k] ** 2
        residual = p.mass(q) @ a + p.constraint_jac(q).T @ lam - p.force(t[k], q, v)
        assert np.max(np.abs(residual)) < 1e-9 * max(1.0, np.max(np.abs(lam)))
        np.testing.assert_allclose(p.constraint_jac(q) @ a + p.accel_term(q, v), 0, atol=1e-11)
    energy = p.invariants()["energy"](t, Y)
    assert np.ptp(energy) < 1e-11 * abs(energy[0])


def test_the_jacobian_loses_n_rows_of_rank_when_the_bars_lie_horizontal():
    """The specification's singular configuration: 1 degree of freedom, N+1 there."""
    n = 3
    p = NFourBar(n=n)
    q = np.zeros(p.nq)
    q[0::2], q[1::2] = np.arange(n + 1) + 1.0, 0.0     # cranks along +x
    G = p.constraint_jac(q)
    assert np.linalg.matrix_rank(G) == n + 1
    assert p.nq - np.linalg.matrix_rank(G) == n + 1
    q0 = p.consistent_start()[0]
    assert p.nq - np.linalg.matrix_rank(p.constraint_jac(q0)) == 1


def test_a_run_that_leaves_the_physical_branch_shows_in_its_error():
    """The underlying ODE at tight tolerance crosses the first singular passage
    (t = 0.71 s) onto another branch: B0's position error is of the size of the
    mechanism, not of the tolerance."""
    p = NFourBar(n=2)
    system = p.formulate("ode")
    t = np.linspace(0.0, 2.0, 41)
    sol = solve_ivp(system.fun, (0.0, 2.0), system.y0, method="DOP853", rtol=1e-8,
                    atol=1e-8, t_eval=t)
    error = np.max(np.abs(sol.y[:2].T - p.exact(t)[:, :2]))
    assert error > 0.5


def test_the_augmented_lagrangian_form_follows_the_branch_to_the_high_precision_level():
    """ALI3-P (trapezoidal rule, h = 1 ms) on N = 2 over the specification's 20 s,
    40 singular passages: within IFToMM's high precision level (1e-3) on B0's
    position, against the stored reference, with the constraints held."""
    p = NFourBar(n=2)
    icls = registry.get_integrator("al-trapezoidal")
    system = convert(p.formulate("al3"), icls)
    sol = icls().solve(system, h=1e-3)
    assert sol.success, sol.message
    ref = references.load(p, compute_missing=False)
    Y = system.output(sol.t, sol.y)
    assert np.max(np.abs(Y[:, :2] - ref.Y[:, :2])) < 1e-3
    assert np.max(p.constraint_residuals(sol.t, Y)[0]) < 1e-8


def test_al_trapezoidal_runs_in_the_matrix_and_counts_honestly():
    """The al3 form's integrator through the harness on the pendulum (1000 steps):
    ok, second-order accurate, and the counts the harness keeps are its own."""
    from integrator_bench.harness.matrix.cases import expand
    from integrator_bench.harness.matrix.record import CaseStatus
    from integrator_bench.harness.run.execution import execute
    case = next(iter(expand(problems=["pendulum"], formulations=["al3"],
                            integrators=["al-trapezoidal"], hs=[1e-2])))
    record = execute(case)
    assert record["status"] == CaseStatus.OK, record["message"]
    assert record["kind"] == "augmented_lagrangian" and record["mescd"] > 2
    counts = record["solver_counts"]
    assert record["nfev"] == counts["nfev"] and record["nsteps"] == counts["nsteps"] == 1000
    for key in ("nlu", "nniter", "nnfail"):
        assert record[key] == counts[key]


def test_the_iftomm_preset_runs_the_iftomm_problems_and_the_levels_table_reads_it(tmp_path):
    """``--preset iftomm`` names A01's to A05's mechanisms (A02 at N = 40) with every
    formulation, A02's al3 at 2 ms among its cases; studies/iftomm_levels.py tables
    the cheapest run within each level, from a store of real runs."""
    import subprocess
    import sys
    from pathlib import Path
    from integrator_bench.harness.matrix.cases import expand
    cases = [c for c in expand(preset="iftomm") if not c.unsupported]
    assert {(c.problem, c.params) for c in cases} == {
        ("pendulum", tuple(sorted((p.name, p.default) for p in registry.problems()[
            "pendulum"].parameters))), ("n_four_bar", (("n", 40.0),)), ("squeezer", ()),
        ("bricard", ()), ("flyball", ())}
    assert any(c.problem == "n_four_bar" and c.formulation == "al3" and c.h == 0.002
               for c in cases)
    # A04 and A05 at 1000 and 4000 steps over their 10 s, the others at 10000 too
    for name in ("bricard", "flyball"):
        assert {c.h for c in cases if c.problem == name and c.h} == {0.01, 0.0025}
    assert {c.h for c in cases if c.problem == "n_four_bar" and c.h} == {0.02, 0.005, 0.002}
    store = tmp_path / "s.sqlite"
    run = subprocess.run([sys.executable, "-m", "integrator_bench.harness.cli", "run", "-p",
                          "pendulum", "-f", "al3", "-i", "al-trapezoidal", "--h", "0.01",
                          "0.001", "--jobs", "1", "--store", str(store)],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    script = Path(__file__).parents[3] / "studies" / "iftomm_levels.py"
    out = subprocess.run([sys.executable, str(script), str(store)], capture_output=True,
                         text=True)
    assert out.returncode == 0, out.stderr
    row = next(x for x in out.stdout.splitlines() if x.startswith("| al3 | al-trapezoidal |"))
    family, low, high = row.split("|")[3:6]
    assert family.strip() == "dae"
    assert "(h 0.01," in low and "(h 0.001," in high      # 8.6e-3, then 9e-5
    assert ", dE " in high                                # the pendulum's energy variation
    assert "- high (0.001) reached by dae: al3/al-trapezoidal." in out.stdout
    missing = subprocess.run([sys.executable, str(script), str(tmp_path / "none.sqlite")],
                             capture_output=True, text=True)
    assert missing.returncode == 2 and "does not exist" in missing.stderr
