"""The formulation generator on sparse mechanical problems.

A problem with ``sparse = True`` returns scipy.sparse matrices, and every
formulation is generated from them without a dense n x n matrix. Checked here:
the sparse path agrees with the dense path on the same model (a sparse wrapper
of registered symbolic problems, and a chain model given both ways); at 1000
links (3002 coordinates, 2000 constraints) every formulation is formed and
evaluated within a memory bound far below one dense n x n matrix; and
``convert`` refuses a large system whose Jacobian an integrator would have to
build densely by finite differences.
"""

import tracemalloc

import numpy as np
import pytest
import scipy.sparse as sp

from integrator_bench.harness.matrix import registry
from integrator_bench.problems.base import Parameter
from integrator_bench.problems.mechanical import FORMULATIONS, MechanicalProblem
from integrator_bench.problems.models.pendulum import Pendulum
from integrator_bench.problems.models.squeezer import Squeezer
from integrator_bench.problems.system import DENSE_JACOBIAN_LIMIT, Unsupported, convert, takes

from derivative_checks import check_model_derivatives, fd  # noqa: E402

MATRICES = ("mass", "constraint_jac", "gv_q", "force_q", "force_v", "mass_q", "gt_q")


class HangingChain(MechanicalProblem):
    """A planar chain of N uniform rigid links, pinned at the origin, with a point
    mass hung from its free end by a zero-length linear spring, under gravity
    and linear viscous damping of every velocity.

    Link i has centre (x_i, y_i) and angle theta_i (3N coordinates), ends
    ``A_i, B_i = c_i -/+ (L/2) (cos theta_i, sin theta_i)``; the joints are
    ``A_0 = 0`` and ``A_i = B_{i-1}`` (2N constraints); the point mass adds
    (X, Y). Inertia of a slender rod ``m L^2 / 12``. Every matrix is built
    vectorized over the links as scipy.sparse. Start: the chain straight along
    +x, at rest (consistent).
    """

    name = "hanging_chain_test"
    description = "test model: pinned chain of rigid links with a spring-hung mass"
    source = "test model"
    sparse = True
    n_links = 0
    t_span = (0.0, 1.0)
    parameters = (
        Parameter("m", 0.05, 1e-6, 1e6, "link mass"),
        Parameter("L", 0.03, 1e-6, 1e3, "link length (pitch)"),
        Parameter("mp", 0.5, 1e-6, 1e6, "hung point mass"),
        Parameter("k", 2e3, 0.0, 1e9, "spring stiffness"),
        Parameter("c", 0.01, 0.0, 1e6, "viscous damping of every velocity"),
        Parameter("g", 9.81, 0.0, 1e3, "gravitational acceleration"),
    )

    @classmethod
    def of_size(cls, n_links, sparse=True):
        coords = tuple(f"{c}{i}" for i in range(n_links) for c in "xyt") + ("X", "Y")
        return type(f"HangingChain{n_links}", (cls,), dict(
            coordinates=coords, n_constraints=2 * n_links, n_links=n_links, sparse=sparse))

    # ------------------------------------------------------------ geometry
    def _geometry(self, q):
        n, half = self.n_links, self.params["L"] / 2
        links = q[:3 * n].reshape(n, 3)
        u = np.column_stack([np.cos(links[:, 2]), np.sin(links[:, 2])])
        w = np.column_stack([-u[:, 1], u[:, 0]])
        return links[:, :2], half * u, half * w, q[3 * n:]

    def _matrix(self, rows, cols, vals, shape=None):
        M = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=shape or (self.nq, self.nq)).tocsr()
        return M if self.sparse else M.toarray()

    def _joint_entries(self, per_link):
        """Entries ``(row, col, value)`` of a (2N, nq) matrix whose joint-j rows
        hold ``+per_link[j]`` in column theta_j and ``+per_link[j-1]`` in
        column theta_{j-1}; ``per_link`` is (N, 2)."""
        n = self.n_links
        j, k = np.repeat(np.arange(n), 2), np.tile([0, 1], n)
        jp, kp = j[2:], k[2:]
        return ([2 * j + k, 2 * jp + kp], [3 * j + 2, 3 * (jp - 1) + 2],
                [per_link[j, k], per_link[jp - 1, kp]])

    # ------------------------------------------------------------ the model
    def start(self):
        n, L = self.n_links, self.params["L"]
        q = np.zeros(self.nq)
        q[0:3 * n:3] = (np.arange(n) + 0.5) * L
        q[3 * n] = n * L
        return q, np.zeros(self.nq)

    def mass(self, q):
        m, L = self.params["m"], self.params["L"]
        d = np.concatenate([np.tile([m, m, m * L**2 / 12], self.n_links), 2 * [self.params["mp"]]])
        return self._matrix([np.arange(self.nq)], [np.arange(self.nq)], [d])

    def _spring(self, q):
        c, r, _, p = self._geometry(q)
        return r[-1], self.params["k"] * (p - c[-1] - r[-1])

    def force(self, t, q, v):
        n, f = self.n_links, -self.params["c"] * v
        f[1:3 * n:3] -= self.params["m"] * self.params["g"]
        f[3 * n + 1] -= self.params["mp"] * self.params["g"]
        r, F = self._spring(q)
        f[3 * n - 3:3 * n - 1] += F
        f[3 * n - 1] += r[0] * F[1] - r[1] * F[0]
        f[3 * n:] -= F
        return f

    def constraint(self, q):
        c, r, _, _ = self._geometry(q)
        ends = np.vstack([np.zeros((1, 2)), (c + r)[:-1]])
        return ((c - r) - ends).ravel()

    def constraint_jac(self, q):
        n = self.n_links
        _, _, w, _ = self._geometry(q)
        j, k = np.repeat(np.arange(n), 2), np.tile([0, 1], n)
        rows, cols, vals = self._joint_entries(-w)
        rows += [2 * j + k, 2 * j[2:] + k[2:]]
        cols += [3 * j + k, 3 * (j[2:] - 1) + k[2:]]
        vals += [np.ones(2 * n), -np.ones(2 * n - 2)]
        return self._matrix(rows, cols, vals, (self.nc, self.nq))

    def gv_q(self, q, v):
        _, r, _, _ = self._geometry(q)
        omega = v[2:3 * self.n_links:3]
        return self._matrix(*self._joint_entries(r * omega[:, None]), (self.nc, self.nq))

    def gt_q(self, q, lam):
        _, r, _, _ = self._geometry(q)
        joint = lam.reshape(-1, 2)
        both = joint + np.vstack([joint[1:], np.zeros((1, 2))])  # joints i and i + 1
        it = np.arange(2, 3 * self.n_links, 3)
        return self._matrix([it], [it], [np.sum(r * both, axis=1)])

    def mass_q(self, q, a):
        return self._matrix([np.empty(0, int)], [np.empty(0, int)], [np.empty(0)])

    def force_v(self, t, q, v):
        i = np.arange(self.nq)
        return self._matrix([i], [i], [np.full(self.nq, -self.params["c"])])

    def force_q(self, t, q, v):
        n, k = self.n_links, self.params["k"]
        _, r, w = self._geometry(q)[:3]
        r, w, F = r[-1], w[-1], self._spring(q)[1]
        cx, cy, th, px, py = 3 * n - 3, 3 * n - 2, 3 * n - 1, 3 * n, 3 * n + 1
        # rows: link force (x, y), torque, point force (x, y); columns c, theta, p
        block = np.array([
            [-k, 0, -k * w[0], k, 0],
            [0, -k, -k * w[1], 0, k],
            [k * r[1], -k * r[0], w[0] * F[1] - w[1] * F[0] - k * (r @ r), -k * r[1], k * r[0]],
            [k, 0, k * w[0], -k, 0],
            [0, k, k * w[1], 0, -k]])
        idx = np.array([cx, cy, th, px, py])
        return self._matrix([np.repeat(idx, 5)], [np.tile(idx, 5)], [block.ravel()])


