"""Plugins: defensive discovery, the conformance check, and the example packages
(``examples/ibench-heun``, explicit, and ``examples/ibench-ros3p``, implicit)."""

import importlib.util
import json
import os
import subprocess
import sys
import textwrap
import warnings
from importlib.metadata import EntryPoint
from pathlib import Path

import math
import time

import numpy as np
import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.checks.conformance import check_plugin
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.harness.checks.verify import WORK_BUDGET, verify
from integrator_bench.integrators.base import Integrator, Solution, Step, Stepper

ROOT = Path(__file__).resolve().parents[3]
EXAMPLES = ROOT / "examples"
EXAMPLE = EXAMPLES / "ibench-heun"


def load_example(folder="ibench-heun", module="ibench_heun", cls="Heun"):
    """The class ``cls`` of an example plugin's module, loaded from its file."""
    spec = importlib.util.spec_from_file_location(module, EXAMPLES / folder / f"{module}.py")
    loaded = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(loaded)
    return getattr(loaded, cls)


@pytest.fixture
def heun():
    cls = registry.register(load_example(), origin="ibench-heun (tests)")
    yield cls
    registry.unregister(cls.name)


def test_example_plugin_passes_the_conformance_check(heun):
    checks = {c.name: c for c in check_plugin("heun", timeout=60)}
    assert all(c.passed is not False for c in checks.values()), \
        [c.line() for c in checks.values()]
    assert checks["runs ode"].passed and checks["order"].passed
    assert checks["unsupported"].passed and checks["counts"].passed
    assert all(checks[f"fails {k}"].passed for k in ("raise", "nan", "blowup"))


def test_conformance_check_catches_a_lying_integrator(heun):
    """Wrong declared order and invented counts are caught."""
    class Liar(heun):
        name = "test-liar"
        order = 4

        def solve(self, system, **kw):
            sol = super().solve(system, **kw)   # the driver reports no nfev: invent one
            sol.counts["nfev"] = sol.counts.get("nfev", 0) + 7
            return sol

    registry.register(Liar, origin="tests")
    try:
        checks = {c.name: c for c in check_plugin("test-liar", timeout=60)}
    finally:
        registry.unregister("test-liar")
    assert checks["order"].passed is False
    assert checks["counts"].passed is False


class OwnLoopEuler(Integrator):
    """Adaptive explicit Euler with its own loop (a plugin that brings solve()).

    The Euler step ``y + h k1`` is kept; ``h (k2 - k1) / 2`` with
    ``k2 = f(t + h, y + h k1)`` (the Euler-Heun pair, Hairer, Norsett and
    Wanner I, sect. II.4) estimates its local error, and ``k2`` is the first
    slope of the next step (one evaluation per attempt). Steps are shortened to
    land on the output times. Declares order 2 although it is of order 1.
    """

    name = "test-own-euler-2"
    description = "adaptive explicit Euler, own loop, claims order 2 (tests only)"
    order = 2
    adaptive = True

    def reported_steps(self, nsteps):
        return nsteps

    def solve(self, system, *, rtol=None, atol=None, h=None):
        f, t, y = system.fun, system.t0, np.array(system.y0, float)
        k1 = f(t, y)
        nfev, nsteps, nreject, ys = 1, 0, 0, [y]
        step = 1e-4 * (system.t_end - system.t0)
        for t_out in system.t_eval[1:]:
            while t < t_out:
                dt = min(step, t_out - t)
                y_new = y + dt * k1
                k2 = f(t + dt, y_new)
                nfev += 1
                scale = atol + rtol * np.maximum(np.abs(y), np.abs(y_new))
                err = math.sqrt(np.mean((0.5 * dt * (k2 - k1) / scale) ** 2))
                if not np.all(np.isfinite(y_new)) or not err <= 1.0:
                    nreject += 1
                    step = 0.2 * dt
                    if step < 1e-12:
                        return Solution(system.t_eval[:len(ys)], np.array(ys), False,
                                        f"step size underflow at t={t:g}", {"nfev": nfev})
                    continue
                t, y, k1, nsteps = (t_out if dt == t_out - t else t + dt), y_new, k2, nsteps + 1
                step = dt * min(5.0, max(0.2, 0.9 / math.sqrt(max(err, 1e-10))))
            ys.append(y)
        counts = {"nfev": nfev, "nsteps": self.reported_steps(nsteps), "nreject": nreject}
        return Solution(system.t_eval, np.array(ys), True, "", counts)


