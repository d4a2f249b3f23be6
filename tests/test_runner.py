"""The runner: every status, durability, resume, and counting."""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest

from integrator_bench.harness import registry
from integrator_bench.harness.cases import expand
from integrator_bench.harness.record import FIELDS
from integrator_bench.harness.runner import execute, run_matrix
from integrator_bench.harness.store import Store, StoreError, load

SMALL = "two_mass:c2=1000"


def test_every_failure_status_is_a_record(broken_integrators, store_path):
    cases = expand(problems=[SMALL], integrators=list(broken_integrators) + ["scipy-RK45"],
                   rtols=[1e-3])
    with Store(store_path) as store:
        df = run_matrix(cases, store=store, jobs=2, timeout=10, progress=False)
    status = dict(zip(df.integrator, df.status))
    assert status == {"test-raises": "error", "test-gives-up": "failed", "test-nan": "failed",
                      "test-hangs": "timeout", "test-segfault": "crashed",
                      "test-memory-hog": "error", "test-overflow": "failed",
                      "test-mechanical-only": "unsupported", "scipy-RK45": "ok"}
    msg = dict(zip(df.integrator, df.message))
    assert "deliberate failure" in msg["test-raises"]
    assert "step size too small" in msg["test-gives-up"]
    assert "non-finite" in msg["test-nan"]
    assert "SIGSEGV" in msg["test-segfault"]
    assert "diverged" in msg["test-overflow"] and "OverflowError" in msg["test-overflow"]
    assert "10 s" in msg["test-hangs"]
    assert "out of memory" in msg["test-memory-hog"] and "MemoryError" in msg["test-memory-hog"]
    assert df.loc[df.status != "ok", "message"].notna().all()
    assert df.loc[df.status == "ok", "message"].isna().all()
    stored = load(store_path)
    assert len(stored) == len(cases)
    assert list(stored.columns) == list(FIELDS)
    gives_up = stored[stored.integrator == "test-gives-up"].iloc[0]
    assert gives_up.nfev == 1 and gives_up.nsteps == 0 and pd.isna(gives_up.nlu)


@pytest.mark.parametrize("name", list(registry.integrators()))
def test_registered_integrator_runs_and_counts_honestly(name):
    """Every live integrator: ok on a stiff linear problem, counts consistent."""
    case = next(iter(expand(problems=[SMALL], integrators=[name], rtols=[1e-6], hs=[1e-3])))
    if case.unsupported and registry.get_integrator(name).accepts == {"mechanical"}:
        pytest.skip("takes only the mechanical form: run on the i3 pendulum in "
                    "tests/test_alpha_methods.py::test_runs_in_the_matrix_on_the_i3_pendulum")
    record = execute(case)
    assert record["status"] == "ok", record["message"]
    icls = registry.get_integrator(name)
    # h = 1e-3 over [0, 10]: a first-order fixed-step method is only about 1e-2 accurate
    assert record["scd"] > (1 if not icls.adaptive and icls.order == 1 else 3)
    assert record["nfev"] > 0 and record["cpu_s"] > 0
    counts = record["solver_counts"]
    if "nfev" in counts:
        # the harness counts finite-difference calls too: never fewer than reported
        assert record["nfev"] >= counts["nfev"]
    for key in ("nsteps", "nlu", "nreject", "nniter", "nnfail"):
        assert record[key] == counts.get(key)


def test_store_refuses_foreign_and_garbage_files(tmp_path):
    import sqlite3
    other = tmp_path / "other.sqlite"
    sqlite3.connect(other).execute("CREATE TABLE x (a)").connection.commit()
    with pytest.raises(StoreError, match="another program"):
        Store(other)
    garbage = tmp_path / "garbage.sqlite"
    garbage.write_bytes(b"not a database at all" * 100)
    with pytest.raises(StoreError, match="not a readable SQLite"):
        Store(garbage)


def test_resume_skips_stored_cases(store_path):
    cases = expand(problems=[SMALL], integrators=["scipy-RK45", "cvode-bdf"], rtols=[1e-3, 1e-5])
    with Store(store_path) as store:
        run_matrix(cases[:2], store=store, jobs=1, progress=False)
        df = run_matrix(cases, store=store, jobs=1, resume=True, progress=False)
    assert len(df) == len(cases)
    stored = load(store_path)
    assert sorted(stored.case_id) == sorted(c.case_id for c in cases)


def test_interrupted_run_resumes_without_loss_or_duplicates(store_path):
    """Interrupt a real `ibench run` with SIGINT, then finish it with --resume."""
    args = [sys.executable, "-m", "integrator_bench.harness.cli", "run", "-p", SMALL, "-i", "scipy-RK45",
            "-i", "scipy-RK23", "-i", "cvode-bdf", "--rtol", "1e-3", "1e-4", "1e-5", "1e-6",
            "--jobs", "1", "--store", str(store_path), "--json"]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    first = proc.stdout.readline()          # one case finished and stored
    assert json.loads(first)["status"] == "ok"
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "--resume" in err
    done_before = len(load(store_path))
    assert 1 <= done_before < 12
    subprocess.run(args + ["--resume"], check=True, capture_output=True, timeout=300)
    stored = load(store_path)
    assert len(stored) == 12
    assert stored.case_id.is_unique
