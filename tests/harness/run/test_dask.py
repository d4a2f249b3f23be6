"""The Dask backend on a real LocalCluster of 2 workers.

Dask workers are fresh processes: they know the integrators of the installed
entry points only, not the tests' runtime-registered broken ones (see
harness/run/dask_backend.py), so these tests use built-in integrators and check
that a runtime-only one becomes an honest ``error`` record.
"""

import hashlib
import json
import subprocess
import sys

import pandas as pd
import pytest

from integrator_bench.harness.run import shipping
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.errors import BadInput, WorkerMismatch
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.harness.matrix.store import Store, load, load_runs
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits

distributed = pytest.importorskip("distributed")

SMALL = "two_mass:c2=1000"
# code_version is left out: each Dask worker reads it from git when it starts, and
# other commits may land in between (the run's provenance lists each worker's)
COMPARED = ["case_id", "status", "nfev", "njev", "nlu", "nsteps", "nreject", "nniter",
            "nnfail", "scd", "mescd"]


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None, silence_logs=40) as cluster, \
            distributed.Client(cluster) as c:
        yield c


def test_dask_gives_the_records_of_the_local_runner(client, store_path, run_cases):
    cases = expand(problems=[SMALL], integrators=["cvode-bdf", "scipy-RK45", "ida"],
                   rtols=[1e-3, 1e-6])
    local = run_cases(cases, RunContext(jobs=2, progress=False))
    with Store(store_path) as store:
        on_dask = run_cases(cases,
                            RunContext(store=store, dask=client, progress=False,
                                       limits=Limits(repeat=2)))
    key = lambda df: df[COMPARED].sort_values("case_id").reset_index(drop=True)  # noqa: E731
    assert key(on_dask).equals(key(local))
    # at most the two samples asked for: a case stops sampling at 0.2 s of CPU
    assert on_dask.repeat.between(1, 2).all() and (on_dask.repeat == 2).any()
    stored = load(store_path)
    assert sorted(stored.case_id) == sorted(c.case_id for c in cases)
    run = load_runs(store_path).iloc[0]
    backend = json.loads(run.backend)
    assert backend["kind"] == "dask" and len(backend["workers"]) == 2
    assert all(w["nthreads"] == 1 and w["cpu_model"] for w in backend["workers"])
    assert set(stored.run_id) == {run.run_id} and run.status == "finished"


def test_dask_task_is_isolated_by_the_same_timeout(client, run_cases):
    case = expand(problems=[SMALL], integrators=["scipy-RK23"], rtols=[1e-8])
    df = run_cases(case, RunContext(dask=client, progress=False, limits=Limits(budget_s=0.05)))
    assert df.status.iloc[0] == CaseStatus.TIMEOUT
    # killed past the budget's backstop, or its solve over the budget of CPU: either way
    # the task's worker had the run's budget
    message, reason = df.message.iloc[0], df.reason.iloc[0]
    assert ((reason == "timeout" and "budget 0.05 s" in message)
            or (reason == "over_budget" and "budget of 0.05 s" in message)), message


def test_runtime_registered_integrator_is_an_error_on_dask(client, broken_integrators, run_cases):
    cases = expand(problems=[SMALL], integrators=["test-raises", "cvode-bdf"], rtols=[1e-3])
    df = run_cases(cases, RunContext(dask=client, progress=False)).set_index("integrator")
    assert df.loc["cvode-bdf", "status"] == CaseStatus.OK
    assert df.loc["test-raises", "status"] == CaseStatus.ERROR
    assert "unknown integrator 'test-raises'" in df.loc["test-raises", "message"]


