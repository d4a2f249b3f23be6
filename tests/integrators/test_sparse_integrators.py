"""Implicit integrators on large sparse systems: same answer, no dense n x n matrix.

Three systems are built here, each in a dense and a sparse variant of the same
numbers:

* a stiff linear ODE, the method-of-lines heat equation ``y' = A y`` on
  ``n`` interior points of (0, 1), ``A = (n + 1)^2 tridiag(1, -2, 1)``, whose
  exact solution from sine modes is known (eigenvalues
  ``-(n + 1)^2 (2 - 2 cos(j pi / (n + 1)))``, stiffness ratio ``~ 4 n^2 / pi^2``);
* an index-1 DAE: the same ``x`` with algebraic ``z_i = x_i + x_{i+1}``;
* a planar chain of ``N`` point masses hanging from the origin, joined by rigid
  links (``N`` distance constraints, index 3), released from the horizontal.

Every implicit integrator of the live registry that takes the kind runs the
small dense and sparse variants to the same answer (the sparse path changes
only the LU, so the two agree to rounding), and the large sparse variant
(4000 ODE states, 8000 DAE states, 3000 coordinates with 1500 constraints)
with a tracemalloc peak far below one dense ``n x n`` matrix.
"""

from __future__ import annotations

import time
import tracemalloc

import numpy as np
import pytest
import scipy.sparse as sp

from integrator_bench.harness.matrix import registry
from integrator_bench.integrators.base import Status
from integrator_bench.integrators.sparse import GroupedDifferences, bandwidths, on_pattern, pattern
from integrator_bench.problems.system import (DaeSystem, MechanicalSystem, OdeSystem, convert,
                                              takes)

N_LARGE = 4000
T_END = 0.1
MODES = (1, 3)
AMPLITUDES = (1.0, 0.5)


# ------------------------------------------------------------------ systems
def laplacian(n):
    """``(n + 1)^2 tridiag(1, -2, 1)``, CSC."""
    k = (n + 1.0) ** 2
    return sp.diags([k, -2 * k, k], [-1, 0, 1], shape=(n, n), format="csc")


def heat_exact(n, t):
    """The exact solution from the sine modes in ``MODES``."""
    i = np.arange(1, n + 1)
    y = np.zeros(n)
    for j, c in zip(MODES, AMPLITUDES):
        lam = -(n + 1.0) ** 2 * (2 - 2 * np.cos(j * np.pi / (n + 1)))
        y += c * np.exp(lam * t) * np.sin(j * np.pi * i / (n + 1))
    return y


def heat_ode(n, variant):
    """``variant``: "dense" (dense jac), "sparse" (sparse jac and pattern), or
    "pattern" (no jac, only ``jac_sparsity``)."""
    A = laplacian(n)
    jac = {"dense": lambda t, y: A.toarray(), "sparse": lambda t, y: A,
           "pattern": None}[variant]
    return OdeSystem(t0=0.0, t_end=T_END, y0=heat_exact(n, 0.0),
                     t_eval=np.linspace(0.0, T_END, 3), atol_scale=1.0,
                     fun=lambda t, y: A @ y, jac=jac,
                     jac_sparsity=None if variant == "dense" else A != 0)


def heat_dae(n, variant):
    """``x' = A x``, ``0 = z - B x`` with ``(B x)_i = x_i + x_{i+1}`` (``2 n`` states)."""
    A = laplacian(n)
    B = sp.diags([1.0, 1.0], [0, 1], shape=(n, n), format="csc")
    eye = sp.identity(n, format="csc")

    def residual(t, y, yp):
        x, z = y[:n], y[n:]
        return np.concatenate([yp[:n] - A @ x, z - B @ x])

    def jac(t, y, yp, cj):
        J = sp.bmat([[cj * eye - A, None], [-B, eye]], format="csc")
        return J.toarray() if variant == "dense" else J

    x0 = heat_exact(n, 0.0)
    system = DaeSystem(t0=0.0, t_end=T_END, y0=np.concatenate([x0, B @ x0]),
                       t_eval=np.linspace(0.0, T_END, 3), atol_scale=1.0,
                       residual=residual, jac=jac,
                       yp0=np.concatenate([A @ x0, B @ (A @ x0)]),
                       algebraic=np.r_[np.zeros(n, bool), np.ones(n, bool)])
    if variant == "sparse-pattern":
        system.jac_sparsity = jac(0.0, system.y0, system.yp0, 1.0) != 0
    return system


