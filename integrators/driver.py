"""The one stepping loop of every stepper-based integrator.

:func:`integrate` drives a :class:`~integrator_bench.integrators.base.Stepper`
from ``t0`` to ``t_end`` (compare scipy's ``solve_ivp`` loop over an
``OdeSolver`` and diffrax's ``diffeqsolve`` loop over ``AbstractSolver.step``).
It owns, once for all methods:

* **step-size control** by a controller chosen per run
  (:mod:`integrator_bench.integrators.control`): a run at ``h`` takes the
  steps ``t0 + k h`` (the last one shortened to end exactly at ``t_end``); a
  run at ``rtol`` accepts a step when the weighted RMS of its error estimate,
  ``rms(e_i / (atol_i + rtol max(|y_n,i|, |y_n+1,i|)))`` over the stepper's
  ``error_mask``, is at most 1, and the controller proposes the next step;
* **output** at ``system.t_eval`` without shortening steps: an output time
  within ``1e-9 h`` of a step end takes the step's value; one inside a step
  takes the step's dense output when the stepper gives one, else the driver's
  interpolation: the Lagrange polynomial of degree ``p + 1`` (``p`` the
  declared order, at least 1; degree at most 8) through ``p + 2`` consecutive
  accepted step values enclosing the output time, as centred as the steps
  taken allow (error ``O(h^(p+2))``, so that it stays well below the method's
  ``O(h^p)`` already at coarse steps; no function evaluations);
* **projection**: when the system carries ``project`` (the ``projection`` and
  ``partitioning`` formulations), every accepted step value and every
  interpolated output is projected;
* **the last step**: under error control a step that would end within 10 % of
  its size before ``t_end`` is stretched to end there, within the stepper's
  ``max_step`` (the code RKC's rule), so
  no run ends with a sliver of a step, which in index-3 formulations disturbs
  the multipliers (their error goes as the velocity error over the step);
* **failure**: a non-finite state (at a fixed step: the end of the run; under
  error control: a rejection by ``factor_min``), an ``OverflowError`` or
  ``FloatingPointError`` from the system (the solution blew up), a step size
  below ``1e-12 max(span, |t|)``, more than ``max_steps`` attempted steps, and a
  :class:`~integrator_bench.integrators.base.StepFailure` (retried at a quarter
  of the step under error control when it allows) each end the run with a
  typed :class:`~integrator_bench.integrators.base.Status`;
* **counts**: ``nsteps`` (accepted steps) and ``nreject`` (rejected by the
  error test); the stepper adds its own (``njev``, ``nlu``, ...).
"""

from __future__ import annotations

import math
import numpy as np

from integrator_bench.integrators.base import Solution, Status, Step, StepFailure
from integrator_bench.integrators.control import ConstantStep, PIControl
from integrator_bench.integrators.interpolation import Interpolation

SNAP = 1e-9            # output times this close (relative to h) to a step end take its value
MIN_STEP = 1e-12       # relative to max(span, |t|): step-size underflow below
FAILURE_FACTOR = 0.25  # step cut after a failed step under error control
LAST_STRETCH = 1.1     # a step within 10 % of t_end is stretched to end there (as RKC does)


class Outputs:
    """The output array and the output times still to fill."""

    def __init__(self, system, degree):
        self.t_eval = system.t_eval
        self.ys = np.empty((self.t_eval.size, system.n))
        self.done = np.zeros(self.t_eval.size, bool)
        self.next = 1                 # the first output time no step has reached yet
        self.pending: list[int] = []  # reached, waiting for the interpolation
        self.interp = Interpolation(degree)
        self.project = getattr(system, "project", None)

    @property
    def filled(self) -> int:
        """How many output times from the first on have their values."""
        return int(np.argmin(self.done)) if not self.done.all() else self.done.size

    def start(self, t0, y0):
        self.ys[0], self.done[0] = y0, True
        self.interp.add(t0, y0)

    def step(self, t_new, h, y_new, step: Step):
        """Fill the outputs up to ``t_new`` after an accepted step."""
        self.interp.add(t_new, y_new)
        while self.next < self.t_eval.size and self.t_eval[self.next] <= t_new + SNAP * h:
            i, te = self.next, self.t_eval[self.next]
            self.next += 1
            if abs(te - t_new) <= SNAP * h:
                self._set(i, y_new, project=False)
            elif step.dense is not None:
                self._set(i, np.asarray(step.dense(te), float))
            else:
                self.pending.append(i)
        self.flush(final=False)

    def flush(self, final: bool):
        while self.pending and self.interp.ready(self.t_eval[self.pending[0]], final):
            i = self.pending.pop(0)
            self._set(i, self.interp(self.t_eval[i]))

    def _set(self, i, value, project=True):
        if project and self.project is not None:
            value = np.asarray(self.project(self.t_eval[i], value), float)
        self.ys[i], self.done[i] = value, True


def _norm(err, y, y_new, rtol, atol, mask) -> float:
    w = atol + rtol * np.maximum(np.abs(y), np.abs(y_new))
    r = err / w
    if mask is not None:
        r = r[mask]
    return float(np.sqrt(np.mean(r * r))) if r.size else 0.0


