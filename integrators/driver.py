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
  error test); the stepper adds its own (``njev``, ``nlu``, ...);
* **state events** (``system.events``, :class:`EventTracker`, shared with the
  scipy wrappers): after each accepted step every event function is evaluated
  at the step end; a strict sign change (respecting ``direction``) is located
  on the step's dense output by the Illinois method (regula falsi with
  halving, bisection when the bracket does not halve) to a bracket of width
  ``4 eps max(|t|, 1) + EVENT_ATOL``, and the crossing is the bracket's end
  past the sign change (as SUNDIALS returns its root), so the same crossing
  is never found again after a restart. The earliest crossing in the step is
  acted on first: non-terminal ones are recorded, a terminal one without
  reset ends the run successfully there, a terminal one whose ``reset``
  returns a state restarts the run from it with a fresh stepper and
  controller (at a fixed step the grid restarts at the event), one whose
  ``reset`` returns None is ignored. Outputs up to the event come from the
  dense output; a stepper without one cannot locate events (its integrator
  declares ``events = False``).
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
EVENT_ATOL = 1e-14     # absolute part of the event-time tolerance (time units)
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

    def restart(self, t, y):
        """The run restarts from ``(t, y)`` after a reset: no interpolation across it."""
        self.interp = Interpolation(self.interp.degree)
        self.interp.add(t, y)

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


def _crossed(direction, g_old, g_new) -> bool:
    """A strict sign change from ``g_old`` to ``g_new`` (reaching zero counts, leaving
    it does not) in the event's ``direction``."""
    rising, falling = g_old < 0 <= g_new, g_old > 0 >= g_new
    return rising if direction > 0 else falling if direction < 0 else rising or falling


def locate(g, a, b, ga, gb) -> float:
    """The end past the sign change of a bracket of ``g`` (``g(a) = ga != 0``,
    ``g(b) = gb`` of the other sign or zero) narrowed to ``4 eps max(|b|, 1) +
    EVENT_ATOL``: Illinois (regula falsi halving the value of an end kept twice;
    Dowell and Jarratt, BIT 11 (1971) 168-174), bisecting when two iterations
    have not halved the bracket."""
    pre = math.copysign(1.0, ga)
    side, widths = 0, [b - a, b - a]
    for _ in range(200):
        tol = 4 * np.finfo(float).eps * max(abs(b), 1.0) + EVENT_ATOL
        if b - a <= tol:
            break
        c = b - gb * (b - a) / (gb - ga)
        if not widths[-2] > 2 * (b - a) and len(widths) > 2:
            c = 0.5 * (a + b)
        c = min(max(c, a + 0.25 * tol), b - 0.25 * tol)
        gc = float(g(c))
        if pre * gc > 0:
            a, ga = c, gc
            if side < 0:
                gb *= 0.5
            side = -1
        else:
            b, gb = c, gc
            if side > 0:
                ga *= 0.5
            side = 1
        widths.append(b - a)
    return b


class EventTracker:
    """Sign changes of ``events`` over accepted steps (see the module docstring).

    Attributes
    ----------
    log : list of (t, name, y_after)
        The crossings acted on, in order (the :class:`Solution`'s ``events``).
    """

    def __init__(self, events, project=None):
        self.events, self.project, self.log, self.g = tuple(events), project, [], None

    def _values(self, t, y):
        return np.array([float(e.value(t, y)) for e in self.events])

    def start(self, t, y):
        """The run (re)starts at ``(t, y)``."""
        self.g = self._values(t, y)

    def step(self, t, t_new, y_new, dense):
        """Check the accepted step ``[t, t_new]`` with ``dense(s) -> y(s)``.

        Returns None to go on, else ``(t_event, y_event, y_after)`` with
        ``y_after`` None for a terminal stop."""
        g_new = self._values(t_new, y_new)
        found = []
        for i, (event, a, b) in enumerate(zip(self.events, self.g, g_new)):
            if _crossed(event.direction, a, b):
                if dense is None:
                    raise StepFailure(Status.METHOD_LIMIT, "the step has no dense output "
                                      "to locate a state event on", retry=False)
                found.append((locate(lambda s, e=event: e.value(s, dense(s)),
                                     t, t_new, a, b), i))
        self.g = g_new
        for t_event, i in sorted(found):
            y_event = np.asarray(dense(t_event), float)
            if self.project is not None:
                y_event = np.asarray(self.project(t_event, y_event), float)
            ends, y_after = act(self.events[i], t_event, y_event, self.log)
            if ends:
                return t_event, y_event, y_after
        return None


def act(event, t, y, log) -> tuple[bool, np.ndarray | None]:
    """Act on ``event``, crossed at ``(t, y)``, as the module docstring says, and
    record it in ``log`` (``(t, name, state after)``) unless it is ignored.

    One rule for every code that locates events (the driver's
    :class:`EventTracker`, the scipy wrappers through it, SUNDIALS' roots in
    :mod:`integrator_bench.integrators.sundials`).

    Returns
    -------
    (ends, y_after) : (bool, ndarray or None)
        ``ends`` False: go on (a non-terminal event, or a crossing the reset
        ignores by returning None). ``ends`` True: the run ends here, with
        ``y_after`` None for a terminal stop, else the state to restart from.
    """
    if not event.terminal or event.reset is None:
        log.append((t, event.name, np.array(y, dtype=float)))
        return event.terminal, None
    y_after = event.reset(t, np.array(y, dtype=float))
    if y_after is None:                   # ignored by the current mode
        return False, None
    y_after = np.array(y_after, dtype=float)
    log.append((t, event.name, y_after.copy()))
    return True, y_after