def chain(N, variant, t_end=0.02):
    """A chain of ``N`` point masses (total mass 1 kg, length 1 m) hanging from
    the origin by rigid links, released at rest from the horizontal."""
    L, m, grav = 1.0 / N, 1.0 / N, 9.81
    nq = 2 * N
    # D q: the link vectors p_i - p_{i-1} (p_{-1} = 0), pairs (x, y)
    D = sp.csc_matrix(sp.identity(nq) - sp.eye(nq, k=-2))
    rows = np.repeat(np.arange(N), 2)

    def block_rows(d):               # (N, 2N): row i holds d_i at columns 2i, 2i+1
        return sp.csc_matrix((d, (rows, np.arange(nq))), shape=(N, nq))

    out = (lambda X: X.toarray()) if variant == "dense" else (lambda X: sp.csc_matrix(X))
    f = np.tile([0.0, -m * grav], N)

    def constraint(q):
        d = (D @ q).reshape(N, 2)
        return 0.5 * (np.sum(d * d, axis=1) - L * L)

    def constraint_jac(q):
        return out(block_rows(D @ q) @ D)

    def accel_term(q, v):
        dv = (D @ v).reshape(N, 2)
        return np.sum(dv * dv, axis=1)

    def tangent(t, q, v, a, lam):
        K = D.T @ sp.diags(np.repeat(lam, 2)) @ D
        return out(K), out(sp.csc_matrix((nq, nq)))

    q0 = np.zeros(nq)
    q0[0::2] = L * np.arange(1, N + 1)
    n = 2 * nq + N
    return MechanicalSystem(
        t0=0.0, t_end=t_end, y0=np.concatenate([q0, np.zeros(nq + N)]),
        t_eval=np.linspace(0.0, t_end, 3), atol_scale=1.0,
        error_mask=np.r_[np.ones(nq, bool), np.zeros(n - nq, bool)],
        nq=nq, nc=N, mass=lambda q: out(m * sp.identity(nq, format="csc")),
        force=lambda t, q, v: f, constraint=constraint, constraint_jac=constraint_jac,
        accel_term=accel_term, tangent=tangent)


# ------------------------------------------------------------------ running
def implicit_taking(example):
    """Registry names of the implicit (or Jacobian-using) integrators taking ``example``."""
    return [pytest.param(name, id=name) for name, cls in registry.integrators().items()
            if (cls.implicit or cls.uses_jacobian) and takes(example, cls)]


def run(name, system, h_steps=100, rtol=1e-6):
    """Solve with the registered integrator: at ``rtol`` when adaptive, else at
    ``h = span / h_steps``; return (solution, tracemalloc peak in bytes, seconds)."""
    cls = registry.get_integrator(name)
    system = convert(system, cls)
    if cls.adaptive:
        kwargs = dict(rtol=rtol, atol=system.atol(rtol))
    else:
        kwargs = dict(h=(system.t_end - system.t0) / h_steps)
    tracemalloc.start()
    start = time.perf_counter()
    try:
        sol = cls().solve(system, **kwargs)
        seconds = time.perf_counter() - start
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return sol, peak, seconds


def agree(a, b, scale):
    assert a.status is Status.SUCCESS and b.status is Status.SUCCESS, (a.message, b.message)
    np.testing.assert_array_equal(a.t, b.t)
    assert np.max(np.abs(a.y - b.y)) <= 1e-8 * scale


# ------------------------------------------------------------------ ODE
ODE_NAMES = implicit_taking(heat_ode(4, "sparse"))


@pytest.mark.parametrize("name", ODE_NAMES)
def test_ode_sparse_agrees_with_dense(name):
    dense_sol = run(name, heat_ode(40, "dense"))[0]
    sparse_sol = run(name, heat_ode(40, "sparse"))[0]
    agree(dense_sol, sparse_sol, 1.0)
    if registry.get_integrator(name).adaptive:
        err = np.max(np.abs(sparse_sol.y[-1] - heat_exact(40, T_END)))
        assert err <= 1e-3


@pytest.mark.parametrize("name", ODE_NAMES)
def test_ode_large_sparse_without_dense_matrix(name):
    system = heat_ode(N_LARGE, "sparse")
    sol, peak, seconds = run(name, system)
    cls = registry.get_integrator(name)
    assert peak < 8 * N_LARGE ** 2 / 20, f"peak {peak / 2**20:.1f} MiB"
    if sol.status is Status.METHOD_LIMIT:   # base.py rule 6: a code that can only densify
        assert "densify" in sol.message and len(sol.t) == 1, sol.message   # declines
        return
    assert sol.status is Status.SUCCESS, sol.message
    exact = heat_exact(N_LARGE, T_END)
    err = np.max(np.abs(sol.y[-1] - exact)) / np.max(np.abs(exact))
    # fixed steps h = T_END / 100: the global error of order p is ~ (h pi^2)^p
    bound = 1e-3 if cls.adaptive else 5 * (T_END / 100 * np.pi ** 2) ** cls.order
    assert err <= max(bound, 1e-6), err
    assert seconds < 20


