"""The budget of a forked process: CPU seconds with backstops, and a memory cap.

What a case's :class:`~integrator_bench.harness.run.isolation.Worker`, a model's call
(:mod:`~integrator_bench.harness.forking.child`) and a contenders' round process are
stopped by: :class:`Watch` reads a process's CPU from ``/proc`` and says when it is
past its budget (or hangs without using CPU, or past the wall-clock backstop);
:func:`limit_memory` caps what a freshly forked process may add to its address space.
"""

from __future__ import annotations

import os
import resource
import time

POLL_S = 0.1                # how often a running process's budget is checked
DEFAULT_MEMORY_MB = 4096.0  # address space a case may add to its worker's (RLIMIT_AS)


def limit_memory(memory_mb: float | None) -> float | None:
    """Cap the address space (RLIMIT_AS) at what the worker inherited plus ``memory_mb``.

    A forked worker starts with its parent's mappings, whose size depends on
    the parent (a Dask worker maps more than ``ibench``), so the limit is on
    what the case adds. An allocation past it fails: numpy raises MemoryError
    (an ``error`` record with reason ``out_of_memory``); code that cannot
    recover kills the worker (a ``crashed`` record). Returns the limit set, in
    MB, or None when none was.
    """
    if not memory_mb:
        return None
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            vm = next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmSize:"))
    except (OSError, StopIteration, ValueError):
        return None  # no way to know the inherited size: leave the address space unlimited
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = vm + int(memory_mb * 2**20)
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    return memory_mb


#: a process given a budget (a model's call, :mod:`~integrator_bench.harness.forking.child`)
#: that has used more CPU than CPU_BACKSTOP times its budget plus CPU_GRACE_S is
#: killed; a case's worker is held closer, its solve and the work around it apart
#: (:mod:`~integrator_bench.harness.run.cpu_watch`)
CPU_BACKSTOP = 1.1
CPU_GRACE_S = 1.0
#: a case whose worker used no CPU for IDLE_S seconds once its wall time passed its
#: budget hangs without working (asleep, blocked): killed
IDLE_S = 1.0
#: the wall-clock backstop: a case still running after WALL_BACKSTOP times its budget
#: plus WALL_SLACK_S seconds of wall time is killed, whatever its CPU (a machine loaded
#: tenfold still gives it its budget of CPU)
WALL_BACKSTOP = 10.0
WALL_SLACK_S = 30.0
_CLOCK_TICK = os.sysconf("SC_CLK_TCK")


def _stat(pid: int) -> list | None:
    """The fields of ``/proc/PID/stat`` after the command's name (the state first),
    or None when it cannot be read (the process is gone)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return f.read().rsplit(b")", 1)[1].split()
    except (OSError, IndexError):
        return None


def process_cpu_of(pid: int, fields: list | None = None) -> float | None:
    """CPU seconds (user and system) process ``pid`` has used, from
    ``/proc/PID/stat`` (Linux; clock ticks of 1/``SC_CLK_TCK`` s; or from its
    ``fields`` already read); None when it cannot be read (the process is gone)."""
    fields = fields or _stat(pid)
    if fields is None:
        return None
    return (int(fields[11]) + int(fields[12])) / _CLOCK_TICK  # utime, stime: fields 14, 15


class Watch:
    """The clocks of a process given a budget of ``timeout`` CPU seconds from now:
    what a model's call (:mod:`~integrator_bench.harness.forking.child`) is
    stopped by, and a case's
    :class:`~integrator_bench.harness.run.isolation.Worker` when it hangs or the machine's wall
    clock runs away (:meth:`stalled`)."""

    def __init__(self, pid: int):
        self.pid, self.start = pid, time.monotonic()
        self.cpu0 = process_cpu_of(pid) or 0.0
        self.last_cpu, self.last_busy = self.cpu0, self.start

    def _look(self, now: float) -> float:
        """The CPU used since the start, noting when the process last used CPU or
        waited for a core (runnable, state ``R``: a process the machine's load
        starves of CPU is not hung)."""
        fields = _stat(self.pid)
        cpu = process_cpu_of(self.pid, fields)
        if cpu is not None and cpu > self.last_cpu:
            self.last_cpu, self.last_busy = cpu, now
        elif fields is not None and fields[0] == b"R":
            self.last_busy = now
        return self.last_cpu - self.cpu0

    def past(self, timeout: float, now: float | None = None) -> str | None:
        """Why the process must be stopped, or None: its CPU past
        :data:`CPU_BACKSTOP` times ``timeout`` plus :data:`CPU_GRACE_S`, or
        :meth:`stalled`."""
        now = time.monotonic() if now is None else now
        used = self._look(now)
        if used > CPU_BACKSTOP * timeout + CPU_GRACE_S:
            return f"no result within {used:.3g} s of CPU (budget {timeout:g} s)"
        return self.stalled(timeout, now)

    def stalled(self, timeout: float, now: float | None = None) -> str | None:
        """Why the process must be stopped whatever its CPU, or None: its wall
        time past the budget with no CPU used for :data:`IDLE_S`, nor waited for
        (asleep or blocked all the while, as far as its looks saw); its wall time
        past :data:`WALL_BACKSTOP` budgets and :data:`WALL_SLACK_S`."""
        now = time.monotonic() if now is None else now
        used, elapsed = self._look(now), now - self.start
        if elapsed > timeout and now - self.last_busy > IDLE_S:
            return (f"no result after {elapsed:.3g} s, the last {now - self.last_busy:.3g} s "
                    f"without using CPU ({used:.3g} s used; budget {timeout:g} s of CPU): hung")
        if elapsed > WALL_BACKSTOP * timeout + WALL_SLACK_S:
            return (f"no result within {elapsed:.3g} s of wall time (the backstop of a "
                    f"{timeout:g} s budget of CPU; {used:.3g} s used)")
        return None
