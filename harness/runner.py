"""Running cases: one worker process per case, bounded in time, never fatal.

:func:`execute` runs one case in the current process and always returns a
record. :func:`run_matrix` runs many, each in a forked worker process with a
wall-clock timeout, a memory limit and one BLAS thread, ``jobs`` at a time
(or on Dask workers, :mod:`integrator_bench.harness.dask_backend`, through the same
:class:`Worker`): a worker that hangs becomes a ``timeout`` record, one that
dies (segfault, ``os._exit``, killed) a ``crashed`` record, an exception an
``error`` record (MemoryError past the limit included). Every record is
committed the moment it arrives, with the id of the run whose provenance the
store keeps; an interrupted or killed run keeps everything finished.
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import faulthandler
import json
import os
import resource
import signal
import statistics
import sys
import threading
import time
from collections import deque
from datetime import datetime, timezone
from multiprocessing.connection import Connection, wait

import numpy as np
import pandas as pd

from integrator_bench.harness import references, registry
from integrator_bench.harness.cases import Case
from integrator_bench.harness.metrics import measure
from integrator_bench.harness.provenance import BLAS_THREADS_PER_WORKER, THREAD_VARS
from integrator_bench.harness.record import FIELDS, empty_record
from integrator_bench.harness.store import Store
from integrator_bench.harness.version import code_version
from integrator_bench.problems.system import Unsupported, convert

DEFAULT_TIMEOUT = 60.0
DEFAULT_MEMORY_MB = 4096.0  # address space a case may add to its worker's (RLIMIT_AS)


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def base_record(case: Case) -> dict:
    icls = registry.integrators().get(case.integrator)
    return empty_record(
        case_id=case.case_id, problem=case.problem, params=case.params_json,
        formulation=case.formulation, integrator=case.integrator,
        origin=getattr(icls, "origin", None), rtol=case.rtol, h=case.h,
        code_version=code_version())


def finish(record: dict, status: str, message: str = "") -> dict:
    record.update(status=status, message=message or None, created=_now())
    return record


class _Counter:
    """Wraps a callable and counts its calls."""

    def __init__(self, fn):
        self.fn, self.n = fn, 0

    def __call__(self, *args):
        self.n += 1
        return self.fn(*args)


def counted(system):
    """A copy of ``system`` whose counted callables count their calls.

    Returns the system and ``{"nfev": counter, "njev": counter or None}``, after
    the kind's ``counted`` declaration.
    """
    counters, changes = {"nfev": None, "njev": None}, {}
    for attr, key in system.counted.items():
        fn = getattr(system, attr)
        if fn is not None:
            changes[attr] = counters[key] = _Counter(fn)
    return dataclasses.replace(system, **changes), counters


def execute(case: Case, reference_dir=None, repeat: int = 1) -> dict:
    """Run one case here and return its record; never raises.

    With ``repeat`` > 1 a successful solve is timed ``repeat`` times, each by a
    fresh integrator instance: ``cpu_s`` and ``wall_s`` are the medians,
    ``cpu_s_min`` the least CPU time; counts and errors come from the first
    solve (they are deterministic).
    """
    record = base_record(case)
    if case.unsupported:
        return finish(record, "unsupported", case.unsupported)
    try:
        problem = registry.get_problem_class(case.problem)(**case.params_dict)
        icls = registry.get_integrator(case.integrator)
        why = icls.mode_unsupported(case.rtol, case.h)
        if why:
            return finish(record, "unsupported", why)
        try:
            system = convert(problem.formulate(case.formulation), icls)
        except Unsupported as exc:
            return finish(record, "unsupported", f"{case.formulation}: {exc}")
        system, counters = counted(system)
        atol = system.atol(case.rtol) if case.rtol is not None else None
        record["atol"] = float(np.min(atol)) if atol is not None else None
        sol, cpu, wall = _timed_solve(icls, system, case, atol)
        _fill_counts(record, sol.counts, counters, icls)
        cpus, walls = [cpu], [wall]
        while sol.success and len(cpus) < repeat:
            _, cpu, wall = _timed_solve(icls, system, case, atol)
            cpus.append(cpu)
            walls.append(wall)
        record.update(cpu_s=statistics.median(cpus), cpu_s_min=min(cpus),
                      wall_s=statistics.median(walls), repeat=len(cpus))
        Y = np.asarray(system.output(sol.t, sol.y), float) if len(sol.t) else np.empty((0, 0))
        if not sol.success:
            return finish(record, "failed", sol.message or "integrator gave up")
        if not np.all(np.isfinite(Y)):
            return finish(record, "failed", "non-finite values in the solution")
        # the reference only after the solve: an integrator's own failure is never
        # hidden behind a missing reference
        ref = references.load(problem, reference_dir, compute_missing=False)
        if len(sol.t) != len(ref.t) or not np.allclose(sol.t, ref.t, rtol=0, atol=1e-12):
            return finish(record, "error", "solution times do not match the output times")
        groups = {"error": problem.component_index(problem.error_components),
                  "velocity": problem.component_index(problem.velocity_components),
                  "lambda": problem.component_index(problem.lambda_components)}
        record.update(measure(Y, ref.Y, problem.atol_scale_vector(), groups))
        drift = problem.constraint_residuals(sol.t, Y)
        if drift is not None:
            record["drift_pos"], record["drift_vel"] = (float(np.max(d)) for d in drift)
        record["reference"] = ref.id
        return finish(record, "ok")
    except Exception as exc:  # any exception is a record, never a crash of the run
        why = f"{type(exc).__name__}: {exc}".splitlines()[0] if str(exc) else type(exc).__name__
        if isinstance(exc, MemoryError):
            limit = f" of {_memory_limit_mb:g} MB" if _memory_limit_mb else ""
            why = f"out of memory (per-case limit{limit}): {why}"
        if isinstance(exc, (OverflowError, FloatingPointError)):
            # arithmetic overflow inside the problem's functions: the solution diverged
            return finish(record, "failed", f"diverged ({why})"[:500])
        return finish(record, "error", why[:500])


def _timed_solve(icls, system, case, atol):
    """Solve once with a fresh integrator; return the solution, CPU and wall seconds."""
    integrator = icls()
    cpu0, wall0 = time.process_time(), time.perf_counter()
    sol = integrator.solve(system, rtol=case.rtol, atol=atol, h=case.h)
    return sol, time.process_time() - cpu0, time.perf_counter() - wall0


def _fill_counts(record, counts, counters, icls):
    counts = {k: int(v) for k, v in counts.items() if v is not None}
    record["solver_counts"] = counts
    fev, jev = counters["nfev"], counters["njev"]
    record["nfev"] = fev.n
    if "njev" in counts:
        record["njev"] = counts["njev"]
    elif icls.uses_jacobian or not icls.implicit:
        record["njev"] = jev.n if jev is not None else 0
    for key in ("nlu", "nsteps", "nreject", "nniter", "nnfail", "nevents"):
        record[key] = counts.get(key)


_memory_limit_mb: float | None = None  # set in a worker: named in out-of-memory messages


def _child(case, conn, reference_dir, memory_mb, repeat, parent):
    """The body of a forked worker: isolate, run one case, send its record."""
    faulthandler.disable()  # a crash becomes a `crashed` record, not a dump on the console
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C stops the parent, which kills us
    _die_with_parent(parent)
    _one_thread()
    _limit_memory(memory_mb)
    try:
        conn.send(execute(case, reference_dir, repeat))
    finally:
        conn.close()


def _die_with_parent(parent: int) -> None:
    """Have the kernel kill this worker when the thread that forked it dies (Linux):
    a runner killed with SIGKILL leaves no orphan worker behind."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent:  # the parent died before prctl took effect
        os._exit(1)


