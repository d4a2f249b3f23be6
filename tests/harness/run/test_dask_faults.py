"""Faults of a Dask cluster end in records and one line, not in a traceback.

A scheduler and two workers (no nanny) run as ``dask scheduler`` / ``dask
worker`` processes on 127.0.0.1; each worker preloads an integrator that sleeps
``SLEEP_S`` and returns the start (registered in the client too), so cases are
in flight when a process is killed with SIGKILL:

* a worker killed mid-run (while it runs a case): the case it was running gets a
  ``crashed`` record
  naming it, the run goes on on the other worker, and the cases after the kill
  run with their references sent again (what the lost worker held is lost);
* the scheduler killed mid-run: ``ibench run`` ends with one line, exit 1, and
  the store keeps every finished case.
"""

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.harness.matrix.store import Store, load
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits

distributed = pytest.importorskip("distributed")

REPO = Path(__file__).resolve().parents[3]
DASK = Path(sys.executable).parent / "dask"
START_S = 90
SLEEP_S = 0.8
PROBLEMS = ["two_mass", "pendulum"]   # 3 parameter sets, references committed

SLEEPER = '''\
"""An integrator that sleeps {sleep} s and returns the start (tests only)."""
import time

import numpy as np

from integrator_bench.harness.matrix import registry
from integrator_bench.integrators.base import Integrator, Solution


class Sleeper(Integrator):
    name = "test-sleeps"
    description = "sleeps, then returns the start (tests only)"
    accepts = frozenset({{"ode"}})

    def solve(self, system, **kw):
        time.sleep({sleep})
        return Solution(system.t_eval, np.repeat(system.y0[None, :], system.t_eval.size, 0))


if Sleeper.name not in registry.integrators():
    registry.register(Sleeper, origin="tests")
'''

DRIVE = '''\
import sys
sys.path.insert(0, {folder!r})
import sleeper  # noqa: F401
from integrator_bench.harness.cli import main
sys.exit(main(sys.argv[1:]))
'''


def _env(data_dir: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("IBENCH_DATA_DIR", "PYTHONPATH")}
    env.update(IBENCH_DATA_DIR=str(data_dir), IBENCH_REFERENCE_DIR=str(data_dir / "reference"))
    return env


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """``{"address", "scheduler": Popen, "workers": {name: Popen}, "base", "sleeper"}``."""
    if not DASK.exists():
        pytest.skip(f"no dask command beside {sys.executable}")
    base = tmp_path_factory.mktemp("faults")
    for problem in PROBLEMS:
        shutil.copytree(REPO / "results" / "reference" / problem, base / "reference" / problem)
    (base / "sleeper.py").write_text(SLEEPER.format(sleep=SLEEP_S))
    procs = {}
    try:
        address, workers = _start_cluster(base, ("w1", "w2"), procs)
        sys.path.insert(0, str(base))
        import sleeper  # noqa: F401  (the client's registration of the same integrator)
        yield {"address": address, "procs": procs, "base": base, "workers": workers}
    finally:
        if str(base) in sys.path:
            sys.path.remove(str(base))
        if "test-sleeps" in registry.integrators():
            registry.unregister("test-sleeps")
        sys.modules.pop("sleeper", None)
        _stop(procs)


def _stop(procs: dict) -> None:
    for proc in procs.values():
        if proc.poll() is None:
            proc.kill()
        proc.wait(10)


def _start_cluster(base: Path, names, procs: dict) -> tuple[str, dict]:
    """Start a scheduler and the workers ``names`` (one thread, no nanny, the
    sleeper of ``base`` preloaded) in ``base``, their processes put in ``procs``;
    return the scheduler's address and ``{name: worker address}``."""
    scheduler_file = base / "scheduler.json"
    with open(base / "scheduler.log", "w") as log:
        procs["scheduler"] = subprocess.Popen(
            [str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0",
             "--no-dashboard", "--scheduler-file", str(scheduler_file)],
            cwd=base, env=_env(base / "sched-data"), stdout=log, stderr=subprocess.STDOUT)
    deadline = time.monotonic() + START_S
    while not scheduler_file.exists():
        assert time.monotonic() < deadline and procs["scheduler"].poll() is None
        time.sleep(0.1)
    for name in names:
        _start_worker(base, name, procs)
    address = json.loads(scheduler_file.read_text())["address"]
    with distributed.Client(address, timeout="30s") as client:
        client.wait_for_workers(len(names), timeout=START_S)
        info = client.scheduler_info(n_workers=-1)["workers"]
        return address, {w["name"]: a for a, w in info.items()}


