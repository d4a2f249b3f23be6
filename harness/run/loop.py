"""The one scheduling loop, shared by both pools: :func:`drive`.

It feeds a *submit/poll* backend, the local pool
(:class:`~integrator_bench.harness.run.local_pool.LocalPool`) or Dask
(:class:`~integrator_bench.harness.run.dask_backend.DaskPool`), the cases a
:class:`~integrator_bench.harness.run.schedule.Schedule` hands out;
:func:`drive_interruptible` is the same with Ctrl-C turned into a flag, as a
:class:`~integrator_bench.harness.run.runner.Session` runs it.
"""

from __future__ import annotations

import signal
import threading
import time

from integrator_bench.harness.run.execution import execute
from integrator_bench.harness.run.schedule import Schedule


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
        and ``close()``:
        :class:`~integrator_bench.harness.run.local_pool.LocalPool` or
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




def drive_interruptible(backend, pending, accept, interrupted: list, on_dispatch=None,
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