def _one_thread() -> None:
    """One BLAS/OpenMP thread per worker: workers already fill the cores."""
    for var in THREAD_VARS:
        os.environ[var] = str(BLAS_THREADS_PER_WORKER)
    from threadpoolctl import threadpool_limits
    threadpool_limits(BLAS_THREADS_PER_WORKER)


def _limit_memory(memory_mb: float | None) -> None:
    """Cap the address space (RLIMIT_AS) at what the worker inherited plus ``memory_mb``.

    A forked worker starts with its parent's mappings, whose size depends on
    the parent (a Dask worker maps more than ``ibench``), so the limit is on
    what the case adds. An allocation past it fails: numpy raises MemoryError
    (an ``error`` record naming memory); code that cannot recover kills the
    worker (a ``crashed`` record).
    """
    global _memory_limit_mb
    if not memory_mb:
        return
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            vm = next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmSize:"))
    except (OSError, StopIteration, ValueError):
        return  # no way to know the inherited size: leave the address space unlimited
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = vm + int(memory_mb * 2**20)
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    _memory_limit_mb = memory_mb


class Worker:
    """One forked process running one case; its record comes back through a pipe.

    Both backends use it: the local runner keeps ``jobs`` of them at once, and
    a Dask task (:func:`run_isolated`) forks one on its Dask worker. A plain
    ``os.fork`` rather than ``multiprocessing``: Dask worker processes are
    daemonic, and multiprocessing refuses children to those.
    """

    def __init__(self, case, reference_dir=None, memory_mb=None, repeat=1):
        self.case, self.exitcode = case, None
        read, write = os.pipe()
        parent = os.getpid()
        for stream in (sys.stdout, sys.stderr):
            stream.flush()  # no buffered output written twice
        pid = os.fork()
        if pid == 0:  # the worker: never returns
            code = 1
            try:
                os.close(read)
                _child(case, Connection(write, readable=False), reference_dir, memory_mb,
                       repeat, parent)
                code = 0
            finally:
                os._exit(code)
        os.close(write)
        self.pid, self.conn, self.start = pid, Connection(read, writable=False), time.monotonic()

    def record(self) -> dict:
        """The record sent by a worker whose pipe is readable, or a ``crashed`` one."""
        try:
            record = self.conn.recv()
        except (EOFError, OSError):
            record = None
        self.join(5)
        if record is None:
            record = finish(base_record(self.case), "crashed", _death(self.exitcode))
        self.close()
        return record

    def timed_out(self, timeout: float, repeat: int = 1) -> dict:
        """Kill the worker and return the case's ``timeout`` record."""
        elapsed = time.monotonic() - self.start
        self.close()
        record = base_record(self.case)
        record["wall_s"] = elapsed
        times = f" for {repeat} timed solves" if repeat > 1 else ""
        return finish(record, "timeout", f"no result within {timeout:g} s{times}; worker killed")

    def join(self, timeout: float) -> None:
        end = time.monotonic() + timeout
        while self.exitcode is None:
            pid, status = os.waitpid(self.pid, os.WNOHANG)
            if pid:
                self.exitcode = os.waitstatus_to_exitcode(status)
            elif time.monotonic() > end:
                return
            else:
                time.sleep(0.01)

    def close(self) -> None:
        """Kill the worker if it still runs, reap it, close the pipe."""
        if self.exitcode is None:
            try:
                os.kill(self.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            self.join(5)
        self.conn.close()


_warmed: set = set()


def _warm(case) -> None:
    """Load here, once per process, what each forked worker would otherwise load
    again: the registries (entry points and their modules), the code version
    and the problem's formulation (compiled models are cached per class).

    The local runner's parent has all of it from expanding the matrix; a Dask
    worker process starts without it, and paid it in every case (about 3x the
    wall time of ``--jobs 2`` on the full preset's two_mass cases).
    """
    key = (case.problem, case.params, case.formulation)
    if key in _warmed:
        return
    _warmed.add(key)
    code_version()
    registry.integrators()
    try:
        registry.get_problem_class(case.problem)(**case.params_dict).formulate(case.formulation)
    except Exception:  # the case's own worker reports it as its record
        pass


def run_isolated(case, timeout=DEFAULT_TIMEOUT, reference_dir=None,
                 memory_mb=None, repeat=1) -> dict:
    """Run one case in a forked worker, wait for it here and return its record.

    What a Dask task runs: the same isolation as the local runner (timeout,
    memory limit, crash), from a Dask worker.
    """
    _warm(case)
    worker = Worker(case, reference_dir, memory_mb, repeat)
    if worker.conn.poll(timeout):  # readable: a record, or end of file when it died
        return worker.record()
    return worker.timed_out(timeout, repeat)


def prepare_references(cases, reference_dir=None, log=None):
    """Make sure every (problem, params) of ``cases`` has a usable reference."""
    seen = set()
    for case in cases:
        key = (case.problem, case.params)
        if key in seen or case.unsupported:
            continue
        seen.add(key)
        problem = registry.get_problem_class(case.problem)(**case.params_dict)
        ref, why = references.read(problem, reference_dir)
        if ref is None:
            if log:
                log(f"computing reference for {problem.label()} ({why})")
            references.load(problem, reference_dir)


def run_matrix(cases, store: Store | None = None, jobs: int | None = None,
               timeout: float = DEFAULT_TIMEOUT, resume: bool = False, progress: bool = True,
               on_record=None, reference_dir=None, memory_mb: float | None = DEFAULT_MEMORY_MB,
               repeat: int = 1, dask=None, command: str | None = None) -> pd.DataFrame:
    """Run ``cases`` and return one DataFrame row per case.

    Parameters
    ----------
    cases : list of Case
    store : Store, optional
        Where each record is committed as it arrives, and the run's
        provenance (:mod:`integrator_bench.harness.provenance`) with it.
    jobs : int, optional
        Worker processes at once (default: the number of cores).
    timeout : float
        Wall-clock seconds a case (all its repeats) may take before its
        worker is killed.
    resume : bool
        Skip cases already in ``store`` for this code version (their stored
        records are returned); a case another run stored meanwhile is not
        stored twice.
    on_record : callable, optional
        Called with every new record (the command line prints JSON lines).
    memory_mb : float or None
        Address space in MiB a case may allocate on top of what its worker
        inherits (RLIMIT_AS); None for no limit.
    repeat : int
        Timed solves per case (see :func:`execute`).
    dask : distributed.Client or str, optional
        Run the cases on Dask instead of local workers: a client, a scheduler
        address ``tcp://HOST:PORT`` or ``local:N`` (see
        :mod:`integrator_bench.harness.dask_backend`). Records, progress and store writes stay
        here.
    command : str, optional
        The command line stored with the provenance (default: ``sys.argv``).
    """
    from integrator_bench.harness import dask_backend, provenance

    if dask is not None and jobs is not None:
        raise ValueError("jobs and dask exclude each other: the Dask workers set the parallelism")
    jobs = jobs or os.cpu_count() or 1
    records = []
    pending = deque(cases)
    if resume and store is not None:
        done = store.done_case_ids(code_version())
        pending = deque(c for c in cases if c.case_id not in done)
        if done:
            old = store.dataframe()
            old = old[(old.code_version == code_version())
                      & old.case_id.isin({c.case_id for c in cases})]
            records.extend(old.drop_duplicates("case_id", keep="last").to_dict("records"))
    prepare_references(pending, reference_dir,
                       log=(lambda m: print(m, file=sys.stderr)) if progress else None)
    with contextlib.ExitStack() as stack:
        client = None
        if dask is not None:
            client = stack.enter_context(dask_backend.connect(dask)) if isinstance(dask, str) \
                else dask
        backend = dask_backend.describe(client) if client else {"kind": "local", "jobs": jobs}
        run_id = None
        if store is not None:
            run_id = store.begin_run(provenance.collect(command, backend, {
                "timeout": timeout, "memory_mb": memory_mb, "repeat": repeat,
                "resume": resume, "cases": len(cases), "pending": len(pending)}))
        bar = stack.enter_context(contextlib.closing(
            _progress(len(cases), len(cases) - len(pending), progress)))
        interrupted = []

        def accept(record):
            record["run_id"] = run_id
            if store is not None and not store.add(record, once=resume):
                bar.update(1)  # another run stored this case meanwhile: keep its record
                return
            records.append(record)
            if on_record:
                on_record(record)
            bar.update(1)

        def on_interrupt(signum, frame):  # a flag, so no fork or store write is cut in half
            interrupted.append(signum)

        in_main = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGINT, on_interrupt) if in_main else None
        status = "failed"
        try:
            options = dict(timeout=timeout, reference_dir=reference_dir, memory_mb=memory_mb,
                           repeat=repeat)
            if client is not None:
                dask_backend.run(client, pending, accept, interrupted, **options)
            else:
                _run_local(pending, jobs, accept, interrupted, **options)
            status = "interrupted" if interrupted else "finished"
        finally:
            if in_main:
                signal.signal(signal.SIGINT, previous)
            if run_id is not None:
                store.finish_run(run_id, status, _now())
    if interrupted:
        raise KeyboardInterrupt
    return to_dataframe(records)


