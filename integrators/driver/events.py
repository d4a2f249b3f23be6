"""State events over accepted steps: the sign-change test, the Illinois locator and
the one action rule (record, stop, reset) shared by every code (rules: :mod:`.driver`)."""

from __future__ import annotations

import math

import numpy as np

from integrator_bench.integrators.outcome import Status, StepFailure

EVENT_ATOL = 1e-14     # absolute part of the event-time tolerance (time units)


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
