"""``ibench verify``: observed order of convergence and stability of every integrator.

For each registered integrator (plugins included), reading only what it
declares, and measuring only what the harness itself sees: the step size it
hands over and the function evaluations it counts (the system's callables are
wrapped by :func:`integrator_bench.harness.measure.counting.counted`). An integrator's
own counts (``Solution.counts``) never enter a verdict, so reporting more steps
than were taken cannot fake an order.

**Order.** On each test problem of :mod:`integrator_bench.harness.checks.verify_problems`
whose kind it accepts (through :func:`integrator_bench.problems.system.convert`,
so DAE-only codes get the ODE problems as index-0 DAEs), the error ``err``
(largest absolute error at the final time over the compared components) is
measured over a ladder:

* **fixed steps**, for every integrator with a stepper (adaptive or not: the
  shared driver then takes exactly the steps ``t0 + k h``) and for one with its
  own :meth:`solve` that takes ``h``: ``h = span / N``, ``N = 8, 11, ...,
  4096``. Two slopes are fitted: of ``log err`` against ``log h`` and against
  ``log(1 / nfev)`` with the harness's ``nfev``. The observed order is the
  smaller one: both equal ``p`` for a method doing a fixed amount of work per
  step (the ``nfev`` slope is larger when Newton iterations per step decrease
  with ``h``), while a method that hides sub-steps inside a step of size ``h``
  shows its true order in the ``nfev`` slope. Verdict: ``|observed - p| <=
  0.3`` (:data:`FIXED_TOL`).
* **tolerances**, for an integrator with its own adaptive loop that cannot
  take ``h`` (library codes and plugins with their own :meth:`solve`):
  ``rtol = 1e-2 ... 1e-11`` (``atol = rtol``); the observed order is the slope
  of ``log err`` against ``log(1 / nfev)``. With the error control spreading
  steps ``h ~ span / nsteps`` and a bounded number of evaluations per step,
  ``err ~ nfev^-p`` for a method of order ``p``. Verdict: ``|observed - p| <
  0.5`` (:data:`ADAPTIVE_TOL`), that is, the observed order is nearer ``p``
  than ``p - 1`` or ``p + 1``. The registered codes of this kind deviate by
  at most 0.39 (scipy-RK23 3.00 and 3.00, scipy-RK45 4.61 and 4.94,
  scipy-Radau 4.79 and 5.06, scipy-DOP853 7.71 and 8.17 on ``nonlinear`` and
  ``oscillator``): the error controller's step choice and an implicit code's
  varying Newton work per step make the slope noisier than at fixed steps.
  A method of order ``p - 1`` claiming ``p`` and scattering as much shows at
  most ``p - 0.6`` and fails; the boundary lies halfway between.

Each ladder stops once its error reached ``1e-11``, or at a **work
budget**: once a run took more than :data:`WORK_BUDGET` evaluations counted by
the harness, or the next run is predicted to (from the growth of the last
rung). A method of order 1 thus ends after a few seconds per problem instead
of running to ``rtol = 1e-11``. A problem whose ladder the budget stopped
before three errors reached the fit window (an order-1 code on the Kepler
orbit) is reported without a verdict; the integrator is then judged on the
other problems, and fails when no problem gives a verdict on its declared
order.

The fit is a least-squares line through the finest (at most 5) ladder points
whose error lies in ``[1e-11, 1e-1]``: above that window the method is not in
its asymptotic regime, below it rounding dominates; fewer than 3 such points
make the check fail ("inconclusive"), unless the work budget cut the ladder
(above). Declared order None (variable-order
codes): the observed slope is reported with no verdict.

An integrator's ``observed_order`` is the per-problem value farthest from the
declared order (the smallest one when no order is declared).

**Stability** (declared ``"A"`` or ``"L"``), on ``y' = lam y`` with
``lam = -1e6`` and on the rotation with eigenvalues ``+-1e6 i`` (for
mechanical integrators: a stiff damper ``c = 1e6`` and a stiff undamped spring
``k = 1e6``):

* an integrator that takes ``h``: 40 steps of ``h = 1`` (``|h lam| = 1e6``):
  the solution must not grow over the second half of the run
  (``|y_40| <= |y_20| (1 + 1e-6)``; mechanical: ``|v|`` for the damper,
  ``sqrt(v^2 + k x^2)`` for the spring) on both problems, which allows the
  bounded transient growth of methods with a non-normal amplification matrix;
  for ``"L"`` the decaying one must reach ``|y_40| <= 1e-3 |y_0|``;
* an adaptive code that cannot take ``h``: ``y' = -1e6 y`` over ``[0, 1]`` at
  ``rtol = 1e-6``: it must finish with ``|y(1)| <= 1e-3`` in at most 20000
  evaluations counted by the harness (an explicit method needs about 1e5
  steps). The imaginary-axis check does not apply (an adaptive code must
  resolve an oscillation, which is accuracy, not stability).

**Real stability interval** (an explicit method declaring
``stability_variants``: the settings that run the variant each label of its
``stability_intervals`` names): for each such label, the integrator at those
settings takes one step of ``h = 1`` on ``y' = -x y`` at
:data:`INTERVAL_SAMPLES` points ``x`` spread over ``(0, beta]`` (``beta`` its
declared interval, the last point ``beta`` itself) and at ``x = (1 +``
:data:`INTERVAL_BEYOND` ``) beta``. Verdict: ``|y_1| <= 1 + 1e-9`` at every
point of ``(0, beta]`` (the declared interval is stable), and ``|y_1| > 1``
somewhere in ``(beta, (1 + INTERVAL_BEYOND) beta]``: the first unstable
sample is searched on a grid there (a declared interval much shorter than
the true one is a wrong claim too). The detail names the measured boundary.

Integrators with no accepted test problem are reported as not verified, which
is not a failure.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.measure.counting import counted
from integrator_bench.harness.measure.metrics import first_nonfinite
from integrator_bench.harness.checks.verify_problems import (ORDER_PROBLEMS, dahlquist,
                                                      mechanical_oscillator, rotation)
from integrator_bench.problems.system import convert, takes

FIXED_TOL = 0.3
ADAPTIVE_TOL = 0.5     # strict: |observed - p| < 0.5
N_LADDER = tuple(int(round(8 * 2 ** (j / 2))) for j in range(19))  # 8, 11, ... 4096 steps
RTOL_LADDER = tuple(10.0 ** -e for e in range(2, 12))   # 1e-2 ... 1e-11
ERR_WINDOW = (1e-11, 1e-1)
FIT_POINTS = 5
WORK_BUDGET = 200_000   # harness-counted evaluations of one ladder run
STIFF = 1e6
STAB_STEPS = 40
STIFF_NFEV = 20_000     # evaluations allowed for the adaptive stiff-decay check
INTERVAL_SAMPLES = 200  # points of (0, beta] where one step must not grow
INTERVAL_BEYOND = 0.05  # some point of (beta, 1.05 beta] must grow
INTERVAL_GROWTH = 1.0 + 1e-9


def adaptive_tolerance(order: int) -> float:
    """The bound on ``|observed - declared|`` (strict) for a tolerance ladder; the
    same for every order (see the module docstring)."""
    return ADAPTIVE_TOL


def fixed_ladder(icls) -> bool:
    """Whether the order is measured at fixed steps (a stepper, or a code taking ``h``)."""
    return icls.has_stepper() or icls.takes_h()


@dataclass
class OrderResult:
    problem: str
    observed_order: float | None
    passed: bool | None
    detail: str = ""
    ladder: list = field(default_factory=list)   # [h or rtol, harness nfev, err]
    method: str = ""                              # "h" or "rtol"


@dataclass
class StabilityResult:
    declared: str
    passed: bool
    checks: dict = field(default_factory=dict)
    detail: str = ""


@dataclass
class IntervalResult:
    passed: bool
    checks: dict = field(default_factory=dict)   # label -> declared, measured, passed
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
    interval: IntervalResult | None = None

    @property
    def passed(self) -> bool | None:
        """False when any check failed; None when nothing could be checked."""
        results = [self.order_passed] + [c.passed for c in (self.stability, self.interval) if c]
        if any(r is False for r in results):
            return False
        return True if any(r is True for r in results) else None

    def to_dict(self) -> dict:
        d = asdict(self)
        d["passed"] = self.passed
        return d


def unusable(sol, system) -> str | None:
    """Why a run cannot be judged, or None: it gave up (its status and message,
    and where its outputs first went non-finite), did not reach ``t_end``, or
    reported success with a non-finite output (where it first appears)."""
    where = first_nonfinite(sol.t, sol.y) if len(sol.t) else None
    if not sol.success:
        return f"{sol.status.value} ({sol.message})" + (f"; {where}" if where else "")
    if len(sol.t) != system.t_eval.size:
        return f"reported success with {len(sol.t)} of {system.t_eval.size} outputs"
    return f"reported success with a {where}" if where else None


def _error(sol, problem, system) -> float:
    if not sol.success or len(sol.t) != system.t_eval.size:
        return math.inf
    y = np.asarray(sol.y, float)[-1:, problem.compared]
    if not np.all(np.isfinite(y)):
        return math.inf
    return float(np.max(np.abs(y - problem.exact(sol.t[-1:]))))


def solve_counted(icls, system, **kw):
    """Solve a counted copy of ``system``; return the solution and the harness's nfev."""
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


