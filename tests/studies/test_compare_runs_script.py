"""studies/compare_runs.py: two stores of one matrix compared case by case."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "studies" / "compare_runs.py"
sys.path.insert(0, str(ROOT / "studies"))
import compare_runs  # noqa: E402


def run(*args, **kw):
    return subprocess.run([sys.executable, *map(str, args)], capture_output=True, text=True,
                          timeout=300, **kw)


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("compare")
    path = tmp / "a.sqlite"
    env = {**os.environ, "IBENCH_DATA_DIR": str(tmp / "data"),
           "IBENCH_REFERENCE_DIR": str(ROOT / "results" / "reference")}
    r = run(Path(sys.executable).parent / "ibench", "run", "-p", "spring_pendulum", "-i", "scipy-RK45",
            "-i", "rk4", "--store", path, env=env)
    assert r.returncode == 0, r.stderr
    return path


def test_a_store_against_itself_is_identical(store):
    r = run(SCRIPT, store, store)
    assert r.returncode == 0, r.stderr
    rows = [line for line in r.stdout.splitlines() if line.startswith("| rk4") or
            line.startswith("| scipy-RK45")]
    assert len(rows) == 2
    for line in rows:
        cells = [c.strip() for c in line.strip("|").split("|")]
        n = cells[4].split("/")
        assert n[0] == n[1] != "0"                  # every ok case has the same counts
        assert cells[5:8] == ["1", "1", "0"]        # ratios 1, no change of scd
    assert "only before: 0; only after: 0" in r.stdout


def test_changed_counts_renames_and_missing_cases(store):
    before = compare_runs._load(store)
    after = before.copy()
    rk4 = after.integrator == "rk4"
    after.loc[rk4, "nfev"] *= 2
    after.loc[rk4, "scd"] += 0.5
    before.loc[before.integrator == "scipy-RK45", "integrator"] = "old-RK45"
    after = after.drop(after.index[after.integrator == "scipy-RK45"][:1])
    table, only_b, only_a = compare_runs.compare(before, after, {"old-RK45": "scipy-RK45"})
    row = table.set_index("integrator").loc["rk4"]
    assert row["nfev after/before"] == 2 and row["max |d scd|"] == pytest.approx(0.5)
    assert row["counts identical"].startswith("0/")
    assert "scipy-RK45" in set(table.integrator) and (only_b, only_a) == (1, 0)


@pytest.mark.parametrize("args, word", [(["/nonexistent.sqlite", "x"], "/nonexistent.sqlite"),
                                        (["STORE", "STORE", "--rename", "hht"], "'hht'")])
def test_bad_input_exits_2_with_one_line(store, args, word):
    r = run(SCRIPT, *[store if a == "STORE" else a for a in args])
    assert r.returncode == 2 and word in r.stderr and len(r.stderr.strip().splitlines()) == 1
