"""``ibench verify``: observed order of convergence and stability of every integrator.

For each registered integrator (plugins included), reading only what it
declares:

**Order.** On each test problem of :mod:`integrator_bench.harness.verify_problems` whose kind
it accepts (through :func:`integrator_bench.problems.system.convert`, so DAE-only codes get the
ODE problems as index-0 DAEs), the error ``err`` (largest absolute error over
the output times and compared components) is measured over a ladder:

* fixed-step integrators: ``h = span / N``, ``N = 8, 16, ..., 4096``, stopped
  once ``err < 1e-11``; the observed order is the slope of ``log err`` against
  ``log h``;
* adaptive integrators: ``rtol = 1e-2 ... 1e-11`` (``atol = rtol``); the
  observed order is the slope of ``log err`` against ``-log nsteps``
  (accepted steps; function evaluations when a code does not count steps).
  With step sizes ``h ~ span/nsteps`` spread over the interval as the error
  control chooses, ``err ~ nsteps^-p`` for a method of order ``p``.

The fit is a least-squares line through the finest (at most 5) ladder points
whose error lies in ``[1e-11, 5e-2]``: above that window the method is not in
its asymptotic regime, below it rounding dominates; fewer than 3 such points
make the check fail ("inconclusive"). The verdict per problem:

* fixed-step, declared order ``p``: pass when ``|observed - p| <= 0.3``;
* adaptive, declared ``p``: pass when ``|observed - p| <= 0.25 p + 0.5`` (a
  tolerance ladder measures the order through the error controller, whose
  step choice and the discreteness of the step counts make the slope
  noisier, more so for high orders; the criterion still separates p from
  p +- 2 for p <= 5 and from the embedded lower order);
* declared order None (variable-order codes): the observed slope is reported
  with no verdict.

An integrator's ``observed_order`` is the per-problem value farthest from the
declared order (the smallest one when no order is declared).

**Stability** (declared ``"A"`` or ``"L"``), on ``y' = lam y`` with
``lam = -1e6`` and on the rotation with eigenvalues ``+-1e6 i`` (for
mechanical integrators: a stiff damper ``c = 1e6`` and a stiff undamped spring
``k = 1e6``):

* fixed-step: 40 steps of ``h = 1`` (``|h lam| = 1e6``): the solution must not
  grow over the second half of the run (``|y_40| <= |y_20| (1 + 1e-6)``;
  mechanical: ``|v|`` for the damper, ``sqrt(v^2 + k x^2)`` for the spring) on
  both problems, which allows the bounded transient growth of methods with a
  non-normal amplification matrix; for ``"L"`` the decaying one must reach
  ``|y_40| <= 1e-3 |y_0|``;
* adaptive: ``y' = -1e6 y`` over ``[0, 1]`` at ``rtol = 1e-6``: it must finish
  in at most 1000 steps (an explicit method needs about 1e5) with
  ``|y(1)| <= 1e-3``. The imaginary-axis check does not apply (an adaptive
  code must resolve an oscillation, which is accuracy, not stability).

Integrators with no accepted test problem are reported as not verified, which
is not a failure.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from integrator_bench.harness import registry
from integrator_bench.harness.runner import counted
from integrator_bench.harness.verify_problems import (ORDER_PROBLEMS, dahlquist, mechanical_oscillator,
                                     rotation)
from integrator_bench.problems.system import convert, takes

FIXED_TOL = 0.3
N_LADDER = tuple(int(round(8 * 2 ** (j / 2))) for j in range(19))  # 8, 11, ... 4096 steps
RTOL_LADDER = tuple(10.0 ** -e for e in range(2, 12))   # 1e-2 ... 1e-11
ERR_WINDOW = (1e-11, 1e-1)
FIT_POINTS = 5
STIFF = 1e6
STAB_STEPS = 40


def adaptive_tolerance(order: int) -> float:
    """Allowed ``|observed - declared|`` for adaptive integrators."""
    return max(0.5, 0.15 * order)


@dataclass
class OrderResult:
    problem: str
    observed_order: float | None
    passed: bool | None
    detail: str = ""
    ladder: list = field(default_factory=list)   # [h or rtol, work, err]


@dataclass
class StabilityResult:
    declared: str
    passed: bool
    checks: dict = field(default_factory=dict)
    detail: str = ""


@dataclass
class Verdict:
    integrator: str
    declared_order: int | None
    observed_order: float | None
    order_passed: bool | None
    adaptive: bool
    orders: list = field(default_factory=list)
    stability: StabilityResult | None = None
    note: str = ""

    @property
    def passed(self) -> bool | None:
        """False when any check failed; None when nothing could be checked."""
        results = [self.order_passed] + ([self.stability.passed] if self.stability else [])
        if any(r is False for r in results):
            return False
        return True if any(r is True for r in results) else None

    def to_dict(self) -> dict:
        d = asdict(self)
        d["passed"] = self.passed
        return d


def _error(sol, problem, system) -> float:
    if not sol.success or len(sol.t) != system.t_eval.size:
        return math.inf
    y = np.asarray(sol.y, float)[-1:, problem.compared]
    if not np.all(np.isfinite(y)):
        return math.inf
    return float(np.max(np.abs(y - problem.exact(sol.t[-1:]))))


def _run(icls, system, **kw):
    system, counters = counted(system)
    sol = icls().solve(system, **kw)
    return sol, counters["nfev"].n


def fit_order(x, err) -> tuple[float | None, str]:
    """Slope of ``log err`` against ``log x`` over the finest in-window points."""
    pts = [(a, e) for a, e in zip(x, err) if ERR_WINDOW[0] <= e <= ERR_WINDOW[1]]
    pts = pts[-FIT_POINTS:]
    if len(pts) < 3:
        return None, f"inconclusive: {len(pts)} ladder points with error in " \
                     f"[{ERR_WINDOW[0]:g}, {ERR_WINDOW[1]:g}]"
    a, e = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.polyfit(a, e, 1)[0]), f"fit over {len(pts)} points"


def order_on(icls, problem) -> OrderResult | None:
    """Observed order of ``icls`` on ``problem``; None when it cannot take it."""
    span = problem.t_adaptive if icls.adaptive else problem.t_fixed
    if not takes(problem.make(span), icls):
        return None
    ladder = []
    try:
        if icls.adaptive:
            for rtol in RTOL_LADDER:
                system = convert(problem.make(span), icls)
                sol, nfev = _run(icls, system, rtol=rtol, atol=system.atol(rtol))
                work = sol.counts.get("nsteps") or nfev
                ladder.append([rtol, int(work), _error(sol, problem, system)])
                if ladder[-1][2] < ERR_WINDOW[0]:
                    break
            slope, detail = fit_order([1.0 / w for _, w, _ in ladder], [e for *_, e in ladder])
        else:
            for n in N_LADDER:
                system = convert(problem.make(span), icls)
                h = span / n
                sol, _ = _run(icls, system, h=h)
                ladder.append([h, int(sol.counts.get("nsteps", n)), _error(sol, problem, system)])
                if ladder[-1][2] < ERR_WINDOW[0]:
                    break
            slope, detail = fit_order([h for h, *_ in ladder], [e for *_, e in ladder])
    except Exception as exc:  # an integrator that raises fails the check, never verify
        return OrderResult(problem.name, None, False, f"{type(exc).__name__}: {exc}", ladder)
    p = icls.order
    if slope is None:
        return OrderResult(problem.name, None, False if p is not None else None, detail, ladder)
    if p is None:
        return OrderResult(problem.name, slope, None, detail + "; variable order: no verdict", ladder)
    tol = adaptive_tolerance(p) if icls.adaptive else FIXED_TOL
    ok = abs(slope - p) <= tol
    return OrderResult(problem.name, slope, ok, f"{detail}; |{slope:.2f} - {p}| "
                       f"{'<=' if ok else '>'} {tol:g}", ladder)


def _growth(sol, system, measure) -> tuple[float, float]:
    """``(m(y_N) / m(y_0), m(y_N) / m(y_{N/2}))`` for the measure ``m``.

    The second, late ratio is the stability verdict: a method whose
    amplification matrix is not normal (multistep, Newmark family) can grow
    the norm for a few steps and still be stable; over the second half of
    the run only a spectral radius above 1 shows. A solution that has
    decayed below 1e-250 counts as decayed.
    """
    if not sol.success or len(sol.t) != system.t_eval.size:
        return math.nan, math.nan
    y = np.asarray(sol.y, float)
    if not np.all(np.isfinite(y)):
        return math.inf, math.inf
    m0, m1, m2 = (float(measure(row)) for row in y)
    late = m2 / m1 if m1 > 1e-250 else (0.0 if m2 <= 1e-250 else math.inf)
    return m2 / m0, late


def stability(icls) -> StabilityResult | None:
    """The Dahlquist-type stability check for a declared ``"A"`` or ``"L"``."""
    if icls.stability not in ("A", "L"):
        return None
    norm = np.linalg.norm
    if takes(dahlquist(-1.0, 1.0), icls):
        decay = (dahlquist(-STIFF, STAB_STEPS), norm)
        spin = (rotation(STIFF, STAB_STEPS), norm)
        stiff = dahlquist(-STIFF, 1.0)
    elif takes(mechanical_oscillator(1.0, 0.0, 1.0), icls):
        decay = (mechanical_oscillator(0.0, STIFF, STAB_STEPS, v0=1.0), lambda y: abs(y[2]))
        spin = (mechanical_oscillator(STIFF, 0.0, STAB_STEPS),
                lambda y: math.sqrt(y[2] ** 2 + STIFF * y[0] ** 2))
        stiff = mechanical_oscillator(0.0, STIFF, 1.0, v0=1.0)
    else:
        return StabilityResult(icls.stability, True, {}, "not verified: no stability test "
                               f"problem for kind {'/'.join(sorted(icls.accepts))}")
    checks = {}
    try:
        if icls.adaptive:
            system = convert(stiff, icls)
            sol, _ = _run(icls, system, rtol=1e-6, atol=system.atol(1e-6))
            steps = sol.counts.get("nsteps")
            end = float(np.max(np.abs(np.asarray(sol.y, float)[-1][:1]))) if sol.success and \
                len(sol.t) == system.t_eval.size else math.inf
            if system.kind == "mechanical":
                end = abs(float(np.asarray(sol.y, float)[-1][2])) if math.isfinite(end) else end
            ok = sol.success and end <= 1e-3 and (steps is None or steps <= 1000)
            checks["stiff_decay"] = {"lam": -STIFF, "t_end": 1.0, "rtol": 1e-6, "nsteps": steps,
                                     "final": end, "passed": bool(ok)}
        else:
            for label, (system, measure) in (("real", decay), ("imaginary", spin)):
                system = convert(system, icls)
                sol, _ = _run(icls, system, h=1.0)
                growth, late = _growth(sol, system, measure)
                ok = late <= 1.0 + 1e-6
                if label == "real" and icls.stability == "L":
                    ok = ok and growth <= 1e-3
                checks[label] = {"h_lam": STIFF, "steps": STAB_STEPS, "growth": growth,
                                 "late_growth": late, "passed": bool(ok), "message": sol.message}
    except Exception as exc:
        return StabilityResult(icls.stability, False, checks, f"{type(exc).__name__}: {exc}")
    return StabilityResult(icls.stability, all(c["passed"] for c in checks.values()), checks)


def verify(name: str) -> Verdict:
    """All checks for the registered integrator ``name``."""
    icls = registry.get_integrator(name)
    orders = [r for r in (order_on(icls, p) for p in ORDER_PROBLEMS) if r is not None]
    verdict = Verdict(name, icls.order, None, None, bool(icls.adaptive), orders,
                      stability(icls))
    if not orders:
        verdict.note = (f"not verified: no test problem for kind "
                        f"{'/'.join(sorted(icls.accepts))}")
        return verdict
    seen = [r.observed_order for r in orders if r.observed_order is not None]
    if seen:
        p = icls.order
        verdict.observed_order = min(seen) if p is None else max(seen, key=lambda o: abs(o - p))
    results = [r.passed for r in orders]
    verdict.order_passed = False if False in results else (True if True in results else None)
    return verdict


def verify_all(names=None) -> list[Verdict]:
    """Verdicts for ``names`` (default: every registered integrator)."""
    names = list(names) if names else list(registry.integrators())
    for n in names:
        registry.get_integrator(n)  # bad names fail before any work
    return [verify(n) for n in names]