def _start_worker(base: Path, name: str, procs: dict) -> None:
    """Start the worker ``name`` (one thread, no nanny, the sleeper of ``base``
    preloaded) on the scheduler of ``base``'s scheduler file, into ``procs``."""
    with open(base / f"{name}.log", "w") as log:
        procs[name] = subprocess.Popen(
            [str(DASK), "worker", "--scheduler-file", str(base / "scheduler.json"),
             "--host", "127.0.0.1", "--nthreads", "1", "--no-nanny",
             "--no-dashboard", "--name", name, "--local-directory",
             str(base / name), "--preload", str(base / "sleeper.py")],
            cwd=base, env=_env(base / f"{name}-data"), stdout=log,
            stderr=subprocess.STDOUT)


def _cases():
    return expand(problems=PROBLEMS, formulations=["ode"], integrators=["test-sleeps"],
                  rtols=[1e-2, 1e-3])


def _kill_when_running(address, worker, proc, stop):
    """SIGKILL ``proc`` (the Dask worker ``worker``) once it has been running a
    task for a quarter of a case (its start logged), after a first record."""
    with distributed.Client(address, timeout="30s") as client:
        while not stop.is_set():
            if client.processing([worker]).get(worker):
                time.sleep(SLEEP_S / 4)
                if client.processing([worker]).get(worker):
                    proc.send_signal(signal.SIGKILL)
                    return
            time.sleep(0.02)


def test_a_lost_worker_crashes_its_cases_and_the_run_goes_on(cluster, store_path, run_cases):
    lost = cluster["workers"]["w1"]
    killer, stop = [], threading.Event()

    def kill_w1_soon(record):
        if not killer:   # after a first record, while w1 runs a case
            killer.append(threading.Thread(target=_kill_when_running, args=(
                cluster["address"], lost, cluster["procs"]["w1"], stop)))
            killer[0].start()

    cases = _cases()
    with Store(store_path) as store:
        df = run_cases(cases,
                       RunContext(store=store, dask=cluster["address"],
                                  reference_dir=cluster["base"] / "reference", progress=False,
                                  limits=Limits(repeat=1, budget_s=60)),
                       on_record=kill_w1_soon)
    stop.set()
    killer[0].join()
    assert cluster["procs"]["w1"].wait(10) == -signal.SIGKILL
    assert sorted(df.case_id) == sorted(c.case_id for c in cases)   # every case has a record
    crashed = df[df.status == CaseStatus.CRASHED]
    # one thread: w1 was running one case; those queued on it ran on w2
    assert len(crashed) == 1, df[["status", "message"]]
    assert set(crashed.message) == {f"the Dask worker {lost} running it was lost"}
    ran = df[df.status != CaseStatus.CRASHED]
    assert len(ran) == len(cases) - 1, df[["status", "message"]]
    assert set(ran.status) <= {CaseStatus.OK, CaseStatus.FAILED}, ran.message.tolist()
    assert len(load(store_path)) == len(cases)


def test_a_lost_scheduler_ends_the_run_in_one_line_keeping_finished_cases(cluster, tmp_path):
    drive = tmp_path / "drive.py"
    drive.write_text(DRIVE.format(folder=str(cluster["base"])))
    store = tmp_path / "s.sqlite"
    data = tmp_path / "data"
    shutil.copytree(cluster["base"] / "reference", data / "reference")
    args = [sys.executable, str(drive), "run", "-i", "test-sleeps", "-f", "ode",
            "--rtol", "1e-2", "1e-3", "--repeat", "1", "--json", "--store", str(store),
            "--dask", cluster["address"], *[a for p in PROBLEMS for a in ("-p", p)]]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=_env(data), cwd=tmp_path)
    first = proc.stdout.readline()       # a case has finished: kill the scheduler
    assert json.loads(first)["integrator"] == "test-sleeps", proc.stderr.read()
    time.sleep(SLEEP_S / 2)
    cluster["procs"]["scheduler"].kill()
    out, err = proc.communicate(timeout=60)
    lines = err.strip().splitlines()
    assert proc.returncode == 1, err
    assert len(lines) == 1 and lines[0].startswith("ibench: lost the Dask scheduler at "
                                                   f"{cluster['address']}"), err
    assert "every finished case is in" in lines[0]
    finished = [json.loads(line) for line in [first, *out.splitlines()]]
    stored = load(store)
    assert sorted(stored.case_id) == sorted(r["case_id"] for r in finished)
    assert 1 <= len(stored) < len(_cases())