class OwnLoopEulerInflated(OwnLoopEuler):
    """The same, reporting ``40 sqrt(steps)`` steps to fake order 2 on step counts."""

    name = "test-own-euler-2-inflated"

    def reported_steps(self, nsteps):
        return int(40 * math.sqrt(nsteps))


class OwnLoopEulerHonest(OwnLoopEuler):
    """The twin that declares order 1."""

    name = "test-own-euler-1"
    order = 1


class EulerHeunStepper(Stepper):
    """The Euler step with the Euler-Heun error estimate, one step at a time."""

    error_order = 1

    def step(self, t, y, h):
        k1 = np.asarray(self.system.fun(t, y), float)
        y_new = y + h * k1
        k2 = np.asarray(self.system.fun(t + h, y_new), float)
        return Step(y_new, error=0.5 * h * (k2 - k1))


class StepperEuler(Integrator):
    name = "test-stepper-euler-2"
    description = "adaptive explicit Euler as a Stepper, claims order 2 (tests only)"
    order = 2
    adaptive = True

    def stepper(self, system, counts, rtol=None, atol=None):
        return EulerHeunStepper(system, counts, rtol, atol)


class StepperEulerHonest(StepperEuler):
    name = "test-stepper-euler-1"
    order = 1


@pytest.fixture
def own_euler():
    classes = (OwnLoopEuler, OwnLoopEulerInflated, OwnLoopEulerHonest,
               StepperEuler, StepperEulerHonest)
    for cls in classes:
        registry.register(cls, origin="tests")
    yield
    for cls in classes:
        registry.unregister(cls.name)


def _ladder_work(verdict):
    return [[run[1] for run in o["ladder"]] for o in verdict.to_dict()["orders"]]


def test_an_own_loop_method_claiming_a_higher_order_fails_check_plugin(own_euler):
    """Honest counts: the harness's nfev shows order 1; the ladder stops at the budget."""
    start = time.perf_counter()
    checks = {c.name: c for c in check_plugin("test-own-euler-2", timeout=60)}
    wall = time.perf_counter() - start
    assert checks["order"].passed is False, checks["order"].line()
    assert checks["counts"].passed and checks["runs ode"].passed
    v = verify("test-own-euler-2")
    assert v.order_passed is False and abs(v.observed_order - 1) <= 0.2
    for work in _ladder_work(v):
        assert all(w <= WORK_BUDGET for w in work[:-1]) and sum(work) <= 4 * WORK_BUDGET
    print(f"check-plugin test-own-euler-2: {wall:.1f} s")


def test_inflated_step_counts_do_not_fake_the_order(own_euler):
    v = verify("test-own-euler-2-inflated")
    assert v.order_passed is False and abs(v.observed_order - 1) <= 0.2


def test_the_twin_declaring_order_1_passes_check_plugin(own_euler):
    """An own-solve plugin (no stepper) keeps working: every check passes."""
    start = time.perf_counter()
    checks = check_plugin("test-own-euler-1", timeout=60)
    wall = time.perf_counter() - start
    assert all(c.passed is not False for c in checks), [c.line() for c in checks]
    assert {c.name: c for c in checks}["order"].passed
    print(f"check-plugin test-own-euler-1: {wall:.1f} s")


@pytest.mark.parametrize("name, passes", [("test-stepper-euler-2", False),
                                          ("test-stepper-euler-1", True)])
def test_a_stepper_is_measured_at_fixed_steps(own_euler, name, passes):
    v = verify(name)
    assert v.order_passed is passes
    assert all(o.method == "h" for o in v.orders)
    assert abs(v.observed_order - 1) <= 0.3


def _fake(name, value):
    return EntryPoint(name, value, registry.GROUPS["integrators"])


def _integrators_with(monkeypatch, extra: list) -> tuple[dict, list[str]]:
    """The integrators the registry finds with the entry points ``extra`` beside the
    installed ones, and the :class:`RegistryWarning` messages it gave."""
    real = registry.entry_points

    def entry_points(group):
        eps = list(real(group=group))
        return eps + extra if group == registry.GROUPS["integrators"] else eps

    registry.refresh()
    monkeypatch.setattr(registry, "entry_points", entry_points)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        found = registry.integrators()
    return found, [str(w.message) for w in caught
                   if issubclass(w.category, registry.RegistryWarning)]