@pytest.mark.parametrize("name", ["bdf2", "w1", "scipy-BDF", "cvode-bdf"])
def test_ode_pattern_only_uses_grouped_differences(name):
    """No ``jac``, only ``jac_sparsity``: grouped differences, 3 calls per Jacobian
    for a tridiagonal pattern instead of ``n``."""
    calls = []
    system = heat_ode(N_LARGE, "pattern")
    fun = system.fun
    system.fun = lambda t, y: calls.append(t) or fun(t, y)
    sol, peak, _ = run(name, system)
    assert sol.status is Status.SUCCESS, sol.message
    assert peak < 8 * N_LARGE ** 2 / 20
    assert len(calls) < N_LARGE      # a dense difference Jacobian alone takes n calls
    exact = heat_exact(N_LARGE, T_END)
    assert np.max(np.abs(sol.y[-1] - exact)) / np.max(np.abs(exact)) <= 1e-2


@pytest.mark.parametrize("n, expected", [(40, Status.SUCCESS), (N_LARGE, Status.METHOD_LIMIT)])
def test_lsoda_wide_structure_dense_when_small_declined_when_large(n, expected):
    """The periodic heat equation: corner entries make the band as wide as the
    matrix. LSODA has no sparse solver: it densifies at 40 states and declines
    at 4000, before allocating anything of size n x n."""
    system = heat_ode(n, "sparse")
    A = laplacian(n) + sp.csc_matrix(([1.0, 1.0], ([0, n - 1], [n - 1, 0])), shape=(n, n))
    system.fun, system.jac, system.jac_sparsity = (lambda t, y: A @ y), (lambda t, y: A), A != 0
    sol, peak, _ = run("scipy-LSODA", system)
    assert sol.status is expected, sol.message
    if expected is Status.METHOD_LIMIT:
        assert "bandwidths" in sol.message and sol.t.size == 1
        assert peak < 8 * n * n / 20


def test_grouped_differences_equal_dense_differences():
    rng = np.random.default_rng(1)
    n = 30
    A = sp.random(n, n, density=0.1, random_state=rng, format="csc") + sp.identity(n)
    fun = lambda t, y: A @ np.sin(y)  # noqa: E731
    y = rng.normal(size=n)
    grouped = GroupedDifferences(A != 0)
    J = grouped(fun, 0.0, y, fun(0.0, y), np.ones(n))
    exact = (A @ sp.diags(np.cos(y))).toarray()
    assert sp.issparse(J) and grouped.ngroups < n
    np.testing.assert_allclose(J.toarray(), exact, atol=1e-6)


def test_pattern_helpers():
    A = laplacian(6)
    P = pattern(A)
    assert bandwidths(P) == (1, 1)
    np.testing.assert_array_equal(on_pattern(A, P), A.data)
    with pytest.raises(ValueError):
        on_pattern(A + sp.eye(6, k=3), P)


# ------------------------------------------------------------------ DAE
DAE_NAMES = implicit_taking(heat_dae(4, "sparse"))


@pytest.mark.parametrize("name", DAE_NAMES)
def test_dae_sparse_agrees_with_dense(name):
    agree(run(name, heat_dae(40, "dense"))[0], run(name, heat_dae(40, "sparse-pattern"))[0],
          1.0)


@pytest.mark.parametrize("name", DAE_NAMES)
def test_dae_large_sparse_without_dense_matrix(name):
    n = N_LARGE
    sol, peak, seconds = run(name, heat_dae(n, "sparse"))
    assert peak < 8 * (2 * n) ** 2 / 20, f"peak {peak / 2**20:.1f} MiB"
    if sol.status is Status.METHOD_LIMIT:   # base.py rule 6: a code that can only densify
        assert "densify" in sol.message and len(sol.t) == 1, sol.message   # declines
        return
    assert sol.status is Status.SUCCESS, sol.message
    x, z = sol.y[-1, :n], sol.y[-1, n:]
    exact = heat_exact(n, T_END)
    assert np.max(np.abs(x - exact)) / np.max(np.abs(exact)) <= 1e-3
    np.testing.assert_allclose(z, x + np.r_[x[1:], 0.0], atol=1e-8)
    assert seconds < 20


# ------------------------------------------------------------------ mechanical
MECH_NAMES = implicit_taking(chain(3, "sparse"))


@pytest.mark.parametrize("name", MECH_NAMES)
def test_mechanical_sparse_agrees_with_dense(name):
    agree(run(name, chain(8, "dense"), h_steps=20)[0],
          run(name, chain(8, "sparse"), h_steps=20)[0], 1.0)


@pytest.mark.parametrize("name", MECH_NAMES)
def test_mechanical_large_sparse_without_dense_matrix(name):
    N = 1500
    system = chain(N, "sparse")
    # h = 2.5e-4: at 1e-3 Newmark's corrector fails on the first step, dense or sparse alike
    sol, peak, seconds = run(name, system, h_steps=80)
    assert sol.status is Status.SUCCESS, sol.message
    nq = system.nq
    assert peak < 8 * nq ** 2 / 20, f"peak {peak / 2**20:.1f} MiB"
    q = sol.y[-1, :nq]
    assert np.max(np.abs(system.constraint(q))) <= 1e-10
    # the chain falls: the free end has moved down
    assert q[-1] < -1e-4
    assert seconds < 20