def initial_step(system, stepper, y0, rtol, atol) -> float:
    """The first step of an adaptive run: the stepper's proposal, or Hairer's
    estimate (Hairer, Norsett and Wanner I, sect. II.4; two evaluations of ``f``)."""
    span = system.t_end - system.t0
    h = stepper.initial_step(system.t0, y0, rtol, atol)
    if h is not None:
        return min(h, span)
    fun = getattr(system, "fun", None)
    if fun is None:
        return 1e-3 * span
    order = (stepper.error_order or 1) + 1
    scale = atol + rtol * np.abs(y0)
    f0 = np.asarray(fun(system.t0, y0), float)
    d0, d1 = (float(np.sqrt(np.mean((x / scale) ** 2))) for x in (y0, f0))
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, span)
    f1 = np.asarray(fun(system.t0 + h0, y0 + h0 * f0), float)
    d2 = float(np.sqrt(np.mean(((f1 - f0) / scale) ** 2))) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, 1e-3 * h0)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / order)
    return min(100 * h0, h1, span)


def integrate(integrator, system, *, rtol=None, atol=None, h=None) -> Solution:
    """Run ``integrator``'s stepper over ``system``: at the fixed step ``h``
    when given, else under error control with ``rtol``/``atol``."""
    counts = {"nsteps": 0, "nreject": 0}
    if h is not None:
        rtol = atol = None
    elif atol is not None:
        atol = np.broadcast_to(np.asarray(atol, float), (system.n,))
    stepper = integrator.stepper(system, counts, rtol=rtol, atol=atol)
    if h is not None:
        control = ConstantStep(h)
    else:
        if stepper.error_order is None or rtol is None:
            raise ValueError(f"{integrator.name} has no error estimate: give h, not rtol")
        control = PIControl(order=stepper.error_order, safety=integrator.safety,
                            factor_min=integrator.factor_min,
                            factor_max=integrator.factor_max,
                            hold_band=integrator.hold_band)
    outputs = Outputs(system, (integrator.order or 1) + 1)
    loop = _Loop(system, stepper, control, counts, outputs, rtol, atol, integrator.max_steps)
    status, message = loop.run()
    outputs.flush(final=True)
    n = outputs.filled
    return Solution(system.t_eval[:n], outputs.ys[:n], message=message, counts=counts,
                    status=status)


class _Loop:
    def __init__(self, system, stepper, control, counts, outputs, rtol, atol, max_steps):
        self.system, self.stepper, self.control = system, stepper, control
        self.counts, self.outputs = counts, outputs
        self.rtol, self.atol, self.max_steps = rtol, atol, max_steps
        self.project = getattr(system, "project", None)
        self.t = system.t0            # start of the step under way, for messages

    def run(self) -> tuple[Status, str]:
        system, stepper = self.system, self.stepper
        t0, t_end = system.t0, system.t_end
        t = t0
        try:
            y = np.asarray(stepper.start(t0, np.array(system.y0, dtype=float)), float)
            self.outputs.start(t0, y)
            if self.control.adaptive:
                return self._adaptive(t, y)
            return self._fixed(t, y)
        except (OverflowError, FloatingPointError) as exc:
            return Status.DIVERGED, (f"overflow in the step from t={self.t:.6g} ({exc}): "
                                     "the solution blew up")

    def _accept(self, t, t_new, h, y, step):
        y_new = step.y
        if self.project is not None:
            y_new = np.asarray(self.project(t_new, y_new), float)
        self.stepper.accept(t_new, y_new)
        self.counts["nsteps"] += 1
        self.outputs.step(t_new, h, y_new, step)
        return y_new

    def _fixed(self, t, y):
        system, h = self.system, self.control.h
        t0, t_end = system.t0, system.t_end
        n = int(math.floor((t_end - t0) / h + SNAP))
        times = t0 + h * np.arange(1, n + 1)
        if times.size == 0 or t_end - times[-1] > SNAP * h:
            times = np.append(times, t_end)
        else:
            times[-1] = t_end
        for t_new in times:
            self.t = t
            try:
                step = self.stepper.step(t, y, t_new - t)
            except StepFailure as exc:
                return exc.status, str(exc)
            if not np.all(np.isfinite(step.y)):
                return Status.NONFINITE_STATE, f"non-finite state at t={t_new:.6g}"
            y = self._accept(t, t_new, h, y, step)
            t = t_new
        return Status.SUCCESS, ""

    def _adaptive(self, t, y):
        system, stepper, control = self.system, self.stepper, self.control
        t_end = system.t_end
        span = t_end - system.t0
        self.t = t
        h = initial_step(system, stepper, y, self.rtol, self.atol)
        attempts = 0
        while t < t_end:
            self.t = t
            if attempts >= self.max_steps:
                return Status.MAX_STEPS, f"more than {self.max_steps} steps"
            cap = stepper.max_step(t, y)
            h = min(h, cap)
            if t + LAST_STRETCH * h >= t_end and t_end - t <= cap:   # no sliver of a last step
                h = t_end - t
            if h < MIN_STEP * max(span, abs(t)):
                return Status.STEP_SIZE_UNDERFLOW, f"step size {h:.3g} too small at t={t:.6g}"
            attempts += 1
            t_new = t_end if h == t_end - t else t + h
            try:
                step = stepper.step(t, y, h)
            except StepFailure as exc:
                if not exc.retry:
                    return exc.status, str(exc)
                h = control.failed(h, FAILURE_FACTOR)
                if h < MIN_STEP * max(span, abs(t)):
                    return exc.status, f"{exc} (at the minimum step)"
                continue
            if np.all(np.isfinite(step.y)):
                err = _norm(step.error, y, step.y, self.rtol, self.atol, stepper.error_mask)
            else:
                err = math.inf
            if not err <= 1.0:
                self.counts["nreject"] += 1
                stepper.reject()
                h = control.reject(h, err)
                continue
            y = self._accept(t, t_new, h, y, step)
            t = t_new
            h = control.accept(h, err)
        return Status.SUCCESS, ""
