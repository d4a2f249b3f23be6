"""Large matrix runs: isolation, durability, concurrency, provenance, repeats, presets.

The kill-and-resume test kills a real ``ibench run`` with SIGKILL; the Dask
tests run a real LocalCluster of 2 workers (tests/harness/run/test_dask.py).
"""

import json
import math
import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time
from importlib import metadata

import numpy as np
import pytest

from integrator_bench.harness.matrix import provenance, registry
from integrator_bench.harness.matrix.cases import PRESETS, expand
from integrator_bench.harness.run import execution
from integrator_bench.harness.run.execution import execute
from integrator_bench.harness.matrix.record import CaseStatus, FIELDS
from integrator_bench.harness.matrix.store import FORMAT_VERSION, Store, load, load_runs
from integrator_bench.integrators.base import Integrator, Solution
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits

SMALL = "two_mass:c2=1000"


def ibench(*args, **kw):
    return subprocess.run([sys.executable, "-m", "integrator_bench.harness.cli", *args], capture_output=True,
                          text=True, timeout=600, **kw)


# --- isolation ---------------------------------------------------------------------------

def test_memory_limit_turns_a_hog_into_an_error_and_spares_the_rest(broken_integrators,
                                                                    store_path, run_cases):
    cases = expand(problems=[SMALL], integrators=["test-memory-hog", "cvode-bdf"], rtols=[1e-4])
    with Store(store_path) as store:
        df = run_cases(cases,
                       RunContext(store=store, jobs=2, progress=False,
                                  limits=Limits(memory_mb=512)))
    rec = df.set_index("integrator")
    assert rec.loc["cvode-bdf", "status"] == CaseStatus.OK  # a real case runs within the limit
    assert rec.loc["test-memory-hog", "status"] == CaseStatus.ERROR
    assert "out of memory" in rec.loc["test-memory-hog", "message"]
    assert "512 MB" in rec.loc["test-memory-hog", "message"]
    # without the limit the same 8 GiB (never touched) are mapped fine: it is the limit
    unbounded = run_cases(cases[:1], RunContext(progress=False, limits=Limits(memory_mb=None)))
    assert unbounded.status.iloc[0] == CaseStatus.OK


def test_worker_dies_with_the_thread_that_forked_it(broken_integrators):
    """PR_SET_PDEATHSIG: a hanging worker whose runner is gone is killed by the kernel."""
    import threading
    from integrator_bench.harness.run.isolation import Worker
    case = expand(problems=[SMALL], integrators=["test-hangs"], rtols=[1e-3])[0]
    made = []

    def fork_and_leave():
        made.append(Worker(case, limits=Limits(memory_mb=4096)))
        # the worker limits its memory right after it asks for the death signal:
        # once the limit shows, the request is in place and this thread may exit
        limits = f"/proc/{made[0].pid}/limits"
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            with open(limits) as f:
                line = next(x for x in f if x.startswith("Max address space"))
            if line.split()[3] != "unlimited":  # the soft limit
                break
            time.sleep(0.01)

    forker = threading.Thread(target=fork_and_leave)
    forker.start()
    forker.join()  # the forking thread has exited; the worker would hang forever
    worker = made[0]
    worker.join(10)
    try:
        assert worker.exitcode == -signal.SIGKILL
    finally:
        worker.close()


class ThreadProbe(Integrator):
    """Reports, as its failure message, the BLAS/OpenMP threads it runs with."""
    name = "test-thread-probe"
    description = "reports its thread settings (tests only)"
    accepts = frozenset({"ode"})

    def solve(self, system, **kw):
        from threadpoolctl import threadpool_info
        threads = sorted({p["num_threads"] for p in threadpool_info()})
        return Solution(system.t_eval[:1], system.y0[None, :], False,
                        json.dumps({"threads": threads, "omp": os.environ.get("OMP_NUM_THREADS")}))


def test_each_case_runs_with_one_blas_thread(run_cases):
    from threadpoolctl import threadpool_limits
    registry.register(ThreadProbe, origin="tests")
    try:
        cases = expand(problems=[SMALL], integrators=[ThreadProbe.name], rtols=[1e-3])
        with threadpool_limits(2):  # the parent allows more: the worker must still use one
            df = run_cases(cases, RunContext(jobs=1, progress=False))
    finally:
        registry.unregister(ThreadProbe.name)
    seen = json.loads(df.message.iloc[0])
    assert seen == {"threads": [1], "omp": "1"}


