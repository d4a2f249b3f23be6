"""DUMKA3 (integrators/dumka.py): the stability intervals of its polynomials, its
order, and its adaptive and fixed-step runs on a stiff 1-D heat equation."""

from __future__ import annotations

import numpy as np
import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.run.execution import counted
from integrator_bench.harness.checks.verify import ORDER_PROBLEMS, order_on, verify
from integrator_bench.integrators import dumka
from integrator_bench.integrators.base import Status
from integrator_bench.integrators.settings import SettingError
from integrator_bench.integrators.dumka import (N_DEG, PUBLISHED_BETA, STAB_REG, USABLE, Dumka3,
                                                stability_function, with_polynomial)
from integrator_bench.problems.system import OdeSystem

DAMPED = range(1, 8)     # P1-P7 keep |R| <= 0.1 on their band (module docstring)
ETA = 0.1 * (1 + 1e-3)


def measured_beta(k: int, eta: float = 1.0) -> float:
    """The largest ``x`` with ``|R_k(-y)| <= eta`` for all ``y`` in ``[y0, x]``, ``y0``
    the first ``y >= 0`` where ``|R_k(-y)| <= eta``: a scan over ``[0, 1.3 beta_k]``
    in steps below ``beta_k / 10^5``, then bisection."""
    x = np.linspace(0.0, 1.3 * STAB_REG[k], 130_001)
    inside = np.abs(stability_function(k, -x)) <= eta
    first = int(np.argmax(inside))
    out = np.nonzero(~inside[first:])[0]
    assert out.size, f"P{k}: |R| <= {eta} over the whole scan"
    lo, hi = x[first + out[0] - 1], x[first + out[0]]
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if abs(stability_function(k, -mid)) <= eta:
            lo = mid
        else:
            hi = mid
    return lo


def heat(n=49, t_end=0.5, n_out=6):
    """``u_t = u_xx`` on (0, 1), zero ends, ``n`` interior points (spectral
    radius ``4/dx^2 sin^2(n pi dx/2)``, about 1e4 for n = 49), with the exact
    semi-discrete solution (three sine modes, eigenvectors of the stencil)."""
    dx = 1.0 / (n + 1)
    x = dx * np.arange(1, n + 1)
    modes, amps = (1, 3, 10), (1.0, 0.5, 0.2)
    lam = [4 / dx**2 * np.sin(m * np.pi * dx / 2) ** 2 for m in modes]

    def fun(t, u):
        d = -2.0 * u
        d[1:] += u[:-1]
        d[:-1] += u[1:]
        return d / dx**2

    def exact(t):
        return sum(a * np.exp(-l * t) * np.sin(m * np.pi * x) for a, m, l in zip(amps, modes, lam))

    system = OdeSystem(t0=0.0, t_end=t_end, y0=exact(0.0), t_eval=np.linspace(0, t_end, n_out),
                       atol_scale=1.0, fun=fun)
    rho = 4 / dx**2 * np.sin(n * np.pi * dx / 2) ** 2
    return system, exact, rho


class Recording(Dumka3):
    """Dumka3 keeping its last stepper, to read the polynomials it used."""

    name = "test-dumka3-recording"

    def stepper(self, system, counts, rtol=None, atol=None):
        Recording.last = super().stepper(system, counts, rtol, atol)
        return Recording.last


def run(cls, system, **kw):
    system, counters = counted(system)
    sol = cls().solve(system, **kw)
    return sol, counters["nfev"].n


@pytest.fixture
def registered():
    """dumka3 (registered by its entry point) and two fixed-polynomial variants,
    registered here as a benchmark script registers them."""
    assert registry.get_integrator("dumka3") is Dumka3
    variants = (with_polynomial(4), with_polynomial(USABLE - 1))
    for cls in variants:
        registry.register(cls, origin="tests")
    yield (Dumka3,) + variants
    for cls in variants:
        registry.unregister(cls.name)


@pytest.mark.parametrize("k", range(USABLE))
def test_stability_interval_matches_published(k):
    beta = measured_beta(k, ETA if k in DAMPED else 1.0)
    assert abs(beta / PUBLISHED_BETA[k] - 1) <= 0.01, (k, beta)
    # the published interval is stable: |R| <= 1 on all of [0, beta_k]
    assert measured_beta(k) >= STAB_REG[k]


def test_stability_function_is_third_order_for_every_polynomial():
    z = np.array([1e-2, 2e-2, 4e-2])
    for k in range(USABLE):
        err = np.abs(stability_function(k, -z) - np.exp(-z))
        slope = np.polyfit(np.log(z), np.log(err), 1)[0]
        assert 3.7 < slope < 4.3, (k, slope)    # R_k(z) - e^z = O(z^4)


def test_p13_of_the_source_is_defective_and_refused():
    # R_13'(0) should be 1 for a consistent method; the source's table gives 1 - 1.7e-5
    d = (stability_function(13, 1e-4) - stability_function(13, -1e-4)).real / 2e-4
    assert abs(d - 1) > 1e-5
    assert measured_beta(13) < 0.2 * PUBLISHED_BETA[13]
    with pytest.raises(ValueError, match="0..12"):
        with_polynomial(13)


