"""Plugins: defensive discovery, the conformance check, and the example package."""

import importlib.util
import json
import os
import subprocess
import sys
import textwrap
import warnings
from importlib.metadata import EntryPoint
from pathlib import Path

import pytest

from integrator_bench.harness import registry
from integrator_bench.harness.conformance import check_plugin

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "ibench-heun"


def load_example():
    spec = importlib.util.spec_from_file_location("ibench_heun", EXAMPLE / "ibench_heun.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.Heun


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
            sol = super().solve(system, **kw)
            sol.counts["nfev"] += 7
            return sol

    registry.register(Liar, origin="tests")
    try:
        checks = {c.name: c for c in check_plugin("test-liar", timeout=60)}
    finally:
        registry.unregister("test-liar")
    assert checks["order"].passed is False
    assert checks["counts"].passed is False


def _fake(name, value):
    return EntryPoint(name, value, registry.GROUPS["integrators"])


def test_broken_plugins_warn_and_leave_the_rest_usable(monkeypatch):
    real = registry.entry_points

    def entry_points(group):
        eps = list(real(group=group))
        if group == registry.GROUPS["integrators"]:
            eps += [_fake("broken-import", "no_such_module_xyz:Thing"),
                    _fake("not-an-integrator", "json:JSONDecoder"),
                    _fake("scipy-RK45", "integrator_bench.integrators.sundials:CvodeBDF")]
        return eps

    registry.refresh()
    monkeypatch.setattr(registry, "entry_points", entry_points)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            found = registry.integrators()
        messages = [str(w.message) for w in caught if issubclass(w.category, registry.RegistryWarning)]
        assert any("broken-import" in m and "ModuleNotFoundError" in m for m in messages)
        assert any("not-an-integrator" in m and "not a subclass" in m for m in messages)
        assert any("scipy-RK45" in m for m in messages)
        assert "broken-import" not in found and "not-an-integrator" not in found
        assert found["scipy-RK45"].__name__ == "RK45"       # the built-in keeps its name
        assert found["cvode-bdf"].origin == "built-in"
    finally:
        monkeypatch.undo()
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
    subprocess.run(pip + ["-e", str(ROOT), str(EXAMPLE), str(broken)], check=True,
                   capture_output=True, timeout=900)
    ibench = str(venv / "bin" / "ibench")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}

    out = subprocess.run([ibench, "list", "integrators", "--json"], capture_output=True,
                         text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    listed = {i["name"]: i for i in json.loads(out.stdout)}
    assert listed["heun"]["origin"] == "ibench-heun 0.1.0"
    assert "broken" not in listed and "cvode-bdf" in listed
    assert "ibench-broken 0.0.1" in out.stderr and "broken on purpose" in out.stderr

    check = subprocess.run([ibench, "check-plugin", "heun"], capture_output=True, text=True,
                           env=env, timeout=600)
    assert check.returncode == 0, check.stdout + check.stderr
    assert "FAIL" not in check.stdout

    store = tmp_path / "s.sqlite"
    run = subprocess.run([ibench, "run", "-i", "heun", "-p", "two_mass:c2=1000", "--h", "1e-3",
                          "--store", str(store), "--json"], capture_output=True, text=True,
                         env=env, timeout=600)
    assert run.returncode == 0, run.stderr
    record = json.loads(run.stdout.splitlines()[0])
    assert record["status"] == "ok" and record["origin"] == "ibench-heun 0.1.0"
    assert record["scd"] > 4
