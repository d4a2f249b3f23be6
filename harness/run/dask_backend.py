"""Running cases on Dask: a running scheduler, or a LocalCluster started here.

``--dask tcp://HOST:PORT`` connects to a running scheduler; ``--dask local:N``
starts a LocalCluster of N worker processes with one thread each. Each case is
one Dask task, :func:`run_task`, which runs it in a forked case worker kept by
its Dask worker's thread from task to task (:func:`case_runner`, an
:class:`integrator_bench.harness.run.isolation.Isolated`), the same
:class:`integrator_bench.harness.run.isolation.Worker` as the local pool keeps:
the same timeout, memory limit, one BLAS thread, no fork per case (a fresh
fork's copy-on-write faults would be counted in the case's CPU), and a crash
becomes a ``crashed`` record without taking the Dask worker down. :class:`DaskPool` is the
submit/poll backend that :func:`integrator_bench.harness.run.loop.drive` (the
one scheduling loop, shared with the local pool) runs; the records, the
progress bar and the store writes stay in the calling (client) process, and
an ``unsupported`` case is recorded there without a task.

A Dask worker shares nothing with the client but the installed package. What
else a case needs travels with its task (:mod:`integrator_bench.harness.run.shipping`):
the reference the client verified, and the bytes of a file a parameter names
(an FMU); the worker reads no reference from its disk and computes none, and
the record names the case as the client does.

The installation must be the client's (:func:`~integrator_bench.harness.matrix.provenance.installation`:
code version, Python, the packages the numbers depend on, the plugins):
:func:`describe` refuses a cluster with a worker of another one before any
case runs (BadInput: the run is not started, nothing is written), and each task
carries the client's installation, so a worker of another one that joins later
runs no case either: its first task raises
:class:`~integrator_bench.harness.errors.WorkerMismatch` and the run stops,
its finished records stored. Refused rather than recorded: a store whose
records came from two versions of the code would mix numbers that cannot be
compared, and the run could not say which to keep.

Dask workers find problems and integrators through the entry points of the
environment they run in, like any fresh process: a class registered at run
time with :func:`integrator_bench.harness.matrix.registry.register` (the tests' broken integrators)
exists only in the process that registered it, so on Dask its cases become
``error`` records naming the unknown integrator. Install it as a plugin (an
entry point) to run it on Dask.
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import tempfile
import threading
import time
import uuid

from integrator_bench.harness.matrix import provenance

from integrator_bench.harness.run import shipping
from integrator_bench.harness.errors import BackendLost, BadInput, WorkerMismatch
from integrator_bench.harness.run.execution import base_record, finish
from integrator_bench.harness.run.isolation import Isolated
from integrator_bench.harness.matrix.line import ProblemSpec
from integrator_bench.harness.matrix.record import CRASHED, EXCEPTION, CaseStatus

#: Dask configuration while ``--dask local:N`` starts its cluster. Dask's nanny sets
#: ``MALLOC_TRIM_THRESHOLD_=65536`` in every worker it spawns (its
#: ``distributed.nanny.pre-spawn-environ``, to hand memory back to the system);
#: glibc then keeps a fixed mmap threshold, so every array over 128 KiB a solve
#: allocates is mapped afresh and its pages faulted in: system CPU counted in the
#: case's budget that a local worker does not pay (docs/dask.md). Unset here, the
#: workers' malloc is the client's; a remote cluster's workers keep their own
#: (``malloc`` in the run's backend provenance says which).
LOCAL_CLUSTER_CONFIG = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}
MALLOC_VARS = ("MALLOC_TRIM_THRESHOLD_", "MALLOC_MMAP_THRESHOLD_", "MALLOC_TOP_PAD_",
               "MALLOC_MMAP_MAX_", "MALLOC_ARENA_MAX", "GLIBC_TUNABLES")

ADDRESS = re.compile(r"^(tcp|tls)://[^\s/:]+:\d{1,5}$")
LOCAL = re.compile(r"^local:(\d+)$")
CONNECT_TIMEOUT = "10s"
REFRESH_S = 5.0  # how often the number of Dask worker threads is asked again
POLL_S = 0.2     # the longest a poll waits for a task to finish


def parse(spec: str) -> tuple[str, str | int]:
    """``("local", N)`` or ``("address", "tcp://HOST:PORT")``; BadInput otherwise."""
    m = LOCAL.match(spec)
    if m and int(m.group(1)) >= 1:
        return "local", int(m.group(1))
    if ADDRESS.match(spec) and 0 < int(spec.rsplit(":", 1)[1]) < 65536:
        return "address", spec
    raise BadInput(f"--dask {spec!r} is neither tcp://HOST:PORT (or tls://) of a running "
                   f"scheduler nor local:N with N >= 1 workers")


@contextlib.contextmanager
def connect(spec: str):
    """A ``distributed.Client`` for ``spec`` (see :func:`parse`), closed on exit.

    Raises BadInput when Dask is not installed, the scheduler cannot be
    reached or a worker's installation differs from this one's (:func:`describe`),
    so nothing is written for a bad ``--dask``.
    """
    kind, arg = parse(spec)
    try:
        import dask
        from distributed import Client, LocalCluster
    except ImportError:
        raise BadInput("--dask needs dask and distributed: "
                       "pip install 'integrator-bench[dask]'") from None
    with contextlib.ExitStack() as stack:
        stack.enter_context(_quiet_distributed())
        if kind == "local":
            # one thread per worker: each runs one case at a time, as a local job does;
            # and malloc as this process has it (LOCAL_CLUSTER_CONFIG)
            with dask.config.set(LOCAL_CLUSTER_CONFIG):
                cluster = stack.enter_context(LocalCluster(
                    n_workers=arg, threads_per_worker=1, processes=True,
                    dashboard_address=None, silence_logs=40))
            client = stack.enter_context(Client(cluster))
        else:
            try:
                client = stack.enter_context(Client(arg, timeout=CONNECT_TIMEOUT))
            except (OSError, TimeoutError) as exc:
                raise BadInput(f"cannot reach the Dask scheduler at {arg}: "
                               f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}"
                               ) from None
        describe(client)
        yield client


@contextlib.contextmanager
def _quiet_distributed():
    """Dask's own log records silenced while the client is in use: a fault (a lost
    worker or scheduler) is told by the records and the run's one line
    (:class:`DaskPool`), not by the tracebacks Dask logs on the way (those of
    the client's attempts to reconnect, cancelled when it closes)."""
    names = ["distributed", *(name for name in logging.root.manager.loggerDict
                              if name.startswith("distributed."))]
    loggers = [logging.getLogger(name) for name in names]   # Dask's config sets some levels
    levels = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for logger, level in zip(loggers, levels):
            logger.setLevel(level)


def _worker_facts() -> dict:
    malloc = {k: os.environ[k] for k in MALLOC_VARS if k in os.environ}
    return {**provenance.machine(), **provenance.installation(), "malloc": malloc}


def describe(client) -> dict:
    """The backend part of a run's provenance: scheduler and, per worker, its
    host, CPU model, cores, threads, installation (code version, Python,
    packages, plugins) and ``malloc``, the glibc malloc settings of its environment
    (:data:`LOCAL_CLUSTER_CONFIG`; empty for glibc's defaults).

    Raises BadInput naming every worker whose installation differs from this
    process's, and how (:func:`refusal`).
    """
    try:
        info = client.scheduler_info(n_workers=-1)
    except TypeError:  # older distributed lists every worker anyway
        info = client.scheduler_info()
    facts = client.run(_worker_facts)
    workers = [{"address": addr, "nthreads": w.get("nthreads"), **facts.get(addr, {})}
               for addr, w in sorted(info.get("workers", {}).items())]
    mine = provenance.installation()
    refused = [refusal(w["address"], w, mine) for w in workers]
    if any(refused):
        raise BadInput("; ".join(filter(None, refused)))
    return {"kind": "dask", "scheduler": client.scheduler.address, "workers": workers}


def refusal(address: str, worker: dict, client: dict) -> str | None:
    """Why the Dask worker at ``address`` runs no case of the client: ``"Dask worker
    tcp://... runs another installation than the client: numpy 2.1.0 (here 2.0.2);
    install the client's versions on it"``; None when its installation
    (``worker``) is the client's (``client``; both from
    :func:`~integrator_bench.harness.matrix.provenance.installation`)."""
    differences = provenance.installation_differences(client, worker)
    if not differences:
        return None
    return (f"Dask worker {address} runs another installation than the client: "
            f"{', '.join(differences)}; install the client's versions on it")


def _threads(client) -> int:
    return max(1, sum(client.nthreads().values()))


def _connection_errors() -> tuple:
    """What a call to the scheduler raises when the connection to it is gone."""
    from distributed.comm.core import CommClosedError
    return (OSError, TimeoutError, CommClosedError)


#: how often a case whose input (a scattered reference or file) was lost with a
#: worker is sent again before it is recorded ``crashed``
RESENDS = 2
#: seconds a run waits with cases to run and no Dask worker left before it ends
NO_WORKER_S = 120.0


class DaskPool:
    """The Dask backend of :func:`integrator_bench.harness.run.loop.drive`: each
    case one Dask task, :func:`run_task`, with its reference and files
    (:class:`~integrator_bench.harness.run.shipping.Packer`).

    At most twice as many tasks as the cluster has threads are in flight
    (asked again every ``REFRESH_S``), so a Ctrl-C or a kill wastes little
    work.

    Faults. Each poll asks the scheduler which workers are there. A worker that
    leaves the cluster (killed, its machine gone) gives every case it had started
    (:func:`run_task` logs each start to the scheduler's events) and that has no
    record yet a ``crashed`` record whose message names it; the run goes on with
    the other workers. While no worker is there (the last one lost, or none
    from the start) no case is sent, and the run waits up to ``NO_WORKER_S`` for
    one to join, a restarted one or a new one, then raises BackendLost saying
    that no worker came (``no Dask worker at ADDRESS for 120 s``), not that the
    scheduler was lost. Whatever was scattered is scattered again for the cases sent
    after the loss, and a case whose scattered input was lost with the worker
    before it started is sent again (up to ``RESENDS`` times, then
    ``crashed``). The scheduler lost (its connection closed, a call to it
    failing, the client no longer running) raises BackendLost naming its
    address: the caller ends the run with one line, every finished record
    stored.
    """

    def __init__(self, client, reference_dir, limits, build=ProblemSpec.build):
        self.client, self.futures = client, {}
        self.packer = shipping.Packer(client, reference_dir, build)
        self.args = (provenance.installation(), limits)
        self.address = getattr(client.scheduler, "address", None) or "?"
        self.sent: dict = {}      # case_id -> times sent again after a lost input
        self.workers: set = set(self._call(client.nthreads))   # the workers at the last poll
        self.lost: set = set()              # every worker that left during the run
        self.alone_since: float | None = None   # since when no worker is left
        self.held: list = []      # cases to send again once a worker is there
        self.topic = f"ibench-started-{uuid.uuid4().hex}"   # run_task's events
        self.window, self.asked = 2 * self._call(_threads, client), time.monotonic()

    def __len__(self) -> int:
        return len(self.futures) + len(self.held)

    def _call(self, function, *args, **kwargs):
        """``function(*args)`` talking to the scheduler; BackendLost when it is gone."""
        if self.client.status != "running":
            raise self._lost()
        try:
            return function(*args, **kwargs)
        except _connection_errors() as exc:
            raise self._lost(exc) from None

    def _lost(self, exc=None) -> BackendLost:
        why = f" ({type(exc).__name__})" if exc is not None else ""
        return BackendLost(f"lost the Dask scheduler at {self.address}{why}")

    def has_room(self) -> bool:
        """Whether a case may be sent: a worker is there (nothing is scattered to a
        cluster without one, where the scatter would wait and fail) and fewer than
        twice the cluster's threads are in flight."""
        if not self.workers:
            return False
        if time.monotonic() - self.asked > REFRESH_S:
            self.window = 2 * self._call(_threads, self.client)
            self.asked = time.monotonic()
        return len(self.futures) < self.window

    def submit(self, case) -> None:
        key = f"ibench-{case.case_id}-{uuid.uuid4().hex[:8]}"
        try:
            handed, files = self._call(self.packer.pack, case)
        except BackendLost:
            # a scatter with no worker left waits, then times out: the case waits for one
            if self.client.status != "running" or self._call(self.client.nthreads):
                raise
            self.workers = set()
            self.held.append(case)
            return
        future = self._call(self.client.submit, run_task, case, handed, files, *self.args,
                            self.topic, key=key, pure=False)
        self.futures[future] = case

    def poll(self):
        """Yield the records of the finished tasks, waiting up to ``POLL_S`` for the
        first when none has finished (woken by its completion, not by a fixed
        sleep: a short case's record comes back, and the next case goes out, as
        soon as it ends), and the ``crashed`` records of the cases a lost worker
        was running (see the class)."""
        from distributed import wait
        from distributed.client import FuturesCancelledError

        done = [f for f in self.futures if f.done()]
        if self.held and self.workers:   # a worker joined: send what waited for one
            for case in self.held[:]:
                self.held.remove(case)
                self.submit(case)
        if not self.futures:   # no worker to send a case to: wait for one to join
            time.sleep(POLL_S)
        elif not done:
            try:   # its TimeoutError is the wait's own
                self._call(_wait_some, wait, list(self.futures))
            except FuturesCancelledError:
                pass   # a cancelled one is looked at below
            done = [f for f in self.futures if f.done()]
        yield from self._lost_workers()
        for fut in done:
            if fut not in self.futures:   # recorded as its lost worker's
                continue
            case = self.futures.pop(fut)
            if fut.status != "cancelled":
                yield _record(fut, case)
            elif self.client.status != "running":
                raise self._lost()
            else:   # its input went with a lost worker before it started
                yield from self._resend(case, "its input was lost with a Dask worker")

    def _lost_workers(self):
        """The ``crashed`` records of the cases without a result that started on a
        worker that has left the cluster (each task cancelled: Dask would run it
        again)."""
        workers = set(self._call(self.client.nthreads))
        gone = self.workers - workers
        self.workers = workers
        self.lost |= gone
        if workers:
            self.alone_since = None
        elif self.alone_since is None:
            self.alone_since = time.monotonic()
        elif time.monotonic() - self.alone_since > NO_WORKER_S:
            raise BackendLost(f"no Dask worker at {self.address} for {NO_WORKER_S:g} s "
                              f"(the scheduler is up, no worker joined)")
        if gone:
            self.packer.release()   # what they held is scattered again when next needed
        unfinished = [f for f in self.futures if f.status != "finished"]
        if not self.lost or not (gone or any(f.status == "cancelled" for f in unfinished)):
            return
        started = self._started()
        for fut in unfinished:
            lost = sorted(started.get(fut.key, set()) & self.lost)
            if lost:
                case = self.futures.pop(fut)
                with contextlib.suppress(*_connection_errors()):
                    fut.cancel()
                yield finish(base_record(case), CaseStatus.CRASHED,
                             f"the Dask worker {lost[0]} running it was lost", CRASHED)

    def _started(self) -> dict:
        """``{task key: the workers it started on}`` of this run's tasks, from the
        events :func:`run_task` logs as it starts (a task a lost worker held but had
        not started is run by another: Dask sends it again)."""
        started: dict = {}
        for _, msg in self._call(self.client.get_events, self.topic):
            started.setdefault(msg["key"], set()).add(msg["worker"])
        return started

    def _resend(self, case, why: str):
        """Send ``case`` again (nothing yielded), or past ``RESENDS`` its
        ``crashed`` record."""
        self.sent[case.case_id] = self.sent.get(case.case_id, 0) + 1
        if self.sent[case.case_id] > RESENDS:
            yield finish(base_record(case), CaseStatus.CRASHED,
                         f"{why}, {RESENDS + 1} times", CRASHED)
            return
        self.packer.release()
        if self.workers:
            self.submit(case)
        else:   # sent once a worker joins
            self.held.append(case)

    def close(self) -> None:
        """Cancel the tasks still in flight and release the scattered references and
        files (nothing to cancel when the scheduler is gone)."""
        self.held.clear()
        if self.futures and self.client.status == "running":
            with contextlib.suppress(*_connection_errors()):
                self.client.cancel(list(self.futures))
        self.packer.release()


def _wait_some(wait, futures) -> None:
    """``wait`` up to ``POLL_S`` for the first of ``futures`` to finish."""
    try:
        wait(futures, timeout=POLL_S, return_when="FIRST_COMPLETED")
    except TimeoutError:
        pass


_kept = threading.local()   # each Dask executor thread's case worker (case_runner)


def case_runner(limits) -> Isolated:
    """The case worker this thread of a Dask worker keeps from task to task
    under ``limits`` (:class:`~integrator_bench.harness.run.isolation.Isolated`:
    replaced after a fault or its
    :data:`~integrator_bench.harness.run.isolation.MAX_CASES` cases, as the local
    pool's), a new one when the limits differ (another run).

    Kept per thread: a forked worker dies with the thread that forked it, and a
    Dask worker with several threads runs a task in each at once.
    """
    run = getattr(_kept, "run", None)
    if run is None or run.limits != limits:
        if run is not None:
            run.close()
        run = _kept.run = Isolated(None, limits)
    return run


def run_task(case, handed, files, installation, limits, topic=None) -> dict:
    """What a Dask task runs: ``case`` with its ``handed`` reference and shipped
    ``files`` (:func:`~integrator_bench.harness.run.shipping.unpack`) in the case
    worker this thread keeps (:func:`case_runner`) under
    ``limits`` (:class:`~integrator_bench.harness.run.limits.Limits`), its
    record under the client's case id and parameters. As it starts it logs
    ``{"key", "worker"}`` to the scheduler's events under ``topic`` (which tasks a
    lost worker was running, :class:`DaskPool`). The worker's temporary files (an
    FMU's extraction) go into its Dask local directory, which Dask removes with
    the worker: a worker process ends without running ``atexit``.

    Raises WorkerMismatch, before anything runs, on a worker whose installation
    differs from the client's (``installation``).
    """
    from distributed import get_worker

    worker = get_worker()
    why = refusal(worker.address, provenance.installation(), installation)
    if why:
        raise WorkerMismatch(f"{why}; it joined after the run started")
    if topic is not None:
        worker.log_event(topic, {"key": worker.get_current_task(), "worker": worker.address})
    scratch = os.path.join(worker.local_directory, "tmp")
    if tempfile.tempdir != scratch:
        os.makedirs(scratch, exist_ok=True)
        tempfile.tempdir = scratch
    record = case_runner(limits)(shipping.unpack(case, files), handed)
    return shipping.as_client_sees(record, case)


def _record(fut, case) -> dict:
    if fut.status == "finished":
        return fut.result()
    if fut.status == "cancelled":
        raise BackendLost(f"the Dask scheduler cancelled the task of {case.label()} "
                          f"(connection lost?)")
    exc = fut.exception()
    if isinstance(exc, WorkerMismatch):
        raise exc
    why = f"{type(exc).__name__}: {exc}".splitlines()[0][:400]
    if type(exc).__name__ == "KilledWorker":
        return finish(base_record(case), CaseStatus.CRASHED,
                      f"the Dask workers running it died: {why}", CRASHED)
    return finish(base_record(case), CaseStatus.ERROR, f"Dask task failed: {why}", EXCEPTION)
