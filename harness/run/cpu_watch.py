"""What a case's worker shows its owner, and when the owner kills it: the budget's
backstop, 0.05 s of CPU past the budget of the solve.

A timed solve ends itself at its budget wherever Python runs
(:mod:`~integrator_bench.harness.measure.tripwire`); compiled code that never
returns to Python (one long LAPACK call, a plugin's loop in ctypes) cannot be
ended from inside its process. So the worker shows its owner, in a page of
memory they share (:class:`Ledger`, written by the tripwire), where its timed
solve stands: its start and its deadline in CPU seconds of the worker, and
the CPU of its timed solves so far. The owner reads the worker's CPU clock
(the kernel's count, to the nanosecond: :func:`cpu_of`) and kills the worker

* when its timed solve has run :data:`KILL_AFTER_S` past its deadline
  (looking more often as the deadline nears: :meth:`CaseWatch.wait_s`);
* when the work around the solves (the problem built, the reference read, the
  errors measured: the case's CPU less its timed solves') passes
  :data:`AROUND_S`, a bound of its own, whatever the budget;
* on the backstops of a process that hangs or the machine's wall clock
  (:class:`~integrator_bench.harness.forking.budget.Watch`).

The figures go to the ``timeout`` record: ``cpu_s_over``, the CPU its solve ran
past the budget, and ``cpu_s_around``.
"""

from __future__ import annotations

import math
import mmap
import time

from integrator_bench.harness.measure import tripwire

#: CPU seconds past the deadline of a timed solve at which its worker is killed
KILL_AFTER_S = 0.05
#: CPU seconds a worker may spend on a case outside its timed solves
AROUND_S = 2.0
#: the least and the most wall seconds between two looks at a worker
MIN_WAIT_S, MAX_WAIT_S = 0.005, 0.1


def cpu_of(pid: int) -> float | None:
    """CPU seconds (all threads, user and system) process ``pid`` has used, from its
    CPU clock (``clock_gettime`` of the clock Linux gives every process,
    ``CPUCLOCK_SCHED``, to the nanosecond; a process that exited but is not yet
    reaped still has it); None when it cannot be read (reaped, another system)."""
    try:
        return time.clock_gettime((~pid << 3) | 2)
    except (OSError, OverflowError):
        return None


class Ledger:
    """Three floats in memory shared by a worker and its owner (a page mapped before
    the fork): the timed solve's start and deadline in CPU seconds of the worker
    (NaN between solves), and the CPU of its timed solves so far."""

    def __init__(self):
        self._map = mmap.mmap(-1, mmap.PAGESIZE)   # anonymous and shared: seen after fork
        self.values = memoryview(self._map).cast("d")
        self.values[0] = self.values[1] = math.nan
        self.values[2] = 0.0

    def show_here(self) -> None:
        """In the forked worker: the tripwire writes its solves here."""
        tripwire.SHOWN[0] = self.values

    def read(self) -> tuple[float, float, float]:
        """``(start, deadline, solved)``."""
        return self.values[0], self.values[1], self.values[2]


class CaseWatch:
    """The CPU of the case a worker ``pid`` runs from now, read against its
    :class:`Ledger`: :meth:`verdict` says why it must be killed, or None."""

    def __init__(self, pid: int, ledger: Ledger):
        self.pid, self.ledger = pid, ledger
        self.cpu0 = cpu_of(pid) or 0.0
        self.solved0 = ledger.read()[2]

    def figures(self) -> dict:
        """``cpu_s_over`` (the CPU its timed solve ran past its deadline; None
        between solves) and ``cpu_s_around`` (its CPU outside the timed solves),
        now; empty when the worker's clock cannot be read."""
        cpu = cpu_of(self.pid)
        if cpu is None:
            return {}
        start, deadline, solved = self.ledger.read()
        in_solve = not math.isnan(start)
        solves = solved - self.solved0 + (cpu - start if in_solve else 0.0)
        over = max(cpu - deadline, 0.0) if in_solve and math.isfinite(deadline) else None
        return {"cpu_s_over": over, "cpu_s_around": max(cpu - self.cpu0 - solves, 0.0)}

    def verdict(self, budget_s: float) -> str | None:
        """Why the worker must be killed now, or None: its timed solve past its
        deadline by :data:`KILL_AFTER_S`, or the work around it past :data:`AROUND_S`."""
        got = self.figures()
        over, around = got.get("cpu_s_over"), got.get("cpu_s_around", 0.0)
        if over is not None and over > KILL_AFTER_S:
            return (f"its solve ran {over:.3g} s of CPU past the budget of {budget_s:g} s "
                    f"without returning to Python")
        if around > AROUND_S:
            return (f"the work around its solve (the problem built, the reference read, "
                    f"the errors measured) took {around:.3g} s of CPU, past its bound of "
                    f"{AROUND_S:g} s")
        return None

    def wait_s(self) -> float:
        """Wall seconds the owner may wait before it looks again: the CPU left
        before a kill (a process of one thread uses CPU no faster than the wall
        clock runs), within [:data:`MIN_WAIT_S`, :data:`MAX_WAIT_S`]."""
        cpu = cpu_of(self.pid)
        start, deadline, _ = self.ledger.read()
        if cpu is None or math.isnan(start) or not math.isfinite(deadline):
            return MAX_WAIT_S
        return min(max(deadline + KILL_AFTER_S - cpu, MIN_WAIT_S), MAX_WAIT_S)
