"""Constrained mechanical systems: the model's derivatives, consistent starts,
the generated formulations and their agreement with the reference."""

import numpy as np
import pytest
import scipy.sparse as sp

from integrator_bench.harness.measure import references

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.run.execution import execute
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.integrators.sparse import dense
from integrator_bench.problems.base import ProblemError
from integrator_bench.problems.mechanical import MechanicalProblem
from integrator_bench.problems.system import convert, takes

from derivative_checks import check_model_derivatives, fd  # noqa: E402  (tests/)


def mechanical_problems():
    return [pytest.param(cls, id=name) for name, cls in registry.problems().items()
            if issubclass(cls, MechanicalProblem)]


@pytest.mark.parametrize("cls", mechanical_problems())
def test_model_derivatives_match_finite_differences(cls):
    p = cls()
    rng = np.random.default_rng(1)
    q0, v0, a0, lam0 = p.consistent_start()
    q = q0 + 0.01 * rng.standard_normal(p.nq)
    v = v0 + rng.standard_normal(p.nq)
    a = rng.standard_normal(p.nq)
    lam = rng.standard_normal(p.nc)
    check_model_derivatives(p, 0.3 * p.t_span[1], q, v, a, lam)


@pytest.mark.parametrize("cls", mechanical_problems())
def test_model_at_many_points_equals_the_model_point_by_point(cls):
    """evaluate_many (one call for all points) against the model called per point,
    and the output and drift built on it."""
    p = cls()
    rng = np.random.default_rng(2)
    q0, v0, _, _ = p.consistent_start()
    n = 7
    t = p.t_span[0] + rng.uniform(size=n) * (p.t_span[1] - p.t_span[0])
    Q = q0 + 0.01 * rng.standard_normal((n, p.nq))
    V = v0 + rng.standard_normal((n, p.nq))
    at = p.at_many(t, n)
    for name, args in (("mass", (Q,)), ("force", (t, Q, V)), ("constraint", (Q, *at)),
                       ("constraint_jac", (Q, *at)), ("accel_term", (Q, V, *at))):
        one_by_one = np.array([dense(getattr(p, name)(*row)) for row in zip(*args)])
        many = p.evaluate_many(name, *args)
        if p.sparse and name in ("mass", "constraint_jac"):  # a list of sparse matrices
            assert all(sp.issparse(m) for m in many), name
            many = np.array([m.toarray() for m in many])
        assert many.shape == one_by_one.shape, name
        np.testing.assert_allclose(many, one_by_one, rtol=1e-13, atol=1e-13, err_msg=name)
    A, Lam = p.accelerations_many(t, Q, V)
    for i in range(n):
        a, lam = p.accelerations(t[i], Q[i], V[i])
        np.testing.assert_allclose(A[i], a, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(Lam[i], lam, rtol=1e-10, atol=1e-10)
    Y = np.hstack([Q, V])
    alpha, beta = p.baumgarte_alpha, p.baumgarte_beta
    for form, extra in (("ode", lambda t, q, v: None),
                        ("baumgarte", lambda t, q, v: 2 * alpha * p.velocity_constraint(t, q, v)
                         + beta**2 * p.constraint(q, *p.at(t)))):
        out = p.formulate(form).output(t, Y)
        assert out.shape == (n, 2 * p.nq + p.nc)
        lam = [p.accelerations(ti, q, v, extra(ti, q, v))[1] for ti, q, v in zip(t, Q, V)]
        np.testing.assert_allclose(out[:, 2 * p.nq:], lam, rtol=1e-10, atol=1e-10, err_msg=form)
    pos, vel = p.constraint_residuals(t, Y)
    np.testing.assert_allclose(pos, [np.linalg.norm(p.constraint(q, *p.at(ti)))
                                     for ti, q in zip(t, Q)], rtol=1e-12)
    np.testing.assert_allclose(vel, [np.linalg.norm(p.velocity_constraint(ti, q, v))
                                     for ti, q, v in zip(t, Q, V)], rtol=1e-12)


@pytest.mark.parametrize("cls", mechanical_problems())
def test_consistent_start(cls):
    p = cls()
    q, v, a, lam = p.consistent_start()
    t0 = p.t_span[0]
    at = p.at(t0)
    scale = max(1.0, np.max(np.abs(q)))
    assert np.max(np.abs(p.constraint(q, *at))) < 1e-12 * scale
    G = p.constraint_jac(q, *at)
    assert np.max(np.abs(p.velocity_constraint(t0, q, v))) < 1e-12 * max(1.0, np.max(np.abs(v)))
    residual = p.mass(q) @ a - p.force(t0, q, v) + G.T @ lam
    assert np.max(np.abs(residual)) < 1e-9 * max(1.0, np.max(np.abs(p.force(0.0, q, v))))
    assert np.max(np.abs(G @ a + p.accel_term(q, v, *at))) < 1e-9 * max(1.0, np.max(np.abs(a)))


def test_start_too_far_from_consistent_is_a_clear_error(monkeypatch):
    from integrator_bench.problems.models.pendulum import Pendulum
    monkeypatch.setattr(Pendulum, "start", lambda self: (np.array([3.0, 0.0]), np.zeros(2)))
    with pytest.raises(ProblemError, match="start too far from consistent"):
        Pendulum().initial_state()


@pytest.mark.parametrize("cls", mechanical_problems())
def test_dae_jacobians_match_finite_differences(cls):
    p = cls()
    rng = np.random.default_rng(2)
    for form in p.formulations:
        s = p.formulate(form)
        if s.kind != "dae" or s.jac is None:
            continue
        y = s.y0 + 0.01 * rng.standard_normal(s.n)
        yp = s.yp0 + 0.01 * rng.standard_normal(s.n)
        cj = 3.0
        J = dense(s.jac(0.0, y, yp, cj))
        num = fd(lambda x: s.residual(0.0, x, yp + cj * (x - y)), y)
        scale = max(1.0, np.max(np.abs(num)))
        np.testing.assert_allclose(J, num, atol=1e-6 * scale, rtol=1e-5, err_msg=form)


def _pick(system, kinds):
    """The first registered integrator (by the live registry) that takes the system
    and is adaptive, preferring DAE codes for DAEs and high order for ODEs."""
    best = None
    # the core dependencies' codes first (scikit-sundae's IDA, with which the references
    # were cross-checked); Assimulo's IDA, an optional extra, fails to start on the
    # squeezer's i3 at rtol 1e-8 and is cross-checked in test_assimulo.py instead
    for name, icls in sorted(registry.integrators().items(),
                             key=lambda item: "assimulo" in item[1].__module__):
        if not icls.adaptive or not takes(system, icls):
            continue
        if system.kind == "dae" and "dae" in icls.accepts:
            return name
        if system.kind == "ode" and (best is None or (icls.order or 0) >
                                     (registry.integrators()[best].order or 0)):
            best = name
    return best


#: problems whose tight runs over their whole span take long, whatever their size: the
#: stiff flyball governor (A05, 10 s at rtol 1e-10: about a minute in all)
LONG = ("flyball",)


def _slow_if_large(params):
    """Large systems (more than 10 coordinates in the default parameter set) and the
    :data:`LONG` ones run in the slow suite."""
    return [pytest.param(*p.values, id=p.id, marks=pytest.mark.slow)
            if p.values[0]().nq > 10 or p.values[0].name in LONG else p for p in params]


@pytest.mark.parametrize("cls", _slow_if_large(mechanical_problems()))
def test_every_formulation_agrees_with_the_reference(cls):
    """The formulation-agreement test: each formulation, with an integrator that
    takes it, at tight tolerance, matches the reference on the positions."""
    p = cls()
    if p.name == "n_four_bar":
        pytest.skip("through singular configurations most forms leave the physical branch "
                    "(tests/problems/models/test_n_four_bar.py); that is what the problem measures")
    for form in p.formulations:
        system = p.formulate(form)
        if system.unsupported:  # refused for every integrator (tests/problems/models/test_iftomm_a04_a05.py)
            continue
        name = _pick(system, None)
        tight = dict(rtols=[1e-10 if system.kind == "ode" else 1e-8])
        want = 7 if system.kind == "ode" else (3 if system.index == 3 else 4)
        if name is None:        # a form only fixed-step codes take (al3): 5000 steps
            name = next(n for n, icls in registry.integrators().items() if takes(system, icls))
            tight, want = dict(hs=[(p.t_span[1] - p.t_span[0]) / 5000]), 3
        case = next(c for c in expand(problems=[p.name], formulations=[form],
                                      integrators=[name], **tight))
        record = execute(case)
        assert record["status"] == CaseStatus.OK, (form, name, record["message"])
        assert record["mescd"] > want, (form, name, record["mescd"])


@pytest.mark.parametrize("cls", mechanical_problems())
def test_reference_satisfies_constraints_to_round_off(cls):
    p = cls()
    ref = references.load(p, compute_missing=False)
    pos, vel = p.constraint_residuals(ref.t, ref.Y)
    qscale = max(1.0, np.max(np.abs(ref.Y[:, :p.nq])))
    vscale = max(1.0, np.max(np.abs(ref.Y[:, p.nq:2 * p.nq])))
    assert np.max(pos) < 1e-10 * qscale
    assert np.max(vel) < 1e-9 * vscale


def test_pendulum_energy_is_conserved_by_the_reference():
    from integrator_bench.problems.models.pendulum import Pendulum
    p = Pendulum()
    ref = references.load(p, compute_missing=False)
    e = p.invariants()["energy"](ref.t, ref.Y)
    assert np.max(np.abs(e - e[0])) < 1e-9 * 9.81


def test_ida_takes_every_dae_form_with_algebraic_variables_out_of_the_error_test():
    from integrator_bench.problems.models.squeezer import Squeezer
    ida = registry.get_integrator("ida")
    p = Squeezer()
    for form, index in (("i3", 3), ("i2", 2), ("ggl", 2), ("i1", 1)):
        s = p.formulate(form)
        assert s.index == index and convert(s, ida) is s
        assert not s.error_mask[s.algebraic].any()
    assert not p.formulate("i3").error_mask[p.nq:].any()   # index 3: velocities out too
    assert p.formulate("i2").error_mask[p.nq:2 * p.nq].all()


def test_projection_goes_only_to_integrators_that_project():
    from integrator_bench.problems.models.pendulum import Pendulum
    s = Pendulum().formulate("projection")
    for name, icls in registry.integrators().items():
        ok = takes(s, icls)
        assert ok == bool(getattr(icls, "projects", False)), name


@pytest.mark.parametrize("name", [n for n, c in registry.integrators().items() if c.projects])
def test_partitioning_renews_a_singular_one_constraint_partition(name):
    """The pendulum released horizontally starts with x dependent; near the bottom
    x's 1x1 block goes singular and the partition must change. Before the renewal
    test measured the block against ||G|| (cond of a 1x1 block is always 1),
    implicit Euler and w1 at h = 0.01 computed the dependent velocity from the
    vanishing independent one and left the pendulum at rest at the bottom."""
    from integrator_bench.problems.models.pendulum import Pendulum
    icls = registry.get_integrator(name)
    system = convert(Pendulum().formulate("partitioning"), icls)
    options = {"rtol": 1e-6, "atol": system.atol(1e-6)} if icls.adaptive else {"h": 0.01}
    sol = icls().solve(system, **options)
    if not sol.success:
        assert not icls.implicit, sol.message  # only explicit methods may blow up here
        pytest.skip(f"{name} fails at this step: {sol.message}")
    speed = np.hypot(sol.y[:, 2], sol.y[:, 3])[np.asarray(sol.t) >= 5.0]
    assert speed.max() > 1.0  # still swinging (at rest at the bottom it would be 0)


@pytest.mark.parametrize("cls", mechanical_problems())
def test_accelerations_agree_with_the_augmented_system_of_the_parts(cls):
    """A model's one-point accelerations (the symbolic ones from one compiled call of
    the whole augmented system) solve ``[[M, G^T], [G, 0]] [a; lam] = [f; -gamma -
    extra]`` built from its parts, at a state off the start."""
    p = cls(**cls.benchmark_parameters[0]) if cls.benchmark_parameters else cls()
    rng = np.random.default_rng(3)
    q0, v0 = (np.asarray(x, float) for x in p.consistent_start()[:2])
    q, v = q0 + 1e-3 * rng.standard_normal(q0.size), v0 + 1e-2 * rng.standard_normal(v0.size)
    extra = rng.standard_normal(p.nc)
    if getattr(p, "redundant_constraints", 0):
        # redundant constraints: on the manifold, with a right-hand side in G's range,
        # the rank-deficient augmented system is consistent (off it, the solve is the
        # least-squares one: a near-singular Jacobian there is not the model's)
        q, v = q0, p._project_velocities(q0, v)
        extra = dense(p.constraint_jac(q)) @ rng.standard_normal(p.nq)
    M, G = (dense(x) for x in (p.mass(q), p.constraint_jac(q, *p.at(0.3))))
    K = np.block([[M, G.T], [G, np.zeros((p.nc, p.nc))]])
    rhs = np.concatenate([p.force(0.3, q, v), -p.accel_term(q, v, *p.at(0.3)) - extra])
    a, lam = p.accelerations(0.3, q, v, extra)
    np.testing.assert_allclose(K @ np.concatenate([a, lam]), rhs, rtol=1e-9,
                               atol=1e-9 * np.max(np.abs(rhs)))


@pytest.mark.parametrize("name", ["pendulum", "chain_drive"])     # dense, sparse
def test_a_singular_augmented_matrix_gives_nan_for_the_integrator_not_an_exception(name):
    """At q = 0 the pendulum's and the chain drive's constraint Jacobians lose rank,
    as a diverging step can leave them: the ODE form's right-hand side, the
    projection and the multipliers among the outputs are NaN there, for the
    integrator's failure handling (``failed``, ``nonfinite_state``), not a
    LinAlgError (SuperLU's RuntimeError for the sparse one) that made the case an
    ``error``."""
    cls = registry.get_problem_class(name)
    problem = cls(**cls.benchmark_parameters[0])
    ode = problem.formulate("ode")
    y0 = np.asarray(ode.y0, float)
    zero = np.zeros_like(y0)
    assert np.isnan(ode.fun(0.0, zero)).all()
    rows = ode.output(np.zeros(2), np.vstack([y0, zero]))      # a good state, a singular one
    assert np.isfinite(rows[0]).all() and np.isnan(rows[1, -problem.nc:]).all()
    assert np.isnan(problem.formulate("projection").project(0.0, zero)).all()


def symbolic_problems():
    from integrator_bench.problems.symbolic import SymbolicMechanics
    return [pytest.param(cls, id=name) for name, cls in registry.problems().items()
            if issubclass(cls, SymbolicMechanics)]


@pytest.mark.parametrize("cls", symbolic_problems())
def test_the_fast_one_point_model_gives_numpys_values_bit_for_bit(cls):
    """Every compiled one-point matrix of a symbolic model, compiled with Python's
    ``math`` for speed, gives exactly the values of the same expressions with
    numpy's functions, at random points (arguments within a few units, the
    parameters the model's own)."""
    rng = np.random.default_rng(7)
    params = [float(v) for v in cls()._pvalues]
    for name, entries in cls._compiled_entries().items():
        fast, numpy_form = entries.fn.fast, entries.fn.make_safe()
        n_args = fast.__code__.co_argcount - len(params)
        for _ in range(50):
            args = [float(x) for x in 3 * rng.standard_normal(n_args)] + params
            np.testing.assert_array_equal(np.asarray(fast(*args), float),
                                          np.asarray(numpy_form(*args), float), err_msg=name)


def test_where_python_floats_raise_the_one_point_model_gives_numpys_nan():
    """At a point where Python's float arithmetic raises (``math.sqrt`` of a
    negative, a run gone astray), the one-point model gives numpy's NaN and its
    warning, for the integrator to fail on, as before it was compiled with ``math``."""
    import sympy as sym
    from integrator_bench.problems.symbolic import _compile_entries_fn
    x = sym.Symbol("x")
    fn = _compile_entries_fn([x], [sym.sqrt(x) + 1, x])
    assert fn(4.0) == [3.0, 4.0]
    with pytest.warns(RuntimeWarning):
        values = fn(-1.0)
    assert np.isnan(values[0]) and values[1] == -1.0


@pytest.mark.parametrize("cls", mechanical_problems())
def test_baumgarte_alpha_is_an_option_of_the_formulation_not_of_the_problem(cls):
    """``baumgarte_alpha`` (beta following it) changes the baumgarte formulation's
    derivative off the constraints and nothing of the problem: same key, same
    reference, the same ode form; ``alpha = 0`` is the underlying ODE."""
    base = cls()
    tuned = cls(baumgarte_alpha=0.0)
    assert (tuned.baumgarte_alpha, tuned.baumgarte_beta) == (0.0, 0.0)
    assert tuned.key_params() == base.key_params() and tuned.unscored().params == base.params
    assert tuned.params["baumgarte_alpha"] == 0.0
    y = base.formulate("ode").y0.copy()
    y[: base.nq] += 1e-3        # off the position constraints: Baumgarte's terms act
    ode = tuned.formulate("ode").fun(0.0, y)
    np.testing.assert_array_equal(tuned.formulate("baumgarte").fun(0.0, y), ode)
    if base.nc:
        assert not np.allclose(base.formulate("baumgarte").fun(0.0, y), ode)
    with pytest.raises(ProblemError, match="baumgarte_alpha=-1"):
        cls(baumgarte_alpha=-1)
