"""A run's time budget, checked by the segment runner at each accepted step."""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import time

@dataclasses.dataclass
class Budget:
    """A run's time budget, checked by :class:`Segments` at each accepted step:
    a run still going ``seconds`` after ``start`` on its ``clock`` is stopped with
    ``Status.OVER_BUDGET`` (the progress in the message). No projection from
    the progress: an implicit code's first steps through a stiff transient can
    take a hundred times as long per unit of time as the rest of its run. Set
    for the runs made inside :func:`budgeted`.

    Parameters
    ----------
    seconds : float
        Seconds the run may take, on ``clock``.
    clock : callable
        The clock the budget is kept on: ``time.perf_counter`` (wall seconds,
        the default: a reference's limit) or ``time.process_time`` (CPU
        seconds of this process: a case's budget, which the machine's load
        does not change).
    report : callable, optional
        ``report(t, percent, elapsed)``, called at an accepted step at most every
        ``every`` wall seconds: the run's progress (a reference's, on the terminal).
    every : float
        Seconds between two reports.
    """

    seconds: float
    start: float = None
    report: object = None
    every: float = 2.0
    clock: object = time.perf_counter

    def __post_init__(self):
        if self.start is None:
            self.start = self.clock()

    def verdict(self, t0: float, t_end: float, t: float) -> str | None:
        """None while the run, now at ``t``, is within its budget, else the message."""
        elapsed = self.clock() - self.start
        done = 100 * (t - t0) / (t_end - t0)
        if self.report is not None and elapsed >= getattr(self, "_next", self.every):
            self._next = elapsed + self.every
            self.report(t, done, elapsed)
        if elapsed <= self.seconds:
            return None
        what = " of CPU" if self.clock is time.process_time else ""
        return (f"stopped at t={t:.6g} ({done:.3g} % of the span) after {elapsed:.3g} s{what}, "
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


def current() -> Budget | None:
    """The :class:`Budget` of the runs being started now (inside :func:`budgeted`), or None."""
    return _BUDGET.get()