def sparse_wrapper(cls):
    """``cls`` with ``sparse = True``, its matrices returned as CSR."""
    def wrap(name):
        def method(self, *args):
            return sp.csr_matrix(getattr(cls, name)(self, *args))
        return method
    return type(f"Sparse{cls.__name__}", (cls,),
                dict(sparse=True, **{name: wrap(name) for name in MATRICES}))


PAIRS = {
    "pendulum": (Pendulum, sparse_wrapper(Pendulum)),
    "squeezer": (Squeezer, sparse_wrapper(Squeezer)),
    "chain5": (HangingChain.of_size(5, sparse=False), HangingChain.of_size(5)),
}


def dense(A):
    return A.toarray() if sp.issparse(A) else np.asarray(A)


def near_start(p, seed=3):
    rng = np.random.default_rng(seed)
    q0, v0, _, _ = p.consistent_start()
    return (q0 + 0.01 * rng.standard_normal(p.nq), v0 + rng.standard_normal(p.nq),
            rng.standard_normal(p.nq), rng.standard_normal(p.nc))


def test_chain_model_derivatives_match_finite_differences():
    p = HangingChain.of_size(4)()
    q, v, a, lam = near_start(p)
    t = 0.3
    for name in MATRICES:
        assert sp.issparse(getattr(p, name)(*{"mass": (q,), "constraint_jac": (q,),
                                               "gv_q": (q, v), "force_q": (t, q, v),
                                               "force_v": (t, q, v), "mass_q": (q, a),
                                               "gt_q": (q, lam)}[name])), name
    check_model_derivatives(p, t, q, v, a, lam)


