"""Every registered problem: Jacobians, invariants, parameters, metadata."""

import json

import numpy as np
import pytest

from integrator_bench.harness.measure import references

from integrator_bench.harness.matrix import registry
from integrator_bench.integrators.sparse import dense
from integrator_bench.problems.base import ProblemError


def problem_instances():
    for name, cls in registry.problems().items():
        for params in cls.benchmark_parameters:
            yield pytest.param(cls, params, id=f"{name}-{params}")


def formulated():
    for name, cls in registry.problems().items():
        for params in cls.benchmark_parameters:
            for form in cls.formulations:
                yield pytest.param(cls, params, form, id=f"{name}-{params}-{form}")


@pytest.mark.parametrize("cls, params, form", list(formulated()))
def test_jacobian_matches_finite_differences(cls, params, form):
    system = cls(**params).formulate(form)
    if getattr(system, "jac", None) is None:    # none given, or a second-order form
        pytest.skip("no analytic Jacobian")
    rng = np.random.default_rng(0)
    for _ in range(3):
        t = system.t0 + rng.uniform() * (system.t_end - system.t0)
        y = system.y0 + 0.1 * rng.standard_normal(system.n)
        if system.kind == "ode":
            f = lambda yy: np.asarray(system.fun(t, yy))
            J = dense(system.jac(t, y))
        else:
            yp = system.yp0 + 0.1 * rng.standard_normal(system.n)
            cj = 7.0
            f = lambda yy: np.asarray(system.residual(t, yy, yp + cj * (yy - y)))
            J = dense(system.jac(t, y, yp, cj))
        fd = np.empty_like(J)
        steps = 1e-7 * np.maximum(1.0, np.abs(y))
        for j in range(system.n):
            e = np.zeros(system.n)
            e[j] = steps[j]
            fd[:, j] = (f(y + e) - f(y - e)) / (2 * steps[j])
        # central differences: truncation O(step^2) within 1e-5 of max(|J|, 1), plus
        # the round-off of differencing f, eps S_i / step, where S_i is the size of
        # the terms f_i sums: |f_i| + sum_j |J_ij y_j| (exact for f linear in y).
        # It is large where a random state gives large forces (deep contact
        # penetration, stretched bushings whose forces cancel in a link's torque)
        terms = np.abs(f(y)) + np.abs(J) @ np.abs(y)
        roundoff = 100 * np.finfo(float).eps * terms[:, None] / steps[None, :]
        np.testing.assert_array_less(np.abs(J - fd), 1e-5 * np.maximum(np.abs(J), 1.0) + roundoff)


@pytest.mark.parametrize("cls, params", list(problem_instances()))
def test_invariants_hold_along_reference(cls, params):
    problem = cls(**params)
    invariants = problem.invariants()
    if not invariants:
        pytest.skip("no invariants declared")
    ref = references.load(problem, compute_missing=False)
    for name, fn in invariants.items():
        values = fn(ref.t, ref.Y)
        spread = np.max(np.abs(values - values[0])) / max(1.0, abs(values[0]))
        assert spread < 1e-9, f"{name} drifts by {spread:.2e}"


@pytest.mark.parametrize("cls, params", list(problem_instances()))
def test_constraint_residuals_vanish_on_reference(cls, params):
    problem = cls(**params)
    ref = references.load(problem, compute_missing=False)
    drift = problem.constraint_residuals(ref.t, ref.Y)
    if drift is None:
        pytest.skip("unconstrained")
    for d in drift:
        assert np.max(d) < 1e-9


@pytest.mark.parametrize("name", list(registry.problems()))
def test_describe_is_complete_json(name):
    d = registry.problems()[name]().describe()
    json.dumps(d, allow_nan=False)
    for key in ("name", "description", "dimension", "t_span", "parameters", "components",
                "initial_values", "formulations"):
        assert key in d
    assert d["dimension"] == len(d["components"]) == len(d["initial_values"])


@pytest.mark.parametrize("name", list(registry.problems()))
def test_fingerprint_depends_on_parameters(name):
    cls = registry.problems()[name]
    a = cls()
    assert a.fingerprint() == cls().fingerprint()
    changed = 0
    for p in cls.parameters:   # the first parameter that can take another value
        other = p.default * 1.5 if p.default else 1.0
        other = min(max(other, p.low), p.high)
        if other == p.default:      # at its upper bound (a switch set to 1): go down
            other = p.low
        try:
            b = cls(**{p.name: other})
        except ProblemError:   # e.g. an integer count that must stay even
            continue
        assert b.fingerprint() != a.fingerprint(), p.name
        changed += 1
        break
    assert changed or not cls.parameters


@pytest.mark.parametrize("name", list(registry.problems()))
def test_bad_parameters_are_refused(name):
    cls = registry.problems()[name]
    with pytest.raises(ProblemError, match="unknown parameter 'no_such'"):
        cls(no_such=1)
    if cls.parameters:
        with pytest.raises(ProblemError, match="not a number"):
            cls(**{cls.parameters[0].name: "abc"})


def test_spring_pendulum_stiffness_range():
    from integrator_bench.problems.models.spring_pendulum import SpringPendulum
    for k in (1.0, 1e7):
        assert SpringPendulum(k=k).params["k"] == k
    with pytest.raises(ProblemError, match="outside its range"):
        SpringPendulum(k=1e8)


@pytest.mark.parametrize("cls, params", list(problem_instances()))
def test_fingerprint_ignores_round_off_but_not_a_change_of_the_equations(cls, params):
    """Another machine's round-off (a few ulps in every probed value) keeps the
    fingerprint, so committed references stay valid there; a change in the
    sixth digit of the right-hand side does not."""
    problem = cls(**params)
    before = problem.fingerprint()
    probe = type(problem)._probe_values
    rng = np.random.default_rng(1)

    def scaled(factor):
        def values(self, y0):
            return [v * (1 + factor * rng.uniform(-1, 1, np.shape(v))) for v in probe(self, y0)]
        return values

    for factor, same in ((8 * np.finfo(float).eps, True), (1e-6, False)):
        problem._probe_values = scaled(factor).__get__(problem)
        assert (problem.fingerprint() == before) is same, factor


@pytest.mark.parametrize("cls, params, form", list(formulated()))
def test_declared_formulation_facts_are_what_formulate_gives(cls, params, form):
    """The report reads a formulation's kind and index from the class
    (``formulation_facts``) without building the problem: where a class declares
    them, they are those of the system it formulates."""
    declared = cls.formulation_facts(form)
    if declared is None:
        pytest.skip("not declared: the report builds the problem")
    system = cls(**params).formulate(form)
    assert declared == (system.kind, getattr(system, "index", None))
