"""Scheduling cases: one loop, two backends, every record stored as it arrives.

:func:`run_matrix` runs many cases, each isolated in a forked worker
(:mod:`integrator_bench.harness.run.isolation`), through :func:`drive`: the one
scheduling loop, which takes a *submit/poll* backend. :class:`LocalPool`
keeps ``jobs`` forked workers of this process busy;
:class:`integrator_bench.harness.run.dask_backend.DaskPool` submits each case as
a Dask task. Either way an ``unsupported`` case is recorded here and costs
no process. Every record is committed the moment it arrives, with the id of
the run whose provenance the store keeps; an interrupted or killed run keeps
everything finished. A record whose integrator's own counts disagree with
the harness's (``count_mismatch``) is warned about once per integrator, on
standard error.

Modules (none imports one that imports it):

* :mod:`~integrator_bench.harness.run.execution` -- one case in this process:
  counting wrappers, the solve, the record, the metrics (:func:`execute`);
* :mod:`~integrator_bench.harness.run.isolation` -- one case in a forked worker:
  timeout, memory limit, one BLAS thread, crash and timeout records
  (:class:`Worker`, :func:`run_isolated`);
* this module and :mod:`~integrator_bench.harness.run.dask_backend` -- many cases.

Import each name from its home module; this one re-exports nothing.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import signal
import sys
import threading
import time
from multiprocessing.connection import wait

import pandas as pd

from integrator_bench.harness.run import dask_backend

from integrator_bench.harness.model import provenance, registry

from integrator_bench.harness.measure import references, unit_costs
from integrator_bench.harness.errors import ReferenceFailure
from integrator_bench.harness.run.execution import MESSAGE_CHARS, base_record, execute, finish, now
from integrator_bench.harness.forking import in_parallel
from integrator_bench.harness.run.isolation import DEFAULT_MEMORY_MB, DEFAULT_TIMEOUT, POLL_S, Worker
from integrator_bench.harness.model.record import FIELDS, NO_REFERENCE, CaseStatus
from integrator_bench.harness.run.schedule import POLICY, CostModel, Schedule, StiffnessBound
from integrator_bench.harness.model.store import Store
from integrator_bench.harness.run.streams import stdout_to_stderr
from integrator_bench.harness.version import code_version
from integrator_bench.problems.base import ProblemError
from integrator_bench.problems.system import convert

__all__ = ["run_matrix", "drive", "LocalPool", "prepare_references", "reference_progress",
           "to_dataframe"]


class LocalPool:
    """The local backend of :func:`drive`: up to ``jobs`` forked workers of this
    process, each serving case after case
    (:class:`~integrator_bench.harness.run.isolation.Worker`), each case within
    its budget of ``timeout`` CPU seconds.

    A case goes to an idle worker, or to a new one when none is idle; a
    worker is replaced only after a fault (crash, kill past the budget's
    backstops, out of memory) or after
    :data:`~integrator_bench.harness.run.isolation.MAX_CASES` cases, so a case
    pays no fork of its own.
    """

    def __init__(self, jobs, timeout, reference_dir, memory_mb, repeat):
        self.jobs, self.timeout = jobs, timeout
        self.options = (reference_dir, memory_mb, repeat, timeout)
        self.running: dict = {}  # pipe -> Worker
        self.idle: list = []     # workers waiting for a case

    def __len__(self) -> int:
        return len(self.running)

    def has_room(self) -> bool:
        return len(self.running) < self.jobs

    def submit(self, case) -> None:
        if self.idle:
            worker = self.idle.pop()
            worker.submit(case)
        else:
            worker = Worker(case, *self.options)
        self.running[worker.conn] = worker

    def poll(self):
        """Yield the records of the finished cases (waiting up to 0.1 s for one),
        then the ``timeout`` records of those past their budget (their workers
        killed)."""
        if not self.running:
            return
        for conn in wait(list(self.running), timeout=POLL_S):
            worker = self.running.pop(conn)
            record = worker.record()
            self._release(worker)
            yield record
        now_s = time.monotonic()
        for conn, worker in list(self.running.items()):
            why = worker.past_budget(self.timeout, now_s)
            if why:
                del self.running[conn]
                yield worker.timed_out(self.timeout, why)

    def _release(self, worker) -> None:
        """Keep a worker that finished its case for the next, or retire it."""
        if worker.usable:
            self.idle.append(worker)
        else:
            worker.close()

    def close(self) -> None:
        """Kill and reap every worker, running or idle."""
        for worker in [*self.running.values(), *self.idle]:
            worker.close()
        self.running.clear()
        self.idle.clear()


def drive(backend, pending: Schedule, accept, interrupted: list, on_dispatch=None,
          deadline: float | None = None) -> bool:
    """The scheduling loop: feed ``backend`` the cases ``pending`` hands out
    while it has room, ``accept`` each record it gives back (and each
    ``skipped`` record the schedule decides), until nothing is pending or
    running, ``interrupted`` holds a signal, or the clock (``time.monotonic``)
    is past ``deadline``: then the cases in flight are stopped with the backend,
    unrecorded, and those not handed out stay so.

    An ``unsupported`` case is recorded here by
    :func:`~integrator_bench.harness.run.execution.execute` (it never reaches the
    backend: no process, no task). A line's next case is handed out only once
    its previous case has its record (:class:`~integrator_bench.harness.run.schedule.Schedule`),
    on the local pool and on Dask alike. The backend is closed on the way out,
    so an interruption or an exception leaves no worker or task behind.

    Parameters
    ----------
    backend
        ``len(backend)`` (cases in flight), ``has_room()``, ``submit(case)``,
        ``poll()`` (an iterable of finished records; it may wait a little)
        and ``close()``: :class:`LocalPool` or
        :class:`~integrator_bench.harness.run.dask_backend.DaskPool`.
    pending : Schedule
        ``next()`` (a case, or None while every line waits), ``done(record)``,
        ``skips()`` (the skipped records decided meanwhile) and truth (cases left).
    on_dispatch : callable, optional
        Called with each case just before it is submitted (or, unsupported,
        recorded here).
    deadline : float, optional
        A ``time.monotonic()`` value past which nothing more is run.

    Returns
    -------
    bool
        Whether cases were left, pending or in flight, at the deadline.
    """
    def in_time():
        return deadline is None or time.monotonic() < deadline

    try:
        while (pending or len(backend)) and not interrupted and in_time():
            while backend.has_room() and in_time():
                case = pending.next()
                for record in pending.skips():
                    accept(record)
                if case is None:
                    break
                if on_dispatch:
                    on_dispatch(case)
                if case.unsupported:
                    accept(execute(case))
                else:
                    backend.submit(case)
            for record in backend.poll():
                pending.done(record)
                accept(record)
            for record in pending.skips():
                accept(record)
        return bool(pending or len(backend)) and not interrupted
    finally:
        backend.close()


def prepare_references(cases, reference_dir=None, log=None,
                       limit: float | None = references.REFERENCE_TIMEOUT, jobs: int = 1,
                       deadline: float | None = None) -> dict:
    """Make sure every (problem, params) of ``cases`` has a usable reference.

    A missing or stale one is computed within ``limit`` wall seconds (None: no
    limit) and, with a ``deadline`` (a ``time.monotonic()`` value), within what
    is left of it when its computation starts; its progress logged every 2 s;
    one that cannot be computed within that (or at all) is not stored. Several are computed side by side, each in a
    forked process, ``jobs`` at a time
    (:func:`~integrator_bench.harness.forking.in_parallel`): the perturbed
    parameter sets of an advice, a sweep of new parameter sets.

    Returns
    -------
    dict
        ``(problem, params)`` -> why it has no reference, for those that have none.
    """
    seen, todo = set(), []
    for case in cases:
        key = (case.problem, case.params)
        if key in seen or case.unsupported:
            continue
        seen.add(key)
        problem = case.spec.build()
        ref, why = references.read(problem, reference_dir)
        if ref is None:
            todo.append((key, problem, why))
    calls = [functools.partial(_reference, problem, why, reference_dir, limit, log, deadline)
             for _, problem, why in todo]
    with stdout_to_stderr():  # C solvers' messages never among the records
        whys = in_parallel(calls, jobs)
    return {key: why for (key, _, _), why in zip(todo, whys) if why is not None}


def prepare_unit_costs(cases) -> None:
    """Measure the unit costs of every (problem, params, formulation) of ``cases``
    in each form their integrators are handed
    (:func:`~integrator_bench.harness.measure.unit_costs.costs_of`), once, in this
    process, before its workers are forked: each case's work then takes them
    from its parent rather than measuring them again (a Dask worker measures
    them itself, once per process)."""
    systems, seen = {}, set()
    for case in cases:
        key = (case.problem, case.params, case.formulation)
        handed = (key, case.integrator)   # costs_of measures each kind of form once
        if case.unsupported or handed in seen:
            continue
        seen.add(handed)
        icls = registry.get_integrator(case.integrator)
        try:
            if key not in systems:
                problem = case.spec.build()
                systems[key] = problem, problem.formulate(case.formulation)
            problem, system = systems[key]
            unit_costs.costs_of(problem, case.formulation, convert(system, icls))
        except Exception:   # noqa: BLE001  the case itself will say why, as its record
            continue


def reference_progress(problem, why: str, limit: float | None, log):
    """Log (when ``log`` is given) that ``problem``'s reference is computed, and
    why; return the ``report(t, percent, elapsed)`` that logs its progress
    (:func:`~integrator_bench.harness.measure.references.compute_within`)."""
    limit_text = "" if limit is None else f", limit {limit:g} s"
    if log:
        log(f"computing reference for {problem.label()} ({why}{limit_text})")

    def report(t, percent, elapsed, label=problem.label()):
        if log:
            log(f"  reference for {label}: t={t:.6g} ({percent:.3g} % of the span) "
                f"after {elapsed:.0f} s{limit_text}")
    return report


def _reference(problem, why: str, reference_dir, limit, log, deadline=None) -> str | None:
    """Compute and store ``problem``'s reference (:func:`prepare_references`): None
    when done, else why it has none."""
    if deadline is not None:
        left = deadline - time.monotonic()
        if left <= 0:
            return f"not computed: no time left ({why})"
        limit = left if limit is None else min(limit, left)
    try:
        references.load(problem, reference_dir, limit=limit,
                        report=reference_progress(problem, why, limit, log))
    except (ReferenceFailure, ProblemError) as exc:  # no reference, or no start to have one from
        if log:
            log(f"ibench: no reference for {problem.label()}: {exc}; its cases are "
                f"recorded error (reason {NO_REFERENCE}), not run")
        return str(exc)
    return None


def no_reference_record(case, why: str) -> dict:
    """The record of a case whose problem has no reference: ``error``, reason
    ``no_reference``, nothing run."""
    return finish(base_record(case), CaseStatus.ERROR,
                  f"not run: no reference for the problem ({why})"[:MESSAGE_CHARS], NO_REFERENCE)


def run_matrix(cases, store: Store | None = None, jobs: int | None = None,
               timeout: float = DEFAULT_TIMEOUT, resume: bool = False, progress: bool = True,
               on_record=None, reference_dir=None, memory_mb: float | None = DEFAULT_MEMORY_MB,
               repeat: int | None = None, dask=None, command: str | None = None,
               on_dispatch=None, skip: bool = True,
               reference_timeout: float | None = references.REFERENCE_TIMEOUT,
               purpose: str = "run", deadline: float | None = None) -> pd.DataFrame:
    """Run ``cases`` and return one DataFrame row per case.

    Parameters
    ----------
    cases : list of Case
    store : Store, optional
        Where each record is committed as it arrives, and the run's
        provenance (:mod:`integrator_bench.harness.model.provenance`) with it.
    jobs : int, optional
        Worker processes at once (default: the number of cores).
    timeout : float
        A case's budget, in CPU seconds of its worker (all its samples): a
        case past it is recorded ``timeout``, whatever the machine's load
        (:class:`~integrator_bench.harness.run.isolation.Worker` for the
        backstops of a case that hangs).
    resume : bool
        Skip cases already in ``store`` for this code version (their stored
        records are returned; a ``skipped`` one only when it was skipped under
        this run's policy); a case another run stored meanwhile is not
        stored twice. The stored records of a line are evidence for its
        cases still to run.
    on_record : callable, optional
        Called with every new record, once it is committed (the command line
        prints JSON lines).
    memory_mb : float or None
        Address space in MiB a case may allocate on top of what its worker
        inherits (RLIMIT_AS); None for no limit.
    repeat : int, optional
        The most timed solves per case (default
        :data:`~integrator_bench.harness.run.execution.MAX_SAMPLES`; fewer once they
        add up to ``MIN_CPU_S``, see :func:`execute`).
    dask : distributed.Client or str, optional
        Run the cases on Dask instead of local workers: a client, a scheduler
        address ``tcp://HOST:PORT`` or ``local:N`` (see
        :mod:`integrator_bench.harness.run.dask_backend`). Records, progress and store writes stay
        here; each case takes its reference (from ``reference_dir``) and the files its
        parameters name along (:mod:`integrator_bench.harness.run.shipping`).
    command : str, optional
        The command line stored with the provenance (default: ``sys.argv``).
    on_dispatch : callable, optional
        Called with each case as it is handed to a worker or a Dask task (an
        ``unsupported`` one as it is recorded here); with ``on_record`` it
        times a case from dispatch to commit (``studies/overhead.py``).
    skip : bool
        Record ``skipped`` the cases that their line's records make hopeless
        (:mod:`integrator_bench.harness.run.schedule`); False (``--no-skip``) runs
        every case. Either way each line runs loose to tight, one case at a
        time, the lines predicted most expensive first (fitted on ``store``'s
        records and on the run so far).
    reference_timeout : float or None
        Wall seconds a missing reference may take to compute
        (:data:`~integrator_bench.harness.measure.references.REFERENCE_TIMEOUT`; None: no
        limit); the cases of a problem left
        without one are recorded ``error`` with reason ``no_reference``, not run.
    purpose : str
        What the run is for, stored with its provenance (``runs.purpose``): ``run``,
        or ``advise`` for the cases of an advice, which the report keeps apart from
        the problems' own records.
    deadline : float, optional
        A ``time.monotonic()`` value past which nothing more is run (an advice's
        budget): missing references are computed within what is left, no case
        starts past it, and the cases in flight at it are stopped and not
        recorded (:func:`drive`).
    """
    if dask is not None and jobs is not None:
        raise ValueError("jobs and dask exclude each other: the Dask workers set the parallelism")
    jobs = jobs or os.cpu_count() or 1
    policy = POLICY if skip else None
    todo, records = _pending(cases, store, resume, policy)
    missing = prepare_references(todo, reference_dir,
                                 log=(lambda m: print(m, file=sys.stderr)) if progress else None,
                                 limit=reference_timeout, jobs=1 if dask is not None else jobs,
                                 deadline=deadline)
    unreferenced = [c for c in todo if (c.problem, c.params) in missing and not c.unsupported]
    todo = [c for c in todo if c not in unreferenced]
    if deadline is not None and time.monotonic() >= deadline:
        unreferenced = []  # past the deadline (a reference cut by it, say) nothing is recorded
    if dask is None:   # measured here once, inherited by every forked worker
        prepare_unit_costs(todo)
    options = dict(timeout=timeout, reference_dir=reference_dir, memory_mb=memory_mb,
                   repeat=repeat)
    with contextlib.ExitStack() as stack:
        client = None
        if dask is not None:
            client = stack.enter_context(dask_backend.connect(dask)) if isinstance(dask, str) \
                else dask
        backend = dask_backend.DaskPool(client, **options) if client is not None \
            else LocalPool(jobs, **options)
        where = dask_backend.describe(client) if client is not None \
            else {"kind": "local", "jobs": jobs}
        run_id = None
        if store is not None:
            run_id = store.begin_run(provenance.collect(command, where, {
                "timeout": timeout, "memory_mb": memory_mb, "repeat": repeat,
                "resume": resume, "cases": len(cases), "pending": len(todo),
                "skip_policy": policy,
                "integrators": sorted({c.line.label for c in cases})}, purpose))
        bar = stack.enter_context(contextlib.closing(
            _progress(len(cases), len(cases) - len(todo), progress)))
        accept = _acceptor(store, run_id, resume, records, on_record, bar, policy)
        for case in unreferenced:
            accept(no_reference_record(case, missing[(case.problem, case.params)]))
        pending = Schedule(todo, skip=skip, model=_cost_model(cases, store), timeout=timeout,
                           evidence=_evidence(cases, todo, records),
                           bound=StiffnessBound(timeout, reference_dir))
        interrupted = _run_interruptible(backend, pending, accept, store, run_id, on_dispatch,
                                         deadline)
    if interrupted:
        raise KeyboardInterrupt
    return to_dataframe(records)


def _pending(cases, store, resume, policy=None):
    """The cases still to run, and the records of those a resumed run skips."""
    if not (resume and store is not None):
        return list(cases), []
    done = store.done_case_ids(code_version(), policy)
    pending = [c for c in cases if c.case_id not in done]
    if not done:
        return pending, []
    old = store.dataframe()
    old = old[(old.code_version == code_version())
              & old.case_id.isin({c.case_id for c in cases} & done)]
    return pending, old.drop_duplicates("case_id", keep="last").to_dict("records")


def _evidence(cases, pending, records):
    """The stored records (a resumed run's) of the lines still to run, each with its case."""
    lines = {c.line for c in pending}
    by_id = {c.case_id: c for c in cases}
    return [(by_id[r["case_id"]], r) for r in records
            if r["case_id"] in by_id and by_id[r["case_id"]].line in lines]


def _cost_model(cases, store):
    """A :class:`~integrator_bench.harness.run.schedule.CostModel` of the run's
    problems, fitted on the store's measured records (any code version)."""
    sizes = {}
    for case in cases:
        key = (case.problem, case.params)
        if key not in sizes and not case.unsupported:
            try:
                problem = case.spec.build()
                sizes[key] = (problem.dimension, problem.t_span[1] - problem.t_span[0])
            except Exception:  # a problem that fails to build fails in its worker
                sizes[key] = (1, 1.0)
    model = CostModel(sizes)
    if store is not None:
        for row in store.measured():
            model.learn_row(row)
    return model


def _acceptor(store, run_id, resume, records, on_record, bar, policy=None):
    """The function taking each new record: stamp, store, keep, report, warn."""
    warned: set = set()

    def accept(record):
        record["run_id"] = run_id
        if store is not None and not store.add(record, once=resume, skip_policy=policy):
            bar.update(1)  # another run stored this case meanwhile: keep its record
            return
        records.append(record)
        if on_record:
            on_record(record)
        _warn_count_mismatch(record, warned, bar)
        bar.update(1)

    return accept


def _warn_count_mismatch(record, warned: set, bar) -> None:
    """One line on standard error, the first time an integrator's own counts
    disagree with the harness's in this run."""
    name = record.get("integrator")
    if not record.get("count_mismatch") or name in warned:
        return
    warned.add(name)
    bar.write(f"ibench: warning: {name} reports counts that disagree with the harness's "
              f"({record['count_mismatch']}, on {record.get('problem')} "
              f"{record.get('formulation')}); nfev keeps the harness's count", file=sys.stderr)


def _run_interruptible(backend, pending, accept, store, run_id, on_dispatch=None,
                       deadline=None) -> list:
    """:func:`drive` with Ctrl-C turned into a flag (no fork or store write is cut
    in half); mark the stored run finished, interrupted (by a signal, or at its
    ``deadline`` with cases left) or failed. Returns the signals caught."""
    interrupted: list = []

    def on_interrupt(signum, frame):
        interrupted.append(signum)

    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, on_interrupt) if in_main else None
    status = "failed"
    try:
        cut = drive(backend, pending, accept, interrupted, on_dispatch, deadline)
        status = "interrupted" if interrupted or cut else "finished"
    finally:
        if in_main:
            signal.signal(signal.SIGINT, previous)
        if run_id is not None:
            store.finish_run(run_id, status, now())
    return interrupted


def _progress(total, initial, enabled):
    from tqdm import tqdm
    tqdm.monitor_interval = 0  # no monitor thread: workers are forked
    return tqdm(total=total, initial=initial, disable=not enabled, file=sys.stderr,
                unit="case", dynamic_ncols=True)


def process_cpu() -> float:
    """CPU seconds of this process and its reaped children (the local workers): what
    a run of the matrix cost here, as ``ibench run``'s summary and ``ibench advise``
    report it."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def to_dataframe(records) -> pd.DataFrame:
    """The records as a DataFrame with the columns of ``FIELDS``
    (``solver_counts`` as JSON text, as the store keeps it)."""
    rows = []
    for r in records:
        r = dict(r)
        if isinstance(r.get("solver_counts"), dict):
            r["solver_counts"] = json.dumps(r["solver_counts"], sort_keys=True)
        rows.append(r)
    return pd.DataFrame(rows, columns=list(FIELDS))