@pytest.mark.parametrize("key", PAIRS)
def test_sparse_path_agrees_with_dense_path(key):
    """Every formulation of the same model, sparse and dense: consistent start,
    right-hand side or residual, Jacobian (sparse, equal entries), outputs at
    several points, projection, the mechanical form's tangent."""
    dense_p, sparse_p = (cls() for cls in PAIRS[key])
    for x, y in zip(dense_p.consistent_start(), sparse_p.consistent_start()):
        np.testing.assert_allclose(y, x, rtol=1e-11, atol=1e-12)
    q, v, a, lam = near_start(dense_p)
    t = 0.37 * dense_p.t_span[1]
    rng = np.random.default_rng(4)
    # al3: tested below; tangent: a sparse problem refuses it (dense QR charts)
    for form in set(FORMULATIONS) - {"partitioning", "al3", "tangent"}:
        ds, ss = dense_p.formulate(form), sparse_p.formulate(form)
        y = ds.y0 + 0.01 * rng.standard_normal(ds.n)
        Y = ds.y0 + 0.01 * rng.standard_normal((6, ds.n))
        np.testing.assert_allclose(ss.output(t, Y), ds.output(t, Y), rtol=1e-9, atol=1e-9)
        if ds.kind == "ode":
            np.testing.assert_allclose(ss.fun(t, y), ds.fun(t, y), rtol=1e-9, atol=1e-9)
            assert ds.jac is None and ss.jac is None and ss.jac_sparsity is None
            if ds.project is not None:
                np.testing.assert_allclose(ss.project(t, y), ds.project(t, y),
                                           rtol=1e-10, atol=1e-12)
            continue
        yp = ds.yp0 + 0.01 * rng.standard_normal(ds.n)
        np.testing.assert_allclose(ss.residual(t, y, yp), ds.residual(t, y, yp),
                                   rtol=1e-10, atol=1e-10)
        if ds.jac is None:
            assert ss.jac is None and ss.jac_sparsity is not None
            continue
        J = ss.jac(t, y, yp, 25.0)
        assert sp.issparse(J) and J.format == "csc", form
        np.testing.assert_allclose(J.toarray(), ds.jac(t, y, yp, 25.0), rtol=1e-12, atol=1e-12)
    K_d, C_d = dense_p.formulate("i3").mechanical.tangent(t, q, v, a, lam)
    K_s, C_s = sparse_p.formulate("i3").mechanical.tangent(t, q, v, a, lam)
    assert sp.issparse(K_s) and sp.issparse(C_s)
    np.testing.assert_allclose(K_s.toarray(), K_d, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(C_s.toarray(), C_d, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("key", PAIRS)
def test_sparse_partitioning_recomputes_at_most_nc_coordinates_onto_the_constraints(key):
    """The sparse partition (pivoted sparse LU of G^T) need not choose the dense
    one's (pivoted QR of G), so its projection is checked for what it must do:
    back onto g = 0 and G v = 0, moving at most nc coordinates and velocities
    and keeping the others."""
    p = PAIRS[key][1]()
    system = p.formulate("partitioning")
    rng = np.random.default_rng(5)
    y = system.y0 + 1e-3 * rng.standard_normal(system.n)
    z = system.project(0.1, y)
    q, v = z[:p.nq], z[p.nq:]
    assert np.max(np.abs(p.constraint(q))) < 1e-12
    assert np.max(np.abs(p.constraint_jac(q) @ v)) < 1e-10 * max(1.0, np.max(np.abs(v)))
    moved = np.flatnonzero(z[:p.nq] != y[:p.nq])
    assert 0 < moved.size <= p.nc
    assert np.array_equal(np.flatnonzero(z[p.nq:] != y[p.nq:]), moved)


@pytest.mark.parametrize("key", PAIRS)
def test_i1_sparsity_holds_every_entry_of_the_finite_difference_jacobian(key):
    p = PAIRS[key][1]()
    system = p.formulate("i1")
    P = system.jac_sparsity.toarray()
    rng = np.random.default_rng(6)
    y = system.y0 + 0.01 * rng.standard_normal(system.n)
    yp = system.yp0 + rng.standard_normal(system.n)
    cj = 7.0
    J = (fd(lambda x: system.residual(0.2, x, yp), y)
         + cj * fd(lambda x: system.residual(0.2, y, x), yp))
    assert P.shape == J.shape
    outside = np.abs(J) * ~P
    assert np.max(outside) < 1e-6 * max(1.0, np.max(np.abs(J))), np.argwhere(outside > 1e-6)
    assert P.sum() < 0.5 * P.size or system.n < 30  # a pattern, not a full matrix


def test_every_formulation_at_1000_links_without_a_dense_n_by_n_matrix():
    """1000 links: 3002 coordinates, 2000 constraints. Formulate every
    formulation, evaluate its right-hand side or residual, its Jacobian (sparse),
    the output at 101 points, a projection and the fingerprint; the traced
    peak stays far below one dense 3002 x 3002 matrix (72 MB; the 101-point
    states and outputs alone take up to 15 MB)."""
    cls = HangingChain.of_size(1000)
    tracemalloc.start()
    try:
        p = cls()
        rng = np.random.default_rng(8)
        t_out = np.linspace(*p.t_span, 101)
        for form in FORMULATIONS:
            s = p.formulate(form)
            y = s.y0 + 1e-6 * rng.standard_normal(s.n)
            Y = np.tile(y, (101, 1))
            assert s.output(t_out, Y).shape == (101, 2 * p.nq + p.nc)
            if s.kind == "augmented_lagrangian":     # the model's sparse blocks, as i3's
                assert sp.issparse(s.mass(y[:p.nq])) and sp.issparse(s.constraint_jac(y[:p.nq]))
                continue
            if s.kind == "ode":
                assert np.all(np.isfinite(s.fun(0.1, y)))
                assert s.jac is None
                if s.project is not None:
                    z = s.project(0.1, y)
                    assert np.max(np.abs(p.constraint(z[:p.nq]))) < 1e-12
                continue
            assert np.all(np.isfinite(s.residual(0.1, y, s.yp0)))
            if s.jac is None:
                assert sp.issparse(s.jac_sparsity)
                continue
            J = s.jac(0.1, y, s.yp0, 100.0)
            assert sp.issparse(J) and J.shape == (s.n, s.n)
            if s.mechanical is not None:
                q, v, lam = s.mechanical.split(y)
                assert all(sp.issparse(B) for B in s.mechanical.tangent(
                    0.1, q, v, s.mechanical.a0, lam))
        drift = p.constraint_residuals(t_out, Y[:, :2 * p.nq])
        assert drift[0].shape == (101,)
        assert len(p.fingerprint()) == 16
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 20 * 2**20, f"peak {peak / 2**20:.1f} MB"


def test_convert_refuses_a_large_system_whose_jacobian_would_be_built_densely():
    """An implicit integrator (or one that uses a Jacobian) given the ode form of
    the 1000-link chain, which has no Jacobian and no sparsity, is unsupported,
    naming the size; explicit ones take it, and so does every integrator the
    ode form of a small chain."""
    integrators = registry.integrators()
    big = HangingChain.of_size(1000)().formulate("ode")
    assert big.n == 6004 > DENSE_JACOBIAN_LIMIT
    for name in ("scipy-Radau", "scipy-BDF", "scipy-LSODA", "cvode-bdf", "ida",
                 "implicit-euler"):
        with pytest.raises(Unsupported, match="n = 6004"):
            convert(big, integrators[name])
    assert takes(big, integrators["scipy-RK45"]) and takes(big, integrators["rk4"])
    small = HangingChain.of_size(5)().formulate("ode")
    for name in ("scipy-Radau", "cvode-bdf", "ida", "scipy-RK45"):
        assert takes(small, integrators[name]), name


def test_convert_takes_a_large_system_that_declares_its_jacobian_sparsity():
    """The large i1 DAE carries jac_sparsity and the large ode form with a
    sparsity becomes a DAE that keeps it: neither is refused for its size."""
    ida = registry.integrators()["ida"]
    p = HangingChain.of_size(1000)()
    assert convert(p.formulate("i1"), ida).jac_sparsity is not None
    ode = p.formulate("ode")
    ode.jac_sparsity = sp.identity(ode.n, format="csr")
    dae = convert(ode, ida)
    assert dae.kind == "dae" and sp.issparse(dae.jac_sparsity)
    assert dae.jac_sparsity.diagonal().all()


@pytest.mark.parametrize("sparse", [False, True], ids=["dense", "sparse"])
@pytest.mark.parametrize("key", PAIRS)
def test_partitioning_of_a_diverged_state_is_non_finite_not_an_exception(key, sparse):
    """A state far off the manifolds (a diverging explicit step's: inf entries make
    ``G_dep`` singular) projects to a non-finite state, which the integrator's
    failure handling takes up, rather than raising out of the run as a harness
    error (SuperLU's "Factor is exactly singular" on chain_drive did)."""
    p = PAIRS[key][int(sparse)]()
    system = p.formulate("partitioning")
    y = system.y0.copy()
    y[: p.nq] = np.inf
    z = system.project(0.1, y)
    assert z.shape == y.shape and not np.all(np.isfinite(z))


@pytest.mark.parametrize("key", ["squeezer", "chain5"])
def test_augmented_lagrangian_runs_alike_on_the_sparse_and_the_dense_model(key):
    """The al3 form with its trapezoidal rule (ALI3-P), 200 steps: the sparse
    model (SuperLU on ``M + alpha G^T G``) gives the dense model's positions and
    velocities, iterated to a tolerance of 1e-12 (the default 1e-8 leaves differences
    of that size; the multipliers differ by the penalty's round-off, 1e-6 relative)."""
    from integrator_bench.harness.matrix import registry
    from integrator_bench.problems.system import convert
    icls = registry.get_integrator("al-trapezoidal")
    runs = []
    for cls in PAIRS[key]:
        p = cls()
        system = convert(p.formulate("al3"), icls)
        sol = icls(tolerance=1e-12).solve(system, h=(p.t_span[1] - p.t_span[0]) / 200)
        assert sol.success, sol.message
        runs.append(np.asarray(sol.y)[:, :2 * p.nq])
    np.testing.assert_allclose(runs[1], runs[0], rtol=1e-7, atol=1e-9 * np.max(np.abs(runs[0])))
