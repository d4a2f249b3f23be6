"""A Dask cluster that shares nothing with the client but the installed package.

A scheduler and two workers run as separate processes (``dask scheduler`` and
``dask worker`` of this environment, on 127.0.0.1, ports chosen by the
operating system), each worker in an empty working directory of its own, with
a data directory of its own, without ``IBENCH_REFERENCE_DIR`` and without
``PYTHONPATH``. Each worker preloads a guard (``--preload``) that refuses, and
logs, every open of a file under the client's folder (where the client's
references and the FMU live) and every reference computed on the worker. So
the records equal the local pool's only when each case's reference and FMU
came with its task.
"""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.harness.run.shipping import FILES_DIR
from integrator_bench.harness.matrix.store import Store, load_runs
from integrator_bench.problems import fmu_build
from integrator_bench.problems.fmu import file_checksum
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits

distributed = pytest.importorskip("distributed")

DASK = Path(sys.executable).parent / "dask"
START_S = 90  # the longest the scheduler and the workers may take to come up
COMPARED = ["case_id", "params", "status", "reason", "message", "nfev", "njev", "nlu",
            "nsteps", "nreject", "nniter", "nnfail", "nevents", "scd", "mescd", "reference"]

GUARD = '''\
"""Preloaded by the test's Dask workers: nothing of the client's folder is opened,
no reference is computed here."""
import os
import sys

from integrator_bench.harness.measure import references

FORBIDDEN, LOG = {forbidden!r}, {log!r}


def _note(what):
    with open(LOG, "a") as f:
        f.write(what + "\\n")


def _guard(event, args):
    if event in ("open", "ctypes.dlopen") and args and isinstance(args[0], (str, bytes)):
        path = os.path.abspath(os.fsdecode(args[0]))
        if path.startswith(FORBIDDEN):
            _note(f"opened {{path}}")
            raise PermissionError(f"a Dask worker opened the client's file {{path}}")


def _compute(problem):
    _note(f"computed the reference of {{problem.label()}}")
    raise RuntimeError("a reference computed on a Dask worker")


references.compute = _compute
sys.addaudithook(_guard)
'''


def _env(data_dir: Path) -> dict:
    env = {k: v for k, v in os.environ.items()
           if k not in ("IBENCH_REFERENCE_DIR", "IBENCH_DATA_DIR", "PYTHONPATH")}
    env["IBENCH_DATA_DIR"] = str(data_dir)
    env["TMPDIR"] = str(data_dir.parent / "tmp")   # its temporary files, seen by the test
    (data_dir.parent / "tmp").mkdir(parents=True, exist_ok=True)
    return env


def _stop(procs) -> None:
    for proc in procs:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
    for proc in procs:
        try:
            proc.wait(15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """``(scheduler address, client folder, [worker folders])``; torn down after."""
    if not DASK.exists():
        pytest.skip(f"no dask command beside {sys.executable}")
    client_dir = tmp_path_factory.mktemp("client")
    base = tmp_path_factory.mktemp("cluster")
    scheduler_file = base / "scheduler.json"
    procs, workers = [], []
    try:
        (base / "scheduler").mkdir()
        with open(base / "scheduler.log", "w") as log:
            procs.append(subprocess.Popen(
                [str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0",
                 "--no-dashboard", "--scheduler-file", str(scheduler_file)],
                cwd=base / "scheduler", env=_env(base / "scheduler"), stdout=log,
                stderr=subprocess.STDOUT))
        deadline = time.monotonic() + START_S
        while not scheduler_file.exists():
            assert time.monotonic() < deadline and procs[0].poll() is None, \
                (base / "scheduler.log").read_text()
            time.sleep(0.2)
        for n in (1, 2):
            home = base / f"worker{n}"
            cwd = home / "cwd"
            cwd.mkdir(parents=True)
            guard = home / "guard.py"
            guard.write_text(GUARD.format(forbidden=str(client_dir) + os.sep,
                                          log=str(home / "guard.log")))
            with open(home / "worker.log", "w") as log:
                procs.append(subprocess.Popen(
                    [str(DASK), "worker", "--scheduler-file", str(scheduler_file),
                     "--host", "127.0.0.1", "--nthreads", "1", "--nworkers", "1",
                     "--no-dashboard", "--death-timeout", "60", "--name", f"w{n}",
                     "--local-directory", str(home / "scratch"), "--preload", str(guard)],
                    cwd=cwd, env=_env(home / "data"), stdout=log, stderr=subprocess.STDOUT))
            workers.append(home)
        address = json.loads(scheduler_file.read_text())["address"]
        with distributed.Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=START_S)
        yield address, client_dir, workers
    finally:
        _stop(procs[1:])
        _stop(procs[:1])


def test_cases_travel_with_their_reference_and_fmu(cluster, store_path, run_cases):
    address, client_dir, workers = cluster
    fmu = fmu_build.build_fmu("two_mass", client_dir / "fmus")
    reference_dir = client_dir / "reference"
    cases = expand(problems=["two_mass:k2=500", f"fmu:path={fmu},k2=500"],
                   integrators=["cvode-bdf", "scipy-RK45", "fmpy-cvode"], rtols=[1e-3, 1e-6])
    local = run_cases(cases,
                      RunContext(jobs=2, reference_dir=reference_dir, progress=False,
                                 limits=Limits(repeat=1)))
    with Store(store_path) as store:
        on_dask = run_cases(cases,
                            RunContext(store=store, dask=address, reference_dir=reference_dir,
                                       progress=False, limits=Limits(repeat=1)))
    key = lambda df: df[COMPARED].sort_values("case_id").reset_index(drop=True)  # noqa: E731
    assert set(on_dask.status) == {CaseStatus.OK, CaseStatus.UNSUPPORTED}, on_dask.message.tolist()
    assert key(on_dask).equals(key(local))
    for home in workers:
        assert not (home / "guard.log").exists(), (home / "guard.log").read_text()
        assert not list((home / "data").rglob("*.npz")), "a worker stored a reference"
        assert not any((home / "cwd").iterdir()), "a worker wrote into its working directory"
        # its FMU extraction lies in its Dask local directory, removed with it
        assert not list((home / "tmp").glob("ibench-fmu-*"))
    # a worker that ran an FMU case extracted it there (the scheduler may hand every
    # FMU case to one worker)
    assert any(list((home / "scratch").rglob("ibench-fmu-*")) for home in workers)
    copies = [p.name for home in workers for p in (home / "scratch").rglob(f"{FILES_DIR}/*")]
    assert copies and set(copies) == {f"{file_checksum(fmu)}.fmu"}
    assert len(copies) <= len(workers)  # once per worker
    backend = json.loads(load_runs(store_path).iloc[0].backend)
    assert backend["scheduler"] == address and len(backend["workers"]) == 2
    assert all(w["packages"]["numpy"] for w in backend["workers"])