def test_advise_ends_in_one_line_when_its_scheduler_is_lost(tmp_path, capsys, monkeypatch):
    """``ibench advise`` (whose matrix runs as ``ibench run``'s) ends a lost Dask
    scheduler as a run does: one line, exit 1."""
    from integrator_bench.harness.advise import advice
    from integrator_bench.harness.cli import main
    from integrator_bench.harness.errors import BackendLost

    def lost(*args, **kwargs):
        raise BackendLost("lost the Dask scheduler at tcp://127.0.0.1:1")

    monkeypatch.setattr(advice, "advise", lost)
    store = tmp_path / "s.sqlite"
    assert main(["advise", "-p", "two_mass", "--target", "1e-3", "--store", str(store),
                 "--out", str(tmp_path / "page")]) == 1
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines == [f"ibench: lost the Dask scheduler at tcp://127.0.0.1:1; every finished "
                     f"case is in {store} (rerun to go on)"]


def test_the_last_worker_lost_the_run_waits_for_one_then_says_no_worker(cluster, tmp_path,
                                                                        monkeypatch, run_cases):
    """The only worker killed mid-run: its case is ``crashed``, the run waits
    ``NO_WORKER_S`` for a worker (none comes) and ends saying so, not that the
    scheduler (still up) was lost; a run on that scheduler, still without a
    worker, waits and says the same, sending nothing."""
    from integrator_bench.harness.errors import BackendLost
    from integrator_bench.harness.run import dask_backend

    monkeypatch.setattr(dask_backend, "NO_WORKER_S", 3.0)
    base = tmp_path / "cluster"
    base.mkdir()
    shutil.copy(cluster["base"] / "sleeper.py", base / "sleeper.py")
    procs, stop = {}, threading.Event()
    try:
        address, workers = _start_cluster(base, ("w3",), procs)
        killer = threading.Thread(target=_kill_when_running,
                                  args=(address, workers["w3"], procs["w3"], stop))
        killer.start()
        with Store(tmp_path / "s.sqlite") as store:
            with pytest.raises(BackendLost, match=r"^no Dask worker at .* for 3 s"):
                run_cases(_cases(),
                          RunContext(store=store, dask=address,
                                     reference_dir=cluster["base"] / "reference", progress=False,
                                     limits=Limits(repeat=1, budget_s=60)))
        stop.set()
        killer.join()
        stored = load(tmp_path / "s.sqlite")
        assert list(stored.status) == ["crashed"], stored[["status", "message"]]
        started = time.monotonic()
        with pytest.raises(BackendLost, match=r"^no Dask worker at .* for 3 s"):
            run_cases(_cases(),
                      RunContext(dask=address, progress=False,
                                 reference_dir=cluster["base"] / "reference",
                                 limits=Limits(repeat=1, budget_s=60)))
        assert time.monotonic() - started >= 3.0
    finally:
        stop.set()
        _stop(procs)


def test_a_worker_that_joins_during_the_wait_runs_the_cases_left(cluster, tmp_path,
                                                                 monkeypatch, run_cases):
    """The only worker killed mid-run, and a new one started once it is gone: the
    run, waiting for a worker (``NO_WORKER_S``, as docs/dask.md promises), sends the
    cases left to the new one and ends with every case recorded, the killed
    worker's case ``crashed``."""
    from integrator_bench.harness.run import dask_backend

    monkeypatch.setattr(dask_backend, "NO_WORKER_S", float(START_S))
    base = tmp_path / "cluster"
    base.mkdir()
    shutil.copy(cluster["base"] / "sleeper.py", base / "sleeper.py")
    procs, stop, threads = {}, threading.Event(), []

    def replace_the_killed_worker():
        while procs["w5"].poll() is None and not stop.is_set():
            time.sleep(0.05)
        if not stop.wait(1.0):   # the run has seen the cluster without a worker
            _start_worker(base, "w6", procs)

    try:
        address, workers = _start_cluster(base, ("w5",), procs)
        threads += [threading.Thread(target=_kill_when_running,
                                     args=(address, workers["w5"], procs["w5"], stop)),
                    threading.Thread(target=replace_the_killed_worker)]
        for thread in threads:
            thread.start()
        cases = _cases()
        df = run_cases(cases,
                       RunContext(dask=address, progress=False,
                                  reference_dir=cluster["base"] / "reference",
                                  limits=Limits(repeat=1, budget_s=60)))
        assert procs["w5"].wait(10) == -signal.SIGKILL and procs["w6"].poll() is None
        assert sorted(df.case_id) == sorted(c.case_id for c in cases)
        assert list(df[df.status == CaseStatus.CRASHED].message) == [
            f"the Dask worker {workers['w5']} running it was lost"]
        assert set(df[df.status != CaseStatus.CRASHED].status) <= {CaseStatus.OK,
                                                                   CaseStatus.FAILED}
    finally:
        stop.set()
        for thread in threads:   # no worker started once the processes are stopped
            thread.join()
        _stop(procs)
