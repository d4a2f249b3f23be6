"""Isolating one case: a forked worker process, bounded in time and memory.

A :class:`Worker` forks a process that runs
:func:`integrator_bench.harness.run.execution.execute` and sends its record back
through a pipe. The worker dies with the thread that forked it
(``PR_SET_PDEATHSIG``), runs one BLAS/OpenMP thread, and may add at most
``memory_mb`` to its address space (``RLIMIT_AS``). A worker that hangs past
its timeout is killed and becomes a ``timeout`` record; one that dies
(segfault, ``os._exit``, killed) a ``crashed`` record. :func:`run_isolated`
is one case run so, waited for here: what a Dask task runs.

Whatever the case writes to its standard output and error -- a C library's
own diagnostics (SUNDIALS' ``[WARNING]`` lines) as much as a Python
``print`` -- goes, at the file-descriptor level, into a temporary file of
its worker (:func:`_capture_output`), never onto the terminal or into
``ibench run --json``'s stream; its lines are summarized at the end of the
record's message, as the case's Python warnings are
(:func:`output_summary`), for ``timeout`` and ``crashed`` records too. Work
done in the calling process (a missing reference computed before the run)
writes its diagnostics to standard error
(:func:`~integrator_bench.harness.run.streams.stdout_to_stderr`).

Scheduling many workers is :mod:`integrator_bench.harness.run.runner`'s.
"""

from __future__ import annotations

import contextlib
import ctypes
import faulthandler
import gc
import os
import resource
import select
import signal
import sys
import tempfile
import time
from collections import Counter
from multiprocessing.connection import Connection, wait

from threadpoolctl import ThreadpoolController

from integrator_bench.harness.measure import references

from integrator_bench.harness.model import registry
from integrator_bench.harness.run.execution import (add_to_message, base_record, execute, finish,
                                                warnings_summary)
from integrator_bench.harness.model.provenance import BLAS_THREADS_PER_WORKER, THREAD_VARS
from integrator_bench.harness.model.record import CRASHED, TIMEOUT, CaseStatus
from integrator_bench.harness.run.streams import flush_output
from integrator_bench.harness.version import code_version

DEFAULT_TIMEOUT = 60.0
DEFAULT_MEMORY_MB = 4096.0  # address space a case may add to its worker's (RLIMIT_AS)
OUTPUT_BYTES = 1 << 20       # the most of a worker's captured output that is read
OUTPUT_LINE_CHARS = 300      # the longest line of output a message quotes


def _child(case, conn, reference_dir, memory_mb, repeat, parent, threads, output, budget_s):
    """The body of a forked worker: isolate, run one case, send its record."""
    gc.freeze()  # the inherited objects: never traversed here, so their pages stay shared
    faulthandler.disable()  # a crash becomes a `crashed` record, not a dump on the console
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C stops the parent, which kills us
    _capture_output(output)
    _die_with_parent(parent)
    _one_thread(threads)
    limit = _limit_memory(memory_mb)
    try:
        record = execute(case, reference_dir, repeat, memory_mb=limit, budget_s=budget_s)
        flush_output()  # all of it in the file before the parent reads it
        conn.send(record)
    finally:
        conn.close()


def _capture_output(fd: int) -> None:
    """Point this process's standard output and error (file descriptors 1 and 2,
    which C libraries write to directly) at the open file ``fd``."""
    flush_output()
    os.dup2(fd, 1)
    os.dup2(fd, 2)


def output_summary(data: bytes) -> str | None:
    """``"output: [WARNING] ... (x2); ..."``: the most frequent lines of a
    worker's captured output, with their counts (as
    :func:`~integrator_bench.harness.run.execution.warnings_summary` gives the
    warnings); None when it wrote nothing."""
    lines = Counter(line.strip()[:OUTPUT_LINE_CHARS]
                    for line in data.decode(errors="replace").splitlines() if line.strip())
    return warnings_summary(lines, "output")


