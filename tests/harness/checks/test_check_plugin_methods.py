"""check-plugin judges the method: ROS3P honest passes, each lying variant fails
on the line that names its lie, and every built-in passes the method checks."""

import math

import numpy as np
import pytest

from integrator_bench.harness.checks import method_checks

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.checks.conformance import check_plugin
from integrator_bench.harness.run.execution import counted
from integrator_bench.integrators.base import Integrator, Solution
from integrator_bench.problems.system import OdeSystem

from test_plugins import load_example

ROS3P = load_example("ibench-ros3p", "ibench_ros3p", "ROS3P")


class ROS3PZeroError(ROS3P):
    """Lies about its error: the estimate is always zero."""

    name = "test-ros3p-zero-error"

    def stepper(self, system, counts, rtol=None, atol=None):
        stepper = super().stepper(system, counts, rtol, atol)
        stepper.estimate = lambda u1, u2, u3: np.zeros_like(u1)
        return stepper


class ROS3PClaimsL(ROS3P):
    """Lies about its stability: R(inf) = 1 - sqrt(3), declared L."""

    name = "test-ros3p-claims-l"
    stability = "L"


class RK4ClaimsA(registry.get_integrator("rk4")):
    """Lies about its stability: the classical RK4, declared A."""

    name = "test-rk4-claims-a"
    stability = "A"


class SkipsThePole(Integrator):
    """Steps over the blow-up: returns the other branch 1/(1 - t) past t = 1 as success."""

    name = "test-skips-the-pole"
    description = "returns the formula 1/(1 - t) at the output times (tests only)"
    order = 1
    adaptive = True

    def solve(self, system, *, rtol=None, atol=None, h=None):
        t = system.t_eval
        y = np.array([[1.0 / (1.0 - s) if s != 1.0 else -1e10] for s in t])
        return Solution(t, y, True, "", {})


LIARS = {ROS3PZeroError: "accuracy", ROS3PClaimsL: "stability", RK4ClaimsA: "stability"}


@pytest.fixture(scope="module")
def registered():
    classes = (ROS3P, *LIARS, SkipsThePole)
    for cls in classes:
        registry.register(cls, origin="tests")
    yield
    for cls in classes:
        registry.unregister(cls.name)


def _lines(name, only=None):
    return {c.name: c for c in check_plugin(name, timeout=60, only=only)}


def test_honest_ros3p_passes_every_line(registered):
    lines = _lines("ros3p")
    assert all(c.passed is not False for c in lines.values()), [c.line() for c in lines.values()]
    for name in ("order", "stability", "accuracy", "fails nan", "fails blowup", "counts"):
        assert lines[name].passed, lines[name].line()
    assert "NaN" in lines["fails nan"].detail


@pytest.mark.parametrize("cls", list(LIARS), ids=lambda c: c.name)
def test_each_liar_fails_on_the_line_of_its_lie(registered, cls):
    """The order line passes (its order is true; ROS3P's is checked by the honest
    twin's full run above, the liars' steps at h are the same), the other
    method line passes or does not apply, the line of the lie fails."""
    lie = LIARS[cls]
    lines = _lines(cls.name, only=("stability", "accuracy")
                   + (("order",) if cls is RK4ClaimsA else ()))
    assert lines[lie].passed is False, lines[lie].line()
    other = {"stability": "accuracy", "accuracy": "stability"}[lie]
    assert lines[other].passed is not False, lines[other].line()
    if cls is RK4ClaimsA:
        assert lines["order"].passed, lines["order"].line()   # stability apart from order
    if cls is ROS3PZeroError:
        assert "never rejected" in lines["accuracy"].detail


def test_check_groups_are_checked(registered):
    with pytest.raises(ValueError, match="unknown check group.*choose from"):
        check_plugin("ros3p", only=("speed",))