def test_broken_plugins_warn_and_leave_the_rest_usable(monkeypatch):
    try:
        found, messages = _integrators_with(monkeypatch, [
            _fake("broken-import", "no_such_module_xyz:Thing"),
            _fake("not-an-integrator", "json:JSONDecoder"),
            _fake("scipy-RK45", "integrator_bench.integrators.sundials:CvodeBDF")])
        assert any("broken-import" in m and "ModuleNotFoundError" in m for m in messages)
        assert any("not-an-integrator" in m and "not a subclass" in m for m in messages)
        assert any("scipy-RK45" in m for m in messages)
        assert "broken-import" not in found and "not-an-integrator" not in found
        assert found["scipy-RK45"].__name__ == "RK45"       # the built-in keeps its name
        assert found["cvode-bdf"].origin == "built-in"
    finally:
        monkeypatch.undo()
        registry.refresh()


def test_a_problem_that_raises_when_built_is_skipped_with_a_warning(capsys):
    """A problem plugin that loads but raises when built (here its start, as a
    symbolic model with a bad expression did from the consistent-start
    projection) is left out of ``ibench list problems`` and of a run that names no
    problem, with a warning naming it and why; every other problem stays."""
    from integrator_bench.harness.cli import main
    from integrator_bench.harness.matrix.cases import expand
    from integrator_bench.problems.models.pendulum import Pendulum

    class BuildsBadly(Pendulum):
        name = "test-builds-badly"

        def start(self):
            raise NameError("name 't' is not defined")

    registry.register(BuildsBadly, origin="tests")
    registry.refresh()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert main(["list", "problems", "--json"]) == 0
            names = [d["name"] for d in json.loads(capsys.readouterr().out)]
            cases = expand(formulations=["ode"], integrators=["scipy-RK45"], rtols=[1e-3])
        messages = [str(w.message) for w in caught
                    if issubclass(w.category, registry.RegistryWarning)]
        assert any("'test-builds-badly' from tests skipped" in m
                   and "NameError: name 't' is not defined" in m for m in messages), messages
        assert "test-builds-badly" not in names and {"pendulum", "kapitza"} <= set(names)
        assert {c.problem for c in cases} >= {"pendulum", "kapitza"}
        assert "test-builds-badly" not in {c.problem for c in cases}
    finally:
        registry.unregister(BuildsBadly.name)
        registry.refresh()


BROKEN_PLUGIN = {
    "pyproject.toml": """
        [build-system]
        requires = ["setuptools>=68"]
        build-backend = "setuptools.build_meta"
        [project]
        name = "ibench-broken"
        version = "0.0.1"
        [project.entry-points."integrator_bench.integrators"]
        broken = "ibench_broken:Broken"
        [tool.setuptools]
        py-modules = ["ibench_broken"]
    """,
    "ibench_broken.py": "raise ImportError('this plugin is broken on purpose')\n",
}


