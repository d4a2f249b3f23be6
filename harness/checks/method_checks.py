"""The checks of ``ibench check-plugin`` that judge the method itself.

:mod:`integrator_bench.harness.checks.conformance` checks the plumbing (declarations,
records, counts, failures); these two check what a plausible wrong method gets
wrong, each on problems whose answer is known exactly, reading only what the
integrator declares and what the harness itself sees.

``accuracy`` (integrators declaring ``adaptive``)
    The ramp ``y' = (1 + tanh((t - 1) / w)) / 2``, ``y(0) = 0``, ``w = 0.01``
    on ``[0, 2]``, exactly ``y(2) = 1`` (:func:`ramp`): ``f`` is zero to
    rounding before the ramp, so steps grow there, and a step that reaches
    into the ramp must be rejected and cut. At ``rtol = 1e-3, 1e-5, 1e-7``
    (``atol = rtol``), each on a fresh system, the error at ``t = 2`` must stay within
    :data:`ACCURACY_FACTOR` times ``rtol`` (what the tolerance promises), its
    slope against ``rtol`` on a log-log scale must be at least
    :data:`MIN_SLOPE` (tolerance proportionality: it falls as ``rtol`` falls;
    ``p / (p + 1) >= 1/2`` for error-per-step control of order ``p``), and an
    integrator that reports ``nreject`` must have rejected a step at one of
    the tolerances: an estimate that never rejects here never bites. An
    integrator taking only mechanical systems runs the undamped oscillator
    ``x'' = -x`` (exact ``cos t``) instead, without the rejection test.
``stability`` (integrators declaring ``"A"`` or ``"L"``)
    The linear test equation at ``z = h lam = r e^(i theta)`` for ``r`` in
    :data:`STAB_RADII` and ``theta`` in :data:`STAB_ANGLES` (the imaginary
    axis, the left half-plane, the negative real axis): as the rotation-decay
    ``y' = r [[cos theta, -sin theta], [sin theta, cos theta]] y`` (eigenvalues
    ``r e^(+-i theta)``) for an ODE integrator, as ``x'' + c x' + k x = 0``
    with ``k = r^2``, ``c = -2 r cos theta`` (the damper ``c = r``, ``k = 0`` on
    the real axis) for a mechanical one. An integrator that takes ``h`` runs
    :data:`STAB_STEPS` steps of ``h = 1``; the observed ``|R(z)|`` is the
    per-step growth over the second half (``(m_N / m_{N/2})^(2/N)`` for the
    Euclidean norm, ``sqrt(v^2 + k x^2)`` for a mechanical system), the
    spectral radius of a multistep or Newmark-family method once its
    transient has passed. ``"A"``: at most ``1 + 1e-6`` at every sample.
    ``"L"``: besides, at most :data:`L_BOUND` at ``|z| = 1e6`` at every angle
    (``|R(z)| -> 0`` as ``|z| -> inf``, with or without a phase); ROS3P's
    ``|R(inf)| = sqrt(3) - 1`` fails it. An adaptive code that cannot take
    ``h`` is judged at ``|lam| = 1e6`` off the imaginary axis: over ``[0, 1]``
    at ``rtol = 1e-6`` it must end with ``|y(1)| <= 1e-3`` in at most
    :data:`STIFF_NFEV` evaluations counted by the harness (an explicit
    method needs about 1e5 steps); its error control hides the difference
    between ``"A"`` and ``"L"``, which is therefore not judged.

A run either check cannot judge (it failed, stopped short of ``t_end`` or
returned a NaN or infinite value) fails the line, naming why
(:func:`~integrator_bench.harness.checks.verify.unusable`: its status and message, or
the time and component where its output first went non-finite).
"""

from __future__ import annotations

import math

import numpy as np

from integrator_bench.harness.checks.verify import solve_counted, unusable
from integrator_bench.harness.checks.verify_problems import mechanical_oscillator
from integrator_bench.problems.system import OdeSystem, convert, takes

ACCURACY_RTOLS = (1e-3, 1e-5, 1e-7)
ACCURACY_FACTOR = 1000.0
MIN_SLOPE = 0.4
RAMP_WIDTH = 0.01
OSCILLATOR_SPAN = 2.0
STAB_RADII = {"ode": (1.0, 1e2, 1e6), "mechanical": (1.0, 1e2, 1e4)}
STAB_ANGLES = (180.0, 150.0, 120.0, 90.0)
STAB_STEPS = 20
L_BOUND = 0.1
A_BOUND = 1.0 + 1e-6
STIFF_NFEV = 20_000


