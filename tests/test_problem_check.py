"""``ibench check-plugin PROBLEM``: a good problem passes every line; a plugin with a
wrong Jacobian, a wrong constraint Jacobian or a wrong g_t fails that line; a model
that crashes fails a line, never the check; an unknown name exits 2 naming both
kinds of valid names."""

import os
import signal
import subprocess
import sys

import numpy as np
import pytest

from integrator_bench.harness.checks.problem_check import (check_problem, parameter_sets,
                                                           resolve)
from integrator_bench.harness.errors import UnknownName
from integrator_bench.harness.matrix import registry
from integrator_bench.problems.base import Parameter, Problem
from integrator_bench.problems.kapitza import Kapitza
from integrator_bench.problems.pendulum import Pendulum

MODEL_LINES = ("builds", "jacobian", "constraint_jac", "constraint_t", "derivatives", "start")


def lines(name, **kw) -> dict:
    return {c.name: c for c in check_problem(name, timeout=60, **kw)}


@pytest.fixture
def registered():
    """Register problem classes for one test, as their entry points would."""
    added = []

    def add(cls):
        registry.register(cls, origin="tests")
        added.append(cls.name)
        return cls

    yield add
    for name in added:
        registry.unregister(name)


def test_a_good_problem_passes_every_line():
    """The pendulum at its defaults and its 8 range ends, its stored reference, and a
    run of each of its formulations; its constraints do not depend on time."""
    found = lines("pendulum")
    assert list(found)[:7] == [*MODEL_LINES, "reference"]
    assert [n for n in found if n.startswith("runs ")] == \
        [f"runs {form}" for form in Pendulum.formulations]
    assert found["constraint_t"].passed is None
    assert all(c.passed for n, c in found.items() if n != "constraint_t"), \
        [c.line() for c in found.values()]
    assert "8 of 8 range ends" in found["builds"].detail


def test_a_driven_problem_passes_the_model_lines():
    """Kapitza's pendulum at its defaults and its 12 range ends (a drive of up to
    1e5 rad/s: the difference quotients in time judged with their own error)."""
    found = lines("kapitza", only=("model",))
    assert list(found) == list(MODEL_LINES)
    assert all(c.passed for c in found.values()), [c.line() for c in found.values()]
    assert "(at 13 parameter sets)" in found["constraint_t"].detail


class Duffing(Problem):
    """x'' = -k x^3, with a Jacobian missing the factor 3 of d(x^3)/dx."""

    name = "_test_wrong_jacobian"
    description = "undamped Duffing oscillator whose Jacobian is wrong (tests)"
    components = ("x", "v")
    t_span = (0.0, 1.0)
    parameters = (Parameter("k", 4.0, 1.0, 100.0, "stiffness"),)

    def initial_state(self):
        return np.array([1.0, 0.0])

    def rhs(self, t, y):
        return np.array([y[1], -self.params["k"] * y[0] ** 3])

    def jac(self, t, y):
        return np.array([[0.0, 1.0], [-self.params["k"] * y[0] ** 2, 0.0]])


def test_a_wrong_jacobian_fails_the_jacobian_line(registered):
    registered(Duffing)
    found = lines(Duffing.name, only=("model",))
    assert found["jacobian"].passed is False
    assert "ode: entry (1, 0)" in found["jacobian"].detail
    assert found["builds"].passed and found["start"].passed
    assert found["constraint_jac"].passed is None   # not a constrained problem


class WrongG(Pendulum):
    name = "_test_wrong_g"

    def constraint_jac(self, q, *t):
        return 1.5 * super().constraint_jac(q, *t)


def test_a_wrong_constraint_jacobian_fails_its_line(registered):
    registered(WrongG)
    found = lines(WrongG.name, only=("model",))
    assert found["constraint_jac"].passed is False
    assert "G: entry (0, " in found["constraint_jac"].detail
    assert found["builds"].passed and found["constraint_t"].passed is None


class WrongGt(Kapitza):
    name = "_test_wrong_gt"

    def constraint_t(self, q, t):
        return -super().constraint_t(q, t)     # the sign of the drive's term lost


def test_a_wrong_g_t_fails_its_line(registered):
    registered(WrongGt)
    found = lines(WrongGt.name, only=("model",))
    assert found["constraint_t"].passed is False
    assert "g_t: entry (0, 0)" in found["constraint_t"].detail
    assert found["constraint_jac"].passed


class Crashes(Duffing):
    """Right Jacobian; its process dies when built at the top of its range."""

    name = "_test_crashes"

    def initial_state(self):
        if self.params["k"] == 100.0:
            os.kill(os.getpid(), signal.SIGKILL)   # as a segfault would end it, without a dump
        return super().initial_state()

    def jac(self, t, y):
        return np.array([[0.0, 1.0], [-3 * self.params["k"] * y[0] ** 2, 0.0]])


def test_a_model_that_crashes_fails_a_line_not_the_check(registered):
    registered(Crashes)
    assert parameter_sets(Crashes) == [{}, {"k": 1.0}, {"k": 100.0}]
    found = lines(Crashes.name, only=("model",))
    assert found["builds"].passed is False
    assert found["builds"].detail.startswith("k=100: its process crashed (SIGKILL) while the check ran")
    assert found["jacobian"].passed and "(at 2 parameter sets)" in found["jacobian"].detail


def test_names_resolve_to_an_integrator_first_or_to_the_problem_asked_for(registered):
    assert resolve("scipy-RK45") == "integrator" and resolve("pendulum") == "problem"
    registered(type("Namesake", (Duffing,), {"name": "scipy-RK45"}))
    assert resolve("scipy-RK45") == "integrator"
    assert resolve("scipy-RK45", problem=True) == "problem"
    with pytest.raises(UnknownName, match="unknown problem 'heun'; valid: "):
        resolve("heun", problem=True)


def test_an_unknown_name_exits_2_naming_the_valid_ones_of_both_kinds():
    r = subprocess.run([sys.executable, "-m", "integrator_bench.harness.cli", "check-plugin",
                        "no_such_plugin", "--json"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 2 and r.stdout == ""
    line, = r.stderr.strip().splitlines()
    assert line.startswith("ibench: error: unknown integrator or problem 'no_such_plugin'; "
                           "valid integrators: ")
    integrators, problems = line.split("; valid problems: ")
    assert "scipy-Radau" in integrators and "kapitza" in problems.split(", ")