def test_unsupported_case_costs_no_process_and_every_worker_is_reaped(broken_integrators,
                                                                      monkeypatch, run_cases):
    """The local pool forks no more workers than it runs at once (each serves
    case after case), none for an unsupported case, and reaps every worker it
    forked by the end."""
    forked = []
    real_fork = os.fork

    def counting_fork():
        pid = real_fork()
        if pid:
            forked.append(pid)
        return pid

    monkeypatch.setattr(os, "fork", counting_fork)
    from integrator_bench.harness.forking import child
    model_forked = []
    real_model_fork = child.fork

    def model_fork(*args, **kw):   # the model's own calls (the fingerprint probe): no worker
        before = len(forked)
        got = real_model_fork(*args, **kw)
        model_forked.extend(forked[before:])
        return got

    monkeypatch.setattr(child, "fork", model_fork)
    cases = expand(problems=[SMALL], integrators=["test-mechanical-only", "scipy-RK45",
                                                  "cvode-bdf"], rtols=[1e-3, 1e-6])
    df = run_cases(cases, RunContext(jobs=2, progress=False))
    run = df[df.status != CaseStatus.UNSUPPORTED]
    assert (df.integrator == "test-mechanical-only").sum() == 2
    assert set(df[df.status == CaseStatus.UNSUPPORTED].integrator) == {"test-mechanical-only"}
    assert len(run) == 4 and set(run.status) == {CaseStatus.OK}
    assert 1 <= len([pid for pid in forked if pid not in model_forked]) <= 2
    for pid in forked:
        with pytest.raises(ChildProcessError):  # reaped: no zombie left behind
            os.waitpid(pid, os.WNOHANG)


# --- repeat ------------------------------------------------------------------------------

def test_repeat_keeps_median_and_minimum_and_counts_of_one_solve(broken_integrators):
    cases = expand(problems=[SMALL], integrators=["cvode-bdf", "test-gives-up"], rtols=[1e-6])
    once = execute(cases[0], repeat=1)
    thrice = execute(cases[0], repeat=3)
    assert once["repeat"] == 1 and once["cpu_s_min"] == once["cpu_s"]
    assert thrice["repeat"] == 3
    assert 0 < thrice["cpu_s_min"] <= thrice["cpu_s"]
    for key in ("nfev", "njev", "nlu", "nsteps", "nreject", "nniter", "nnfail", "scd"):
        assert thrice[key] == once[key], key
    failed = execute(cases[1], repeat=3)  # a failed solve is not timed again
    assert failed["status"] == CaseStatus.FAILED and failed["repeat"] == 1


def test_each_repeat_solves_a_freshly_formulated_system(monkeypatch):
    """A problem with modes keeps its mode in the system it formulates (the
    woodpecker's, an FMU's discrete state): a repeated solve must not start in
    the mode the last one ended in, so each solve gets a system formulated anew."""
    icls = registry.get_integrator("cvode-bdf")
    solved = []
    original = icls.solve

    def solve(self, system, **kw):
        solved.append(system.events[0].reset)     # a closure over the system's mode
        return original(self, system, **kw)
    monkeypatch.setattr(icls, "solve", solve)
    # all three timed solves, however slow the machine (they stop at 0.2 s of CPU)
    monkeypatch.setattr(execution, "MIN_CPU_S", math.inf)
    case = next(c for c in expand(problems=["woodpecker"], integrators=["cvode-bdf"],
                                  rtols=[1e-4]))
    record = execute(case, repeat=3)
    assert record["status"] == CaseStatus.OK and record["repeat"] == 3, record["message"]
    # one solve a sample, the first counted and timed (a reset at the events: through solve)
    n = record["repeat"]
    assert len(solved) == n and len({id(reset) for reset in solved}) == n


# --- durability --------------------------------------------------------------------------

KILL_ARGS = ["run", "-p", SMALL, "-i", "scipy-RK45", "-i", "scipy-RK23", "-i", "cvode-bdf",
             "--rtol", "1e-3", "1e-4", "1e-5", "1e-6", "1e-7", "1e-8", "1e-9", "1e-10",
             "--jobs", "2", "--json"]
N_KILL_CASES = 24  # about 5 s on an idle machine: long enough to be killed mid-run


