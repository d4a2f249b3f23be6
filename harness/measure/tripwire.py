"""A timed solve's budget of CPU, ended from inside its process: the tripwire.

A case's solve is timed within its budget of CPU seconds of its process. The
shared driver and every loop fed through the segment runner check that budget
at each accepted step (:class:`~integrator_bench.integrators.driver.Budget`); a
library's own loop (scipy's ``solve_ivp``, SUNDIALS' through scikit-sundae,
Assimulo's ``simulate``) is not fed step by step, and ran on past it until its
worker was killed. :func:`armed` ends every loop at the budget:

* a wall-clock timer (``setitimer(ITIMER_REAL)``, ``SIGALRM``) rings after the
  CPU seconds left: a process of one thread (a worker runs one BLAS thread)
  uses CPU no faster than the wall clock runs, so when it rings the budget may
  be spent, never long past. Its handler reads the process's CPU clock and sets
  the timer again to what is left, until nothing is; then the budget is
  *spent*: the handler raises :class:`OverBudget` in the Python code running (a
  library's Python loop, or the model, which every C library here calls back
  in Python), again every :data:`AGAIN_S` seconds while the solve goes on (a
  library that catches it and carries on), and every counted call of the
  model raises it at once (:mod:`~integrator_bench.harness.measure.counting`),
  so that no library takes another step;
* not a CPU timer (``setitimer(ITIMER_PROF)``, ``RLIMIT_CPU``, a POSIX timer on
  the process's CPU clock): while any process-wide CPU timer is armed, this
  machine's kernel advances the process's CPU clock at the scheduler's ticks
  only, and a millisecond solve measured 0 s (docs/full-run.md);
* C code that never returns to Python (one long LAPACK call, a plugin's loop
  in ctypes) is out of its reach: the worker shows its owner where its timed
  solve stands (:data:`SHOWN`), and the owner kills it 0.05 s of CPU past the
  budget (:mod:`~integrator_bench.harness.run.cpu_watch`).

The CPU of every timed solve is added up (:func:`solved`), so that what the
worker does around the solves (the problem built, the reference read, the
errors measured) is counted apart (the record's ``cpu_s_around``).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import signal
import sys
import threading
import time

#: seconds between two raises of :class:`OverBudget` once the budget is spent
AGAIN_S = 0.01
#: the shortest the timer is set to
MIN_S = 0.001


class OverBudget(BaseException):
    """Raised inside a timed solve whose budget of CPU is spent. A BaseException,
    so that a library's or a wrapper's ``except Exception`` does not take it for a
    failure of the library's own."""


#: ``[True]`` while the budget of the solve running is spent: every counted call
#: of the model raises :class:`OverBudget` (read by the counting functions)
SPENT = [False]
#: where this process shows its owner the timed solve running: None, or a list of
#: three floats (a worker's shared memory, :mod:`~integrator_bench.harness.run.cpu_watch`):
#: the solve's start and its deadline in CPU seconds of the process (NaN between
#: solves), and the CPU of its timed solves so far
SHOWN: list = [None]
_TOTAL = [0.0]          # CPU seconds of every timed solve of this process
#: the file descriptor this process's output is captured in (a worker's; None: not
#: captured): what a library prints once its solve's budget is spent (Assimulo prints
#: the traceback of the exception it was handed, f2py that its callback failed) is
#: cut off (:func:`cut_output`)
CAPTURED: list = [None]
_CUT: list = [None]     # the captured output's length when a budget was last spent


def cut_output() -> None:
    """Cut the captured output (:data:`CAPTURED`) back to its length when a solve's
    budget was last spent, once; call it with Python's streams flushed."""
    at, _CUT[0] = _CUT[0], None
    if at is not None and CAPTURED[0] is not None:
        os.ftruncate(CAPTURED[0], at)


def _note_output() -> None:
    """Note the captured output's length (Python's buffered streams flushed first)."""
    if CAPTURED[0] is None:
        return
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):   # a write this handler interrupted
            stream.flush()
    _CUT[0] = os.fstat(CAPTURED[0]).st_size


def solved() -> float:
    """CPU seconds of this process's timed solves so far (all of them, budgeted or not)."""
    return _TOTAL[0]


@dataclasses.dataclass
class Trip:
    """A timed solve's budget: ``seconds`` of CPU from ``start`` (CPU seconds of the
    process); ``spent_at``, the CPU when the budget was found spent (None: not
    spent; no budget: ``seconds`` None)."""

    seconds: float | None
    start: float
    spent_at: float | None = None

    @property
    def deadline(self) -> float:
        return math.inf if self.seconds is None else self.start + self.seconds


def _show(start: float, deadline: float) -> None:
    shown = SHOWN[0]
    if shown is not None:
        shown[0], shown[1], shown[2] = start, deadline, _TOTAL[0]


@contextlib.contextmanager
def armed(seconds: float | None):
    """Time a solve run inside the block within ``seconds`` of CPU of this process
    (None: no budget, counted only): :class:`OverBudget` is raised in it once
    they are spent (see the module's docstring). Yields the :class:`Trip`, whose
    ``spent_at`` says whether it was spent, however the block then ended (a
    library may catch the exception and end as a failure of its own).

    The timer is set only in the main thread (where Python runs signal
    handlers); elsewhere the block is timed without it."""
    trip = Trip(seconds, time.process_time())
    timer = seconds is not None and threading.current_thread() is threading.main_thread()
    state = ["arming"]          # then "armed" inside the block, "done" after it

    def ring(signum, frame):
        if state[0] == "done":
            return
        now = time.process_time()
        if state[0] == "arming" or (trip.spent_at is None and now < trip.deadline):
            signal.setitimer(signal.ITIMER_REAL, max(trip.deadline - now, MIN_S))
            return
        if trip.spent_at is None:
            trip.spent_at, SPENT[0] = now, True
            _note_output()
        signal.setitimer(signal.ITIMER_REAL, AGAIN_S)
        raise OverBudget(f"{now - trip.start:.3g} s of CPU, past the budget of "
                         f"{seconds:g} s")

    old = None
    if timer:
        old = signal.signal(signal.SIGALRM, ring)
        signal.siginterrupt(signal.SIGALRM, False)   # a library's system calls restart
        signal.setitimer(signal.ITIMER_REAL, max(seconds, MIN_S))
    _show(trip.start, trip.deadline)
    state[0] = "armed"
    try:
        yield trip
    finally:
        state[0] = "done"
        if timer:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, signal.SIG_DFL if old is None else old)
        SPENT[0] = False
        _TOTAL[0] += time.process_time() - trip.start
        _show(math.nan, math.nan)