def test_ros3p_is_order_3_and_not_l_stable():
    """The coefficients: order 3 at fixed steps, R(-inf) = 1 - sqrt(3)."""
    def run(A, h, t_end):
        system = OdeSystem(t0=0.0, t_end=t_end, y0=np.ones(A.shape[0]),
                           t_eval=np.array([0.0, t_end]), atol_scale=1.0,
                           fun=lambda t, y: A @ y + np.cos(t), jac=lambda t, y: A)
        return ROS3P().solve(system, h=h).y[-1]

    A = np.array([[-2.0, 1.0], [1.0, -3.0]])
    ref = run(A, 1 / 4096, 1.0)
    errs = [np.max(np.abs(run(A, 1 / n, 1.0) - ref)) for n in (16, 32, 64)]
    assert all(abs(math.log2(a / b) - 3) < 0.15 for a, b in zip(errs, errs[1:])), errs
    y = ROS3P().solve(OdeSystem(t0=0.0, t_end=1.0, y0=np.ones(1), t_eval=np.array([0.0, 1.0]),
                                atol_scale=1.0, fun=lambda t, y: -1e9 * y,
                                jac=lambda t, y: np.array([[-1e9]])), h=1.0).y[-1, 0]
    assert abs(y - (1 - math.sqrt(3))) < 1e-6


def test_a_jump_over_the_pole_is_judged_not_a_missing_reference(registered):
    line = _lines("test-skips-the-pole", only=("fails",))["fails blowup"]
    assert line.passed is False and "stepped over the blow-up" in line.detail
    assert "Reference" not in line.detail


@pytest.mark.parametrize("jac", ["analytic", "none", "sparse"])
def test_ros3p_uses_the_jacobian_it_is_given(jac):
    """system.jac None: finite differences (counted in nfev); sparse: stays sparse."""
    import scipy.sparse as sp

    A = np.array([[-2.0, 1.0], [1.0, -3.0]])
    jacs = {"analytic": lambda t, y: A, "none": None, "sparse": lambda t, y: sp.csr_matrix(A)}
    system, counters = counted(OdeSystem(
        t0=0.0, t_end=1.0, y0=np.ones(2), t_eval=np.array([0.0, 1.0]), atol_scale=1.0,
        fun=lambda t, y: A @ y, jac=jacs[jac]))
    sol = ROS3P().solve(system, h=0.1)
    assert np.allclose(sol.y[-1], (sp.linalg.expm(A) @ np.ones(2)), atol=1e-3)
    assert sol.counts["njev"] == 10 and sol.counts["nlu"] == 10
    # three evaluations a step (two stages, one for f_t); a difference Jacobian n + 1 more
    assert counters["nfev"].n == 10 * (3 + (3 if jac == "none" else 0))


#: built-ins the checks find wrong, each with its own defect: they must keep failing
#: (a fix shows up here), on the line named
KNOWN_FAILURES = {
    # Assimulo's RungeKutta34 never rejects a step: its error estimate only sets the
    # next step (assimulo/solvers/runge_kutta.py, RungeKutta34._iter), so the ramp's
    # error stays at 0.16 whatever the tolerance
    "assimulo-rk34": "accuracy",
}


@pytest.mark.parametrize("name", sorted(registry.integrators()))
def test_every_registered_integrator_passes_the_method_checks(name):
    icls = registry.get_integrator(name)
    for judge in (method_checks.stability, method_checks.accuracy):
        passed, detail = judge(icls)
        if KNOWN_FAILURES.get(name) == judge.__name__:
            assert passed is False, f"{name} now passes {judge.__name__}: {detail}"
        else:
            assert passed is not False, f"{judge.__name__}: {detail}"


def test_the_ramp_is_exact_and_needs_rejections():
    system, exact = method_checks.ramp()
    assert abs(exact - 1.0) < 1e-15 and method_checks.ramp_exact(0.0) == 0.0
    for t in (0.5, 0.99, 1.0, 1.01, 1.7):   # y' = f
        d = (method_checks.ramp_exact(t + 1e-6) - method_checks.ramp_exact(t - 1e-6)) / 2e-6
        assert abs(d - system.fun(t, None)[0]) < 1e-6
    heun = load_example("ibench-heun", "ibench_heun", "Heun")
    sol = heun().solve(system, rtol=1e-5, atol=system.atol(1e-5))
    assert sol.counts["nreject"] > 0 and abs(sol.y[-1, 0] - exact) < 1e-3