def _survivors(marker: str) -> list[int]:
    """Pids of processes whose command line names ``marker`` (the store path)."""
    found = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                if marker.encode() in f.read():
                    found.append(int(pid))
        except OSError:
            pass
    return found


def _killed_run(args, marker, after_lines=None, after_s=None):
    """Start ``ibench`` with ``args``; SIGKILL it after some JSON lines or seconds.

    Returns the records it printed (each printed only after its commit). Its
    temporary directory is the marker's folder: a killed command cannot remove
    its FMU extraction folder, which must not be left in the system's.
    """
    env = {**os.environ, "TMPDIR": os.path.dirname(marker)}
    proc = subprocess.Popen([sys.executable, "-m", "integrator_bench.harness.cli", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                            env=env)
    printed = []
    if after_lines:
        while len(printed) < after_lines:
            line = proc.stdout.readline()
            assert line, "the run ended before it could be killed"
            printed.append(json.loads(line))
    else:
        time.sleep(after_s)
    if proc.poll() is not None:
        pytest.fail("the run finished before it could be killed: lengthen its matrix")
    proc.send_signal(signal.SIGKILL)
    rest, _ = proc.communicate(timeout=60)
    printed += [json.loads(line) for line in rest.splitlines() if line.strip()]
    assert proc.returncode == -signal.SIGKILL
    deadline = time.monotonic() + 10  # its workers die with it (PR_SET_PDEATHSIG)
    while _survivors(marker) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _survivors(marker), "worker processes outlived the killed run"
    return printed


def test_sigkilled_run_resumes_to_every_case_exactly_once(store_path):
    args = KILL_ARGS + ["--store", str(store_path)]
    printed = _killed_run(args, str(store_path), after_lines=2)
    printed += _killed_run(args + ["--resume"], str(store_path), after_s=1.5)  # anywhere
    with sqlite3.connect(store_path) as db:
        assert db.execute("PRAGMA integrity_check").fetchone() == ("ok",)
    stored = load(store_path)
    assert stored.case_id.is_unique
    # nothing printed (so committed) was lost, and it was kept as it was, not redone
    kept = stored.set_index("case_id")
    for rec in printed:
        assert kept.loc[rec["case_id"], "created"] == rec["created"]
        assert kept.loc[rec["case_id"], "run_id"] == rec["run_id"]
    r = ibench(*args, "--resume")
    assert r.returncode == 0, r.stderr
    stored = load(store_path)
    assert len(stored) == N_KILL_CASES and stored.case_id.is_unique
    assert (stored.status == CaseStatus.OK).all()
    runs = load_runs(store_path)
    assert len(runs) in (2, 3)  # the second kill may come before that run began
    assert runs.finished.iloc[:-1].isna().all()  # killed runs: no finish time
    assert runs.status.iloc[-1] == "finished"
    assert set(stored.run_id) <= set(runs.run_id)


_WRITER = textwrap.dedent("""
    import sys, time
    from integrator_bench.harness.matrix.store import Store
    path, tag, n, once, start = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4] == "1", float(sys.argv[5])
    while time.time() < start:
        time.sleep(0.001)
    with Store(path) as store:
        stored = sum(store.add({"case_id": f"{'same' if once else tag}-{i}", "problem": tag,
                                "code_version": "v", "status": "ok"}, once=once)
                     for i in range(n))
    print(stored)
""")


def test_store_set_up_retries_when_sqlite_refuses_to_wait(store_path, monkeypatch):
    """SQLite answers "database is locked" at once, not after the busy timeout, when
    two processes opening a new store would deadlock (seen in CI as a flaky
    test_two_processes_writing_one_new_store). Opening must retry, not give up."""
    import integrator_bench.harness.matrix.store as store_module

    class Refusing:
        def __init__(self, db):
            self.db, self.refusals = db, 2

        def execute(self, sql, *args):
            if sql.startswith(("PRAGMA journal_mode", "BEGIN IMMEDIATE")) and self.refusals:
                self.refusals -= 1
                raise sqlite3.OperationalError("database is locked")
            return self.db.execute(sql, *args)

        def __getattr__(self, name):
            return getattr(self.db, name)

    connect = sqlite3.connect
    monkeypatch.setattr(store_module.sqlite3, "connect",
                        lambda *a, **k: Refusing(connect(*a, **k)))
    store = Store(store_path)
    assert store.db.refusals == 0
    assert "records" in {r[0] for r in store.db.execute(
        "SELECT name FROM sqlite_master WHERE type='table'")}


def test_store_commits_without_a_disk_flush_and_keeps_them_when_killed(store_path):
    """A commit does not wait for the disk (WAL with synchronous NORMAL, not FULL),
    yet every committed record survives its process dying without closing the store."""
    writer = ("import os, sys\n"
              "from integrator_bench.harness.matrix.store import Store\n"
              "store = Store(sys.argv[1])\n"
              "print(store.db.execute('PRAGMA synchronous').fetchone()[0], flush=True)\n"
              "for i in range(5):\n"
              "    store.add({'case_id': f'c{i}', 'problem': 'p', 'status': 'ok'})\n"
              "os._exit(0)\n")
    done = subprocess.run([sys.executable, "-c", writer, str(store_path)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["1"]            # 1: NORMAL (2 would be FULL)
    assert sorted(load(store_path).case_id) == [f"c{i}" for i in range(5)]


@pytest.mark.parametrize("once", [False, True])
def test_two_processes_writing_one_new_store(store_path, once):
    """Both create the store and insert at the same moment: nothing lost or corrupted;
    with ``once`` (resume) a case both write is stored once."""
    start = time.time() + 1.0
    procs = [subprocess.Popen([sys.executable, "-c", _WRITER, str(store_path), tag, "300",
                               "1" if once else "0", str(start)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for tag in ("a", "b")]
    outs = [p.communicate(timeout=120) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1] for o in outs]
    counts = [int(o[0]) for o in outs]
    with sqlite3.connect(store_path) as db:
        assert db.execute("PRAGMA integrity_check").fetchone() == ("ok",)
        assert db.execute("PRAGMA journal_mode").fetchone() == ("wal",)
    stored = load(store_path)
    if once:
        assert sum(counts) == 300 and len(stored) == 300 and stored.case_id.is_unique
    else:
        assert counts == [300, 300] and len(stored) == 600
        assert (stored.problem.value_counts() == 300).all()


def test_older_store_is_read_as_it_is_and_upgraded_in_place_by_a_run(tmp_path):
    """A format-1 store (no runs table, no run_id) reads with the new columns null and
    is left as it was; a writer (a run) upgrades it: it gains the columns, keeps its rows."""
    path = tmp_path / "old.sqlite"
    new_fields = ("run_id", "cpu_s_min", "repeat", "cpu_s_iqr", "timing", "timing_mismatch")
    old_fields = [f for f in FIELDS if f not in new_fields]
    with sqlite3.connect(path) as db:
        db.execute("CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT)")
        db.executemany("INSERT INTO meta VALUES (?, ?)",
                       [("format", "integrator-bench-store"), ("version", "1")])
        db.execute(f"CREATE TABLE records (id INTEGER PRIMARY KEY AUTOINCREMENT, "
                   f"{', '.join(old_fields)})")
        db.execute("INSERT INTO records (case_id, problem, status, code_version) "
                   "VALUES ('x', 'two_mass', 'ok', 'old')")
    before = path.read_bytes()
    df = load(path)
    assert list(df.columns) == list(FIELDS)
    assert len(df) == 1 and df.case_id.iloc[0] == "x" and df[list(new_fields)].isna().all().all()
    assert len(load_runs(path)) == 0
    assert path.read_bytes() == before      # a reader writes nothing
    Store(path).close()
    with sqlite3.connect(path) as db:
        assert dict(db.execute("SELECT key, value FROM meta"))["version"] == str(FORMAT_VERSION)
    assert load(path).equals(df)
    out = tmp_path / "report"
    assert ibench("report", "--store", str(path), "--out", str(out)).returncode == 0
    assert "No run provenance stored" in (out / "index.md").read_text()


def test_readers_open_a_store_read_only_and_report_a_read_only_file(tmp_path):
    """``load``, ``load_runs`` and ``ibench report`` only read: the store's bytes stay
    as they were, a write through a reader's connection is refused, and a store
    whose file is read-only is reported."""
    path = tmp_path / "s.sqlite"
    with Store(path) as store:
        store.add({"case_id": "x", "problem": "two_mass", "status": "ok",
                   "code_version": "v"})
    path.chmod(0o444)
    before = path.read_bytes()
    reader = Store(path, create=False)
    with pytest.raises(sqlite3.OperationalError, match="readonly"):
        reader.db.execute("CREATE TABLE written (a)")
    reader.close()
    assert len(load(path)) == 1 and len(load_runs(path)) == 0
    out = tmp_path / "report"
    r = ibench("report", "--store", str(path), "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert (out / "index.html").exists() and path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.glob("s.sqlite*")) == ["s.sqlite"]   # no -wal


# --- provenance --------------------------------------------------------------------------

def test_run_stores_provenance_and_report_shows_it(tmp_path):
    store = tmp_path / "s.sqlite"
    r = ibench("run", "-p", SMALL, "-i", "cvode-bdf", "--rtol", "1e-4", "1e-6", "--repeat", "3",
               "--store", str(store), "--json")
    assert r.returncode == 0, r.stderr
    records = [json.loads(line) for line in r.stdout.splitlines()]
    assert all(rec["repeat"] == 3 and rec["cpu_s_min"] <= rec["cpu_s"] for rec in records)
    runs = load_runs(store)
    assert len(runs) == 1
    run = runs.iloc[0]
    assert {rec["run_id"] for rec in records} == set(load(store).run_id) == {run.run_id}
    assert run.status == "finished" and run.finished >= run.started
    assert run.code_version == records[0]["code_version"]
    versions = json.loads(run.versions)
    for name in ("numpy", "scipy", "scikit-sundae", "fmpy"):
        assert versions[name] == provenance.package_version(name)  # fmpy: null when absent
    assert versions["numpy"] == metadata.version("numpy")
    assert versions["plugins"] == provenance.plugin_versions()
    with open("/proc/cpuinfo") as f:
        model = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    assert run.cpu_model == model
    assert run.host == os.uname().nodename
    threads = json.loads(run.threads)
    assert threads["blas_threads_per_worker"] == 1 and "OMP_NUM_THREADS" in threads["env"]
    assert "--repeat 3" in run.command
    assert json.loads(run.backend) == {"kind": "local", "jobs": os.cpu_count()}
    assert json.loads(run.options)["repeat"] == 3
    out = tmp_path / "report"
    assert ibench("report", "--store", str(store), "--out", str(out)).returncode == 0
    index = (out / "index.md").read_text()
    assert "## Runs (provenance)" in index
    for text in (run.run_id, run.code_version, model, versions["numpy"], versions["scipy"],
                 versions["scikit-sundae"], "--repeat 3"):
        assert text in index


# --- bad input ---------------------------------------------------------------------------

@pytest.mark.parametrize("args, needle", [
    (["--repeat", "0"], "--repeat '0' must be at least 1"),
    (["--repeat", "two"], "--repeat 'two' is not a whole number"),
    (["--memory", "-1"], "--memory '-1' must be a positive"),
    (["--jobs", "0"], "--jobs '0' must be at least 1"),
    (["--dask", "nonsense"], "--dask 'nonsense' is neither tcp://HOST:PORT"),
    (["--dask", "local:0"], "--dask 'local:0' is neither"),
    (["--dask", "tcp://127.0.0.1:99999"], "is neither"),
    (["--dask", "local:2", "--jobs", "2"], "not allowed with argument"),
    (["--rtol=-1e-6"], "--rtol '-1e-6' must be a positive"),
    (["--timeout=-1e-3"], "--timeout '-1e-3' must be a positive"),
])
def test_bad_run_options_exit_2_and_write_nothing(args, needle, tmp_path):
    store = tmp_path / "s.sqlite"
    r = ibench("run", "-p", SMALL, "-i", "cvode-bdf", *args, "--store", str(store))
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], r.stderr
    assert list(tmp_path.iterdir()) == []


def test_unreachable_dask_scheduler_exits_2_and_writes_nothing(tmp_path):
    import socket
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    r = ibench("run", "-p", SMALL, "-i", "cvode-bdf", "--dask", f"tcp://127.0.0.1:{port}",
               "--store", str(tmp_path / "s.sqlite"))
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "cannot reach the Dask scheduler" in lines[0], r.stderr
    assert list(tmp_path.iterdir()) == []


def _store_like(folder, records=None, version=None):
    """A real store (format 2, WAL) with another ``records`` table or version."""
    path = folder / "store.sqlite"
    Store(path).close()
    db = sqlite3.connect(path, isolation_level=None)
    if records:
        db.execute("DROP TABLE records")
        db.execute(f"CREATE TABLE records ({records})")
    if version:
        db.execute("UPDATE meta SET value = ? WHERE key = 'version'", (version,))
    db.execute("PRAGMA journal_mode=DELETE")   # so that a switch to WAL would show
    db.close()
    return path


def _foreign(tmp_path):
    path = tmp_path / "other.sqlite"
    with sqlite3.connect(path) as db:
        db.execute("CREATE TABLE x (a)")
    return path


@pytest.mark.parametrize("make, needle", [
    (lambda d: d / "missing" / "s.sqlite", "does not exist"),
    (lambda d: (d / "file").write_text("x") and d / "file" / "s.sqlite", "does not exist"),
    (lambda d: (d / "dir.sqlite").mkdir() or d / "dir.sqlite", "is not a file"),
    (lambda d: (d / "garbage.sqlite").write_bytes(b"garbage" * 200) and d / "garbage.sqlite",
     "not a readable SQLite file"),
    (_foreign, "another program"),
    (lambda d: _store_like(d, records="x TEXT"),
     "has a records table that is not integrator-bench's (no column id, case_id, "
     "code_version)"),
    (lambda d: _store_like(d, version="99"), "was written by a newer integrator-bench"),
], ids=["missing-dir", "under-a-file", "directory", "garbage", "foreign", "other-records",
        "newer"])
@pytest.mark.parametrize("command", ["run", "report"])
def test_bad_store_exits_2_and_is_left_untouched(make, needle, command, tmp_path):
    path = make(tmp_path)
    before = {p: (p.stat().st_mtime_ns, p.read_bytes() if p.is_file() else None)
              for p in tmp_path.rglob("*")}
    args = ["run", "-p", SMALL, "-i", "cvode-bdf"] if command == "run" else ["report"]
    r = ibench(*args, "--store", str(path))
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], r.stderr
    after = {p: (p.stat().st_mtime_ns, p.read_bytes() if p.is_file() else None)
             for p in tmp_path.rglob("*")}
    assert after == before  # nothing created, nothing changed (no -wal, no report)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes to read-only directories anyway")
def test_store_in_read_only_directory_exits_2(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    r = ibench("run", "-p", SMALL, "-i", "cvode-bdf", "--store", str(ro / "s.sqlite"))
    assert r.returncode == 2 and "not writable" in r.stderr
    assert list(ro.iterdir()) == []


# --- the full preset ---------------------------------------------------------------------

@pytest.mark.parametrize("name", list(registry.integrators()))
def test_full_preset_covers_every_problem_formulation_and_ladder(name):
    cases = [c for c in expand(preset="full") if c.integrator == name]
    icls = registry.integrators()[name]
    for pname, pcls in registry.problems().items():
        mine = [c for c in cases if c.problem == pname]
        for params in pcls.benchmark_parameters:
            full = tuple(sorted(pcls(**params).params.items()))
            assert {c.formulation for c in mine if c.params == full} == set(pcls.formulations)
            for form in pcls.formulations:
                here = [c for c in mine if c.formulation == form and c.params == full]
                rtols = sorted({c.rtol for c in here if c.rtol is not None})
                hs = {c.h for c in here if c.h is not None}
                # the rtol ladder when it is adaptive, the h ladder when it takes a step
                assert rtols == (sorted(PRESETS["full"].rtol) if icls.adaptive else [])
                if icls.adaptive:  # three decades each side of the report's 1e-5
                    assert min(rtols) == pytest.approx(1e-8)
                    assert max(rtols) == pytest.approx(1e-2)
                assert len(hs) == (len(PRESETS["full"].h_per_span) if icls.takes_h() else 0)
    assert len({c.case_id for c in cases}) == len(cases)


def test_quick_preset_leaves_out_large_problems_unless_named():
    """A bare quick run covers the problems of at most ``max_dimension`` states
    (its first parameter set) and names the others; ``-p`` runs any of them."""
    from integrator_bench.harness.matrix.cases import left_out

    limit = PRESETS["quick"].max_dimension
    large = left_out("quick")
    for name, cls in registry.problems().items():
        assert (name in large) == (cls(**cls.benchmark_parameters[0]).dimension > limit), name
    bare = {c.problem for c in expand(preset="quick")}
    assert not bare & set(large)
    assert set(registry.problems()) - set(large) <= bare
    for name in large:
        assert {c.problem for c in expand(problems=[name], preset="quick")} == {name}
    assert left_out("full") == []