def _lncosh(x):
    a = np.abs(x)
    return a + np.log1p(np.exp(-2.0 * a)) - math.log(2.0)


def ramp_exact(t, w: float = RAMP_WIDTH) -> float:
    """``y(t) = (t + w ln cosh((t - 1) / w) - w ln cosh(1 / w)) / 2``: ``y(0) = 0``,
    ``y(2) = 1``."""
    return 0.5 * (t + w * _lncosh((t - 1.0) / w) - w * _lncosh(1.0 / w))


def ramp(w: float = RAMP_WIDTH) -> tuple[OdeSystem, float]:
    """The ramp system on ``[0, 2]`` and its exact ``y(2)``."""
    def fun(t, y):
        return np.full(1, 0.5 * (1.0 + math.tanh((t - 1.0) / w)))

    return OdeSystem(t0=0.0, t_end=2.0, y0=np.zeros(1), t_eval=np.array([0.0, 2.0]),
                     atol_scale=1.0, fun=fun, jac=lambda t, y: np.zeros((1, 1))), \
        float(ramp_exact(2.0, w))


def _accuracy_problem(icls):
    """``(system, exact final value, component, rejections judged)`` or None."""
    system, exact = ramp()
    if takes(system, icls):
        return convert(system, icls), exact, 0, True
    oscillator = mechanical_oscillator(1.0, 0.0, OSCILLATOR_SPAN)
    if takes(oscillator, icls):
        return convert(oscillator, icls), math.cos(OSCILLATOR_SPAN), 0, False
    return None


def accuracy(icls) -> tuple[bool | None, str]:
    """The ``accuracy`` verdict and its one-line detail (see the module docstring)."""
    if not icls.adaptive:
        return None, "runs at fixed steps only (no tolerance to keep)"
    if _accuracy_problem(icls) is None:
        return None, f"no accuracy test problem for kind {'/'.join(sorted(icls.accepts))}"
    errors, rejects = [], []
    for rtol in ACCURACY_RTOLS:
        system, exact, i, judge_rejects = _accuracy_problem(icls)   # a fresh one each time
        sol, nfev = solve_counted(icls, system, rtol=rtol, atol=system.atol(rtol))
        why = unusable(sol, system)
        if why:
            return False, f"no usable run at rtol {rtol:g}: {why}"
        errors.append(max(abs(float(np.asarray(sol.y, float)[-1, i]) - exact), 1e-16))
        rejects.append(sol.counts.get("nreject"))
    slope = float(np.polyfit(np.log10(ACCURACY_RTOLS), np.log10(errors), 1)[0])
    text = ", ".join(f"{e:.1e} at {r:g}" for e, r in zip(errors, ACCURACY_RTOLS))
    problems = []
    worst = max(e / r for e, r in zip(errors, ACCURACY_RTOLS))
    if worst > ACCURACY_FACTOR:
        problems.append(f"error up to {worst:.3g} x rtol (allowed {ACCURACY_FACTOR:g})")
    if slope < MIN_SLOPE:
        problems.append(f"error does not fall with rtol (slope {slope:.2f} < {MIN_SLOPE})")
    reported = [n for n in rejects if n is not None]
    if judge_rejects and reported and not any(reported):
        problems.append("its error estimate never rejected a step on a problem that needs it")
    name = "ramp" if judge_rejects else "oscillator"
    detail = f"{name}: error {text}; slope {slope:.2f}"
    if judge_rejects:
        detail += (f"; nreject {'/'.join(str(n) for n in rejects)}" if reported
                   else "; nreject not reported (not judged)")
    return not problems, "; ".join(problems + [detail])


def _rotation_decay(r: float, theta: float, t_end: float) -> OdeSystem:
    c, s = math.cos(math.radians(theta)), math.sin(math.radians(theta))
    A = r * np.array([[c, -s], [s, c]])
    return OdeSystem(t0=0.0, t_end=t_end, y0=np.array([1.0, 0.0]),
                     t_eval=np.array([0.0, t_end / 2, t_end]), atol_scale=1.0,
                     fun=lambda t, y: A @ y, jac=lambda t, y: A)


