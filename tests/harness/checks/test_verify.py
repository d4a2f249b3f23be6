"""``ibench verify``: the command line, its verdicts, and stability over the live registry."""

import json

import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.cli import main
from integrator_bench.harness.checks.verify import adaptive_tolerance, fit_order, stability, verify
from integrator_bench.integrators.base import Integrator
from integrator_bench.integrators.fixed_step import ExplicitEuler

INTEGRATORS = registry.integrators()
DECLARES_STABILITY = sorted(n for n, c in INTEGRATORS.items() if c.stability in ("A", "L"))


class WrongOrder(ExplicitEuler):
    name = "test-wrong-order"
    description = "explicit Euler claiming order 2 (tests only)"
    order = 2


class WrongStability(ExplicitEuler):
    name = "test-wrong-stability"
    description = "explicit Euler claiming A-stability (tests only)"
    stability = "A"


class OtherKind(Integrator):
    name = "test-other-kind"
    description = "takes a kind no test problem has (tests only)"
    accepts = frozenset({"hybrid"})
    order = 2
    adaptive = False


@pytest.fixture
def liars():
    for cls in (WrongOrder, WrongStability, OtherKind):
        registry.register(cls, origin="tests")
    yield
    for cls in (WrongOrder, WrongStability, OtherKind):
        registry.unregister(cls.name)


def test_verify_json_reports_declared_observed_and_checks(capsys):
    assert main(["verify", "-i", "rk4", "-i", "implicit-euler", "--json"]) == 0
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [d["integrator"] for d in lines] == ["rk4", "implicit-euler"]
    rk4, ie = lines
    assert rk4["declared_order"] == 4 and abs(rk4["observed_order"] - 4) <= 0.3
    assert rk4["passed"] is True and rk4["order_passed"] is True and rk4["stability"] is None
    assert {o["problem"] for o in rk4["orders"]} == {"nonlinear", "oscillator"}
    assert all(o["passed"] and len(o["ladder"]) >= 3 for o in rk4["orders"])
    assert ie["stability"]["declared"] == "L" and ie["stability"]["passed"] is True
    assert set(ie["stability"]["checks"]) == {"real", "imaginary"}


def test_verify_table_output(capsys):
    assert main(["verify", "-i", "trapezoidal"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[:3] == ["integrator", "declared", "observed"]
    assert out[1].split()[0] == "trapezoidal" and out[1].split()[-1] == "pass"


def test_verify_bad_name_exits_2_with_one_line(capsys):
    assert main(["verify", "-i", "no-such-method"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no-such-method" in err[0] and "rk4" in err[0]


def test_a_false_order_claim_fails_and_exits_1(liars, capsys):
    v = verify("test-wrong-order")
    assert v.passed is False and v.order_passed is False
    assert abs(v.observed_order - 1.0) <= 0.3
    assert main(["verify", "-i", "test-wrong-order", "--json"]) == 1
    assert json.loads(capsys.readouterr().out)["passed"] is False


def test_a_false_stability_claim_fails(liars):
    v = verify("test-wrong-stability")
    assert v.order_passed is True
    assert v.stability.passed is False
    assert v.passed is False


def test_no_test_problem_is_reported_not_failed(liars):
    v = verify("test-other-kind")
    assert v.passed is None and v.orders == []
    assert v.note.startswith("not verified: no test problem for kind hybrid")


def test_fit_order_uses_only_the_asymptotic_window():
    hs = [1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125]
    errs = [10.0, 1e-3, 1e-3 / 8, 1e-3 / 64, 1e-3 / 512, 1e-16]  # pre-asymptotic, then rounding
    slope, detail = fit_order(hs, errs)
    assert slope == pytest.approx(3.0)
    assert fit_order(hs[:2], errs[:2])[0] is None


def test_adaptive_tolerance_separates_the_neighbouring_orders():
    """Narrower than 1 (p - 1 fails) and wider than the 0.39 the registered codes need."""
    for p in range(1, 9):
        assert 0.39 < adaptive_tolerance(p) <= 0.5


class HiddenSubsteps(ExplicitEuler):
    """Explicit Euler doing ``N / 8`` hidden sub-steps per step of a ladder of
    ``N`` steps on ``[0, 3]``: its error is ``O(h^2)`` in the step ``h`` the
    driver hands over, but ``O(1 / nfev)`` in the harness's count."""

    name = "test-hidden-substeps"
    description = "explicit Euler with hidden sub-steps claiming order 2 (tests only)"
    order = 2

    def step_function(self, system, counts):
        euler = super().step_function(system, counts)

        def step(t, y, dt):
            n = max(1, round(3.0 / 8 / dt))
            for k in range(n):
                y = euler(t + k * dt / n, y, dt / n)
            return y
        return step


def test_hidden_work_inside_a_step_does_not_fake_the_order():
    registry.register(HiddenSubsteps, origin="tests")
    try:
        v = verify("test-hidden-substeps")
    finally:
        registry.unregister(HiddenSubsteps.name)
    assert v.order_passed is False and abs(v.observed_order - 1) <= 0.3
    assert "against h" in v.orders[0].detail   # the h slope alone would say about 2


@pytest.mark.parametrize("name", DECLARES_STABILITY)
def test_declared_stability_holds(name):
    result = stability(INTEGRATORS[name])
    assert result.passed, (result.checks, result.detail)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(INTEGRATORS))
def test_every_registered_integrator_gets_a_sound_verdict(name):
    """The whole of ``ibench verify`` over the live registry (about 3 minutes)."""
    v = verify(name)
    assert v.passed is not False, v.to_dict()
    if v.declared_order is None and v.orders:
        assert v.order_passed is None   # variable order: reported, no verdict
