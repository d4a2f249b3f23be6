"""Running cases on Dask: a running scheduler, or a LocalCluster started here.

``--dask tcp://HOST:PORT`` connects to a running scheduler; ``--dask local:N``
starts a LocalCluster of N worker processes with one thread each. Each case is
one Dask task, :func:`run_task`, which forks a worker process on the Dask
worker (:func:`integrator_bench.harness.run.isolation.run_isolated`) through the same
:class:`integrator_bench.harness.run.isolation.Worker` as the local pool: the same
timeout, memory limit, one BLAS thread, and a crash becomes a ``crashed``
record without taking the Dask worker down. :class:`DaskPool` is the
submit/poll backend that :func:`integrator_bench.harness.run.runner.drive` (the
one scheduling loop, shared with the local pool) runs; the records, the
progress bar and the store writes stay in the calling (client) process, and
an ``unsupported`` case is recorded there without a task.

A Dask worker shares nothing with the client but the installed package. What
else a case needs travels with its task (:mod:`integrator_bench.harness.run.shipping`):
the reference the client verified, and the bytes of a file a parameter names
(an FMU); the worker reads no reference from its disk and computes none, and
the record names the case as the client does.

The installation must be the client's (:func:`~integrator_bench.harness.model.provenance.installation`:
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
time with :func:`integrator_bench.harness.model.registry.register` (the tests' broken integrators)
exists only in the process that registered it, so on Dask its cases become
``error`` records naming the unknown integrator. Install it as a plugin (an
entry point) to run it on Dask.
"""

from __future__ import annotations

import contextlib
import re
import time
import uuid

from integrator_bench.harness.model import provenance

from integrator_bench.harness.run import shipping
from integrator_bench.harness.errors import BackendLost, BadInput, WorkerMismatch
from integrator_bench.harness.run.execution import base_record, finish
from integrator_bench.harness.run.isolation import run_isolated
from integrator_bench.harness.model.record import CRASHED, EXCEPTION, CaseStatus

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
        from distributed import Client, LocalCluster
    except ImportError:
        raise BadInput("--dask needs dask and distributed: "
                       "pip install 'integrator-bench[dask]'") from None
    with contextlib.ExitStack() as stack:
        if kind == "local":
            # one thread per worker: each runs one case at a time, as a local job does
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


def _worker_facts() -> dict:
    return {**provenance.machine(), **provenance.installation()}


def describe(client) -> dict:
    """The backend part of a run's provenance: scheduler and, per worker, its
    host, CPU model, cores, threads and installation (code version, Python,
    packages, plugins).

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
    :func:`~integrator_bench.harness.model.provenance.installation`)."""
    differences = provenance.installation_differences(client, worker)
    if not differences:
        return None
    return (f"Dask worker {address} runs another installation than the client: "
            f"{', '.join(differences)}; install the client's versions on it")


def _threads(client) -> int:
    return max(1, sum(client.nthreads().values()))


class DaskPool:
    """The Dask backend of :func:`integrator_bench.harness.run.runner.drive`: each
    case one Dask task, :func:`run_task`, with its reference and files
    (:class:`~integrator_bench.harness.run.shipping.Packer`).

    At most twice as many tasks as the cluster has threads are in flight
    (asked again every ``REFRESH_S``), so a Ctrl-C or a kill wastes little
    work. :meth:`poll` raises BackendLost when the scheduler cancels tasks
    (connection lost).
    """

    def __init__(self, client, timeout, reference_dir, memory_mb, repeat):
        self.client, self.futures = client, {}
        self.packer = shipping.Packer(client, reference_dir)
        self.args = (provenance.installation(), timeout, memory_mb, repeat)
        self.window, self.asked = 2 * _threads(client), time.monotonic()

    def __len__(self) -> int:
        return len(self.futures)

    def has_room(self) -> bool:
        if time.monotonic() - self.asked > REFRESH_S:
            self.window, self.asked = 2 * _threads(self.client), time.monotonic()
        return len(self.futures) < self.window

    def submit(self, case) -> None:
        key = f"ibench-{case.case_id}-{uuid.uuid4().hex[:8]}"
        handed, files = self.packer.pack(case)
        future = self.client.submit(run_task, case, handed, files, *self.args, key=key,
                                    pure=False)
        self.futures[future] = case

    def poll(self):
        """Yield the records of the finished tasks, waiting up to ``POLL_S`` for the
        first when none has finished (woken by its completion, not by a fixed
        sleep: a short case's record comes back, and the next case goes out, as
        soon as it ends)."""
        from distributed import wait

        done = [f for f in self.futures if f.done()]
        if not done and self.futures:
            try:
                wait(list(self.futures), timeout=POLL_S, return_when="FIRST_COMPLETED")
            except TimeoutError:
                pass
            done = [f for f in self.futures if f.done()]
        for fut in done:
            yield _record(fut, self.futures.pop(fut))

    def close(self) -> None:
        """Cancel the tasks still in flight and release the scattered references and files."""
        if self.futures:
            self.client.cancel(list(self.futures))
        self.packer.release()


def run_task(case, handed, files, installation, timeout, memory_mb, repeat) -> dict:
    """What a Dask task runs: ``case`` with its ``handed`` reference and shipped
    ``files`` (:func:`~integrator_bench.harness.run.shipping.unpack`) in a forked
    worker (:func:`~integrator_bench.harness.run.isolation.run_isolated`), its
    record under the client's case id and parameters.

    Raises WorkerMismatch, before anything runs, on a worker whose installation
    differs from the client's (``installation``).
    """
    from distributed import get_worker

    why = refusal(get_worker().address, provenance.installation(), installation)
    if why:
        raise WorkerMismatch(f"{why}; it joined after the run started")
    record = run_isolated(shipping.unpack(case, files), timeout, handed, memory_mb, repeat)
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