@pytest.mark.parametrize("name", ["ros3p", "scipy-Radau", "scipy-LSODA", "rk4"])
def test_the_models_nan_is_named_in_the_record(registered, name):
    """Whatever the integrator makes of the model's NaN (a step-size underflow, a
    ValueError, a "successful" NaN solution, a non-finite state), the record says
    ``nonfinite_state`` and names the model's NaN."""
    from integrator_bench.harness.checks.conformance import _case, _faulty_problems, _tolerance
    from integrator_bench.harness.run.execution import execute

    pcls = next(p for p in _faulty_problems() if p.name == "_check_nan")
    registry.register(pcls, origin="tests")
    try:
        icls = registry.get_integrator(name)
        record = execute(_case(icls, pcls(), "ode", **_tolerance(icls, pcls())))
    finally:
        registry.unregister(pcls.name)
    assert (record["status"], record["reason"]) == ("failed", "nonfinite_state"), record
    assert record["message"].startswith("the model returned NaN (function at t=")


def test_an_undeclared_counter_fails_the_counts_line_and_a_declared_one_passes():
    """``Solution.counts`` beyond the n-prefix vocabulary must be declared in
    ``extra_counters`` (Assimulo's ``nfev_jac``, ``nlsred``)."""
    from integrator_bench.harness.checks import conformance
    from integrator_bench.harness.matrix import registry
    from integrator_bench.integrators.base import Integrator, Solution

    class OwnLoop(Integrator):
        name = "test-own-counter"
        description = "explicit Euler with its own loop, reporting a counter of its own"
        reference = "Hairer, Norsett, Wanner, Solving ODEs I, sect. II.1"
        adaptive = False

        def solve(self, system, *, rtol=None, atol=None, h=None):
            import numpy as np
            t, y, ys = system.t0, np.array(system.y0, float), [np.array(system.y0, float)]
            for t_next in system.t_eval[1:]:
                while t < t_next - 1e-12:
                    step = min(h, t_next - t)
                    y, t = y + step * np.asarray(system.fun(t, y)), t + step
                ys.append(y.copy())
            return Solution(system.t_eval, np.array(ys), counts={"nwidgets": 1})

    ran = [next((p, f, {"h": min(p.default_step_sizes())})
                for p, f, s in conformance._candidates()
                if s.kind == "ode" and not s.events)]
    registry.register(OwnLoop, origin="test")
    try:
        assert conformance._counts(OwnLoop, ran, 60)[0].passed is False
        OwnLoop.extra_counters = {"nwidgets": "widgets made"}
        assert conformance._counts(OwnLoop, ran, 60)[0].passed is True
    finally:
        registry.unregister(OwnLoop.name)


def test_a_hostile_problem_plugin_never_changes_the_verdict():
    """check-plugin judges on the project's own problems: a one-state problem plugin
    whose right-hand side gives NaN (the smallest registered problem) is never one
    of them, and gbs still runs its ODE to ok."""
    from integrator_bench.harness.checks import conformance
    from integrator_bench.problems.base import Problem

    class Hostile(Problem):
        name = "hostile_nan"
        description, source = "NaN from the start", "tests"
        components, t_span, parameters = ("x",), (0.0, 1.0), ()
        benchmark_parameters, error_components, atol_scale = ({},), ("x",), 1.0

        def initial_state(self):
            return np.array([1.0])

        def rhs(self, t, y):
            return np.full(1, np.nan)

        def jac(self, t, y):
            return np.full((1, 1), np.nan)

    registry.register(Hostile, origin="ibench-hostile 1.0")
    try:
        assert "hostile_nan" not in {p.name for p, _, _ in conformance._candidates()}
        checks, _ = conformance._runs(registry.get_integrator("gbs"), 60.0)
        [runs] = [c for c in checks if c.name == "runs ode"]
        assert runs.passed, runs.detail
    finally:
        registry.unregister("hostile_nan")