def _test_system(icls, r, theta, t_end):
    """The test equation at ``z = r e^(i theta)`` in a kind ``icls`` takes:
    ``(system, measure, kind)``, or None."""
    ode = _rotation_decay(r, theta, t_end)
    if takes(ode, icls):
        return convert(ode, icls), lambda y: float(np.linalg.norm(y[:2])), "ode"
    cos = round(math.cos(math.radians(theta)), 15)   # 0 on the imaginary axis
    k, c = (0.0, r) if theta == 180.0 else (r * r, -2.0 * r * cos)
    mech = mechanical_oscillator(k, c, t_end, v0=1.0, x0=1.0 / max(r, 1.0))
    if takes(mech, icls):
        return (convert(mech, icls), lambda y: math.sqrt(y[2] ** 2 + k * y[0] ** 2),
                "mechanical")
    return None


def _late_rate(sol, system, measure) -> tuple[float, str | None]:
    """Per-step growth over the second half of a run of ``STAB_STEPS`` steps, and
    why it could not be measured (:func:`unusable`; the growth is then inf)."""
    why = unusable(sol, system)
    if why:
        return math.inf, why
    y = np.asarray(sol.y, float)
    mid, end = measure(y[1]), measure(y[2])
    if mid < 1e-250:
        return (0.0 if end <= mid else math.inf), None
    return (end / mid) ** (2.0 / STAB_STEPS), None


def _z(r, theta) -> str:
    return f"{r:g} e^(i {theta:g} deg)"


def stability(icls) -> tuple[bool | None, str]:
    """The ``stability`` verdict and its one-line detail (see the module docstring)."""
    if icls.stability not in ("A", "L"):
        return None, "no stability declared"
    found = _test_system(icls, 1.0, 180.0, 1.0)
    if found is None:
        return None, f"no stability test problem for kind {'/'.join(sorted(icls.accepts))}"
    radii = STAB_RADII[found[2]]
    if icls.takes_h():
        return _stability_at_h(icls, radii)
    return _stiff_decay(icls, radii[-1])


def _stability_at_h(icls, radii):
    """|R(z)| sampled at ``h = 1``; the worst sample overall and at the largest ``|z|``."""
    worst, worst_far = (-1.0, None), (-1.0, None)
    for r in radii:
        for theta in STAB_ANGLES:
            system, measure, _ = _test_system(icls, r, theta, float(STAB_STEPS))
            sol, _ = solve_counted(icls, system, h=1.0)
            rate, why = _late_rate(sol, system, measure)
            sample = (rate, (r, theta, why))
            worst = max(worst, sample, key=lambda x: x[0])
            if r == radii[-1]:
                worst_far = max(worst_far, sample, key=lambda x: x[0])
    rate, (r, theta, why) = worst
    if why:
        return False, (f"declared {icls.stability}: no usable run at z = {_z(r, theta)}: "
                       f"{why}")
    if rate > A_BOUND:
        return False, (f"declared {icls.stability}: |R(z)| {rate:.3g} > 1 at z = "
                       f"{_z(r, theta)}: unstable in the left half-plane")
    detail = (f"|R(z)| <= {rate:.3g} on {len(radii) * len(STAB_ANGLES)} samples of the "
              f"closed left half-plane, |z| up to {radii[-1]:g}")
    if icls.stability == "L":
        rate, (r, theta, _) = worst_far
        if rate > L_BOUND:
            return False, (f"declared L: |R(z)| {rate:.3g} > {L_BOUND:g} at z = {_z(r, theta)}: "
                           "R(z) does not vanish as |z| grows (A-stable at most)")
        detail += f"; L: |R(z)| <= {rate:.3g} at |z| = {radii[-1]:g}"
    return True, detail


def _stiff_decay(icls, r):
    """An adaptive code that cannot take ``h``: stiff decay at ``|lam| = r``."""
    most = 0
    for theta in STAB_ANGLES[:-1]:
        system, measure, _ = _test_system(icls, r, theta, 1.0)
        sol, nfev = solve_counted(icls, system, rtol=1e-6, atol=system.atol(1e-6))
        why = unusable(sol, system)
        if why:
            return False, (f"declared {icls.stability}: at lam = {_z(r, theta)} over [0, 1] "
                           f"at rtol 1e-6: no usable run: {why}")
        end = measure(np.asarray(sol.y, float)[-1])
        if not (end <= 1e-3 and nfev <= STIFF_NFEV):
            return False, (f"declared {icls.stability}: at lam = {_z(r, theta)} over [0, 1] "
                           f"at rtol 1e-6: |y(1)| {end:.3g}, nfev {nfev} "
                           f"(allowed 1e-3 and {STIFF_NFEV})")
        most = max(most, nfev)
    return True, (f"stiff decay at |lam| = {r:g} off the imaginary axis in at most {most} "
                  "evaluations (an adaptive code: A and L not told apart)")
