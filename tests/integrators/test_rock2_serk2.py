"""ROCK2 and SERK2v2 (integrators/rock2.py, integrators/serk2.py): their
coefficient tables, the real stability intervals ``ibench verify`` measures on
the running integrators, their order, and their adaptive and fixed-stage runs
on a stiff 1-D heat equation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.run.execution import counted
from integrator_bench.harness.checks.verify import intervals, verify
from integrator_bench.integrators import rock2, rock2_coefficients, serk2, serk2_coefficients
from integrator_bench.integrators.settings import SettingError
from test_dumka import heat  # noqa: E402

WITH_VARIANTS = sorted(n for n, c in registry.integrators().items() if c.stability_variants)
#: registry name -> (module, its step function)
STABILIZED = {"rock2": rock2, "serk2v2": serk2}
STEP = {"rock2": rock2.rock2_step, "serk2v2": serk2.serk2_step}


def run(cls, system, **kw):
    system, counters = counted(system)
    sol = cls.solve(system, **kw)
    return sol, counters["nfev"].n


def test_tables_are_complete_and_consistent():
    assert len(rock2_coefficients.RECF) == sum(2 * m - 1 for m in rock2_coefficients.MS) == 4476
    assert len(rock2_coefficients.FP1) == len(rock2_coefficients.FP2) == 46
    assert rock2.STAGES[0] == 3 and rock2.STAGES[-1] == 200
    assert len(serk2_coefficients.B) == sum(m + 1 for m in serk2_coefficients.MS) == 1001
    start = 0
    for m in serk2_coefficients.MS:     # R(0) = 1: each block of weights sums to 1
        assert abs(sum(serk2_coefficients.B[start:start + m + 1]) - 1) < 1e-11
        start += m + 1


@pytest.mark.parametrize("name", WITH_VARIANTS)
def test_declared_intervals_hold_on_the_running_integrator(name):
    result = intervals(registry.get_integrator(name))
    assert result.passed, result.checks


def test_rock2_intervals_grow_as_0_81_s_squared():
    beta = {int(k[2:]): v for k, v in rock2.Rock2.stability_intervals.items()}
    assert all(0.80 <= beta[s] / s**2 <= 0.811 for s in beta if s >= 20)


def test_serk2_150_and_250_are_shorter_than_0_8_s_squared():
    beta = dict(zip(serk2.STAGES, serk2.BETA))
    assert all(0.80 <= beta[s] / s**2 <= 0.82 for s in (10, 20, 50, 100, 200))
    assert all(0.74 <= beta[s] / s**2 <= 0.75 for s in (150, 250))
    # the stage rule never picks a stage count whose interval is too short
    for x in np.linspace(1.0, serk2.BETA[-1], 500):
        assert x <= beta[serk2.stages_for(x, 1.0)]


@pytest.mark.parametrize("name,module,table,index",
                         [("rock2", rock2, "RECF", 60), ("serk2v2", serk2, "B", 15)])
def test_a_broken_coefficient_fails_the_interval_check(monkeypatch, name, module, table, index):
    values = list(getattr(module, table))
    values[index] *= 1.05
    monkeypatch.setattr(module, table, tuple(values))
    assert intervals(registry.get_integrator(name)).passed is False


@pytest.mark.parametrize("name", sorted(STABILIZED))
def test_observed_order_two_with_ibench_verify(name):
    v = verify(name)
    assert v.passed is True and v.order_passed is True, v.to_dict()
    assert abs(v.observed_order - 2) <= 0.3


@pytest.mark.parametrize("name", sorted(STABILIZED))
def test_adaptive_heat_meets_tolerance_with_many_stages(name):
    system, exact, rho = heat()
    cls = registry.get_integrator(name)
    sol, nfev = run(cls(), system, rtol=1e-4, atol=system.atol(1e-4))
    assert sol.success
    err = np.max(np.abs(np.asarray(sol.y) - np.array([exact(t) for t in sol.t])))
    assert err < 1e-2
    # explicit Euler would need h < 2 / rho: rho / 2 * 0.5 = 2500 steps
    assert sol.counts["nsteps"] < 200 and nfev < 2500, (sol.counts, nfev)


@pytest.mark.parametrize("name", sorted(STABILIZED))
def test_fixed_stages_setting_and_its_bad_value(name):
    """At a fixed stage count ``s``: stable at ``h rho = beta(s) / 2``, unstable at
    ``1.5 beta(s)``, ``s`` evaluations per step and no spectral radius."""
    system, exact, rho = heat()
    module = STABILIZED[name]
    cls = registry.get_integrator(name)
    s = module.STAGES[3]
    beta = module.real_stability_interval(STEP[name], s)
    size = np.max(np.abs(system.y0))
    steps = int(np.ceil(system.t_end * rho / (0.5 * beta)))   # the outputs on the grid
    sol, nfev = run(cls(stages=s), system, h=system.t_end / steps)
    # F_n first same as last, a dense output's F reused by the next step
    assert sol.success and nfev == steps * s
    assert np.max(np.abs(np.asarray(sol.y)[-1])) <= size
    sol, _ = run(cls(stages=s), system, h=1.5 * beta / rho)
    assert not sol.success or np.max(np.abs(np.asarray(sol.y)[-1])) > size
    bad = module.STAGES[-1] + 1
    with pytest.raises(SettingError, match=f"stages={bad} is not one of 0\\|{module.STAGES[0]}"):
        cls(stages=bad)


def test_fixed_step_beyond_the_largest_interval_is_a_method_limit():
    system, exact, rho = heat()
    longer = dataclasses.replace(system, t_end=200.0, t_eval=np.array([0.0, 200.0]))
    for cls in (rock2.Rock2, serk2.Serk2):
        sol, _ = run(cls(), longer, h=200.0)
        assert sol.status.value == "method_limit" and "stages" in sol.message


def test_stability_intervals_are_measured_on_first_use_once():
    """Importing the integrators measures no stability polynomial (every command
    paid it at import); an interval is computed when first read, and only once."""
    import subprocess
    import sys

    from integrator_bench.integrators.base import Intervals

    script = ("from integrator_bench.harness.matrix import registry\n"
              "c = registry.integrators()\n"
              "print(len(c['rkc'].stability_intervals._values),"
              " len(c['rock2'].stability_intervals._values),"
              " len(c['rock2'].stability_intervals))\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["0", "0", "7"]
    calls = []
    lazy = Intervals({"a": lambda: calls.append("a") or 2.0, "b": lambda: 3})
    assert (len(lazy), list(lazy), calls) == (2, ["a", "b"], [])
    assert lazy["a"] == lazy["a"] == 2.0 and calls == ["a"]
    assert dict(lazy) == {"a": 2.0, "b": 3.0} and type(lazy["b"]) is float
