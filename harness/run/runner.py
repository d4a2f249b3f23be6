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
import dataclasses
import functools
import json
import os
import signal
import sys
import threading
import time
from multiprocessing.connection import wait
from pathlib import Path

import pandas as pd

from integrator_bench.harness.run import dask_backend, model_calls, progress

from integrator_bench.harness.matrix import provenance

from integrator_bench.harness.measure import references
from integrator_bench.harness.errors import ModelFault, ReferenceFailure, StoreError
from integrator_bench.harness.run.execution import MESSAGE_CHARS, base_record, execute, finish, now
from integrator_bench.harness.forking import child, in_parallel
from integrator_bench.harness.run.isolation import Worker
from integrator_bench.harness.matrix.record import FIELDS, NO_REFERENCE, CaseStatus
from integrator_bench.harness.run.plan import committed_model
from integrator_bench.harness.run.raced import policy_of
from integrator_bench.harness.run.schedule import (POLICY, CostModel, Schedule, StiffnessBound,
                                                  problem_size)
from integrator_bench.harness.matrix.store import DEFAULT_STORE, Store
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import DEFAULT_MEMORY_MB
from integrator_bench.harness.run.streams import stdout_to_stderr
from integrator_bench.harness.version import code_version
from integrator_bench.problems.base import ProblemError

__all__ = ["run_matrix", "Session", "drive", "LocalPool", "prepare_references", "reference_progress",
           "to_dataframe"]


class LocalPool:
    """The local backend of :func:`drive`: up to ``jobs`` forked workers of this
    process, each serving case after case
    (:class:`~integrator_bench.harness.run.isolation.Worker`), each case within
    its budget of CPU seconds (:meth:`~integrator_bench.harness.run.limits.Limits.budget_of`).

    A case goes to an idle worker, or to a new one when none is idle; a
    worker is replaced only after a fault (crash, kill past the budget's
    backstops, out of memory) or after
    :data:`~integrator_bench.harness.run.isolation.MAX_CASES` cases, so a case
    pays no fork of its own.
    """

    def __init__(self, jobs, reference_dir, limits):
        self.jobs, self.limits = jobs, limits
        self.options = (reference_dir, limits)
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
        """Yield the records of the finished cases (waiting for one until a running
        case needs a look: ``Worker.wait_s``), then the ``timeout`` records of those
        past their budget (their workers killed)."""
        if not self.running:
            return
        for conn in wait(list(self.running),
                         timeout=min(w.wait_s() for w in self.running.values())):
            worker = self.running.pop(conn)
            record = worker.record()
            self._release(worker)
            yield record
        now_s = time.monotonic()
        for conn, worker in list(self.running.items()):
            budget = self.limits.budget_of(worker.case)
            why = worker.past_budget(budget, now_s)
            if why:
                del self.running[conn]
                yield worker.timed_out(budget, why)

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
                if case.settled:   # unsupported, or its problem failed to build
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


@dataclasses.dataclass(frozen=True)
class Missing:
    """Why a problem has no reference (:func:`prepare_references`), and what its
    cases are recorded as: ``error``, or ``crashed`` / ``timeout`` when its
    model crashed or hung while the reference was checked or computed
    (:class:`~integrator_bench.harness.errors.ModelFault`)."""

    why: str
    status: str = CaseStatus.ERROR.value


#: what ends a run's row ``interrupted`` rather than ``failed``: Ctrl-C (SIGTERM), and a
#: store that can take no more (a full disk, a file made read-only)
STOPPED_BY = (KeyboardInterrupt, StoreError)

#: what a fault's message says the model was doing while a stored reference was checked
CHECKING = "its stored reference was checked (the fingerprint probe)"