class _EventHit(Exception):
    """A terminal event acted on inside :meth:`_Loop._accept`."""

    def __init__(self, t, y_after, name):
        super().__init__(name)
        self.t, self.y_after, self.name = t, y_after, name


def initial_step(system, stepper, y0, rtol, atol, t0=None) -> float:
    """The first step of an adaptive run from ``t0`` (default ``system.t0``): the
    stepper's proposal, or Hairer's estimate (Hairer, Norsett and Wanner I,
    sect. II.4; two evaluations of ``f``)."""
    t0 = system.t0 if t0 is None else t0
    span = system.t_end - t0
    h = stepper.initial_step(t0, y0, rtol, atol)
    if h is not None:
        return min(h, span)
    fun = getattr(system, "fun", None)
    if fun is None:
        return 1e-3 * span
    order = (stepper.error_order or 1) + 1
    scale = atol + rtol * np.abs(y0)
    f0 = np.asarray(fun(t0, y0), float)
    d0, d1 = (float(np.sqrt(np.mean((x / scale) ** 2))) for x in (y0, f0))
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, span)
    f1 = np.asarray(fun(t0 + h0, y0 + h0 * f0), float)
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

    def fresh():
        """A new stepper and controller (the start, and every restart after a reset)."""
        stepper = integrator.stepper(system, counts, rtol=rtol, atol=atol)
        if h is not None:
            return stepper, ConstantStep(h)
        if stepper.error_order is None or rtol is None:
            raise ValueError(f"{integrator.name} has no error estimate: give h, not rtol")
        return stepper, PIControl(order=stepper.error_order, safety=integrator.safety,
                                  factor_min=integrator.factor_min,
                                  factor_max=integrator.factor_max,
                                  hold_band=integrator.hold_band)

    stepper, control = fresh()
    outputs = Outputs(system, (integrator.order or 1) + 1)
    events = (EventTracker(system.events, getattr(system, "project", None))
              if system.events else None)
    loop = _Loop(system, stepper, control, counts, outputs, rtol, atol, integrator.max_steps,
                 events=events, fresh=fresh)
    status, message = loop.run()
    outputs.flush(final=True)
    n = outputs.filled
    log = events.log if events is not None else []
    if events is not None:
        counts["nevents"] = len(log)
    return Solution(system.t_eval[:n], outputs.ys[:n], message=message, counts=counts,
                    status=status, events=log)


class _Loop:
    def __init__(self, system, stepper, control, counts, outputs, rtol, atol, max_steps,
                 events=None, fresh=None):
        self.system, self.stepper, self.control = system, stepper, control
        self.counts, self.outputs = counts, outputs
        self.rtol, self.atol, self.max_steps = rtol, atol, max_steps
        self.events, self.fresh, self.attempts = events, fresh, 0
        self.project = getattr(system, "project", None)
        self.t = system.t0            # start of the step under way, for messages

    def run(self) -> tuple[Status, str]:
        system = self.system
        t_end, span = system.t_end, system.t_end - system.t0
        t, y = system.t0, np.array(system.y0, dtype=float)
        try:
            y = np.asarray(self.stepper.start(t, y), float)
            self.outputs.start(t, y)
            while True:
                if self.events is not None:
                    self.events.start(t, y)
                try:
                    if self.control.adaptive:
                        return self._adaptive(t, y)
                    return self._fixed(t, y)
                except _EventHit as hit:
                    t, y = hit.t, hit.y_after
                    if y is None:
                        return Status.SUCCESS, (f"stopped by the terminal event {hit.name!r} "
                                                f"at t={t:.9g}")
                if t_end - t <= MIN_STEP * max(span, abs(t)):   # a reset at t_end
                    for i in np.flatnonzero(~self.outputs.done):
                        self.outputs._set(i, y, project=False)
                    return Status.SUCCESS, ""
                self.stepper, self.control = self.fresh()
                y = np.asarray(self.stepper.start(t, y), float)
                self.outputs.restart(t, y)
        except StepFailure as exc:        # from the event location
            return exc.status, str(exc)
        except (OverflowError, FloatingPointError) as exc:
            return Status.DIVERGED, (f"overflow in the step from t={self.t:.6g} ({exc}): "
                                     "the solution blew up")

    def _accept(self, t, t_new, h, y, step):
        y_new = step.y
        if self.project is not None:
            y_new = np.asarray(self.project(t_new, y_new), float)
        self.stepper.accept(t_new, y_new)
        self.counts["nsteps"] += 1
        if self.events is not None:
            hit = self.events.step(t, t_new, y_new, step.dense)
            if hit is not None:                 # outputs up to the event, then stop/restart
                t_event, y_event, y_after = hit
                self.outputs.step(t_event, h, y_event, step)
                raise _EventHit(t_event, y_after, self.events.log[-1][1])
        self.outputs.step(t_new, h, y_new, step)
        return y_new

    def _fixed(self, t, y):
        system, h = self.system, self.control.h
        t0, t_end = t, system.t_end            # t0: the start, or the restart after a reset
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
        h = initial_step(system, stepper, y, self.rtol, self.atol, t0=t)
        while t < t_end:
            self.t = t
            if self.attempts >= self.max_steps:
                return Status.MAX_STEPS, f"more than {self.max_steps} steps"
            cap = stepper.max_step(t, y)
            h = min(h, cap)
            if t + LAST_STRETCH * h >= t_end and t_end - t <= cap:   # no sliver of a last step
                h = t_end - t
            if h < MIN_STEP * max(span, abs(t)):
                return Status.STEP_SIZE_UNDERFLOW, f"step size {h:.3g} too small at t={t:.6g}"
            self.attempts += 1
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
