"""studies/fidelity.py: its table, its summary and its manners (the targets
themselves are measured by running it in full, not here: timings flake in tests)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "studies" / "fidelity.py"


def run(*args):
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True,
                          timeout=600)


def test_quick_run_prints_ratios_their_median_and_the_driver_share():
    r = run("--quick", "--repeat", "2")
    assert r.returncode in (0, 1), r.stderr      # 1: a target missed on a busy machine
    rows = [line for line in r.stdout.splitlines() if line.startswith("| two_mass")]
    assert {row.split("|")[2].strip() for row in rows} == {"scipy-RK45", "cvode-bdf"}
    for row in rows:
        cells = [c.strip() for c in row.split("|")[1:-1]]
        assert cells[3] == "library"
        harness, plain, ratio = float(cells[4]), float(cells[5]), float(cells[6].split()[0])
        assert harness > 0 and plain > 0 and abs(ratio - harness / plain) < 0.01 * ratio
    assert re.search(r"median ratio harness / plain: \d\.\d{3}", r.stdout)
    assert re.search(r"largest ratio: \d+\.\d{3} \(two_mass", r.stdout)
    share = re.search(r"\| rk4 \| h [\d.e-]+ \| [\d.e-]+ \| ([\d.]+) % \|", r.stdout)
    assert share and 0 < float(share.group(1)) < 100
    assert ("target missed" in r.stdout) == (r.returncode == 1)


def test_bad_input_is_one_line_and_exit_2():
    r = run("--rounds", "0")
    assert r.returncode == 2
    assert r.stdout == "" and len(r.stderr.strip().splitlines()) == 1 and "--rounds" in r.stderr


def test_a_problem_outside_the_fixed_set_is_one_line_naming_the_choices():
    r = run("--problem", "pendulum")
    assert r.returncode == 2 and r.stdout == ""
    assert len(r.stderr.strip().splitlines()) == 1 and "'pendulum'" in r.stderr
    assert "two_mass, squeezer, slider_crank, chain_bushing" in r.stderr


def _module():
    import importlib.util
    spec = importlib.util.spec_from_file_location("fidelity", SCRIPT)
    fidelity = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fidelity)
    return fidelity


def test_a_failing_plain_call_is_a_row_not_the_end_of_the_run(monkeypatch):
    fidelity = _module()

    def broken(*args):
        def call():
            raise RuntimeError("the library refused")
        return call
    monkeypatch.setattr(fidelity, "plain_call", broken)
    cases = fidelity.make_cases(["two_mass:c2=1000"], ["scipy-RK45"], [1e-3, 1e-6])
    rows = fidelity.measure(cases, rounds=2, repeat=1)
    assert [(r["status"], r["note"], r["ratio"]) for r in rows] == \
        [("plain call failed", "RuntimeError: the library refused", None)] * 2
    assert "plain call failed" in fidelity.table(rows)[-1]


def test_a_timeout_skips_the_lines_tighter_tolerances(monkeypatch):
    """As ``ibench run`` does: after a timeout at one rtol, the same line's tighter
    tolerances are not started (each would wait out the budget too)."""
    fidelity = _module()
    started = []

    def times_out(case):
        started.append(case.rtol)
        return {"status": "timeout", "timing": None, "timing_mismatch": None,
                "message": "timeout", "cpu_s": None}
    cases = fidelity.make_cases(["two_mass:c2=1000"], ["scipy-RK45"], [1e-6, 1e-3, 1e-9])
    rows = fidelity.measure(cases, rounds=2, repeat=1, run=times_out)
    assert started == [1e-6, 1e-3]
    status = {r["case"].rtol: (r["status"], r["note"]) for r in rows}
    assert status[1e-9] == ("skipped", "rtol 1e-03 timed out")
    assert status[1e-6][0] == status[1e-3][0] == "timeout"