def _over_budget(ladder) -> bool:
    """Whether the last run (or the next one, predicted from the last rung's
    growth) exceeds the work budget."""
    if ladder[-1][1] > WORK_BUDGET:
        return True
    if len(ladder) >= 2 and ladder[-2][1] > 0:
        return ladder[-1][1] ** 2 / ladder[-2][1] > WORK_BUDGET
    return False


def _climb(icls, problem, span, rungs, key) -> tuple[list, bool, str | None]:
    """Run the ladder ``key = rung`` (``h`` or ``rtol``) until the error floor or
    the work budget; return the ladder, whether the budget stopped it, and why the
    first unusable run was (``"at h=0.1: non-finite output at t=..."``, None when
    every run was usable)."""
    ladder, failed = [], None
    for i, rung in enumerate(rungs):
        system = convert(problem.make(span), icls)
        kw = {"h": span / rung} if key == "h" else {"rtol": rung, "atol": system.atol(rung)}
        sol, nfev = solve_counted(icls, system, **kw)
        ladder.append([kw[key], int(nfev), _error(sol, problem, system)])
        why = unusable(sol, system)
        if why and failed is None:
            failed = f"at {key}={kw[key]:g}: {why}"
        if ladder[-1][2] < ERR_WINDOW[0]:
            break
        if _over_budget(ladder):
            return ladder, i + 1 < len(rungs), failed
    return ladder, False, failed


