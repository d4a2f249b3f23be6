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

Scheduling many workers is :mod:`integrator_bench.harness.run.loop`'s.
"""

from __future__ import annotations

import contextlib
import faulthandler
import gc
import os
import signal
import sys
import tempfile
import time
from collections import Counter

from threadpoolctl import ThreadpoolController

from integrator_bench.harness.measure import references, tripwire

from integrator_bench.harness.matrix import builds, registry
from integrator_bench.harness.matrix.line import ProblemSpec
from integrator_bench.harness.run.execution import (add_to_message, base_record, execute, finish,
                                                warnings_summary)
from integrator_bench.harness.matrix.provenance import BLAS_THREADS_PER_WORKER, THREAD_VARS
from integrator_bench.harness.matrix.record import CRASHED, OUT_OF_MEMORY, TIMEOUT, CaseStatus
from integrator_bench.harness.forking.budget import Watch, limit_memory
from integrator_bench.harness.forking import (become_subreaper, death, die_with_parent, fork,
                                             kill_adopted, kill_descendants, mark_isolated,
                                             wait_exit)
from integrator_bench.harness.run.cpu_watch import CaseWatch, Ledger
from integrator_bench.harness.run.limits import Limits
from integrator_bench.harness.run.streams import flush_output
from integrator_bench.harness.version import code_version

OUTPUT_BYTES = 1 << 20       # the most of a worker's captured output that is read
OUTPUT_LINE_CHARS = 300      # the longest line of output a message quotes
#: the most cases a worker runs before it is replaced (what a case leaves behind in
#: its process stays bounded)
MAX_CASES = 200


def _serve(conn, reference_dir, limits, parent, threads, output, ledger):
    """The body of a forked worker: isolate once, then run the cases sent
    through ``conn`` one at a time, each record sent back, until the pipe
    closes. Each message is ``(case, reference)``: the reference a Dask task
    hands with its case (:class:`~integrator_bench.harness.measure.references.Handed`),
    or None for the worker's own ``reference_dir``.

    Each case's output starts from an empty file (the parent reads it once
    the record has come); each case's budget is ``limits.budget_s`` CPU seconds
    of this process, its samples ``limits.repeat`` at most, its memory
    ``limits.memory_mb`` (:func:`~integrator_bench.harness.run.execution.execute`);
    its timed solves shown to the parent in ``ledger``
    (:class:`~integrator_bench.harness.run.cpu_watch.Ledger`), what a library
    printed once a solve's budget was spent cut off
    (:func:`~integrator_bench.harness.measure.tripwire.cut_output`).
    """
    limit = isolate(parent, threads, output, limits.memory_mb)
    ledger.show_here()
    tripwire.CAPTURED[0] = 1
    try:
        while True:
            try:
                case, handed = conn.recv()
            except EOFError:
                return
            flush_output()
            os.ftruncate(1, 0)  # fds 1 and 2 share one offset: this case's output from 0
            os.lseek(1, 0, os.SEEK_SET)
            record = execute(case, reference_dir if handed is None else handed,
                             limits.repeat, memory_mb=limit,
                             budget_s=limits.budget_of(case))
            flush_output()  # all of it in the file before the parent reads it
            tripwire.cut_output()
            conn.send(record)
    finally:
        conn.close()


def isolate(parent: int, threads: ThreadpoolController, output: int,
            memory_mb: float | None) -> float | None:
    """Make this freshly forked process a worker: inherited objects frozen (their
    pages stay shared), no fault dump, Ctrl-C left to ``parent`` (which kills
    it), a process group of its own, the reaper of what it leaves (whatever
    detached itself stays below it, :func:`~integrator_bench.harness.forking.become_subreaper`,
    and is killed with it), standard output and error into the file
    ``output``, death with ``parent``, one BLAS thread (``threads``: the parent's
    :func:`thread_controller`), its address space capped at ``memory_mb`` more
    than it inherited. Returns the memory limit set (:func:`limit_memory`).
    What a case's worker and a contenders' round process
    (:mod:`~integrator_bench.harness.run.resample`) both do first."""
    gc.freeze()  # the inherited objects: never traversed here, so their pages stay shared
    mark_isolated()  # the problems it builds are built here, without a trial of their own
    faulthandler.disable()  # a crash becomes a `crashed` record, not a dump on the console
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C stops the parent, which kills us
    os.setpgid(0, 0)  # a group of its own: killed with what a case started (killpg)
    become_subreaper()  # what a case started in a session of its own stays below it
    _capture_output(output)
    die_with_parent(parent)
    _one_thread(threads)
    return limit_memory(memory_mb)


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


def _one_thread(threads: ThreadpoolController) -> None:
    """One BLAS/OpenMP thread per worker: workers already fill the cores.

    ``threads`` is the parent's controller of its loaded BLAS/OpenMP libraries
    (:func:`thread_controller`); a library loaded later reads the environment.
    """
    for var in THREAD_VARS:
        os.environ[var] = str(BLAS_THREADS_PER_WORKER)
    threads.limit(limits=BLAS_THREADS_PER_WORKER)


_controller: list = [None, -1]  # the controller, and len(sys.modules) when it was built


def thread_controller() -> ThreadpoolController:
    """The BLAS/OpenMP libraries of this process, found once and inherited by
    every forked worker (finding them is costly, so not in each worker, see
    docs/timing.md, "Measurements behind the code");
    found again when modules were imported since, which may have loaded more."""
    if _controller[1] != len(sys.modules):
        _controller[:] = [ThreadpoolController(), len(sys.modules)]
    return _controller[0]


class Worker:
    """A forked process running cases one at a time; each record comes back
    through a pipe.

    A worker serves case after case (:meth:`submit`, then :meth:`record`), so a
    case pays no fork; it is replaced after a fault (a crash, a kill at its
    budget, an out-of-memory record: :attr:`usable` turns False) or after
    :data:`MAX_CASES` cases. Both backends use it: the local pool keeps
    ``jobs`` of them, and a Dask task (:func:`run_isolated`) forks one for its
    case on its Dask worker. A plain ``os.fork`` rather than
    ``multiprocessing``: Dask worker processes are daemonic, and
    multiprocessing refuses children to those.

    Its budget is in CPU seconds of its own process (``budget_s``): the case's
    solve stops itself at it wherever Python runs
    (:mod:`~integrator_bench.harness.measure.tripwire`); the owner kills a worker
    whose solve runs on past it in compiled code, or whose work around the solve
    passes its own bound (:mod:`~integrator_bench.harness.run.cpu_watch`), or that
    hangs (:meth:`past_budget`), looking every :meth:`wait_s` seconds.
    """

    def __init__(self, case=None, reference_dir=None, limits: Limits = Limits(),
                 build=ProblemSpec.build):
        self.case, self.exitcode, self.cases_run, self.dead = None, None, 0, False
        if case is not None:
            _warm(case, reference_dir, build)
        self.output = tempfile.TemporaryFile(prefix="ibench-output-")  # see _capture_output
        self.ledger = Ledger()      # where the worker shows its timed solves
        parent, threads = os.getpid(), thread_controller()
        self.conn, self.pid = fork(lambda conn: _serve(
            conn, reference_dir, limits, parent, threads, self.output.fileno(), self.ledger))
        if case is not None:
            self.submit(case)

    def submit(self, case, reference_dir=None) -> None:
        """Send ``case`` to the idle worker, with its own reference (a Dask task's
        :class:`~integrator_bench.harness.measure.references.Handed`) or None for the
        worker's; its clocks start."""
        self.case, self.cases_run = case, self.cases_run + 1
        self.watch, self.cpu = Watch(self.pid), CaseWatch(self.pid, self.ledger)
        self.start = self.watch.start
        self.conn.send((case, reference_dir))

    @property
    def usable(self) -> bool:
        """Whether the worker may take another case: not dead (nor exited
        meanwhile, as it does when the thread that forked it ends), and under
        :data:`MAX_CASES`."""
        return not self.dead and self.cases_run < MAX_CASES and not self.reaped()

    def past_budget(self, budget_s: float, now: float | None = None) -> str | None:
        """Why the current case must be stopped, or None: its CPU
        (:meth:`~integrator_bench.harness.run.cpu_watch.CaseWatch.verdict`), or a
        hang (:meth:`Watch.stalled`)."""
        return self.cpu.verdict(budget_s) or self.watch.stalled(budget_s, now)

    def wait_s(self) -> float:
        """Wall seconds until the current case must be looked at again
        (:meth:`~integrator_bench.harness.run.cpu_watch.CaseWatch.wait_s`)."""
        return self.cpu.wait_s()

    def record(self) -> dict:
        """The record sent by a worker whose pipe is readable, or a ``crashed`` one
        (the worker then is dead and reaped)."""
        try:
            record = self.conn.recv()
        except (EOFError, OSError):
            record = None
        if record is None:
            self.dead = True
            self.join(5)
            record = finish(base_record(self.case), CaseStatus.CRASHED, death(self.exitcode),
                            CRASHED)
        elif record.get("reason") == OUT_OF_MEMORY:
            self.dead = True   # what failed to allocate may have left it half-done
        return self._with_output(record)

    def timed_out(self, budget_s: float, why: str | None = None) -> dict:
        """Kill the worker and return the case's ``timeout`` record."""
        elapsed = time.monotonic() - self.start
        with contextlib.suppress(ProcessLookupError):
            os.kill(self.pid, signal.SIGSTOP)   # its CPU stands still while it is read
        figures = self.cpu.figures()
        self.close(output=False)
        record = base_record(self.case)
        record.update(figures, wall_s=elapsed, budget_s=budget_s)
        why = why or f"no result within {budget_s:g} s"
        return self._with_output(finish(record, CaseStatus.TIMEOUT, f"{why}; worker killed",
                                        TIMEOUT))

    def _with_output(self, record: dict) -> dict:
        """``record`` with the summary of what its case wrote (:func:`output_summary`)
        at the end of its message."""
        if self.output.closed:
            return record
        fd = self.output.fileno()
        data = os.pread(fd, min(os.fstat(fd).st_size, OUTPUT_BYTES), 0)
        if self.dead:
            self.output.close()
        return add_to_message(record, output_summary(data))

    def join(self, timeout: float) -> None:
        """Reap the worker once it exits, waiting up to ``timeout`` seconds."""
        end = time.monotonic() + timeout
        while not self.reaped():
            left = end - time.monotonic()
            if left <= 0:
                return
            wait_exit(self.pid, left)

    def reaped(self) -> bool:
        """Whether the worker has exited, its exit status collected (never waits)."""
        if self.exitcode is None:
            pid, status = os.waitpid(self.pid, os.WNOHANG)
            if pid:
                self.exitcode = os.waitstatus_to_exitcode(status)
        return self.exitcode is not None

    def close(self, output: bool = True) -> None:
        """Kill the worker and its process group (what its cases started) if it
        still runs, reap it, kill what it left here if it died (its orphans come to
        this process, :func:`~integrator_bench.harness.forking.kill_adopted`), close
        the pipe and (with ``output``) its captured output."""
        self.dead = True
        if self.exitcode is None:
            kill_descendants(self.pid)   # what its cases started, in any session or group
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self.pid, signal.SIGKILL)
        if self.exitcode is None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.pid, signal.SIGKILL)
            self.join(5)
        kill_adopted(self.pid)   # what a worker that died (a crash) left came here: killed
        self.conn.close()
        if output:
            self.output.close()


