"""Running batches of cases in one command's context: :class:`Session`.

A session runs each batch through :func:`~integrator_bench.harness.run.loop.drive`,
the one scheduling loop, on one of two pools: the local one
(:class:`~integrator_bench.harness.run.local_pool.LocalPool`, forked workers of
this process) or Dask (:class:`~integrator_bench.harness.run.dask_backend.DaskPool`).
Either way an ``unsupported`` case is recorded here and costs no process. The
references are made ready first
(:func:`~integrator_bench.harness.run.referencing.prepare_references`). Every
record is committed the moment it arrives, with the id of the run whose
provenance the store keeps; an interrupted or killed run keeps everything
finished. A record whose integrator's own counts disagree with the harness's
(``count_mismatch``) is warned about once per integrator, on standard error.

Modules (none imports one that imports it):

* :mod:`~integrator_bench.harness.run.execution` -- one case in this process:
  counting wrappers, the solve, the record, the metrics (:func:`execute`);
* :mod:`~integrator_bench.harness.run.isolation` -- one case in a forked worker:
  its budget, memory limit, one BLAS thread, crash and timeout records
  (:class:`Worker`, :func:`run_isolated`);
* :mod:`~integrator_bench.harness.run.loop`, the two pools and this module -- many cases.

Import each name from its home module; this one re-exports nothing.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import json
import os
import sys
import time
from pathlib import Path

import pandas as pd

from integrator_bench.harness.errors import StoreError
from integrator_bench.harness.matrix import provenance
from integrator_bench.harness.matrix.line import ProblemSpec
from integrator_bench.harness.matrix.record import FIELDS
from integrator_bench.harness.matrix.store import DEFAULT_STORE, Store
from integrator_bench.harness.run import dask_backend, progress
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.execution import now
from integrator_bench.harness.run.local_pool import LocalPool
from integrator_bench.harness.run.loop import drive_interruptible
from integrator_bench.harness.run.plan import committed_model
from integrator_bench.harness.run.raced import policy_of
from integrator_bench.harness.run.referencing import no_reference_record, prepare_references
from integrator_bench.harness.run.schedule import (POLICY, CostModel, Schedule, StiffnessBound,
                                                  problem_size)
from integrator_bench.harness.version import code_version

__all__ = ["Session", "process_cpu", "to_dataframe"]


#: what ends a run's row ``interrupted`` rather than ``failed``: Ctrl-C (SIGTERM), and a
#: store that can take no more (a full disk, a file made read-only)
STOPPED_BY = (KeyboardInterrupt, StoreError)


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
    build : callable
        ``build(spec)``: the problem of a :class:`~integrator_bench.harness.matrix.line.ProblemSpec`,
        built once in this process for the whole session.
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
        # each problem built once here, for its reference, its size, a worker's warm-up
        # and a Dask task's reference (a foreign one: its stand-in, builds.py)
        self.build = functools.lru_cache(maxsize=None)(ProblemSpec.build)

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

    def run(self, cases, budget_s: float | None = None, deadline: float | None = None,
            on_record=None, on_dispatch=None) -> pd.DataFrame:
        """Run a batch of ``cases`` and return one DataFrame row per case.

        Parameters
        ----------
        cases : list of Case
        budget_s : float, optional
            This batch's per-case budget of CPU seconds (default: the context's
            :attr:`~integrator_bench.harness.run.limits.Limits.budget_s`).
        deadline : float, optional
            A ``time.monotonic()`` value past which nothing more is run (an
            advice's budget): missing references are computed within what is
            left, no case starts past it, and the cases in flight at it are
            stopped and not recorded
            (:func:`~integrator_bench.harness.run.loop.drive`).
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
        budget_s = context.limits.budget_s if budget_s is None else budget_s
        policy = policy_of(POLICY if context.skip else None, context.race)
        todo, records = self._pending(cases, policy)
        interrupted: list = []   # the signals caught while the cases run
        log = (lambda m: print(m, file=sys.stderr)) if context.progress else None
        missing = prepare_references(todo, context.reference_dir, log=log,
                                     limit=context.limits.reference_timeout,
                                     jobs=1 if self.client is not None else context.parallel,
                                     deadline=deadline,
                                     memory_mb=context.limits.memory_mb, build=self.build)
        unreferenced = [c for c in todo if c.spec in missing and not c.settled]
        todo = [c for c in todo if c not in unreferenced]
        if deadline is not None and time.monotonic() >= deadline:
            unreferenced = []  # past the deadline (a reference cut by it, say) nothing is recorded
        limits = dataclasses.replace(context.limits, budget_s=budget_s)
        backend = (dask_backend.DaskPool(self.client, context.reference_dir, limits, self.build)
                   if self.client is not None
                   else LocalPool(context.parallel, context.reference_dir, limits, self.build))
        self._begin(cases, todo, budget_s, policy)
        with contextlib.closing(progress.bar(len(cases), len(cases) - len(todo),
                                             context.progress)) as bar:
            accept = self._acceptor(records, on_record, bar, policy)
            for case in unreferenced:
                accept(no_reference_record(case, missing[case.spec]))
            for record in records if context.race is not None else ():
                context.race.learn(record)   # a resumed run's stored records first
            pending = Schedule(todo, skip=context.skip, model=self._cost_model(cases),
                               budget_s=budget_s, evidence=_evidence(cases, todo, records),
                               bound=StiffnessBound(budget_s, context.reference_dir,
                                                    stop=lambda: bool(interrupted)),
                               race=context.race, repeat=limits.repeat)
            bar.left = progress.time_left(pending, context.parallel)
            try:
                cut = drive_interruptible(backend, pending, accept, interrupted, on_dispatch,
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

    def _begin(self, cases, todo, budget_s, policy) -> None:
        """The session's provenance row, begun with its first batch that has a case."""
        integrators = {c.line.label for c in cases}
        if self.run_id is None:
            if self.store is None or not cases:
                return
            self._options = {"timeout": budget_s, "memory_mb": self.context.limits.memory_mb,
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
            spec = case.spec
            if spec not in self._model.sizes and spec not in new and not case.settled:
                new[spec] = problem_size(spec, self.build)
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