def test_example_installs_into_a_fresh_environment(tmp_path):
    """pip-install integrator-bench, the example and a broken plugin into a new
    virtual environment; the example is listed, conforms and runs."""
    broken = tmp_path / "broken"
    broken.mkdir()
    for name, text in BROKEN_PLUGIN.items():
        (broken / name).write_text(textwrap.dedent(text))
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    pip = [str(venv / "bin" / "python"), "-m", "pip", "install", "-q"]
    subprocess.run(pip + ["-e", str(ROOT), str(EXAMPLE), str(EXAMPLES / "ibench-ros3p"),
                          str(broken)], check=True, capture_output=True, timeout=900)
    ibench = str(venv / "bin" / "ibench")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}

    out = subprocess.run([ibench, "list", "integrators", "--json"], capture_output=True,
                         text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    listed = {i["name"]: i for i in json.loads(out.stdout)}
    assert listed["heun"]["origin"] == "ibench-heun 0.1.0"
    assert "broken" not in listed and "cvode-bdf" in listed
    assert "ibench-broken 0.0.1" in out.stderr and "broken on purpose" in out.stderr

    assert listed["ros3p"]["origin"] == "ibench-ros3p 0.1.0"
    assert listed["ros3p"]["implicit"] and listed["ros3p"]["uses_jacobian"]

    for name in ("heun", "ros3p"):
        check = subprocess.run([ibench, "check-plugin", name], capture_output=True, text=True,
                               env=env, timeout=600)
        assert check.returncode == 0, check.stdout + check.stderr
        assert "FAIL" not in check.stdout
        for line in ("order", "stability", "accuracy", "fails nan", "fails blowup"):
            assert f" {line}: " in check.stdout

    store = tmp_path / "s.sqlite"

    def first_record(name, *mode):
        run = subprocess.run([ibench, "run", "-i", name, "-p", "two_mass:c2=1000", *mode,
                              "--store", str(store), "--json"], capture_output=True, text=True,
                             env=env, timeout=600)
        assert run.returncode == 0, run.stderr
        return json.loads(run.stdout.splitlines()[0])

    record = first_record("heun", "--h", "1e-3")
    assert record["status"] == CaseStatus.OK and record["origin"] == "ibench-heun 0.1.0"
    assert record["scd"] > 4
    record = first_record("ros3p", "--rtol", "1e-8")   # 4.7 digits: see the example's notes
    assert record["status"] == CaseStatus.OK and record["origin"] == "ibench-ros3p 0.1.0"
    assert record["njev"] > 0 and record["nlu"] >= record["nsteps"] and record["scd"] > 4


class MemoryHog(Integrator):
    """Reserves 512 MiB (never touched) before it returns the start (tests only)."""
    name = "test-memory-hog"
    description = "reserves 512 MiB (tests only)"
    accepts = frozenset({"ode"})

    def solve(self, system, **kw):
        reserved = np.empty(512 * 2**20 // 8)   # address space, not memory
        del reserved
        return Solution(system.t_eval, np.repeat(system.y0[None, :], system.t_eval.size, 0))


def test_check_plugin_runs_its_checks_under_the_memory_cap_of_a_run():
    """``check-plugin --memory`` caps every forked check as ``ibench run --memory`` caps
    a case: past the cap the reservation fails, an ``error`` record that says so."""
    registry.register(MemoryHog, origin="tests")
    try:
        capped = {c.name: c for c in check_plugin(MemoryHog.name, timeout=60, only=["runs"],
                                                  memory_mb=64)}
        free = {c.name: c for c in check_plugin(MemoryHog.name, timeout=60, only=["runs"],
                                                memory_mb=None)}
    finally:
        registry.unregister(MemoryHog.name)
    assert capped["runs ode"].passed is False and "out of memory" in capped["runs ode"].detail
    assert "out of memory" not in free["runs ode"].detail
    # the other checks' forked processes (counts, order, stability, accuracy, fails)
    from integrator_bench.harness.checks.conformance import in_child
    assert in_child(_reserve, (), 60, 64)[1].startswith("its process raised MemoryError")
    assert in_child(_reserve, (), 60, None) == (True, None)


def _reserve() -> bool:
    np.empty(512 * 2**20 // 8)
    return True


MONKEYPATCHER = '''
from integrator_bench.harness.measure import metrics
from integrator_bench.integrators.scipy_ivp import RK45


def mixed_max(*args, **kwargs):   # every error made 0.0
    return 0.0


metrics.mixed_max = mixed_max


class Quiet(RK45):
    name = "quiet-rk45"
'''


def test_a_plugin_that_replaces_a_harness_function_is_named_loudly(tmp_path, monkeypatch):
    """A plugin that, as it loads, replaces ``metrics.mixed_max`` (every error 0.0)
    gets a warning naming it and the function, whether or not it is ever selected."""
    import sys

    from integrator_bench.harness.measure import metrics

    (tmp_path / "ibench_sneaky.py").write_text(MONKEYPATCHER)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(metrics, "mixed_max", metrics.mixed_max)   # restored afterwards
    try:
        _, messages = _integrators_with(monkeypatch, [_fake("quiet-rk45", "ibench_sneaky:Quiet")])
        assert any("'quiet-rk45'" in m and "replaced integrator_bench.harness.measure."
                   "metrics.mixed_max" in m for m in messages), messages
    finally:
        monkeypatch.undo()
        sys.modules.pop("ibench_sneaky", None)
        registry.refresh()
