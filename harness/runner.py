"""Running cases: one worker process per case, bounded in time, never fatal.

:func:`execute` runs one case in the current process and always returns a
record. :func:`run_matrix` runs many, each in a forked worker process with a
wall-clock timeout, ``jobs`` at a time: a worker that hangs becomes a
``timeout`` record, one that dies (segfault, ``os._exit``, out of memory) a
``crashed`` record, an exception an ``error`` record. Every record is stored
the moment it arrives; an interrupted run keeps everything finished.
"""

from __future__ import annotations

import dataclasses
import faulthandler
import json
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
from collections import deque
from datetime import datetime, timezone
from multiprocessing.connection import wait

import numpy as np
import pandas as pd

from harness import references, registry
from harness.cases import Case
from harness.metrics import measure
from harness.record import FIELDS, empty_record
from harness.store import Store
from harness.version import code_version
from problems.system import convert

DEFAULT_TIMEOUT = 60.0


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


def execute(case: Case, reference_dir=None) -> dict:
    """Run one case here and return its record; never raises."""
    record = base_record(case)
    if case.unsupported:
        return finish(record, "unsupported", case.unsupported)
    try:
        problem = registry.get_problem_class(case.problem)(**case.params_dict)
        icls = registry.get_integrator(case.integrator)
        system = convert(problem.formulate(case.formulation), icls.accepts, icls.max_index)
        if system is None:
            return finish(record, "unsupported", f"{case.integrator} cannot take {case.formulation}")
        ref = references.load(problem, reference_dir, compute_missing=False)
        system, counters = counted(system)
        atol = system.atol(case.rtol) if case.rtol is not None else None
        record["atol"] = float(np.min(atol)) if atol is not None else None
        integrator = icls()
        cpu0, wall0 = time.process_time(), time.perf_counter()
        sol = integrator.solve(system, rtol=case.rtol, atol=atol, h=case.h)
        record["cpu_s"] = time.process_time() - cpu0
        record["wall_s"] = time.perf_counter() - wall0
        _fill_counts(record, sol.counts, counters, icls)
        Y = np.asarray(system.output(sol.t, sol.y), float) if len(sol.t) else np.empty((0, 0))
        if not sol.success:
            return finish(record, "failed", sol.message or "integrator gave up")
        if not np.all(np.isfinite(Y)):
            return finish(record, "failed", "non-finite values in the solution")
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
        return finish(record, "error", f"{type(exc).__name__}: {exc}".splitlines()[0][:500])


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


def _child(case, conn, reference_dir):
    faulthandler.disable()  # a crash becomes a `crashed` record, not a dump on the console
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    try:
        conn.send(execute(case, reference_dir))
    finally:
        conn.close()


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
               on_record=None, reference_dir=None) -> pd.DataFrame:
    """Run ``cases`` and return one DataFrame row per case.

    Parameters
    ----------
    cases : list of Case
    store : Store, optional
        Where each record is committed as it arrives.
    jobs : int, optional
        Worker processes at once (default: the number of cores).
    timeout : float
        Wall-clock seconds a case may take before its worker is killed.
    resume : bool
        Skip cases already in ``store`` for this code version (their stored
        records are returned).
    on_record : callable, optional
        Called with every new record (the command line prints JSON lines).
    """
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
    ctx = mp.get_context("fork")
    running: dict = {}
    bar = _progress(len(cases), len(cases) - len(pending), progress)

    def accept(record):
        if store is not None:
            store.add(record)
        records.append(record)
        if on_record:
            on_record(record)
        bar.update(1)

    interrupted = []

    def on_interrupt(signum, frame):  # a flag, so no fork or store write is cut in half
        interrupted.append(signum)

    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, on_interrupt) if in_main else None
    try:
        while (pending or running) and not interrupted:
            while pending and len(running) < jobs:
                case = pending.popleft()
                if case.unsupported:
                    accept(execute(case))
                    continue
                recv, send = ctx.Pipe(duplex=False)
                proc = ctx.Process(target=_child, args=(case, send, reference_dir), daemon=True)
                proc.start()
                send.close()
                running[recv] = (proc, case, time.monotonic())
            if not running:
                continue
            for conn in wait(list(running), timeout=0.2):
                proc, case, _ = running.pop(conn)
                try:
                    record = conn.recv()
                except (EOFError, OSError):
                    proc.join(5)
                    record = finish(base_record(case), "crashed", _death(proc.exitcode))
                conn.close()
                proc.join(5)
                accept(record)
            now = time.monotonic()
            for conn, (proc, case, start) in list(running.items()):
                if now - start > timeout:
                    proc.kill()
                    proc.join(5)
                    conn.close()
                    del running[conn]
                    record = base_record(case)
                    record["wall_s"] = now - start
                    accept(finish(record, "timeout", f"no result within {timeout:g} s; worker killed"))
    finally:
        if in_main:
            signal.signal(signal.SIGINT, previous)
        for conn, (proc, _, _) in running.items():
            proc.kill()
            proc.join(5)
            conn.close()
        bar.close()
    if interrupted:
        raise KeyboardInterrupt
    return to_dataframe(records)


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
