"""studies/overhead.py: its figures, its verdict and its manners (the targets
themselves are measured by running it, not here: timings flake in tests)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "studies" / "overhead.py"


def run(*args):
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True,
                          timeout=600)


def test_reports_the_overhead_and_forks_none_for_unsupported_cases():
    # rk4 is fixed-step (rtol is unsupported for it); scipy-RK45 takes no h: both unsupported
    r = run("-p", "pendulum", "-f", "ode", "-i", "rk4", "-i", "scipy-RK45", "--h", "0.01",
            "--rtol", "1e-4", "--jobs", "1", "--max-ms", "1e6")
    assert r.returncode == 0, r.stderr
    assert "overhead per case run (ms): median" in r.stdout
    # one worker serves both cases (--jobs 1)
    assert "processes forked: 1 for 2 cases run; by unsupported cases: 0" in r.stdout
    assert "unsupported cases (ms in the parent)" in r.stdout


def test_a_missed_target_exits_1_and_names_it():
    r = run("-p", "pendulum", "-f", "ode", "-i", "rk4", "--h", "0.01", "--jobs", "1",
            "--max-ms", "1e-6")
    assert r.returncode == 1
    assert "target missed: median overhead" in r.stdout


def test_bad_input_is_one_line_and_exit_2():
    r = run("-p", "no_such_problem")
    assert r.returncode == 2
    assert r.stdout == "" and len(r.stderr.strip().splitlines()) == 1
    assert "no_such_problem" in r.stderr