def prepare_references(cases, reference_dir=None, log=None,
                       limit: float | None = references.REFERENCE_TIMEOUT, jobs: int = 1,
                       deadline: float | None = None,
                       memory_mb: float | None = DEFAULT_MEMORY_MB) -> dict:
    """Make sure every (problem, params) of ``cases`` has a usable reference.

    Every model's code runs outside this process
    (:mod:`~integrator_bench.harness.run.model_calls`, each call within ``limit``
    CPU seconds and the backstops of a case's budget, its address space capped
    at ``memory_mb``): the stored references are checked against their
    problems' fingerprints one after the other in one forked process, then
    read here without calling the model
    (:func:`~integrator_bench.harness.measure.references.stored`), so that the
    workers forked later inherit them. A missing or stale one is computed within
    ``limit`` wall seconds (None: no limit) and, with a ``deadline`` (a
    ``time.monotonic()`` value), within what is left of it when its computation
    starts; its progress logged every 2 s; one that cannot be computed within
    that (or at all) is not stored. Several are computed side by side, ``jobs``
    at a time (:func:`~integrator_bench.harness.forking.in_parallel`), each in
    a process of its own: the perturbed parameter sets of an advice, a sweep of
    new parameter sets.

    Returns
    -------
    dict
        ``(problem, params)`` -> :class:`Missing`, for those that have no reference.
    """
    seen, problems = set(), []
    for case in cases:
        key = (case.problem, case.params)
        if key in seen or case.settled:
            continue
        seen.add(key)
        problems.append((key, case.spec.build()))
    checked = child.calls(
        [functools.partial(_unusable, problem, reference_dir) for _, problem in problems],
        CHECKING, limit, memory_mb, expected=(ProblemError,))
    missing, todo = {}, []
    for (key, problem), why in zip(problems, checked):
        if isinstance(why, Exception):
            missing[key] = _missing(problem, why, log)
        elif why:
            todo.append((key, problem, why))
        else:
            references.stored(problem, reference_dir)   # read here: inherited by the workers
    calls = [functools.partial(_reference, problem, why, reference_dir, limit, log, deadline,
                               memory_mb)
             for _, problem, why in todo]
    with stdout_to_stderr():  # C solvers' messages never among the records
        whys = in_parallel(calls, jobs)
    missing.update({key: why for (key, _, _), why in zip(todo, whys) if why is not None})
    return missing


def _unusable(problem, reference_dir) -> str:
    """Why ``problem``'s stored reference cannot be used ("" when it can): what the
    fingerprint probe says, in the process :func:`prepare_references` forks."""
    return references.read(problem, reference_dir)[1]


def _missing(problem, exc: Exception, log) -> Missing:
    """The :class:`Missing` of a problem whose reference failed with ``exc``,
    logged."""
    status = getattr(exc, "status", CaseStatus.ERROR.value)
    if log:
        log(f"ibench: no reference for {problem.label()}: {exc}; its cases are "
            f"recorded {status} (reason {NO_REFERENCE}), not run")
    return Missing(str(exc), status)


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


def _reference(problem, why: str, reference_dir, limit, log, deadline=None,
               memory_mb=DEFAULT_MEMORY_MB) -> Missing | None:
    """Compute and store ``problem``'s reference in a process of its own
    (:func:`prepare_references`): None when done, else why it has none."""
    if deadline is not None:
        left = deadline - time.monotonic()
        if left <= 0:
            return Missing(f"not computed: no time left ({why})")
        limit = left if limit is None else min(limit, left)
    try:
        model_calls.reference(problem, reference_dir, limit, memory_mb=memory_mb,
                              progress=lambda why: reference_progress(problem, why, limit, log))
    except (ReferenceFailure, ProblemError, ModelFault) as exc:
        # no reference, no start to have one from, or a model that failed
        return _missing(problem, exc, log)
    return None


def no_reference_record(case, missing: Missing) -> dict:
    """The record of a case whose problem has no reference: reason
    ``no_reference``, status ``error`` (``crashed`` or ``timeout`` when its model
    crashed or hung), nothing run."""
    return finish(base_record(case), CaseStatus(missing.status),
                  f"not run: no reference for the problem ({missing.why})"[:MESSAGE_CHARS],
                  NO_REFERENCE)