def _slope(ladder, key) -> tuple[float | None, str]:
    """The observed order of a ladder (see the module docstring)."""
    errs = [e for *_, e in ladder]
    by_work, detail = fit_order([1.0 / max(w, 1) for _, w, _ in ladder], errs)
    if key == "rtol" or by_work is None:
        return by_work, detail + (" against 1/nfev" if by_work is not None else "")
    by_h, _ = fit_order([h for h, *_ in ladder], errs)
    slope = min(by_h, by_work)
    return slope, f"{detail}: {by_h:.2f} against h, {by_work:.2f} against 1/nfev"


def order_on(icls, problem) -> OrderResult | None:
    """Observed order of ``icls`` on ``problem``; None when it cannot take it."""
    key = "h" if fixed_ladder(icls) else "rtol"
    span = problem.t_fixed if key == "h" else problem.t_adaptive
    if not takes(problem.make(span), icls):
        return None
    ladder, budget = [], False
    try:
        ladder, budget, failed = _climb(icls, problem, span,
                                        N_LADDER if key == "h" else RTOL_LADDER, key)
        slope, detail = _slope(ladder, key)
        if failed and slope is None:
            detail += f" (first unusable run {failed})"
    except Exception as exc:  # an integrator that raises fails the check, never verify
        return OrderResult(problem.name, None, False, f"{type(exc).__name__}: {exc}", ladder,
                           key)
    p = icls.order
    if slope is None:
        if budget:   # judged on the other problems; see verify()
            detail += f" within the work budget of {WORK_BUDGET} evaluations"
            return OrderResult(problem.name, None, None, detail, ladder, key)
        return OrderResult(problem.name, None, False if p is not None else None, detail,
                           ladder, key)
    if p is None:
        return OrderResult(problem.name, slope, None, detail + "; variable order: no verdict",
                           ladder, key)
    if key == "h":
        tol, rel = FIXED_TOL, ("<=", ">")
        ok = abs(slope - p) <= tol
    else:
        tol, rel = adaptive_tolerance(p), ("<", ">=")
        ok = abs(slope - p) < tol
    return OrderResult(problem.name, slope, ok, f"{detail}; |{slope:.2f} - {p}| "
                       f"{rel[0] if ok else rel[1]} {tol:g}", ladder, key)


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
        if not fixed_ladder(icls):
            system = convert(stiff, icls)
            sol, nfev = solve_counted(icls, system, rtol=1e-6, atol=system.atol(1e-6))
            end = float(np.max(np.abs(np.asarray(sol.y, float)[-1][:1]))) if sol.success and \
                len(sol.t) == system.t_eval.size else math.inf
            if system.kind == "mechanical":
                end = abs(float(np.asarray(sol.y, float)[-1][2])) if math.isfinite(end) else end
            ok = sol.success and end <= 1e-3 and nfev <= STIFF_NFEV
            checks["stiff_decay"] = {"lam": -STIFF, "t_end": 1.0, "rtol": 1e-6, "nfev": nfev,
                                     "final": end, "passed": bool(ok)}
        else:
            for label, (system, measure) in (("real", decay), ("imaginary", spin)):
                system = convert(system, icls)
                sol, _ = solve_counted(icls, system, h=1.0)
                growth, late = _growth(sol, system, measure)
                ok = late <= 1.0 + 1e-6
                if label == "real" and icls.stability == "L":
                    ok = ok and growth <= 1e-3
                checks[label] = {"h_lam": STIFF, "steps": STAB_STEPS, "growth": growth,
                                 "late_growth": late, "passed": bool(ok), "message": sol.message}
    except Exception as exc:
        return StabilityResult(icls.stability, False, checks, f"{type(exc).__name__}: {exc}")
    return StabilityResult(icls.stability, all(c["passed"] for c in checks.values()), checks)


