"""A problem plugin whose constructor crashes (SIGSEGV) or hangs costs its own cases,
never the command: its build is tried first in a process of its own
(harness/matrix/builds.py). Beside two_mass in one ``ibench run`` its cases are
recorded ``crashed`` / ``timeout`` with reason ``build_failed``, two_mass runs ``ok``,
the run exits 0; ``ibench list problems`` lists the others and names it in one
warning line.

Nor is it ever built in the command's own process: the command holds a stand-in
carrying what its trial gave back (harness/matrix/stand_in.py), its code runs only
in isolated processes. A constructor that crashes in every process but the first
that builds it costs its own cases, and the command's pid never constructs one."""

from __future__ import annotations

import json
import os
import pickle
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import plugin_dist
import pytest

from integrator_bench.harness.forking.child import call
from integrator_bench.harness.matrix import builds, registry
from integrator_bench.harness.matrix.stand_in import ForeignCode, StandIn, system_of
from integrator_bench.problems.models.two_mass import TwoMass

REPO = Path(__file__).resolve().parents[3]
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


class Recorded(Decay):
    """Writes the pid of every process that constructs it to $IBENCH_TEST_PIDS."""
    name = "ctor_recorded"

    def __init__(self, **params):
        with open(os.environ["IBENCH_TEST_PIDS"], "a") as f:
            f.write(f"{os.getpid()}\\n")
        super().__init__(**params)


class FirstOnly(Recorded):
    """Builds in the first process that builds it, crashes (SIGSEGV) in every later one."""
    name = "ctor_first_only"

    def __init__(self, **params):
        built = os.path.exists(os.environ["IBENCH_TEST_PIDS"])
        super().__init__(**params)
        if built:
            os.kill(os.getpid(), signal.SIGSEGV)
'''
FAULTY = {"ctor_segv": "Segfaults", "ctor_hang": "Hangs", "ctor_spin": "Spins"}
#: problems that build in their trial: one recording who builds it, one building only once
RECORDED = {"ctor_recorded": "Recorded", "ctor_first_only": "FirstOnly"}


@pytest.fixture(scope="module")
def plugin_path(tmp_path_factory):
    """A folder on PYTHONPATH that registers the faulty problems as a plugin does."""
    return plugin_dist.install(tmp_path_factory.mktemp("plugin"), "faulty_builds", PLUGIN,
                               {**FAULTY, **RECORDED})


@pytest.fixture
def env(tmp_path, plugin_path):
    refs = tmp_path / "reference"
    shutil.copytree(REPO / "results" / "reference" / "two_mass", refs / "two_mass")
    return {**os.environ, "PYTHONPATH": str(plugin_path), "IBENCH_REFERENCE_DIR": str(refs),
            "IBENCH_DATA_DIR": str(tmp_path / "data"), "IBENCH_BUILD_TIMEOUT": "1",
            "IBENCH_TEST_PIDS": str(tmp_path / "pids")}


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


def _run_beside_two_mass(env, tmp_path, problem) -> tuple[int, dict]:
    """``ibench run`` of ``problem`` beside two_mass: its pid and the records by problem."""
    proc = subprocess.Popen(
        [*IBENCH, "run", "-p", problem, "-p", "two_mass:c2=0.1", "-i", "scipy-RK45",
         "--rtol", "1e-3", "--store", str(tmp_path / "s.sqlite"), "--json", "--no-contenders"],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, err = proc.communicate(timeout=600)
    assert proc.returncode == 0, err[-3000:]
    return proc.pid, {rec["problem"]: rec for rec in map(json.loads, out.splitlines())}


def _builders(env) -> list[int]:
    return [int(pid) for pid in Path(env["IBENCH_TEST_PIDS"]).read_text().split()]


def test_the_commands_process_never_constructs_a_plugins_problem(env, tmp_path):
    pid, records = _run_beside_two_mass(env, tmp_path, "ctor_recorded")
    assert {name: rec["status"] for name, rec in records.items()} == {"ctor_recorded": "ok",
                                                                      "two_mass": "ok"}
    assert _builders(env) and pid not in _builders(env)


def test_a_build_that_crashes_after_its_trial_costs_its_own_cases(env, tmp_path):
    """Its trial (the first build) passes, every later build crashes: once the second
    build was the command's own, which it killed (exit -11, no record)."""
    pid, records = _run_beside_two_mass(env, tmp_path, "ctor_first_only")
    assert records["two_mass"]["status"] == "ok"
    record = records["ctor_first_only"]
    assert record["status"] == "crashed" and "crashed (SIGSEGV)" in record["message"], record
    assert len(_builders(env)) > 1 and pid not in _builders(env)


class _Runtime(TwoMass):
    """two_mass registered at run time: a problem from outside the project."""
    name = "_stand_in_two_mass"


@pytest.fixture
def runtime():
    registry.register(_Runtime)
    yield _Runtime
    registry.unregister(_Runtime.name)
    registry.refresh()


def test_a_foreign_problem_is_a_stand_in_with_its_facts_and_none_of_its_code(runtime):
    stand_in, real = builds.build(runtime, {"c2": 0.1}), TwoMass(c2=0.1)
    assert isinstance(stand_in, StandIn) and builds.class_of(stand_in) is runtime
    assert pickle.loads(pickle.dumps(stand_in)).label() == stand_in.label()
    assert stand_in.params == real.params
    assert stand_in.label() == real.label().replace("two_mass", runtime.name)
    assert (stand_in.dimension, stand_in.t_span) == (real.dimension, real.t_span)
    assert np.array_equal(stand_in.t_eval, real.t_eval)
    assert stand_in.key_params() == real.key_params()
    assert stand_in.default_step_sizes() == real.default_step_sizes()
    assert np.array_equal(stand_in.atol_scale_vector(), real.atol_scale_vector())
    assert (stand_in.origin, stand_in.description) == ("runtime", real.description)
    facts, system = system_of(stand_in, "ode"), real.formulate("ode")
    assert (facts.kind, facts.n, facts.t_end) == (system.kind, system.n, system.t_end)
    for code in ("rhs", "jac", "formulate", "initial_state", "fingerprint", "exact"):
        with pytest.raises(ForeignCode, match=f"{code} of problem {runtime.name}"):
            getattr(stand_in, code)
    # in an isolated process it is the problem itself
    assert call(lambda: stand_in.fingerprint(), "a test") == \
        call(lambda: runtime(c2=0.1).fingerprint(), "a test")


def test_the_projects_own_problems_are_built_here():
    registry.problems()   # the registry gives the built-ins their origin
    assert type(builds.build(TwoMass, {"c2": 0.1})) is TwoMass
