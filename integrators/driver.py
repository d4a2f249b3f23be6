"""The segment runner every integrator feeds, and the stepping loop of the steppers.

:class:`Segments` owns, once for every family, what happens between a code's
accepted steps and the :class:`~integrator_bench.integrators.base.Solution`:
output filling, state events (located here, or found by the library), their
action, terminal stops, resets and restarts. A code feeds it in one of two
ways (compare scipy's ``solve_ivp``, one loop over every ``OdeSolver``, and
diffrax's ``diffeqsolve``, one loop over every ``AbstractSolver.step``):

* **steps**: after each accepted step, :meth:`Segments.step` ``(t_old, t, y,
  dense)`` with the state kept at ``t`` and ``dense(s) -> y(s)`` on ``[t_old,
  t]`` (None: the driver's interpolation). The steppers of this package
  (:func:`integrate`), scipy's ``OdeSolver`` classes
  (:mod:`~integrator_bench.integrators.scipy_ivp`) and SUNDIALS
  (:mod:`~integrator_bench.integrators.sundials`, whose ``dense`` asks the
  solver for its interpolant) all do;
* **roots**: a code with root finding of its own (SUNDIALS; Assimulo would
  be another) builds its :class:`Segments` with ``locate=False`` and hands
  each root it returns to :meth:`Segments.roots` ``(t, y, indices, dense, h)``
  (the events found there, and the size of the step that holds the root)
  before it feeds that step.

The code's loop over one segment is ``advance(t, y) -> (status, message)``;
:meth:`Segments.run` calls it from the start and again after every reset,
with ``restart(t, y_after) -> y`` (a fresh code from the reset state) in
between. A stop or a reset found inside ``step``/``roots`` ends ``advance``
by an exception the runner catches, so the code's loop needs no event logic
(a ``try``/``finally`` there keeps the counts of the code that stopped).

The rules:

* **output** at ``system.t_eval`` without shortening steps: an output time
  within ``1e-9 h`` of a step end takes the step's value; one inside a step
  takes the step's dense output when the code gives one, else the driver's
  interpolation: the Lagrange polynomial of degree ``p + 1`` (``p`` the
  declared order, at least 1; degree at most 8) through ``p + 2`` consecutive
  accepted step values enclosing the output time, as centred as the steps
  taken allow (error ``O(h^(p+2))``, so that it stays well below the method's
  ``O(h^p)`` already at coarse steps; no function evaluations). When the
  system carries ``project`` (the ``projection`` and ``partitioning``
  formulations) every interpolated output is projected; the code feeds
  projected step values;
* **state events** (``system.events``, located here): at each step end every
  event function is evaluated; a strict sign change (respecting
  ``direction``) is located on the step's dense output by the Illinois method
  (regula falsi with halving, bisection when the bracket does not halve) to a
  bracket of width ``4 eps max(|t|, 1) + EVENT_ATOL``, and the crossing is the
  bracket's end past the sign change (as SUNDIALS returns its root), so the
  same crossing is never found again after a restart. A code without dense
  output cannot locate events (its integrator declares ``events = False``);
* **action** (:func:`act`, also on library roots): the earliest crossing is
  acted on first; a non-terminal one is recorded; a terminal one without
  reset ends the run successfully there ("stopped by the terminal event
  NAME at t=T"); a terminal one whose ``reset`` returns a state restarts the
  run from it with a fresh code (fresh stepper and controller; at a fixed
  step the grid restarts at the event), or ends it when the event lies within
  ``MIN_STEP max(span, |t|)`` of ``t_end`` (the outputs left take the reset
  state); one whose ``reset`` returns None is ignored. Outputs up to the
  event come from the dense output.
* **budget**: a run started inside :func:`budgeted` is stopped at its first
  accepted step past its :class:`Budget` (``Status.OVER_BUDGET``, the progress
  in the message).

:func:`integrate` drives a :class:`~integrator_bench.integrators.base.Stepper`
from ``t0`` to ``t_end`` with one loop for fixed and adaptive runs:

* **step-size control** by the controller of the run, a
  :class:`~integrator_bench.integrators.control.StepSizeController`: a
  :class:`~integrator_bench.integrators.control.ConstantStep` for a run at
  ``h`` (steps ``t0 + k h``, the last one shortened to end exactly at
  ``t_end``), else a :class:`~integrator_bench.integrators.control.PIControl`
  built from the integrator's ``controller`` constants. The controller owns
  the error norm (a step is accepted when the weighted RMS of its error
  estimate over the stepper's ``error_mask`` is at most 1), the bound by the
  stepper's ``max_step``, the stretch of a last step that would end within
  10 % of its size before ``t_end`` (no sliver of a last step, the code RKC's
  rule) and the step-size underflow test;
* **projection**: when the system carries ``project``, every accepted step
  value is projected;
* **the state** the driver keeps (what ``start`` returns, each accepted step
  value) is made read-only (:func:`kept`): a stepper that writes into the state
  it is handed fails at that write, and the driver, trying the step once more on
  a writeable copy, names it (:class:`~integrator_bench.integrators.base.InputModified`);
* **failure**: a non-finite state (at a fixed step: the end of the run; under
  error control: a rejection by ``factor_min``), an ``OverflowError`` or
  ``FloatingPointError`` from the system (the solution blew up), a step size
  below ``MIN_STEP max(span, |t|)``, more than ``max_steps`` attempted steps,
  and a :class:`~integrator_bench.integrators.base.StepFailure` (retried at a
  quarter of the step when the controller allows) each end the run with a
  typed :class:`~integrator_bench.integrators.base.Status`;
* **counts**: ``nsteps`` (accepted steps) and ``nreject`` (rejected by the
  error test); the stepper adds its own (``njev``, ``nlu``, ...).
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import math
import time

import numpy as np

from integrator_bench.integrators.outcome import InputModified, Solution, Status, StepFailure
from integrator_bench.integrators.control import (MIN_STEP, ConstantStep, StepSizeUnderflow,
                                                   rms)
from integrator_bench.integrators.interpolation import Interpolation

SNAP = 1e-9            # output times this close (relative to h) to a step end take its value
FAILURE_FACTOR = 0.25  # step cut after a failed step under error control
EVENT_ATOL = 1e-14     # absolute part of the event-time tolerance (time units)
STALLED = 1000         # a library code's returns in a row that do not advance t: underflow


class Outputs:
    """The output array and the output times still to fill."""

    def __init__(self, system, degree, batch=False):
        self.t_eval, self.batch = system.t_eval, batch
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

    def step(self, t_new, h, y_new, dense):
        """Fill the outputs up to ``t_new`` after an accepted step."""
        self.interp.add(t_new, y_new)
        self.fill(t_new, h, y_new, dense)

    def fill(self, t_new, h, y_new, dense):
        """Fill the outputs up to ``t_new``, where the state is ``y_new``; those
        inside the step from ``dense`` (one call on all of them when ``batch``)."""
        if self.next >= self.t_eval.size or self.t_eval[self.next] > t_new + SNAP * h:
            if self.pending:                   # no output time reached: the common case
                self.flush(final=False)
            return
        inner = []
        while self.next < self.t_eval.size and self.t_eval[self.next] <= t_new + SNAP * h:
            i, te = self.next, self.t_eval[self.next]
            self.next += 1
            if abs(te - t_new) <= SNAP * h:
                self._set(i, y_new, project=False)
            else:
                inner.append(i)
        if dense is None:
            self.pending.extend(inner)
        elif self.batch and inner:
            for i, value in zip(inner, np.asarray(dense(self.t_eval[inner]), float).T):
                self._set(i, value)
        else:
            for i in inner:
                self._set(i, np.asarray(dense(self.t_eval[i]), float))
        self.flush(final=False)

    def inside(self, t_new, h) -> bool:
        """Whether an output time lies inside the step ending at ``t_new`` (so that
        :meth:`fill` will call its dense output)."""
        return (self.next < self.t_eval.size
                and self.t_eval[self.next] < t_new - SNAP * h)

    def flush(self, final: bool):
        while self.pending and self.interp.ready(self.t_eval[self.pending[0]], final):
            i = self.pending.pop(0)
            self._set(i, self.interp(self.t_eval[i]))

    def rest(self, y):
        """Every output not filled takes ``y`` (a reset at ``t_end``)."""
        for i in np.flatnonzero(~self.done):
            self._set(i, y, project=False)

    def _set(self, i, value, project=True):
        if project and self.project is not None:
            value = np.asarray(self.project(self.t_eval[i], value), float)
        self.ys[i], self.done[i] = value, True


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

    def __init__(self, events, project=None, log=None):
        self.events, self.project, self.g = tuple(events), project, None
        self.log = [] if log is None else log

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

    One rule for every code, through :class:`Segments`: the crossings its
    :class:`EventTracker` locates and the roots a library finds.

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

class Stall:
    """A library code's steps that no longer advance ``t`` (``t + h = t``).

    SUNDIALS in one-step mode (whose ``max_num_steps`` counts the steps of one
    call) and scipy's LSODA (whose step size can reach zero near a blow-up)
    keep returning without moving; neither fails by itself. Called with each
    return's ``(t_old, t)``, an instance answers None while the code moves and
    ``(Status.STEP_SIZE_UNDERFLOW, message)`` after :data:`STALLED` returns in a
    row that did not.
    """

    def __init__(self):
        self.count = 0

    def __call__(self, t_old: float, t: float) -> tuple[Status, str] | None:
        self.count = self.count + 1 if t <= t_old else 0
        if self.count <= STALLED:
            return None
        return Status.STEP_SIZE_UNDERFLOW, (f"{STALLED} steps in a row did not advance "
                                            f"t = {t_old:.9g} (t + h = t)")


@dataclasses.dataclass
class Budget:
    """A run's wall-time budget, checked by :class:`Segments` at each accepted step:
    a run still going ``seconds`` after ``start`` is stopped with
    ``Status.OVER_BUDGET`` (the progress in the message). No projection from
    the progress: an implicit code's first steps through a stiff transient can
    take a hundred times as long per unit of time as the rest of its run. Set
    for the runs made inside :func:`budgeted`.

    Parameters
    ----------
    seconds : float
        Wall seconds the run may take.
    report : callable, optional
        ``report(t, percent, elapsed)``, called at an accepted step at most every
        ``every`` wall seconds: the run's progress (a reference's, on the terminal).
    every : float
        Seconds between two reports.
    """

    seconds: float
    start: float = dataclasses.field(default_factory=time.perf_counter)
    report: object = None
    every: float = 2.0

    def verdict(self, t0: float, t_end: float, t: float) -> str | None:
        """None while the run, now at ``t``, is within its budget, else the message."""
        elapsed = time.perf_counter() - self.start
        done = 100 * (t - t0) / (t_end - t0)
        if self.report is not None and elapsed >= getattr(self, "_next", self.every):
            self._next = elapsed + self.every
            self.report(t, done, elapsed)
        if elapsed <= self.seconds:
            return None
        return (f"stopped at t={t:.6g} ({done:.3g} % of the span) after {elapsed:.3g} s, "
                f"past its budget of {self.seconds:.3g} s")


#: the :class:`Budget` of the runs being made (None: none); see :func:`budgeted`
_BUDGET: contextvars.ContextVar = contextvars.ContextVar("budget", default=None)


@contextlib.contextmanager
def budgeted(budget: Budget | None):
    """Runs started inside the block (their :class:`Segments` made there) keep to
    ``budget``; None sets none."""
    token = _BUDGET.set(budget)
    try:
        yield budget
    finally:
        _BUDGET.reset(token)


class _Ended(Exception):
    """A terminal event acted on inside :meth:`Segments.step` or :meth:`Segments.roots`:
    ends the code's segment loop (``y_after`` None: a stop, else the reset state)."""

    def __init__(self, t, y_after, name):
        super().__init__(name)
        self.t, self.y_after, self.name = t, y_after, name