def test_cli_dask_local_cluster(tmp_path):
    store = tmp_path / "s.sqlite"
    r = subprocess.run([sys.executable, "-m", "integrator_bench.harness.cli", "run", "-p", SMALL, "-i",
                        "cvode-bdf", "--rtol", "1e-3", "1e-5", "--dask", "local:2", "--json",
                        "--store", str(store)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    printed = [json.loads(line) for line in r.stdout.splitlines()]
    assert len(printed) == 2 and all(rec["status"] == CaseStatus.OK for rec in printed)
    run = load_runs(store).iloc[0]
    assert json.loads(run.backend)["kind"] == "dask" and "--dask local:2" in run.command
    assert len(load(store)) == 2


class _Counting:
    """A Dask client that counts the tasks submitted through it."""

    def __init__(self, client):
        self.client, self.submitted = client, []

    def submit(self, fn, case, *args, **kw):
        self.submitted.append(case.integrator)
        return self.client.submit(fn, case, *args, **kw)

    def __getattr__(self, name):
        return getattr(self.client, name)


def test_unsupported_case_costs_no_dask_task(client, broken_integrators, run_cases):
    cases = expand(problems=[SMALL], integrators=["test-mechanical-only", "cvode-bdf"],
                   rtols=[1e-3])
    counting = _Counting(client)
    df = run_cases(cases, RunContext(dask=counting, progress=False)).set_index("integrator")
    assert counting.submitted == ["cvode-bdf"]
    assert df.loc["test-mechanical-only", "status"] == CaseStatus.UNSUPPORTED
    assert df.loc["test-mechanical-only", "reason"] == "unsupported"
    assert df.loc["cvode-bdf", "status"] == CaseStatus.OK and pd.isna(df.loc["cvode-bdf", "reason"])


def test_dask_holds_a_lines_next_case_until_its_previous_record(client, run_cases):
    """Each line runs loose to tight on Dask too: a case is dispatched only after
    the record of its line's previous case came back."""

    cases = expand(problems=[SMALL], integrators=["scipy-RK45", "scipy-Radau"],
                   rtols=[1e-3, 1e-5, 1e-7])
    events = []
    run_cases(cases, RunContext(dask=client, progress=False),
              on_dispatch=lambda c: events.append(("dispatch", c.case_id)),
              on_record=lambda r: events.append(("record", r["case_id"])))
    by_id = {c.case_id: c for c in cases}
    seen = {}
    for kind, cid in events:
        key = by_id[cid].line
        if kind == "dispatch":
            prev = seen.get(key)
            assert prev is None or prev[1] == "record", "dispatched before its line's record"
            assert prev is None or by_id[prev[0]].rtol > by_id[cid].rtol  # loose to tight
        seen[key] = (cid, kind)
    assert sum(k == "record" for k, _ in events) == len(cases)


def _pretend_installation(client, change):
    """Have every worker report its installation with ``change`` applied (None: as it is)."""
    def patch():
        from integrator_bench.harness.matrix import provenance
        real = getattr(provenance, "real_installation", provenance.installation)
        provenance.real_installation = real
        provenance.installation = real if change is None else (lambda: {**real(), **change})
    client.run(patch)


def test_a_worker_of_another_installation_runs_no_case(client, store_path, run_cases):
    cases = expand(problems=[SMALL], integrators=["cvode-bdf"], rtols=[1e-3, 1e-5])
    _pretend_installation(client, {"code_version": "0123456789ab"})
    try:
        with Store(store_path) as store, pytest.raises(
                BadInput, match=r"Dask worker tcp://\S+ runs another installation than the "
                r"client: code_version 0123456789ab \(here \w+"):
            run_cases(cases, RunContext(store=store, dask=client, progress=False))
        assert load_runs(store_path).empty and load(store_path).empty  # refused at connect
    finally:
        _pretend_installation(client, None)
    # one that joins after the check: its first task raises, before the case runs
    dispatched = []

    def on_dispatch(case):
        if not dispatched:
            _pretend_installation(client, {"python": "2.7.18"})
        dispatched.append(case)
    try:
        with Store(store_path) as store, pytest.raises(
                WorkerMismatch, match=r"python 2\.7\.18 \(here 3\..*joined after the run"):
            run_cases(cases, RunContext(store=store, dask=client, progress=False),
                      on_dispatch=on_dispatch)
    finally:
        _pretend_installation(client, None)
    assert load(store_path).empty and load_runs(store_path).status.tolist() == ["failed"]


def test_a_shipped_file_is_written_once_and_checked(tmp_path, monkeypatch):
    monkeypatch.setattr(shipping, "_local_directory", lambda: str(tmp_path))
    data = b"PK not really an FMU"
    sha = hashlib.sha256(data).hexdigest()
    case = expand(problems=[SMALL], integrators=["cvode-bdf"], rtols=[1e-3])[0]
    shipped = shipping.unpack(case, [("c2", sha, ".fmu", data)])  # any parameter will do
    copy = tmp_path / shipping.FILES_DIR / f"{sha}.fmu"
    assert shipped.params_dict["c2"] == str(copy) and copy.read_bytes() == data
    copy.write_bytes(b"kept")  # there already: not written again
    assert shipping.local_copy(sha, ".fmu", data) == copy and copy.read_bytes() == b"kept"
    with pytest.raises(ValueError, match="does not match its SHA-256"):
        shipping.local_copy("0" * 64, ".fmu", data)
    record = shipping.as_client_sees({"case_id": "x", "params": "y"}, case)
    assert (record["case_id"], record["params"]) == (case.case_id, case.params_json)


class _Scatters:
    """Stands in for a Dask client: scatter gives back what it was given."""

    def scatter(self, data, hash=True):
        return data


def test_a_case_whose_file_is_gone_takes_no_file_and_says_why(tmp_path):
    from integrator_bench.harness.matrix.cases import Case

    data = tmp_path / "m.fmu"
    data.write_bytes(b"bytes")
    case = Case("fmu", (("path", str(data)),), "ode", "cvode-bdf", 1e-3)
    packer = shipping.Packer(_Scatters())
    handed, files = packer.pack(case)
    assert [f[:3] for f in files] == [("path", hashlib.sha256(b"bytes").hexdigest(), ".fmu")]
    assert handed.reference is None and "could not build the problem" in handed.why
    data.unlink()
    assert shipping.Packer(_Scatters()).pack(case)[1] == []  # the worker names it missing


def _kept_worker_pid():
    """The pid of the case worker this Dask executor thread keeps (None: none yet)."""
    from integrator_bench.harness.run import dask_backend
    run = getattr(dask_backend._kept, "run", None)
    return None if run is None or run.worker is None else run.worker.pid


def test_a_dask_worker_keeps_its_case_worker_from_task_to_task(store_path, run_cases):
    """One forked case worker serves a Dask worker's cases, as the local pool's do
    (a fork per task counted its copy-on-write faults in each case's CPU), and
    each case is measured against the reference handed with it, whatever problem
    came before it in that worker."""
    cases = expand(problems=[SMALL, "pendulum"], integrators=["cvode-bdf", "scipy-RK45"],
                   rtols=[1e-3, 1e-5])
    local = run_cases(cases, RunContext(jobs=1, progress=False))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=None, silence_logs=40) as cluster, \
            distributed.Client(cluster) as c:
        assert c.submit(_kept_worker_pid, pure=False).result() is None
        first = run_cases(cases[:1], RunContext(dask=c, progress=False))
        pid = c.submit(_kept_worker_pid, pure=False).result()
        on_dask = run_cases(cases, RunContext(dask=c, progress=False))
        assert pid is not None and c.submit(_kept_worker_pid, pure=False).result() == pid
    assert first.status.iloc[0] == CaseStatus.OK
    key = lambda df: df[COMPARED].sort_values("case_id").reset_index(drop=True)  # noqa: E731
    assert key(on_dask).equals(key(local))
    ran = on_dask[on_dask.status != CaseStatus.UNSUPPORTED]
    assert set(ran.problem) == {"two_mass", "pendulum"}
    assert (ran.status == CaseStatus.OK).all() and ran.mescd.notna().all()


def test_local_cluster_workers_keep_the_clients_malloc(monkeypatch):
    """Dask's nanny sets MALLOC_TRIM_THRESHOLD_ in its workers, which makes glibc map
    every large array afresh (system CPU in each case's budget); ``--dask local:N``
    starts its workers without it, and the backend's provenance says so."""
    import os

    from integrator_bench.harness.run import dask_backend

    # a LocalCluster started with Dask's defaults sets it in its creator's environment too
    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)
    with dask_backend.connect("local:1") as client:
        env = client.run(os.environ.get, "MALLOC_TRIM_THRESHOLD_")
        facts = dask_backend.describe(client)
    assert list(env.values()) == [None]
    assert [w["malloc"] for w in facts["workers"]] == [{}]
