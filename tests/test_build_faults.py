"""A problem plugin whose constructor crashes (SIGSEGV) or hangs costs its own cases,
never the command: its build is tried first in a process of its own
(harness/matrix/builds.py). Beside two_mass in one ``ibench run`` its cases are
recorded ``crashed`` / ``timeout`` with reason ``build_failed``, two_mass runs ``ok``,
the run exits 0; ``ibench list problems`` lists the others and names it in one
warning line."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import plugin_dist
import pytest

REPO = Path(__file__).resolve().parents[1]
IBENCH = [sys.executable, "-m", "integrator_bench.harness.cli"]

PLUGIN = '''
import os
import signal
import time


class Segfaults(Decay):
    name = "ctor_segv"

    def __init__(self, **params):
        os.kill(os.getpid(), signal.SIGSEGV)


class Hangs(Decay):
    name = "ctor_hang"

    def __init__(self, **params):
        time.sleep(3600)


class Spins(Decay):
    name = "ctor_spin"

    def __init__(self, **params):
        while True:
            pass
'''
FAULTY = {"ctor_segv": "Segfaults", "ctor_hang": "Hangs", "ctor_spin": "Spins"}


@pytest.fixture(scope="module")
def plugin_path(tmp_path_factory):
    """A folder on PYTHONPATH that registers the faulty problems as a plugin does."""
    return plugin_dist.install(tmp_path_factory.mktemp("plugin"), "faulty_builds", PLUGIN,
                               FAULTY)


@pytest.fixture
def env(tmp_path, plugin_path):
    refs = tmp_path / "reference"
    shutil.copytree(REPO / "results" / "reference" / "two_mass", refs / "two_mass")
    return {**os.environ, "PYTHONPATH": str(plugin_path), "IBENCH_REFERENCE_DIR": str(refs),
            "IBENCH_DATA_DIR": str(tmp_path / "data"), "IBENCH_BUILD_TIMEOUT": "1"}


def _ibench(env, *args):
    return subprocess.run([*IBENCH, *args], env=env, capture_output=True, text=True,
                          timeout=600)


@pytest.mark.parametrize("fault, status", [("ctor_segv", "crashed"), ("ctor_hang", "timeout"),
                                           ("ctor_spin", "timeout")])
def test_a_constructor_that_crashes_or_hangs_costs_its_own_cases(env, tmp_path, fault, status):
    started = time.monotonic()
    r = _ibench(env, "run", "-p", fault, "-p", "two_mass:c2=0.1", "-i", "scipy-RK45",
                "--rtol", "1e-3", "--store", str(tmp_path / "s.sqlite"), "--json",
                "--no-contenders")
    assert r.returncode == 0, r.stderr[-3000:]
    records = {rec["problem"]: rec for rec in map(json.loads, r.stdout.splitlines())}
    assert records["two_mass"]["status"] == "ok"
    record = records[fault]
    assert (record["status"], record["reason"]) == (status, "build_failed"), record
    said = "crashed (SIGSEGV)" if fault == "ctor_segv" else "gave no result"
    assert f"the model {said} while the problem was built" in record["message"], record
    assert time.monotonic() - started < 120


def test_list_problems_names_the_faulty_builds_in_a_line_each(env):
    r = _ibench(env, "list", "problems")
    assert r.returncode == 0, r.stderr[-3000:]
    assert "two_mass" in r.stdout and not any(name in r.stdout for name in FAULTY)
    for name, said in (("ctor_segv", "crashed (SIGSEGV)"), ("ctor_hang", "gave no result"),
                       ("ctor_spin", "gave no result")):
        [line] = [line for line in r.stderr.splitlines() if f"problem {name!r}" in line]
        assert "skipped: it failed to build: the model " + said in line, line


def test_a_bad_build_budget_is_one_line_and_exit_2(env):
    r = _ibench({**env, "IBENCH_BUILD_TIMEOUT": "-1"}, "run", "-p", "ctor_segv", "-i",
                "scipy-RK45", "--rtol", "1e-3", "--json")
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.strip().splitlines()[-1].startswith("ibench: error: IBENCH_BUILD_TIMEOUT='-1' must be a positive")


def test_reference_stiffness_and_advise_name_the_faulty_build_in_one_line(env, tmp_path):
    r = _ibench(env, "reference", "-p", "ctor_segv", "-p", "two_mass:c2=0.1", "--json")
    assert r.returncode == 1, r.stderr[-3000:]
    assert [json.loads(line)["problem"] for line in r.stdout.splitlines()] == ["two_mass"]
    assert "ibench: no reference for ctor_segv: the model crashed (SIGSEGV) while the " \
           "problem was built" in r.stderr.splitlines()
    r = _ibench(env, "stiffness", "-p", "ctor_hang", "--store", str(tmp_path / "s.sqlite"))
    assert r.returncode == 1
    assert r.stderr.strip().splitlines()[-1].startswith(
        "ibench: no stiffness analysis for ctor_hang: the model gave no result"), r.stderr
    r = _ibench(env, "advise", "-p", "ctor_segv", "--target", "1e-3", "--budget", "6",
                "--store", str(tmp_path / "s.sqlite"), "--json")
    assert r.returncode == 1 and r.stdout == ""
    assert r.stderr.strip().splitlines()[-1].startswith("ibench: no advice for ctor_segv: "
                                                        "the model crashed (SIGSEGV)")


def test_ctrl_c_stops_a_hanging_build_at_once(env, tmp_path):
    """A constructor that hangs within its budget: Ctrl-C stops the command within a
    second (its line said), its build's process killed."""
    proc = subprocess.Popen([*IBENCH, "run", "-p", "ctor_hang", "-i", "scipy-RK45", "--rtol",
                             "1e-3", "--store", str(tmp_path / "s.sqlite")],
                            env={**env, "IBENCH_BUILD_TIMEOUT": "600"}, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    end = time.monotonic() + 120
    while not _building(proc.pid):   # its trial's process forked
        assert time.monotonic() < end and proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    [child] = _building(proc.pid)
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    said = [(time.monotonic() - sent, line) for line in proc.stderr]
    proc.wait(timeout=30)
    [when] = [t for t, line in said if line.startswith("ibench: interrupted")]
    assert when < 1.0 and proc.returncode == 130, said
    with pytest.raises(ProcessLookupError):
        os.kill(child, 0)


def _building(pid: int) -> list[int]:
    from integrator_bench.harness.forking import children
    return children(pid)