class Segments:
    """Outputs, state events, stops, resets and the :class:`Solution` of one run,
    fed by a code's accepted steps or roots (see the module docstring).

    Parameters
    ----------
    system : System
        The (converted) system: ``t_eval``, ``events``, ``project``.
    degree : int
        Degree of the interpolation of outputs inside steps without dense output.
    locate : bool
        True: the runner locates ``system.events`` on the steps' dense output;
        False: the code finds the roots and feeds them to :meth:`roots`.
    batch : bool
        True when ``dense`` takes an array of times and returns the states as
        columns (scipy's ``DenseOutput``): the outputs inside a step are then
        evaluated in one call, as ``solve_ivp`` does.
    """

    def __init__(self, system, degree=1, locate=True, batch=False):
        self.system, self.log = system, []
        self.stopped, self.t_last = False, None     # a terminal stop; the last step's end
        self.events = tuple(system.events)
        self.outputs = Outputs(system, degree, batch)
        self.tracker = (EventTracker(self.events, getattr(system, "project", None), self.log)
                        if self.events and locate else None)
        self.budget = _BUDGET.get()

    def next_output(self) -> float:
        """The first output time no step has reached yet (``t_end`` when none is left)."""
        t_eval = self.outputs.t_eval
        return t_eval[min(self.outputs.next, t_eval.size - 1)]

    def step(self, t_old, t, y, dense, h=None):
        """An accepted step ``[t_old, t]`` ending at the state ``y`` (projected when the
        formulation projects), with ``dense(s) -> y(s)`` or None; ``h`` (default ``t -
        t_old``) scales the output snap. Raises the runner's stop at a terminal event,
        and ``StepFailure(OVER_BUDGET)`` past the run's :class:`Budget`."""
        h = t - t_old if h is None else h
        self.t_last = t
        if self.budget is not None:
            over = self.budget.verdict(self.system.t0, self.system.t_end, t)
            if over:
                raise StepFailure(Status.OVER_BUDGET, over, retry=False)
        if self.tracker is not None:
            hit = self.tracker.step(t_old, t, y, dense)
            if hit is not None:                 # outputs up to the event, then stop/restart
                t_event, y_event, y_after = hit
                self.outputs.step(t_event, h, y_event, dense)
                raise _Ended(t_event, y_after, self.log[-1][1])
        self.outputs.step(t, h, y, dense)

    def roots(self, t, y, indices, dense, h):
        """The code's root at ``(t, y)`` of the events numbered ``indices``, inside a
        step of size ``h`` with ``dense`` on it: each acted on (:func:`act`), and the
        outputs up to ``t`` filled. Raises the runner's stop at a terminal event."""
        y = np.array(y, dtype=float)
        for i in indices:
            ends, y_after = act(self.events[i], t, y, self.log)
            if ends:
                self.outputs.fill(t, h, y, dense)
                raise _Ended(t, y_after, self.events[i].name)
        self.outputs.fill(t, h, y, dense)

    def at_end(self, t) -> bool:
        """Whether ``t`` is ``t_end`` to the tolerance of a reset there."""
        t0, t_end = self.system.t0, self.system.t_end
        return t_end - t <= MIN_STEP * max(t_end - t0, abs(t))

    def run(self, t, y, advance, restart) -> tuple[Status, str]:
        """Run the code from ``(t, y)``: ``advance(t, y) -> (status, message)`` over
        each segment, ``restart(t, y_after) -> y`` after each reset (see the module
        docstring). Returns the run's status and message."""
        self.outputs.start(t, y)
        try:
            while True:
                if self.tracker is not None:
                    self.tracker.start(t, y)
                try:
                    return advance(t, y)
                except _Ended as end:
                    t = end.t
                    if end.y_after is None:
                        self.stopped = True
                        return Status.SUCCESS, (f"stopped by the terminal event {end.name!r} "
                                                f"at t={t:.9g}")
                    if self.at_end(t):
                        self.outputs.rest(end.y_after)
                        return Status.SUCCESS, ""
                    y = np.asarray(restart(t, end.y_after), float)
                    self.outputs.restart(t, y)
        except StepFailure as exc:        # from the event location
            return exc.status, str(exc)

    def solution(self, status, message, counts) -> Solution:
        """The run's :class:`Solution`: the outputs filled, the events acted on
        (``counts["nevents"]`` when the system has events).

        A code that returns success with outputs left unfilled and no terminal
        stop (Assimulo's RungeKutta34 ends its loop when a diverged step makes
        ``t`` NaN) did not reach ``t_end``: the run failed, ``nonfinite_state``
        when its last step ended at a non-finite time, ``solver_failure`` else."""
        self.outputs.flush(final=True)
        n = self.outputs.filled
        if status is Status.SUCCESS and n < self.system.t_eval.size and not self.stopped:
            finite = self.t_last is not None and np.isfinite(self.t_last)
            status = Status.SOLVER_FAILURE if finite else Status.NONFINITE_STATE
            message = (f"the code returned success, but its outputs end at "
                       f"t={self.system.t_eval[n - 1]:.6g} (last step to t={self.t_last})")
        if self.events:
            counts["nevents"] = len(self.log)
        return Solution(self.system.t_eval[:n], self.outputs.ys[:n], message=message,
                        counts=counts, status=status, events=self.log)


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
    d0, d1 = (rms(x / scale) for x in (y0, f0))
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, span)
    f1 = np.asarray(fun(t0 + h0, y0 + h0 * f0), float)
    d2 = rms((f1 - f0) / scale) / h0
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
        return stepper, integrator.controller(stepper.error_order, rtol=rtol, atol=atol,
                                              mask=stepper.error_mask,
                                              span=(system.t0, system.t_end))

    segments = Segments(system, (integrator.order or 1) + 1)
    loop = _Loop(system, fresh, counts, segments, rtol, atol, integrator.max_steps)
    try:
        y0 = kept(loop.stepper.start(system.t0, np.array(system.y0, dtype=float)), "start")
        status, message = segments.run(system.t0, y0, loop.advance, loop.restart)
    except StepFailure as exc:        # from the stepper's start
        status, message = exc.status, str(exc)
    except (OverflowError, FloatingPointError) as exc:
        status, message = Status.DIVERGED, (f"overflow in the step from t={loop.t:.6g} "
                                            f"({exc}): the solution blew up")
    return segments.solution(status, message, counts)


