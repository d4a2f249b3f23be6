"""The local backend of :func:`~integrator_bench.harness.run.loop.drive`: forked
workers of this process, :class:`LocalPool`.

The Dask backend beside it is :class:`~integrator_bench.harness.run.dask_backend.DaskPool`;
both are driven by the one scheduling loop,
:func:`~integrator_bench.harness.run.loop.drive`.
"""

from __future__ import annotations

import time
from multiprocessing.connection import wait

from integrator_bench.harness.matrix.line import ProblemSpec
from integrator_bench.harness.run.isolation import Worker


class LocalPool:
    """The local backend of :func:`drive`: up to ``jobs`` forked workers of this
    process, each serving case after case
    (:class:`~integrator_bench.harness.run.isolation.Worker`), each case within
    its budget of CPU seconds (:meth:`~integrator_bench.harness.run.limits.Limits.budget_of`).

    A case goes to an idle worker, or to a new one when none is idle; a
    worker is replaced only after a fault (crash, kill past the budget's
    backstops, out of memory) or after
    :data:`~integrator_bench.harness.run.isolation.MAX_CASES` cases, so a case
    pays no fork of its own. ``build(spec)`` gives a case's problem to the worker's
    warm-up (:class:`~integrator_bench.harness.run.isolation.Worker`; the session's,
    built once).
    """

    def __init__(self, jobs, reference_dir, limits, build=ProblemSpec.build):
        self.jobs, self.limits = jobs, limits
        self.options = (reference_dir, limits, build)
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