def run_matrix(cases, context: RunContext | None = None, *, on_record=None, on_dispatch=None,
               deadline: float | None = None, **options) -> pd.DataFrame:
    """Run ``cases`` and return one DataFrame row per case.

    One batch in a :class:`Session` of its own; a command that runs several
    batches (an advice's rounds) opens one :class:`Session` and runs them all in it.

    Parameters
    ----------
    cases : list of Case
    context : RunContext, optional
        The store, backend, reference directory, policies and limits the cases
        run under (:class:`~integrator_bench.harness.run.context.RunContext`).
    on_record, on_dispatch, deadline
        As :meth:`Session.run` takes them.
    **options
        Without ``context``: its fields and those of its
        :class:`~integrator_bench.harness.run.limits.Limits`, by keyword
        (``store``, ``jobs``, ``dask``, ``reference_dir``, ``resume``, ``skip``,
        ``progress``, ``command``, ``purpose``, ``timeout``, ``repeat``,
        ``memory_mb``, ``reference_timeout``); with it: the ones that differ from it.
    """
    context = RunContext.of(**options) if context is None else context.replace(**options)
    with Session(context) as session:
        return session.run(cases, on_record=on_record, on_dispatch=on_dispatch,
                           deadline=deadline)


class Session:
    """Batches of cases run in one :class:`~integrator_bench.harness.run.context.RunContext`.

    Opened (``with Session(context) as session``), it connects to Dask once
    (when the context names an address) and then opens the store (when the
    context names a path; in that order, so that a bad ``--dask`` writes
    nothing). Each :meth:`run` is a batch; all of them share one provenance row
    (begun with the first batch that has a case, marked ``finished``,
    ``interrupted`` or ``failed`` on the way out, its ``cases``, ``pending`` and
    ``integrators`` the batches' together, its ``timeout`` the first batch's),
    the store's records read once (a resumed session's done cases, and what the
    cost model is fitted on), and one cost model (the committed one's rates at first,
    :func:`~.plan.committed_model`), which learns each record as it arrives.

    Attributes
    ----------
    context : RunContext
        What the batches run under; a command may replace it between batches
        (the advice's references, once it has computed tighter ones).
    store : Store or None
        The open store.
    """

    def __init__(self, context: RunContext):
        self.context = context
        self.store = None
        self.client = None
        self.where: dict = {}
        self.run_id = None
        self.status = "finished"      # "interrupted" once a batch is, "failed" once one fails
        self._stack = contextlib.ExitStack()
        self._done: dict | None = None     # case_id -> its record (a resumed session's)
        self._measured: list | None = None  # the store's measured records, read once
        self._model = committed_model({}, frozen=False)
        self._options: dict = {}

    def __enter__(self) -> "Session":
        context = self.context
        with contextlib.ExitStack() as stack:
            self.client = stack.enter_context(dask_backend.connect(context.dask)) \
                if isinstance(context.dask, str) else context.dask
            store = context.store
            if store is not None and not isinstance(store, Store):
                if Path(store) == DEFAULT_STORE:  # the data directory may not exist yet
                    DEFAULT_STORE.parent.mkdir(parents=True, exist_ok=True)
                store = stack.enter_context(Store(Path(store)))
            self.store = store
            self.where = dask_backend.describe(self.client) if self.client is not None \
                else {"kind": "local", "jobs": context.parallel}
            self._stack = stack.pop_all()
        return self

    def __exit__(self, kind, exc, tb) -> None:
        try:
            if self.run_id is not None:
                status = self.status
                if status == "finished" and kind is not None:
                    status = "interrupted" if issubclass(kind, STOPPED_BY) else "failed"
                try:
                    self.store.finish_run(self.run_id, status, now(), self._options)
                except StoreError:
                    if kind is None:
                        raise
                    # the store that failed a write fails this one too: the error on
                    # the way out says so
        finally:
            self._stack.close()

    def run(self, cases, timeout: float | None = None, deadline: float | None = None,
            on_record=None, on_dispatch=None) -> pd.DataFrame:
        """Run a batch of ``cases`` and return one DataFrame row per case.

        Parameters
        ----------
        cases : list of Case
        timeout : float, optional
            This batch's per-case budget (default: the context's
            :attr:`~integrator_bench.harness.run.limits.Limits.timeout`).
        deadline : float, optional
            A ``time.monotonic()`` value past which nothing more is run (an
            advice's budget): missing references are computed within what is
            left, no case starts past it, and the cases in flight at it are
            stopped and not recorded (:func:`drive`).
        on_record : callable, optional
            Called with every new record, once it is committed (the command line
            prints JSON lines).
        on_dispatch : callable, optional
            Called with each case as it is handed to a worker or a Dask task (an
            ``unsupported`` one as it is recorded here); with ``on_record`` it
            times a case from dispatch to commit (``studies/overhead.py``).

        Each line runs loose to tight, one case at a time, the lines predicted
        most expensive first; raises KeyboardInterrupt after Ctrl-C, every
        finished case kept.
        """
        context = self.context
        timeout = context.limits.timeout if timeout is None else timeout
        policy = policy_of(POLICY if context.skip else None, context.race)
        todo, records = self._pending(cases, policy)
        interrupted: list = []   # the signals caught while the cases run
        log = (lambda m: print(m, file=sys.stderr)) if context.progress else None
        missing = prepare_references(todo, context.reference_dir, log=log,
                                     limit=context.limits.reference_timeout,
                                     jobs=1 if self.client is not None else context.parallel,
                                     deadline=deadline,
                                     memory_mb=context.limits.memory_mb)
        unreferenced = [c for c in todo if (c.problem, c.params) in missing and not c.settled]
        todo = [c for c in todo if c not in unreferenced]
        if deadline is not None and time.monotonic() >= deadline:
            unreferenced = []  # past the deadline (a reference cut by it, say) nothing is recorded
        limits = dataclasses.replace(context.limits, timeout=timeout)
        backend = (dask_backend.DaskPool(self.client, context.reference_dir, limits)
                   if self.client is not None
                   else LocalPool(context.parallel, context.reference_dir, limits))
        self._begin(cases, todo, timeout, policy)
        with contextlib.closing(progress.bar(len(cases), len(cases) - len(todo),
                                             context.progress)) as bar:
            accept = self._acceptor(records, on_record, bar, policy)
            for case in unreferenced:
                accept(no_reference_record(case, missing[(case.problem, case.params)]))
            for record in records if context.race is not None else ():
                context.race.learn(record)   # a resumed run's stored records first
            pending = Schedule(todo, skip=context.skip, model=self._cost_model(cases),
                               timeout=timeout, evidence=_evidence(cases, todo, records),
                               bound=StiffnessBound(timeout, context.reference_dir,
                                                    stop=lambda: bool(interrupted)),
                               race=context.race, repeat=limits.repeat)
            bar.left = progress.time_left(pending, context.parallel)
            try:
                cut = _run_interruptible(backend, pending, accept, interrupted, on_dispatch,
                                         deadline)
            except BaseException as exc:
                self.status = "interrupted" if isinstance(exc, STOPPED_BY) else "failed"
                raise
        if (interrupted or cut) and self.status == "finished":
            self.status = "interrupted"
        if interrupted:
            raise KeyboardInterrupt
        return to_dataframe(records)

    def supersede(self, record: dict) -> None:
        """Store a newer record of a case this session ran (its contenders' rounds
        added, :mod:`integrator_bench.harness.contend`): stamped with the session's
        run, it supersedes the earlier one, which the store keeps."""
        record["run_id"] = self.run_id
        if self.store is not None:
            self.store.add(record)

    def _begin(self, cases, todo, timeout, policy) -> None:
        """The session's provenance row, begun with its first batch that has a case."""
        integrators = {c.line.label for c in cases}
        if self.run_id is None:
            if self.store is None or not cases:
                return
            self._options = {"timeout": timeout, "memory_mb": self.context.limits.memory_mb,
                             "repeat": self.context.limits.repeat,
                             "resume": self.context.resume, "cases": len(cases),
                             "pending": len(todo), "skip_policy": policy,
                             "integrators": sorted(integrators)}
            self.run_id = self.store.begin_run(provenance.collect(
                self.context.command, self.where, self._options, self.context.purpose))
            return
        self._options["cases"] += len(cases)
        self._options["pending"] += len(todo)
        self._options["integrators"] = sorted({*self._options["integrators"], *integrators})

    def _pending(self, cases, policy):
        """The cases still to run, and the records of those a resumed session skips
        (the store's, read with the first batch, and the session's own)."""
        if not (self.context.resume and self.store is not None):
            return list(cases), []
        if self._done is None:
            done = self.store.done_case_ids(code_version(), policy)
            old = self.store.dataframe() if done else pd.DataFrame(columns=["case_id"])
            if done:
                old = old[(old.code_version == code_version()) & old.case_id.isin(done)]
            self._done = {r["case_id"]: r for r in
                          old.drop_duplicates("case_id", keep="last").to_dict("records")}
        ids = {c.case_id for c in cases}
        return ([c for c in cases if c.case_id not in self._done],
                [r for case_id, r in self._done.items() if case_id in ids])

    def _cost_model(self, cases) -> CostModel:
        """The session's :class:`~integrator_bench.harness.run.schedule.CostModel`,
        given the sizes of the batch's new problems and fitted on the store's
        measured records of them (any code version, read once)."""
        new = {}
        for case in cases:
            key = (case.problem, case.params)
            if key not in self._model.sizes and key not in new and not case.settled:
                new[key] = problem_size(case.spec)
        if not new:
            return self._model
        self._model.sizes.update(new)
        if self.store is not None:
            if self._measured is None:
                self._measured = self.store.measured()
            for row in self._measured:
                self._model.learn_row(row, among=new)
        return self._model

    def _acceptor(self, records, on_record, bar, policy=None):
        """The function taking each new record: stamp, store, keep, report, warn."""
        warned: set = set()
        store, once = self.store, self.context.resume

        def accept(record):
            record["run_id"] = self.run_id
            if store is not None and not store.add(record, once=once, skip_policy=policy):
                bar.update(1)  # another run stored this case meanwhile: keep its record
                return
            records.append(record)
            if self._done is not None:
                self._done[record["case_id"]] = record
            if on_record:
                on_record(record)
            _warn_count_mismatch(record, warned, bar)
            bar.update(1)

        return accept


def _evidence(cases, pending, records):
    """The stored records (a resumed run's) of the lines still to run, each with its case."""
    lines = {c.line for c in pending}
    by_id = {c.case_id: c for c in cases}
    return [(by_id[r["case_id"]], r) for r in records
            if r["case_id"] in by_id and by_id[r["case_id"]].line in lines]


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


def _run_interruptible(backend, pending, accept, interrupted: list, on_dispatch=None,
                       deadline=None):
    """:func:`drive` with Ctrl-C turned into a flag (no fork or store write is cut
    in half): each signal caught is appended to ``interrupted``. Returns whether
    cases were left at the ``deadline``."""

    def on_interrupt(signum, frame):
        interrupted.append(signum)

    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, on_interrupt) if in_main else None
    try:
        cut = drive(backend, pending, accept, interrupted, on_dispatch, deadline)
    finally:
        if in_main:
            signal.signal(signal.SIGINT, previous)
    return cut


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