def kept(y, source: str) -> np.ndarray:
    """``y`` as the state the driver keeps: a float array made read-only, so that a
    stepper writing into the state it is handed fails at that write (rule 10 of
    :mod:`integrator_bench.integrators.base`). ``source`` names the stepper's
    method that gave it, for the error when it gave None."""
    if y is None:
        raise TypeError(f"the stepper's {source}() returned None: it must return the state "
                        "the driver keeps (the base class's start returns y0)")
    y = np.asarray(y, float)
    y.flags.writeable = False
    return y


def _writes_state(stepper, t, y, h) -> bool:
    """Whether ``stepper.step`` writes into the state it is handed: tried once more
    on a writeable copy of ``y`` (after a ``ValueError`` from the read-only one)."""
    probe = np.array(y, dtype=float)
    try:
        stepper.step(t, probe, h)
    except Exception:  # the write shows in the probe whatever happens after it
        pass
    return not np.array_equal(probe, y, equal_nan=True)


class _Loop:
    """The stepping loop of one stepper-based run: one segment per :meth:`advance`."""

    def __init__(self, system, fresh, counts, segments, rtol, atol, max_steps):
        self.system, self.fresh, self.counts, self.segments = system, fresh, counts, segments
        self.rtol, self.atol, self.max_steps = rtol, atol, max_steps
        self.stepper, self.control = fresh()
        self.project = getattr(system, "project", None)
        self.attempts = 0
        self.t = system.t0            # start of the step under way, for messages

    def restart(self, t, y_after):
        """A fresh stepper and controller from the reset state."""
        self.stepper, self.control = self.fresh()
        return kept(self.stepper.start(t, y_after), "start")

    def advance(self, t, y) -> tuple[Status, str]:
        """Step from ``(t, y)`` to ``t_end``, feeding every accepted step to the segments."""
        system, stepper, control = self.system, self.stepper, self.control
        t_end = system.t_end
        self.t = t
        h = control.init(t, t_end, lambda: initial_step(system, stepper, y, self.rtol,
                                                        self.atol, t0=t))
        while t < t_end:
            self.t = t
            if control.adaptive:
                if self.attempts >= self.max_steps:
                    return Status.MAX_STEPS, f"more than {self.max_steps} steps"
                try:
                    h = control.attempt(t, h, stepper.max_step(t, y))
                except StepSizeUnderflow as exc:
                    return Status.STEP_SIZE_UNDERFLOW, str(exc)
                self.attempts += 1
            t_new = t_end if h == t_end - t else t + h
            try:
                step = stepper.step(t, y, h)
            except StepFailure as exc:
                h = control.failed(h, FAILURE_FACTOR) if exc.retry else None
                if h is None:
                    return exc.status, (f"{exc} (at the minimum step)"
                                        if exc.retry and control.adaptive else str(exc))
                continue
            except ValueError:
                if _writes_state(stepper, t, y, h):
                    raise InputModified(f"the stepper's step() wrote into the state y it was "
                                        f"handed (the step from t={t:.6g}); the driver keeps "
                                        "it read-only: compute a new array") from None
                raise
            err = control.norm(step.error, y, step.y)
            accept, h_next = control.adapt(h, err)
            if not accept:
                self.counts["nreject"] += 1
                stepper.reject()
                h = h_next
                continue
            if err == math.inf:
                return Status.NONFINITE_STATE, f"non-finite state at t={t_new:.6g}"
            y_new = step.y
            if self.project is not None:
                y_new = self.project(t_new, y_new)
            y_new = kept(y_new, "step" if self.project is None else "project")
            stepper.accept(t_new, y_new)
            self.counts["nsteps"] += 1
            self.segments.step(t, t_new, y_new, step.dense, h)
            t, y, h = t_new, y_new, h_next
        return Status.SUCCESS, ""