def _die_with_parent(parent: int) -> None:
    """Have the kernel kill this worker when the thread that forked it dies (Linux):
    a runner killed with SIGKILL leaves no orphan worker behind."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent:  # the parent died before prctl took effect
        os._exit(1)


def _one_thread(threads: ThreadpoolController) -> None:
    """One BLAS/OpenMP thread per worker: workers already fill the cores.

    ``threads`` is the parent's controller of its loaded BLAS/OpenMP libraries
    (:func:`_thread_controller`); a library loaded later reads the environment.
    """
    for var in THREAD_VARS:
        os.environ[var] = str(BLAS_THREADS_PER_WORKER)
    threads.limit(limits=BLAS_THREADS_PER_WORKER)


_controller: list = [None, -1]  # the controller, and len(sys.modules) when it was built


def _thread_controller() -> ThreadpoolController:
    """The BLAS/OpenMP libraries of this process, found once and inherited by
    every forked worker (finding them in each worker cost 10-40 ms a case);
    found again when modules were imported since, which may have loaded more."""
    if _controller[1] != len(sys.modules):
        _controller[:] = [ThreadpoolController(), len(sys.modules)]
    return _controller[0]


def _limit_memory(memory_mb: float | None) -> float | None:
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


class Worker:
    """One forked process running one case; its record comes back through a pipe.

    Both backends use it: the local pool keeps ``jobs`` of them at once, and
    a Dask task (:func:`run_isolated`) forks one on its Dask worker. A plain
    ``os.fork`` rather than ``multiprocessing``: Dask worker processes are
    daemonic, and multiprocessing refuses children to those.
    """

    def __init__(self, case, reference_dir=None, memory_mb=None, repeat=None, timeout=None):
        self.case, self.exitcode = case, None
        _warm(case, reference_dir)
        self.output = tempfile.TemporaryFile(prefix="ibench-output-")  # see _capture_output
        parent, threads = os.getpid(), _thread_controller()
        self.conn, self.pid = _fork(lambda conn: _child(
            case, conn, reference_dir, memory_mb, repeat, parent, threads, self.output.fileno(),
            None if timeout is None else timeout / 2))
        self.start = time.monotonic()

    def record(self, wait_exit: bool = True) -> dict:
        """The record sent by a worker whose pipe is readable, or a ``crashed`` one.

        With ``wait_exit`` False, a worker that sent its record is not waited
        for while it exits (tearing down its address space takes a few ms):
        :attr:`exitcode` stays None until :meth:`reaped` or :meth:`close`
        collects it.
        """
        try:
            record = self.conn.recv()
        except (EOFError, OSError):
            record = None
        if record is not None and not wait_exit:
            self.conn.close()
            self.reaped()
            return self._with_output(record)
        self.join(5)
        if record is None:
            record = finish(base_record(self.case), CaseStatus.CRASHED, _death(self.exitcode),
                            CRASHED)
        self._with_output(record)
        self.close()
        return record

    def timed_out(self, timeout: float, repeat: int | None = None) -> dict:
        """Kill the worker and return the case's ``timeout`` record."""
        elapsed = time.monotonic() - self.start
        self.close(output=False)
        record = base_record(self.case)
        record["wall_s"] = elapsed
        times = f" for up to {repeat} timed solves" if repeat and repeat > 1 else ""
        return self._with_output(finish(
            record, CaseStatus.TIMEOUT, f"no result within {timeout:g} s{times}; worker killed",
            TIMEOUT))

    def _with_output(self, record: dict) -> dict:
        """``record`` with the summary of what the worker wrote (:func:`output_summary`)
        at the end of its message; closes the captured output."""
        if self.output.closed:
            return record
        fd = self.output.fileno()
        data = os.pread(fd, min(os.fstat(fd).st_size, OUTPUT_BYTES), 0)
        self.output.close()
        return add_to_message(record, output_summary(data))

    def join(self, timeout: float) -> None:
        """Reap the worker once it exits, waiting up to ``timeout`` seconds."""
        end = time.monotonic() + timeout
        while not self.reaped():
            left = end - time.monotonic()
            if left <= 0:
                return
            _wait_exit(self.pid, left)

    def reaped(self) -> bool:
        """Whether the worker has exited, its exit status collected (never waits)."""
        if self.exitcode is None:
            pid, status = os.waitpid(self.pid, os.WNOHANG)
            if pid:
                self.exitcode = os.waitstatus_to_exitcode(status)
        return self.exitcode is not None

    def close(self, output: bool = True) -> None:
        """Kill the worker if it still runs, reap it, close the pipe and (with
        ``output``) its captured output."""
        if self.exitcode is None:
            try:
                os.kill(self.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            self.join(5)
        self.conn.close()
        if output:
            self.output.close()


def _wait_exit(pid: int, timeout: float) -> None:
    """Wait until process ``pid`` exits or ``timeout`` seconds pass (it stays unreaped).

    Woken by the exit itself through a pidfd (Linux 5.3 and later); elsewhere,
    sleeps 10 ms (the caller polls).
    """
    try:
        fd = os.pidfd_open(pid)
    except (AttributeError, OSError):
        time.sleep(min(timeout, 0.01))
        return
    try:
        select.select([fd], [], [], timeout)
    finally:
        os.close(fd)


def _death(exitcode) -> str:
    if exitcode is not None and exitcode < 0:
        try:
            return f"worker killed by signal {signal.Signals(-exitcode).name}"
        except ValueError:
            return f"worker killed by signal {-exitcode}"
    return f"worker exited with status {exitcode} without a result"


_warmed: set = set()


def _warm(case, reference_dir=None) -> None:
    """Load here, once per process, what each forked worker would otherwise load
    again: the registries (entry points and their modules), the code version,
    the problem's formulation (compiled models are cached per class) and its
    reference (kept by :mod:`~integrator_bench.harness.measure.references` once read).

    Called by every :class:`Worker` before it forks. Unwarmed, a Dask worker
    process paid it in every case (about 3x the wall time of ``--jobs 2`` on
    the full preset's two_mass cases), and the local runner, whose parent had
    the registries and models from expanding the matrix but not the
    references, about 9 ms a case on the quick preset.
    """
    key = (case.problem, case.params, case.formulation)
    if key in _warmed:
        return
    _warmed.add(key)
    code_version()
    registry.integrators()
    try:
        problem = registry.get_problem_class(case.problem)(**case.params_dict)
        problem.formulate(case.formulation)
        references.read(problem, reference_dir)
    except Exception:  # the case's own worker reports it as its record
        pass


def in_parallel(calls, jobs: int) -> list:
    """``[call() for call in calls]``, each call in a process forked for it, at
    most ``jobs`` at a time, the results in the order of ``calls``.

    Each process dies with this one (``PR_SET_PDEATHSIG``) and ignores Ctrl-C,
    which stops this one, which kills them. An exception a call raises is raised
    here once it arrives (the other processes killed); a process that dies
    without a result raises ``RuntimeError``. A call's result and exception must
    pickle.
    """
    results, pending, running = [None] * len(calls), list(enumerate(calls)), {}
    try:
        while pending or running:   # running: the pipe of each process -> (pid, index)
            while pending and len(running) < max(1, jobs):
                i, call = pending.pop(0)
                conn, pid = _fork_call(call)
                running[conn] = (pid, i)
            for conn in wait(list(running)):
                pid, i = running.pop(conn)
                try:
                    ok, value = conn.recv()
                except (EOFError, OSError):
                    ok, value = False, None
                conn.close()
                _, status = os.waitpid(pid, 0)
                if not ok:
                    raise value if isinstance(value, BaseException) else RuntimeError(
                        f"a forked process died without a result "
                        f"({_death(os.waitstatus_to_exitcode(status))})")
                results[i] = value
    finally:
        for conn, (pid, _) in running.items():
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            conn.close()
    return results


def _fork(body) -> tuple:
    """Fork a process that runs ``body(conn)``, ``conn`` its end of a pipe, and
    exits (status 0 when ``body`` returned): ``(this end of the pipe, its pid)``."""
    read, write = os.pipe()
    for stream in (sys.stdout, sys.stderr):
        stream.flush()  # no buffered output written twice
    pid = os.fork()
    if pid == 0:  # the child: never returns
        code = 1
        try:
            os.close(read)
            body(Connection(write, readable=False))
            code = 0
        finally:
            os._exit(code)
    os.close(write)
    return Connection(read, writable=False), pid


def _fork_call(call) -> tuple:
    """Fork a process that sends ``(True, call())`` or ``(False, the exception)``
    through a pipe and exits: ``(its end of the pipe, its pid)``."""
    parent = os.getpid()

    def body(conn):
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        _die_with_parent(parent)
        try:
            out = (True, call())
        except BaseException as exc:  # sent to the parent, which raises it
            out = (False, exc)
        try:
            conn.send(out)
        except Exception as exc:  # a result or exception that does not pickle
            conn.send((False, RuntimeError(f"{type(exc).__name__}: {exc}")))
        flush_output()
    return _fork(body)


def run_isolated(case, timeout=DEFAULT_TIMEOUT, reference_dir=None,
                 memory_mb=None, repeat=None) -> dict:
    """Run one case in a forked worker, wait for it here and return its record.

    What a Dask task runs: the same isolation as the local pool (timeout,
    memory limit, crash), from a Dask worker, whose ``reference_dir`` is the
    reference handed with the case
    (:class:`~integrator_bench.harness.measure.references.Handed`).
    """
    worker = Worker(case, reference_dir, memory_mb, repeat, timeout)
    if worker.conn.poll(timeout):  # readable: a record, or end of file when it died
        return worker.record()
    return worker.timed_out(timeout, repeat)