def test_broken_coefficient_fails_the_interval_check(monkeypatch):
    subs = [list(s) for s in dumka.SUBSTEPS[9]]
    subs[3][1] *= 1.05                                  # one factor of P9 off by 5 %
    table = list(dumka.SUBSTEPS)
    table[9] = tuple(tuple(s) for s in subs)
    monkeypatch.setattr(dumka, "SUBSTEPS", tuple(table))
    assert abs(measured_beta(9) / PUBLISHED_BETA[9] - 1) > 0.01


def test_observed_order_three_with_ibench_verify(registered):
    for cls in registered:
        v = verify(cls.name)
        assert v.order_passed is True, v
        assert abs(v.observed_order - 3) <= 0.3


def test_broken_coefficient_fails_the_order_check(monkeypatch):
    last = list(dumka.LAST_A21)
    last[0] += 1e-3                     # P0 (the one small spectral radii take)
    monkeypatch.setattr(dumka, "LAST_A21", tuple(last))
    results = [order_on(Dumka3, p) for p in ORDER_PROBLEMS]
    assert any(r is not None and r.passed is False for r in results)


def test_adaptive_heat_meets_tolerance_cheaply_and_adapts_degree():
    rtol = 1e-5
    system, exact, rho = heat()
    assert 9e3 < rho < 1.1e4
    sol, nfev = run(Recording, system, rtol=rtol, atol=system.atol(rtol))
    assert sol.success and len(sol.t) == system.t_eval.size
    err = max(np.max(np.abs(y - exact(t))) for t, y in zip(sol.t, sol.y))
    assert err <= rtol, err
    used = Recording.last.used
    assert len(used) >= 3, used          # the degree follows the step
    rk45 = registry.get_integrator("scipy-RK45")
    system, _, _ = heat()
    sol45, nfev45 = run(rk45, system, rtol=rtol, atol=system.atol(rtol))
    assert sol45.success
    assert 5 * nfev < nfev45, (nfev, nfev45)


def test_fixed_step_degree_grows_with_h_rho():
    chosen = []
    for h in (1e-4, 1e-3, 1e-2):
        system, exact, rho = heat(t_end=0.1)
        sol, _ = run(Recording, system, h=h)
        assert sol.success
        assert np.max(np.abs(sol.y[-1] - exact(0.1))) < 1e-3
        used = Recording.last.used
        k = max(used)
        assert STAB_REG[k] >= h * rho and (k == 0 or STAB_REG[k - 1] < h * rho * 1.2)
        chosen.append(k)
    assert chosen == sorted(chosen) and chosen[0] < chosen[-1], chosen


def test_method_limit_beyond_the_largest_interval():
    system, _, rho = heat(t_end=10.0)
    h = 2.0 * STAB_REG[USABLE - 1] / rho
    sol = Dumka3().solve(system, h=h)
    assert sol.status is Status.METHOD_LIMIT
    assert f"degree {N_DEG[USABLE - 1]}" in sol.message and "exceeds" in sol.message


def test_fixed_polynomial_variant_has_orlovs_label():
    cls = with_polynomial(4)            # Orlov's P4 is degree 21, P9 degree 81
    assert cls.name == "dumka3-P4" and list(cls.stability_intervals) == ["P4 (degree 21)"]
    assert list(with_polynomial(9).stability_intervals) == ["P9 (degree 81)"]
    assert not cls.adaptive and cls.takes_h()
    system, exact, rho = heat(t_end=0.05)
    h = 0.9 * PUBLISHED_BETA[4] / rho
    sol, nfev = run(cls, system, h=h)
    assert sol.success and np.max(np.abs(sol.y[-1] - exact(0.05))) < 1e-3
    steps = int(np.ceil(0.05 / h - 1e-9))
    assert nfev == 1 + 21 * steps      # no spectral radius: f(y0), then 21 per step
    assert cls.mode_unsupported(1e-6, None) is not None


@pytest.mark.parametrize("name", ["dumka3", "rkc"])
def test_the_step_limit_message_says_where_its_spectral_radius_was_estimated(name):
    """The radius a failing step used, where it was estimated (a run that blew up
    estimates at its blown-up state) and the first estimate, the start's: here the
    coupling damper's -c2 (m1 + m2) / (m1 m2) = -2e7, times RKC's safety 1.2."""
    from integrator_bench.harness.matrix.cases import expand
    from integrator_bench.harness.run.execution import execute

    case, = [c for c in expand(problems=["two_mass:c2=10000000"], integrators=[name],
                               hs=[0.1]) if not c.unsupported]
    record = execute(case)
    assert record["reason"] == "method_limit", record["message"]
    assert "with spectral radius 2.4e+07 (its estimate at t=0, where |y| = 1.42; " \
           "2.4e+07 at the first)" in record["message"]


def test_the_former_numeric_setting_is_refused_with_the_new_values():
    with pytest.raises(SettingError, match=r"polynomial=6 is not one of auto\|P0\|P1"):
        Dumka3(polynomial="6")
    assert Dumka3(polynomial="P5").polynomial == "P5"
