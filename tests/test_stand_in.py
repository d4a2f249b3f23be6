"""A problem from outside the project is never built in the command's own process
(harness/matrix/builds.py, harness/matrix/stand_in.py): the command holds a stand-in
carrying what its trial build in a process of its own gave back, and its model's
code runs only in isolated processes. A constructor that crashes in every process
but the first that builds it therefore costs its own cases, and the command's pid
never constructs it."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import plugin_dist
import pytest

from integrator_bench.harness.forking.child import call
from integrator_bench.harness.matrix import builds, registry
from integrator_bench.harness.matrix.stand_in import ForeignCode, StandIn, system_of
from integrator_bench.problems.two_mass import TwoMass

REPO = Path(__file__).resolve().parents[1]
IBENCH = [sys.executable, "-m", "integrator_bench.harness.cli"]

PLUGIN = '''
import os
import signal


class Recorded(Decay):
    """Writes the pid of every process that constructs it to $IBENCH_TEST_PIDS."""
    name = "ctor_recorded"

    def __init__(self, **params):
        with open(os.environ["IBENCH_TEST_PIDS"], "a") as f:
            f.write(f"{os.getpid()}\\n")
        super().__init__(**params)


class FirstOnly(Decay):
    """Builds in the first process that builds it; crashes (SIGSEGV) in every later one."""
    name = "ctor_first_only"

    def __init__(self, **params):
        path = os.environ["IBENCH_TEST_BUILDS"]
        done = os.path.exists(path)
        with open(path, "a") as f:
            f.write(f"{os.getpid()}\\n")
        if done:
            os.kill(os.getpid(), signal.SIGSEGV)
        super().__init__(**params)
'''
PROBLEMS = {"ctor_recorded": "Recorded", "ctor_first_only": "FirstOnly"}


@pytest.fixture(scope="module")
def plugin_path(tmp_path_factory):
    return plugin_dist.install(tmp_path_factory.mktemp("plugin"), "stand_in_builds", PLUGIN,
                               PROBLEMS)


@pytest.fixture
def env(tmp_path, plugin_path):
    refs = tmp_path / "reference"
    shutil.copytree(REPO / "results" / "reference" / "two_mass", refs / "two_mass")
    return {**os.environ, "PYTHONPATH": str(plugin_path), "IBENCH_REFERENCE_DIR": str(refs),
            "IBENCH_DATA_DIR": str(tmp_path / "data"),
            "IBENCH_TEST_PIDS": str(tmp_path / "pids"),
            "IBENCH_TEST_BUILDS": str(tmp_path / "builds")}


def _run(env, tmp_path, problem):
    proc = subprocess.Popen(
        [*IBENCH, "run", "-p", problem, "-p", "two_mass:c2=0.1", "-i", "scipy-RK45",
         "--rtol", "1e-3", "--store", str(tmp_path / "s.sqlite"), "--json"],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, err = proc.communicate(timeout=600)
    return proc.pid, proc.returncode, out, err


def test_the_commands_process_never_constructs_a_plugins_problem(env, tmp_path):
    pid, code, out, err = _run(env, tmp_path, "ctor_recorded")
    assert code == 0, err
    records = [json.loads(line) for line in out.splitlines()]
    assert {r["problem"]: r["status"] for r in records} == {"ctor_recorded": "ok",
                                                           "two_mass": "ok"}
    builders = {int(p) for p in Path(env["IBENCH_TEST_PIDS"]).read_text().split()}
    assert builders and pid not in builders


def test_a_build_that_crashes_after_its_trial_costs_its_own_cases(env, tmp_path):
    # its trial (the first build) passes; every later build, in the case's worker or a
    # model's call, crashes: before, the second build was the command's own, and killed it
    pid, code, out, err = _run(env, tmp_path, "ctor_first_only")
    assert code == 0, err
    records = [json.loads(line) for line in out.splitlines()]
    status = {r["problem"]: r["status"] for r in records}
    assert status["two_mass"] == "ok"
    assert status["ctor_first_only"] in ("crashed", "error")
    builders = [int(p) for p in Path(env["IBENCH_TEST_BUILDS"]).read_text().split()]
    assert len(builders) > 1 and pid not in builders


class _Runtime(TwoMass):
    """two_mass registered at run time: from outside the project."""
    name = "_stand_in_two_mass"


@pytest.fixture
def runtime():
    registry.register(_Runtime)
    yield _Runtime
    registry.unregister(_Runtime.name)
    registry.refresh()


def test_a_foreign_problem_is_a_stand_in_with_its_facts_and_no_code(runtime):
    stand_in = builds.build(runtime, {"c2": 0.1})
    real = TwoMass(c2=0.1)
    assert isinstance(stand_in, StandIn)
    assert stand_in.params == real.params and stand_in.label() == real.label().replace(
        "two_mass", runtime.name)
    assert stand_in.dimension == real.dimension and stand_in.t_span == real.t_span
    assert np.array_equal(stand_in.t_eval, real.t_eval)
    assert stand_in.key_params() == real.key_params()
    assert stand_in.default_step_sizes() == real.default_step_sizes()
    assert np.array_equal(stand_in.atol_scale_vector(), real.atol_scale_vector())
    assert stand_in.origin == "runtime" and stand_in.description == real.description
    assert system_of(stand_in, "ode").kind == "ode"
    assert system_of(stand_in, "ode").n == real.formulate("ode").n
    for code in ("rhs", "jac", "formulate", "initial_state", "fingerprint"):
        with pytest.raises(ForeignCode, match=f"{code} of problem {runtime.name}"):
            getattr(stand_in, code)
    # in an isolated process it is the problem itself
    assert call(lambda: stand_in.fingerprint(), "a test") == \
        call(lambda: runtime(c2=0.1).fingerprint(), "a test")


def test_the_projects_own_problems_are_built_here():
    registry.problems()   # the registry gives the built-ins their origin
    assert type(builds.build(TwoMass, {"c2": 0.1})) is TwoMass