_warmed: set = set()


def _warm(case, reference_dir=None, build=ProblemSpec.build) -> None:
    """Load here, once per process, what each forked worker would otherwise load
    again: the registries (entry points and their modules), the code version,
    the problem's formulation (compiled models are cached per class) and its
    reference (kept by :mod:`~integrator_bench.harness.measure.references` once read).

    Called by every :class:`Worker` before it forks, so that a worker process
    (a Dask worker's or the local pool's, whose parent has the registries and
    models from expanding the matrix but not the references) does not pay for
    them again in every case (docs/timing.md, "Measurements behind the code").
    ``build(spec)`` gives the problem (default: built here,
    :meth:`~integrator_bench.harness.matrix.line.ProblemSpec.build`): a session's,
    built once for all its uses.
    """
    key = (case.spec, case.formulation)
    if key in _warmed:
        return
    _warmed.add(key)
    code_version()
    registry.integrators()
    try:
        if builds.foreign(registry.get_problem_class(case.problem)):
            return   # not project code: built in the worker only (a Dask worker's too)
        problem = build(case.spec)
        problem.formulate(case.formulation)
        references.stored(problem, reference_dir)   # no call of the model here
    except Exception:  # the case's own worker reports it as its record
        pass


class Isolated:
    """Cases run one at a time in a forked :class:`Worker` kept from one case to the
    next (replaced after a fault), as the local pool runs them: a long-lived
    worker, warm. What a study that compares the recorded CPU with plain calls
    times ``ibench run``'s recording by; each call waits for its case's record.

    The first solve in a freshly forked process pays for the pages it writes that
    it shares with its parent (every object it touches, the heap it allocates
    from), a cost a worker serving many cases pays once (docs/timing.md,
    "Measurements behind the code").
    """

    def __init__(self, reference_dir=None, limits: Limits = Limits()):
        self.limits, self.reference_dir = limits, reference_dir
        self.worker = None

    def __call__(self, case, reference_dir=None) -> dict:
        """Run ``case`` in the worker and return its record; ``reference_dir``, when
        given, is this case's reference (a Dask task's
        :class:`~integrator_bench.harness.measure.references.Handed`) in place of
        the one the runner was made with."""
        reference_dir = self.reference_dir if reference_dir is None else reference_dir
        if self.worker is not None and self.worker.usable:
            self.worker.submit(case, reference_dir)
        else:
            if self.worker is not None:
                self.worker.close()
            self.worker = Worker(case, reference_dir, self.limits)
        worker = self.worker
        while not worker.conn.poll(worker.wait_s()):  # readable: a record, or end of file
            why = worker.past_budget(self.limits.budget_of(case))
            if why:
                return worker.timed_out(self.limits.budget_of(case), why)
        return worker.record()

    def close(self) -> None:
        if self.worker is not None:
            self.worker.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def run_isolated(case, reference_dir=None, limits: Limits = Limits()) -> dict:
    """Run one case in a worker forked for it, wait for it here and return its record.

    What a Dask task runs: the same isolation as the local pool (budget,
    memory limit, crash), from a Dask worker, whose ``reference_dir`` is the
    reference handed with the case
    (:class:`~integrator_bench.harness.measure.references.Handed`).
    """
    with Isolated(reference_dir, limits) as run:
        return run(case)
