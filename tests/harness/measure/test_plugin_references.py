"""Where references are kept: the project's own problems in ``REFERENCE_DIR`` (a
checkout's committed ``results/reference/``), a plugin's apart in
``PLUGIN_REFERENCE_DIR`` (``<data dir>/plugin-reference``, untracked)."""

from __future__ import annotations

import subprocess

import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.measure import references
from integrator_bench.harness import paths
from integrator_bench.problems.models.two_mass import TwoMass


class PluginTwoMass(TwoMass):
    """The two-mass model under another name, as a plugin would register it."""

    name = "plugin_two_mass_ref"


@pytest.fixture
def dirs(tmp_path, monkeypatch):
    own, plugin = tmp_path / "reference", tmp_path / "plugin-reference"
    monkeypatch.setattr(references, "REFERENCE_DIR", own)
    monkeypatch.setattr(references, "PLUGIN_REFERENCE_DIR", plugin)
    registry.register(PluginTwoMass, origin="ibench-some-plugin 0.1")
    yield own, plugin
    registry.unregister(PluginTwoMass.name)
    registry.refresh()


def test_a_plugins_reference_is_kept_apart_from_the_projects(dirs):
    own, plugin = dirs
    npz, js = references.paths(PluginTwoMass())
    assert npz.is_relative_to(plugin) and js.is_relative_to(plugin)
    npz, js = references.paths(TwoMass())
    assert npz.is_relative_to(own) and js.is_relative_to(own)


def test_a_computed_plugin_reference_lands_in_the_plugin_folder(dirs):
    own, plugin = dirs
    problem = PluginTwoMass()
    ref = references.load(problem, limit=120)
    assert ref is not None
    assert list((plugin / problem.name).glob("*.npz"))
    assert not own.exists() or not list(own.rglob("*.npz"))
    again, why = references.read(problem)
    assert again is not None, why


def test_the_plugin_folder_is_untracked_in_a_checkout():
    if paths.CHECKOUT is None:
        pytest.skip("an installed copy: no checkout")
    rel = paths.CHECKOUT / "results" / "plugin-reference" / "x" / "y.npz"
    done = subprocess.run(["git", "check-ignore", "-q", str(rel)], cwd=paths.CHECKOUT)
    assert done.returncode == 0, "results/plugin-reference/ must be ignored by git"


def test_a_reference_that_fails_ends_in_one_line(tmp_path, monkeypatch, capsys):
    """``ibench reference`` on a set whose reference fails (the codes disagree, a code
    fails) says so in one line and exits 1, as ``ibench run`` records ``no_reference``."""
    from integrator_bench.harness import cli
    from integrator_bench.harness.errors import ReferenceFailure

    monkeypatch.setattr(references, "REFERENCE_DIR", tmp_path / "reference")

    def fails(problem, tighten=1.0):
        raise ReferenceFailure("scipy-Radau failed: the step size became too small")

    monkeypatch.setattr(references, "compute", fails)
    assert cli.main(["reference", "-p", "two_mass:c2=0.1", "--recompute"]) == 1
    out, err = capsys.readouterr()
    lines = [x for x in err.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith("ibench: no reference for two_mass:"), err
    assert lines[0].endswith(": scipy-Radau failed: the step size became too small"), err
    assert "Traceback" not in err and not out
