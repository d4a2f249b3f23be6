"""The segment runner: outputs, state events, stops, resets, restarts, the budget and
the :class:`~integrator_bench.integrators.outcome.Solution` of one run, fed by a
code's accepted steps or roots (rules: :mod:`.driver`)."""

from __future__ import annotations

import numpy as np

from integrator_bench.integrators.control import MIN_STEP
from integrator_bench.integrators.driver.budget import current as current_budget
from integrator_bench.integrators.driver.events import EventTracker, act
from integrator_bench.integrators.driver.outputs import Outputs
from integrator_bench.integrators.outcome import Solution, Status, StepFailure

STALLED = 1000         # a library code's returns in a row that do not advance t: underflow


def nonfinite(t, values, what="non-finite state") -> StepFailure | None:
    """The failure ``NONFINITE_STATE`` ("``what`` at t=T") when ``values`` (a state,
    or the model's value at ``t``) hold a NaN or an infinity, else None: the one
    test of the codes fed to :class:`Segments` with ``finite=True``, and of a
    wrapper that checks the model's values before its code sees them."""
    if np.isfinite(values).all():
        return None
    return StepFailure(Status.NONFINITE_STATE, f"{what} at t={t:.6g}", retry=False)


def ended_short(t_filled, t_last) -> tuple[Status, str]:
    """The failure of a code that returned success with its outputs ending at
    ``t_filled``, short of ``t_end``, and no terminal stop (Assimulo's
    RungeKutta34 leaves its loop, saying it completed, when its step size turns
    NaN): it did not reach ``t_end``. ``(Status.NONFINITE_STATE, message)`` when
    its last step ended at ``t_last`` non-finite (or None: no step), else
    ``(Status.SOLVER_FAILURE, message)``; the one rule of :meth:`Segments.solution`
    and of a library's own loop over the output times."""
    finite = t_last is not None and np.isfinite(t_last)
    return (Status.SOLVER_FAILURE if finite else Status.NONFINITE_STATE,
            f"the code returned success, but its outputs end at t={t_filled:.6g} "
            f"(last step to t={t_last})")


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
    finite : bool
        True: a step ending at a non-finite state ends the run
        (``NONFINITE_STATE``), for a code that would run on (RODAS accepts a NaN
        error estimate); False: the code's own error test decides.
    directions : bool
        False when the code's roots carry no direction (Assimulo's state events;
        ODEPACK's LSODAR reports none): the runner keeps, of the events at a
        root, those crossed in their ``direction``, judged by each event's sign
        at the start of the step that holds the root.
    """

    def __init__(self, system, degree=1, locate=True, batch=False, finite=False,
                 directions=True):
        self.system, self.log = system, []
        self.finite, self.directions = finite, directions
        self.ends = None          # the last two step ends, (t, y), when filtering roots
        self.stopped, self.t_last = False, None     # a terminal stop; the last step's end
        self.events = tuple(system.events)
        self.outputs = Outputs(system, degree, batch)
        self.tracker = (EventTracker(self.events, getattr(system, "project", None), self.log)
                        if self.events and locate else None)
        self.budget = current_budget()
        if finite or not directions:     # the steppers' path keeps its plain step
            self.step = self._checked

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

    def _checked(self, t_old, t, y, dense, h=None):
        """:meth:`step` after a library code's checks: a non-finite state or time
        ends the run (``finite``), the step's end is kept for :meth:`crossed`
        (``directions`` False)."""
        if self.finite:
            failed = nonfinite(t, np.append(t, y))     # a NaN time too
            if failed is not None:
                self.t_last = t
                raise failed
        if not self.directions:
            self.ends = (self.ends[1], (t, y))
        Segments.step(self, t_old, t, y, dense, h)

    def roots(self, t, y, indices, dense, h):
        """The code's root at ``(t, y)`` of the events numbered ``indices``, inside a
        step of size ``h`` with ``dense`` on it: each acted on (:func:`act`), and the
        outputs up to ``t`` filled (with ``directions=False``, only the events crossed
        in their direction). Raises the runner's stop at a terminal event."""
        y = np.array(y, dtype=float)
        if not self.directions:
            indices = self.crossed(t, indices)
            if not indices:                 # every root crossed against its direction
                return
        for i in indices:
            ends, y_after = act(self.events[i], t, y, self.log)
            if ends:
                self.outputs.fill(t, h, y, dense)
                raise _Ended(t, y_after, self.events[i].name)
        self.outputs.fill(t, h, y, dense)

    def crossed(self, t, indices) -> list[int]:
        """Of the events numbered ``indices`` with a root at ``t``, those crossed in
        their ``direction``: the sign of each at the start of the step holding the
        root (the last step end before ``t``; the code may feed that step before or
        after the root) must be the opposite of the direction."""
        before, last = self.ends
        t0, y0 = before if last[0] >= t else last
        return [i for i in indices if self.events[i].direction
                in (0, -np.sign(self.events[i].value(t0, y0)))]

    def reached(self, t, y):
        """The code's state at ``t``, a step end already fed, is ``y`` after all (a
        library that applied an event there itself): the output at ``t``, if there
        is one, takes ``y``, and the interpolation restarts from it."""
        y = np.array(y, dtype=float)
        self.outputs.replace(t, y)
        self.outputs.restart(t, y)
        if not self.directions:
            self.ends = ((t, y), (t, y))

    def applied(self, t, name, y_after):
        """An event ``name`` that the code located and acted on itself at ``t`` (fmpy,
        whose FMU updates its own state), leaving ``y_after``: recorded, and
        :meth:`reached`."""
        self.log.append((t, name, np.array(y_after, dtype=float)))
        self.reached(t, y_after)

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
                if not self.directions:
                    self.ends = ((t, y), (t, y))
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
        stop did not reach ``t_end``: the run failed (:func:`ended_short`)."""
        self.outputs.flush(final=True)
        n = self.outputs.filled
        if status is Status.SUCCESS and n < self.system.t_eval.size and not self.stopped:
            status, message = ended_short(self.system.t_eval[n - 1], self.t_last)
        if self.events:
            counts["nevents"] = len(self.log)
        return Solution(self.system.t_eval[:n], self.outputs.ys[:n], message=message,
                        counts=counts, status=status, events=self.log)
