"""Timing cases again, side by side: the contenders' rounds.

A :class:`Block` is a few cases of one problem timed again in rounds: every
case once per round, the order rotated from round to round (no case always
follows the same other), each solve on a fresh counted system, timed as the
matrix times a case's later samples
(:func:`~integrator_bench.harness.run.execution.solve_timed`). A block runs in
a process of its own, forked for it and isolated as a case's worker is
(:func:`~integrator_bench.harness.run.isolation.isolate`: one BLAS thread,
memory cap, output captured, death with its parent), so samples come from
several processes, as pyperf spreads its values over worker processes because
one process's memory layout alone moves a timing. Its first ``warmups``
rounds are not kept: a freshly forked process pays the copy-on-write faults
of the pages its first solves write (pyperf likewise discards a warmup value
per process). Which cases to time, and whether more rounds are needed, is
the caller's (:mod:`integrator_bench.harness.contend`).

:func:`run_blocks` runs blocks on up to ``jobs`` processes at once; a block
whose process crashes or runs past its CPU budget gives no samples, and the
run goes on.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import signal
import warnings
from multiprocessing.connection import wait

from integrator_bench.harness.forking import fork
from integrator_bench.harness.forking.budget import POLL_S, process_cpu_of
from integrator_bench.harness.matrix import registry
from integrator_bench.harness.measure.counting import counted
from integrator_bench.harness.run.execution import atol_of, solve_timed
from integrator_bench.harness.run.isolation import isolate, thread_controller
from integrator_bench.harness.run.limits import Limits
from integrator_bench.integrators.base import Status
from integrator_bench.problems.system import convert

#: rounds a block's process times and discards before it keeps any (pyperf: 1)
WARMUPS = 1
#: a block's process is killed past this many times its predicted CPU, plus
#: BACKSTOP_GRACE_S (its predicted CPU: its cases' recorded CPU times its rounds)
BACKSTOP = 3.0
BACKSTOP_GRACE_S = 2.0


@dataclasses.dataclass(frozen=True)
class Block:
    """Cases to time in ``rounds`` kept rounds (after :data:`WARMUPS` discarded
    ones) in one process. ``cpu_s`` is what the block is predicted to cost (the
    kill backstop's base)."""

    cases: tuple
    rounds: int
    cpu_s: float = 1.0
    warmups: int = WARMUPS


class _Timer:
    """One case made ready to be timed again: problem built and formulated once,
    each solve on a fresh counted system (formulated and counted outside the
    timed region)."""

    def __init__(self, case):
        self.case = case
        self.icls = registry.get_integrator(case.integrator)
        self.problem = case.spec.build()
        self.settings = case.settings_dict
        self.outputs = self.atol = None

    def __call__(self) -> float | None:
        """One timed solve's CPU seconds; None when it did not end in success with
        the outputs of the first (it did other work: no sample)."""
        system = counted(convert(self.problem.formulate(self.case.formulation), self.icls))[0]
        if self.atol is None:
            self.atol = atol_of(system, self.case.rtol)
        sol, cpu, _ = solve_timed(self.icls, self.settings, system, self.case, self.atol)
        if sol.status is not Status.SUCCESS or (self.outputs is not None
                                                and len(sol.t) != self.outputs):
            return None
        self.outputs = len(sol.t)
        return cpu


def time_block(block: Block) -> dict:
    """Run ``block`` here: ``case_id -> [CPU seconds of each kept round]``; a case
    whose solve fails or does other work than before stops there (its list is
    shorter), as does one that raises."""
    timers, out = [], {}
    for case in block.cases:
        try:
            timers.append(_Timer(case))
            out[case.case_id] = []
        except Exception:  # noqa: BLE001  no samples for a case that cannot be built here
            continue
    alive = list(range(len(timers)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")    # the case's first solve has said it all once
        for r in range(block.warmups + block.rounds):
            shift = r % max(len(alive), 1)
            for i in alive[shift:] + alive[:shift]:
                try:
                    cpu = timers[i]()
                except Exception:  # noqa: BLE001  a solve that raises gives no more samples
                    cpu = None
                if cpu is None:
                    alive.remove(i)
                elif r >= block.warmups:
                    out[timers[i].case.case_id].append(cpu)
    return out


def run_blocks(blocks, limits: Limits = Limits(), jobs: int = 1, then=None) -> list:
    """Run each of ``blocks`` in a forked, isolated process of its own, up to ``jobs``
    at once, and return one result per block run, in the order started: ``(block,
    result, cpu_s)``, the result the dict of :func:`time_block` or a string saying
    why there is none (the process crashed, or ran past :data:`BACKSTOP` times
    its predicted CPU plus :data:`BACKSTOP_GRACE_S`), ``cpu_s`` the CPU its
    process used.

    ``then(block, result, cpu_s)``, when given, is called as each block ends and
    returns the blocks to run next (a contest's next rounds), so that no
    process waits for the slowest block of a batch.
    """
    pending, done = list(blocks), []
    running: dict = {}     # conn -> (block, pid)
    parent, threads = os.getpid(), thread_controller()
    null = os.open(os.devnull, os.O_WRONLY)

    def ended(block, result, pid):
        cpu = process_cpu_of(pid) or 0.0     # an exited, unreaped process keeps its times
        done.append((block, result, cpu))
        if then is not None:
            pending.extend(then(block, result, cpu))
    try:
        while pending or running:
            while pending and len(running) < max(jobs, 1):
                block = pending.pop(0)
                conn, pid = fork(lambda c, b=block: _serve_block(
                    c, b, parent, threads, null, limits.memory_mb))
                running[conn] = (block, pid)
            for conn in wait(list(running), timeout=POLL_S):
                block, pid = running.pop(conn)
                try:
                    result = conn.recv()
                except (EOFError, OSError):
                    result = "the process timing the block died without a result"
                with contextlib.suppress(ChildProcessError):   # exited; its times final
                    os.waitid(os.P_PID, pid, os.WEXITED | os.WNOWAIT)
                ended(block, result, pid)
                _reap(conn, pid)
            for conn, (block, pid) in list(running.items()):
                used = process_cpu_of(pid)
                if used is not None and used > BACKSTOP * block.cpu_s + BACKSTOP_GRACE_S:
                    del running[conn]
                    ended(block, f"killed after {used:.3g} s of CPU (predicted "
                                 f"{block.cpu_s:.3g} s)", pid)
                    _reap(conn, pid)
    finally:
        for conn, (_, pid) in running.items():
            _reap(conn, pid)
        os.close(null)
    return done


def _serve_block(conn, block, parent, threads, output, memory_mb) -> None:
    """The body of a block's process: isolated as a worker, time, send the result."""
    isolate(parent, threads, output, memory_mb)
    conn.send(time_block(block))
    conn.close()


def _reap(conn, pid: int) -> None:
    """Kill (if still running) and reap a block's process; close its pipe."""
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(pid, signal.SIGKILL)
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, signal.SIGKILL)
    with contextlib.suppress(ChildProcessError):
        os.waitpid(pid, 0)
    conn.close()