def _one_step_growth(icls, settings: dict, x: float) -> float:
    """``|y_1|`` after one step ``h = 1`` of ``icls(**settings)`` on ``y' = -x y``."""
    system, _ = counted(dahlquist(-x, 1.0))
    sol = icls(**settings).solve(system, h=1.0)
    y = np.asarray(sol.y, float)
    if not sol.success or len(sol.t) != system.t_eval.size or not np.isfinite(y[-1, 0]):
        return math.inf
    return abs(float(y[-1, 0]))


def intervals(icls) -> IntervalResult | None:
    """The real-stability-interval check (see the module docstring); None when the
    integrator declares no ``stability_variants``."""
    if not icls.stability_variants:
        return None
    checks, bad = {}, []
    for label, settings in icls.stability_variants.items():
        beta = float(icls.stability_intervals[label])
        inside = beta * np.linspace(1.0 / INTERVAL_SAMPLES, 1.0, INTERVAL_SAMPLES)
        worst = max(_one_step_growth(icls, settings, x) for x in inside)
        beyond = beta * (1.0 + INTERVAL_BEYOND * np.linspace(0.05, 1.0, 20))
        first = next((x for x in beyond
                      if _one_step_growth(icls, settings, x) > INTERVAL_GROWTH), None)
        ok = worst <= INTERVAL_GROWTH and first is not None
        checks[label] = {"declared": beta, "max_growth_inside": worst,
                         "first_unstable": first, "passed": bool(ok)}
        if not ok:
            bad.append(f"{label}: " + (f"|R| {worst:.6g} > 1 inside [-{beta:.6g}, 0]"
                                       if worst > INTERVAL_GROWTH else
                                       f"still stable at -{beta * (1 + INTERVAL_BEYOND):.6g}"))
    detail = "; ".join(bad) or (f"{len(checks)} declared intervals stable and tight "
                                f"(within {INTERVAL_BEYOND:.0%})")
    return IntervalResult(not bad, checks, detail)


def verify(name: str) -> Verdict:
    """All checks for the registered integrator ``name``."""
    icls = registry.get_integrator(name)
    orders = [r for r in (order_on(icls, p) for p in ORDER_PROBLEMS) if r is not None]
    verdict = Verdict(name, icls.order, None, None, bool(icls.adaptive), orders,
                      stability(icls), interval=intervals(icls))
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
    if verdict.order_passed is None and icls.order is not None:
        verdict.order_passed = False   # a declared order no problem could confirm
        verdict.note = "no test problem reached the asymptotic error window"
    return verdict

