"""SUNDIALS IDA on the large chain: the declared structural pattern of the
sparse mechanical DAE forms, the Krylov path with SuperLU's exact preconditioner,
and the counting of accepted steps."""

import multiprocessing

import numpy as np
import pytest
import scipy.sparse as sp

from integrator_bench.harness.matrix import registry
from integrator_bench.integrators import sundials
from integrator_bench.problems.system import convert

N_LARGE, T_END, RTOL = 300, 0.005, 1e-5


def chain(n_links, t_end=T_END):
    return registry.get_problem_class("chain_drive")(n_links=n_links, t_end=t_end)


def _solve_in_child(n_links, send):
    problem = chain(n_links)
    system = convert(problem.formulate("ggl"), registry.get_integrator("ida"))
    sol = registry.get_integrator("ida")().solve(system, rtol=RTOL, atol=system.atol(RTOL))
    send.send((sol.success, sol.message, sol.counts, system.n, sol.y[-1][:problem.nq]))


def test_ida_ggl_large_chain_finishes_and_agrees_with_hht():
    """IDA on ``ggl`` at 300 links (3004 states) in a forked process, so that a
    solver aborting the process (SuperLU_MT out of storage did) fails the test;
    its positions agree with HHT on the ``i3`` form at rtol 1e-7 (an independent
    method and formulation, 74 steps) to 4e-4 of the largest displacement
    (about 5 mm in this span; HHT at rtol 1e-5 is off by 1.4e-5 m, IDA by 7e-7)."""
    ctx = multiprocessing.get_context("fork")
    receive, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_solve_in_child, args=(N_LARGE, send))
    proc.start()
    send.close()
    got = receive.recv() if receive.poll(120) else None
    proc.join(10)
    assert got is not None, f"IDA's process died (exit code {proc.exitcode})"
    success, message, counts, n, q_ida = got
    assert success, message
    assert n >= sundials.KRYLOV_MIN      # the Krylov path was taken
    assert counts["nlu"] == counts["njev"] > 0
    assert counts["nfev"] >= counts["nsteps"] > 0

    problem = chain(N_LARGE)
    mech = convert(problem.formulate("i3"), registry.get_integrator("hht"))
    hht = registry.get_integrator("hht")().solve(mech, rtol=1e-7, atol=mech.atol(1e-7))
    assert hht.success, hht.message
    q0, q_hht = problem.formulate("i3").y0[:problem.nq], hht.y[-1][:problem.nq]
    motion = np.max(np.abs(q_hht - q0))
    assert motion > 1e-3                     # the chain has moved
    assert np.max(np.abs(q_ida - q_hht)) < 4e-4 * motion


@pytest.mark.parametrize("form", ["i3", "i2", "ggl"])
def test_declared_pattern_is_structural(form):
    """The Jacobian at a random state with every pin in contact with both
    sprockets (contact radius enlarged after the pattern was taken) and random
    multipliers has no non-zero outside the declared pattern."""
    problem = chain(30)
    system = problem.formulate(form)
    P = sp.csc_matrix(system.jac_sparsity, dtype=bool)
    problem.contact_radius = 1e3          # every pin penetrates every sprocket
    rng = np.random.default_rng(3)
    y = system.y0 + 1e-3 * rng.standard_normal(system.n)
    y[2 * problem.nq:] = rng.standard_normal(system.n - 2 * problem.nq)
    yp = rng.standard_normal(system.n)
    J = sp.csc_matrix(system.jac(0.3 * problem.t_span[1], y, yp, 1e3))
    J.eliminate_zeros()
    assert J.nnz > 0.5 * P.nnz             # contacts active: a well-filled Jacobian
    assert (abs(J).astype(bool) > P).nnz == 0


def test_krylov_path_matches_direct_solver_and_counts_steps_exactly():
    """Below KRYLOV_MIN the same system goes to SuperLU_MT: the Krylov path,
    forced on it, takes the same steps and residuals (the same modified Newton
    iteration) and the same solution; ``nsteps`` equals the internal steps of
    a run advanced one step at a time without output times, and so never
    exceeds the residual count (re-returned steps were once counted)."""
    problem = chain(30, t_end=0.01)
    system = convert(problem.formulate("ggl"), registry.get_integrator("ida"))
    assert system.n < sundials.KRYLOV_MIN
    ida = registry.get_integrator("ida")
    direct = ida().solve(system, rtol=RTOL, atol=system.atol(RTOL))
    old, sundials.KRYLOV_MIN = sundials.KRYLOV_MIN, 0
    try:
        krylov = ida().solve(system, rtol=RTOL, atol=system.atol(RTOL))
    finally:
        sundials.KRYLOV_MIN = old
    assert direct.success and krylov.success, (direct.message, krylov.message)
    # the direct solver's linear-solver setups are SUNDIALS' own; the Krylov path's are
    # the preconditioner's factorizations, one per Jacobian
    assert direct.counts["nlu"] > 0 and krylov.counts["nlu"] == krylov.counts["njev"]
    for key in ("nsteps", "nfev"):
        assert abs(krylov.counts[key] - direct.counts[key]) <= 0.05 * direct.counts[key]
    scale = np.max(np.abs(direct.y[:, :problem.nq]))
    assert np.max(np.abs(krylov.y[:, :problem.nq] - direct.y[:, :problem.nq])) < 1e-6 * scale
    assert direct.counts["nsteps"] <= direct.counts["nfev"]

    atol = np.array(system.atol(RTOL))
    atol[~system.error_mask] = sundials.EXCLUDED_ATOL
    P = sundials.pattern(system.jac_sparsity)   # with the diagonal, as IDA gets it

    def resfn(t, y, yp, res):
        res[:] = system.residual(t, y, yp)

    def jacfn(t, y, yp, res, cj, JJ):
        JJ[:] = sundials.on_pattern(system.jac(t, y, yp, cj), P)

    solver = sundials._make(sundials.ida.IDA, resfn, dict(
        rtol=RTOL, atol=atol, algebraic_idx=np.flatnonzero(system.algebraic),
        linsolver="sparse", sparsity=P, nthreads=1, jacfn=jacfn, max_num_steps=100_000))
    solver.init_step(system.t0, system.y0, system.yp0)
    steps, t = 0, system.t0
    while t < system.t_end:
        res = solver.step(system.t_end, method="onestep", tstop=system.t_end)
        assert res.success, res.message
        steps, t = steps + 1, float(res.t)
    assert direct.counts["nsteps"] == steps
