"""Measure the harness's overhead per case: what a run costs beyond the solves.

Runs a selection of the matrix (the options of ``ibench run``: ``--preset``,
``-p``, ``-f``, ``-i``, ``--rtol``, ``--h``, ``--jobs``, ``--timeout``) into a
temporary store, and times every case in the parent from its dispatch (the
runner's ``on_dispatch``) to the commit of its record (``on_record``, called
after the store's insert). A case's overhead is that time minus its solve's
wall time (``wall_s`` of its record): the fork, the set-up in the worker
(problem, formulation, counting wrappers), the measurement against the
reference, the pipe, the store's commit and the progress bar. Prints, for the
cases that ran in a worker, the median and percentiles of the overhead per
case, the total overhead and its share of the total solve time, and the
median split into the worker's own work around the solve (building the
system, measuring the errors: :func:`~integrator_bench.harness.run.execution.execute`
minus the solve, timed in the worker by wrapping the ``execute`` the worker
calls) and the rest (fork, thread and memory limits, pipe, store, scheduling);
for the ``unsupported`` cases their cost in the parent; the processes forked
against the cases (an ``unsupported`` case must fork none) and the run's wall
time.

    python studies/overhead.py                                   # the quick preset
    python studies/overhead.py --preset full -p two_mass -p pendulum --jobs 2

Exits 1 when an ``unsupported`` case forked a process or a target is missed
(median above ``--max-ms``; share above ``--max-share``, checked on the full
preset only unless given: the quick preset's cases are chosen to be short, so
there a few ms a case is a large share), 2 on bad input.
Not an asv benchmark: asv looks for ``time_``/``track_`` names, this module has none.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

# the harness before numpy, as ``ibench`` imports them: importing the harness sets
# one BLAS thread per process (harness/__init__.py), which OpenBLAS reads when numpy
# loads it; a process whose OpenBLAS started a thread pool forks workers that spend
# about twice as long around each solve (quick preset: 16 ms against 8 ms a case)
from integrator_bench.harness.forking import child  # isort: skip
from integrator_bench.harness.run import isolation  # isort: skip

import numpy as np  # noqa: E402
from integrator_bench.harness.matrix.cases import PRESETS, expand
from integrator_bench.harness.errors import BadInput
from integrator_bench.harness.matrix.registry import UnknownName
from integrator_bench.harness.run.limits import DEFAULT_BUDGET_S
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits
from integrator_bench.harness.run.runner import Session
from integrator_bench.harness.sources.numbers import listed_cases
from integrator_bench.harness.matrix.store import Store

MAX_MEDIAN_MS = 20.0  # the target: at most 20 ms per case
MAX_SHARE = 0.05  # and at most 5 % of the solve time (full preset)


class Timings:
    """Dispatch and commit times of every case, and the forks made meanwhile."""

    def __init__(self):
        self.dispatched: dict[str, float] = {}
        self.unsupported: set[str] = set()
        # case id, dispatch to commit, the solve's wall_s, execute() in the worker (s)
        self.rows: list[tuple[str, float, float | None, float | None]] = []
        self.forks = 0
        self.forks_by_unsupported = 0
        self.model_call_forks = 0   # the processes the model's own calls ran in (not cases)
        self._current_unsupported = False
        self._in_model_call = False

    def on_dispatch(self, case) -> None:
        self._current_unsupported = bool(case.unsupported)
        if case.unsupported:
            self.unsupported.add(case.case_id)
        self.dispatched[case.case_id] = time.perf_counter()

    def on_fork(self) -> None:
        """Before every ``os.fork`` of this process (``os.register_at_fork``)."""
        if self._in_model_call:
            self.model_call_forks += 1
            return
        self.forks += 1
        if self._current_unsupported:
            self.forks_by_unsupported += 1

    def model_calls_counted(self, fork):
        """``fork`` of :mod:`~integrator_bench.harness.forking.child` (the fingerprint
        probe, a missing reference, the stiffness bound, a plugin's trial build), its
        forks counted apart."""
        def counted(*args, **kwargs):
            self._in_model_call = True
            try:
                return fork(*args, **kwargs)
            finally:
                self._in_model_call = False
        return counted

    def on_record(self, record: dict) -> None:
        self._current_unsupported = False
        elapsed = time.perf_counter() - self.dispatched[record["case_id"]]
        self.rows.append((record["case_id"], elapsed, record.get("wall_s"),
                          record.get(EXECUTE_S)))


EXECUTE_S = "_overhead_execute_s"  # added to a record by the timed execute; not stored


def timed_execute(execute):
    """``execute`` that adds its own duration to the record, under :data:`EXECUTE_S`."""
    def timed(*args, **kwargs):
        start = time.perf_counter()
        record = dict(execute(*args, **kwargs))   # a plain dict: the Record takes its fields only
        record[EXECUTE_S] = time.perf_counter() - start
        return record
    return timed


def measure(cases, jobs: int | None, timeout: float,
            repeat: int | None = None) -> tuple[Timings, float]:
    """Run ``cases`` into a temporary store, ``repeat`` samples at most a case (the
    preset's, as ``ibench run`` takes them); return their timings and the run's wall
    time."""
    timings = Timings()
    os.register_at_fork(before=timings.on_fork)  # counts the workers the runner forks
    child.fork = timings.model_calls_counted(child.fork)
    isolation.execute = timed_execute(isolation.execute)  # what a forked worker calls
    with tempfile.TemporaryDirectory() as tmp, Store(Path(tmp) / "overhead.sqlite") as store:
        start = time.perf_counter()
        context = RunContext(store=store, jobs=jobs, progress=sys.stderr.isatty(),
                             command="studies/overhead.py",
                             limits=Limits(budget_s=timeout, repeat=repeat))
        with Session(context) as session:
            session.run(cases, on_record=timings.on_record, on_dispatch=timings.on_dispatch)
        total = time.perf_counter() - start
    return timings, total


def report(timings: Timings, total_wall: float) -> list[str]:
    """The lines printed: overhead of the cases run, of the unsupported ones, forks."""
    ran = [(dt, wall) for cid, dt, wall, _ in timings.rows if cid not in timings.unsupported]
    skipped = [dt for cid, dt, _, _ in timings.rows if cid in timings.unsupported]
    around = [(ex - (wall or 0.0), dt - ex) for cid, dt, wall, ex in timings.rows
              if cid not in timings.unsupported and ex is not None]
    lines = [f"cases: {len(timings.rows)} ({len(ran)} run in a worker, "
             f"{len(skipped)} unsupported); run wall time {total_wall:.1f} s"]
    if ran:
        over = np.array([dt - (wall or 0.0) for dt, wall in ran]) * 1e3
        solve = sum(wall or 0.0 for _, wall in ran)
        p10, p50, p90, p99 = np.percentile(over, [10, 50, 90, 99])
        lines += [
            f"overhead per case run (ms): median {p50:.1f}, p10 {p10:.1f}, p90 {p90:.1f}, "
            f"p99 {p99:.1f}, max {over.max():.1f}",
            f"total overhead {over.sum() / 1e3:.1f} s over {solve:.1f} s of solves "
            f"({100 * over.sum() / 1e3 / solve:.1f} % of the solve time)" if solve > 0 else
            f"total overhead {over.sum() / 1e3:.1f} s (no solve time recorded)"]
    if around:
        inside, outside = (np.median(x) * 1e3 for x in zip(*around))
        lines.append(f"median split (ms): {inside:.1f} in the worker's execute around the "
                     f"solve, {outside:.1f} outside it (fork, limits, pipe, store, scheduling)")
    if skipped:
        lines.append(f"unsupported cases (ms in the parent): median {np.median(skipped) * 1e3:.2f}, "
                     f"total {sum(skipped):.2f} s")
    lines.append(f"processes forked: {timings.forks} for {len(ran)} cases run; "
                 f"by unsupported cases: {timings.forks_by_unsupported}; for the model's "
                 f"own calls (references, stiffness): {timings.model_call_forks}")
    return lines


def verdict(timings: Timings, max_ms: float, max_share: float | None) -> list[str]:
    """The targets missed, one line each (none: all met)."""
    ran = [(dt, wall or 0.0) for cid, dt, wall, _ in timings.rows
           if cid not in timings.unsupported]
    missed = []
    if timings.forks_by_unsupported:
        missed.append(f"{timings.forks_by_unsupported} processes forked for unsupported cases")
    if ran:
        over = [dt - wall for dt, wall in ran]
        median_ms = float(np.median(over)) * 1e3
        solve = sum(wall for _, wall in ran)
        if median_ms > max_ms:
            missed.append(f"median overhead {median_ms:.1f} ms > {max_ms:g} ms")
        if max_share is not None and solve > 0 and sum(over) / solve > max_share:
            missed.append(f"overhead share {100 * sum(over) / solve:.1f} % > {100 * max_share:g} %")
    return missed


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2
        self.exit(2, f"overhead.py: error: {message}\n")


def parse_args(argv=None) -> argparse.Namespace:
    p = _Parser(description=__doc__.splitlines()[0])
    p.add_argument("--preset", default="quick", choices=sorted(PRESETS))
    p.add_argument("-p", "--problem", action="append", metavar="PROBLEM")
    p.add_argument("-f", "--formulation", action="append")
    p.add_argument("-i", "--integrator", action="append")
    p.add_argument("--rtol", nargs="+", type=float)
    p.add_argument("--h", nargs="+", type=float)
    p.add_argument("--jobs", type=int, default=None, help="worker processes (default: cores)")
    p.add_argument("--timeout", type=float, default=DEFAULT_BUDGET_S)
    p.add_argument("--max-ms", type=float, default=MAX_MEDIAN_MS,
                   help=f"target median overhead per case (default {MAX_MEDIAN_MS:g})")
    p.add_argument("--max-share", type=float, default=None,
                   help=f"target overhead share of the solve time (default {MAX_SHARE:g} "
                        "on the full preset, none otherwise)")
    args = p.parse_args(argv)
    for name in ("jobs", "timeout", "rtol", "h"):
        for value in np.atleast_1d(getattr(args, name) if getattr(args, name) is not None
                                   else []):
            if value <= 0:
                p.error(f"--{name} must be positive, not {value:g}")
    return args


def main(argv=None) -> int:
    args = parse_args(argv)
    try:
        cases = expand(problems=args.problem, formulations=args.formulation,
                       integrators=args.integrator, rtols=args.rtol, hs=args.h,
                       preset=args.preset, listed=listed_cases(args.preset))
    except (BadInput, UnknownName) as exc:
        print(f"overhead.py: error: {exc}", file=sys.stderr)
        return 2
    if not cases:
        print("overhead.py: error: the selection gives no cases", file=sys.stderr)
        return 2
    timings, total = measure(cases, args.jobs, args.timeout, PRESETS[args.preset].samples)
    print("\n".join(report(timings, total)))
    max_share = args.max_share if args.max_share is not None else \
        (MAX_SHARE if args.preset == "full" else None)
    missed = verdict(timings, args.max_ms, max_share)
    for line in missed:
        print(f"target missed: {line}")
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