def _run_local(pending, jobs, accept, interrupted, timeout, reference_dir, memory_mb, repeat):
    """Keep ``jobs`` forked workers busy until ``pending`` is empty or a Ctrl-C."""
    running: dict = {}  # pipe -> Worker
    try:
        while (pending or running) and not interrupted:
            while pending and len(running) < jobs:
                case = pending.popleft()
                if case.unsupported:
                    accept(execute(case))
                    continue
                worker = Worker(case, reference_dir, memory_mb, repeat)
                running[worker.conn] = worker
            if not running:
                continue
            for conn in wait(list(running), timeout=0.2):
                accept(running.pop(conn).record())
            now = time.monotonic()
            for conn, worker in list(running.items()):
                if now - worker.start > timeout:
                    del running[conn]
                    accept(worker.timed_out(timeout, repeat))
    finally:
        for worker in running.values():
            worker.close()


def _death(exitcode) -> str:
    if exitcode is not None and exitcode < 0:
        try:
            return f"worker killed by signal {signal.Signals(-exitcode).name}"
        except ValueError:
            return f"worker killed by signal {-exitcode}"
    return f"worker exited with status {exitcode} without a result"


def _progress(total, initial, enabled):
    from tqdm import tqdm
    tqdm.monitor_interval = 0  # no monitor thread: workers are forked
    return tqdm(total=total, initial=initial, disable=not enabled, file=sys.stderr,
                unit="case", dynamic_ncols=True)


def to_dataframe(records) -> pd.DataFrame:
    rows = []
    for r in records:
        r = dict(r)
        if isinstance(r.get("solver_counts"), dict):
            r["solver_counts"] = json.dumps(r["solver_counts"], sort_keys=True)
        rows.append(r)
    return pd.DataFrame(rows, columns=list(FIELDS))
