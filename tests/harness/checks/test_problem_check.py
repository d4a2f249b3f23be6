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
from integrator_bench.problems.models.kapitza import Kapitza
from integrator_bench.problems.models.pendulum import Pendulum

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
    assert found["builds"].detail.startswith("k=100: its process crashed (SIGKILL) while the problem was built")
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


class Sized(Duffing):
    """n uncoupled Duffing oscillators; the analytic Jacobian is wrong in the last
    column only (``wrong``), and takes ``n / 50`` seconds of CPU (``slow``): a model whose
    checks cost in proportion to its size."""

    name = "_test_sized"
    parameters = (Parameter("n", 10, 10, 100, "oscillators"),
                  Parameter("wrong", 0.0, 0.0, 1.0, "1: the last column wrong"),
                  Parameter("slow", 0.0, 0.0, 1.0, "1: the Jacobian takes n / 50 s"))
    components = ()

    def __init__(self, **params):
        super().__init__(**params)
        n = int(self.params["n"])
        self.components = tuple(f"{c}{i}" for i in range(n) for c in "xv")

    def initial_state(self):
        return np.tile([1.0, 0.0], int(self.params["n"]))

    def rhs(self, t, y):
        x, v = y[0::2], y[1::2]
        return np.column_stack([v, -4.0 * x ** 3]).ravel()

    def jac(self, t, y):
        if self.params["slow"]:   # CPU, which the budget counts (a sleep is not work)
            import time
            end = time.process_time() + self.params["n"] / 50
            while time.process_time() < end:
                pass
        J = np.zeros((y.size, y.size))
        idx = np.arange(0, y.size, 2)
        J[idx, idx + 1] = 1.0
        J[idx + 1, idx] = -12.0 * y[idx] ** 2
        J[-1, -1] += 1.0 if self.params["wrong"] else 0.0
        return J


def test_a_large_problem_is_checked_at_its_last_columns(registered):
    """200 unknowns, 40 columns compared: the last ones are always among them, so a
    Jacobian wrong in the last column alone fails (a draw of 40 at random would
    miss it four times in five)."""
    from integrator_bench.harness.checks import quotients

    p = Sized(n=100, wrong=1.0)
    assert quotients.jacobian(Sized(n=100))[0] is True
    passed, detail = quotients.jacobian(p)
    assert passed is False and "entry (199, 199)" in detail


def test_a_larger_parameter_set_gets_a_budget_scaled_by_its_size(registered):
    """The defaults (20 unknowns) check in 0.2 s within the timeout of 1.5 s; the
    range end of 200 unknowns takes 2 s a Jacobian, more than the timeout, and
    passes within its budget, ten times the timeout (its size ten times the
    defaults')."""
    from integrator_bench.harness.checks.problem_check import SIZE_SCALE, _budget

    assert _budget(1.5, 200, 20) == 15.0 and _budget(1.5, 10, 20) == 1.5
    assert _budget(1.0, 10 ** 6, 20) == SIZE_SCALE
    slow = type("Slow", (Sized,), {"name": "_test_slow_sized", "parameters": (
        Parameter("n", 10, 10, 100, "oscillators"),
        Parameter("wrong", 0.0, 0.0, 0.0, ""), Parameter("slow", 1.0, 1.0, 1.0, ""))})
    registered(slow)
    found = {c.name: c for c in check_problem(slow.name, timeout=1.5, only=("model",))}
    assert found["builds"].passed, found["builds"].detail
    assert found["jacobian"].passed and "(at 2 parameter sets)" in found["jacobian"].detail
