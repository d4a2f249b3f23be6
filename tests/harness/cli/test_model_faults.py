"""A model that raises, returns the wrong shape, segfaults or loops forever -- a
problem plugin or an FMU built from the test FMU's sources with the fault
compiled in -- costs its own cases, never the command: beside two_mass in one
``ibench run`` its cases are recorded with the fault and two_mass runs ``ok``;
``reference``, ``stiffness`` and ``advise`` name it in one line; no temporary
directory is left behind. Each model works at its start (where the FMU's set-up
calls it) and fails past it, where the fingerprint probe, the reference and the
stiffness analysis call it."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import plugin_dist
import pytest

HERE = Path(__file__).resolve().parents[2]
REPO = HERE.parent
IBENCH = [sys.executable, "-m", "integrator_bench.harness.cli"]

PLUGIN = '''
import ctypes


class Raising(Decay):
    name = "bad_raise"

    def fault(self, y):
        raise RuntimeError("the plugin's model failed")


class WrongShape(Decay):
    name = "bad_shape"

    def fault(self, y):
        return np.zeros(3)


class Segfault(Decay):
    name = "bad_segv"

    def fault(self, y):
        ctypes.string_at(0)


class Spin(Decay):
    name = "bad_spin"

    def fault(self, y):
        while True:
            pass
'''

#: the faults compiled into the Van der Pol FMU's derivatives past its start
FMU_FAULTS = {"segv": "*(volatile int *)0 = 1;", "spin": "volatile int on = 1; while (on) {}"}
PLUGINS = ("bad_raise", "bad_shape", "bad_segv", "bad_spin")


@pytest.fixture(scope="module")
def plugin_path(tmp_path_factory):
    """A folder on PYTHONPATH that registers the faulty problems as a plugin does."""
    return plugin_dist.install(tmp_path_factory.mktemp("plugin"), "faulty_problems", PLUGIN,
                               dict(zip(PLUGINS, ("Raising", "WrongShape", "Segfault", "Spin"))))


@pytest.fixture(scope="module")
def faulty_fmus(tmp_path_factory):
    """fault -> the Van der Pol FMU (tests/fmu_vanderpol) with that fault compiled
    into its derivatives for t > 0."""
    pytest.importorskip("fmpy")
    from integrator_bench.problems import fmu_build

    out = {}
    for fault, code in FMU_FAULTS.items():
        src = tmp_path_factory.mktemp(f"src_{fault}")
        shutil.copytree(HERE / "fmu_vanderpol", src, dirs_exist_ok=True)
        c = src / "sources" / "vanderpol.c"
        text = c.read_text()
        body = "    (void)t; (void)p;\n"
        assert body in text
        c.write_text(text.replace(body, f"    (void)p;\n    if (t > 0.0) {{ {code} }}\n"))
        try:
            out[fault] = fmu_build.build_fmu("vanderpol", tmp_path_factory.mktemp(fault),
                                             source_dir=src)
        except RuntimeError as exc:  # no CMake or C compiler here
            pytest.skip(str(exc))
    return out


@pytest.fixture
def env(tmp_path, plugin_path):
    """The environment of a command: the plugin installed, references (two_mass's
    committed ones) and temporary files in folders of the test's own."""
    refs = tmp_path / "reference"
    shutil.copytree(REPO / "results" / "reference" / "two_mass", refs / "two_mass")
    (tmp_path / "tmp").mkdir()
    return {**os.environ, "PYTHONPATH": str(plugin_path), "IBENCH_REFERENCE_DIR": str(refs),
            "IBENCH_DATA_DIR": str(tmp_path / "data"), "TMPDIR": str(tmp_path / "tmp")}


def _ibench(env, *args, timeout=300):
    return subprocess.run([*IBENCH, *args], env=env, capture_output=True, text=True,
                          timeout=timeout)


def _left_in_tmp(env) -> list:
    return sorted(p.name for p in Path(env["TMPDIR"]).iterdir())


def test_faulty_models_beside_two_mass_in_one_run(env, faulty_fmus, tmp_path):
    fmus = [f"fmu:path={faulty_fmus[f]}" for f in FMU_FAULTS]
    problems = [*PLUGINS, *fmus, "two_mass:c2=0.1"]
    r = _ibench(env, "run", *(a for p in problems for a in ("-p", p)), "-i", "scipy-RK45",
                "--rtol", "1e-3", "--reference-timeout", "2", "--store",
                str(tmp_path / "s.sqlite"), "--json", "--no-contenders")
    assert r.returncode == 0, r.stderr[-3000:]
    records = {rec["problem"] if rec["problem"] != "fmu" else
               Path(json.loads(rec["params"])["path"]).parent.name.rstrip("0123456789"):
               rec for rec in map(json.loads, r.stdout.splitlines())}
    assert records["two_mass"]["status"] == "ok"
    expected = {"bad_raise": ("error", "the model raised RuntimeError: the plugin's model "
                                       "failed while its reference was computed"),
                "bad_shape": ("error", "the model raised ValueError"),
                "bad_segv": ("crashed", "the model crashed (SIGSEGV) while its reference"),
                "bad_spin": ("timeout", "the model gave no result while its reference"),
                "segv": ("crashed", "the model crashed (SIGSEGV) while its reference"),
                "spin": ("timeout", "the model gave no result while its reference")}
    for name, (status, said) in expected.items():
        record = records[name]
        assert (record["status"], record["reason"]) == (status, "no_reference"), record
        assert said in record["message"], record["message"]
    assert _left_in_tmp(env) == []


def test_reference_names_each_fault_and_shows_two_mass(env, faulty_fmus):
    problems = [*PLUGINS, *(f"fmu:path={faulty_fmus[f]}" for f in FMU_FAULTS), "two_mass:c2=0.1"]
    r = _ibench(env, "reference", *(a for p in problems for a in ("-p", p)),
                "--reference-timeout", "2", "--json")
    assert r.returncode == 1
    assert [json.loads(line)["problem"] for line in r.stdout.splitlines()] == ["two_mass"]
    lines = r.stderr.splitlines()
    assert sum(line.startswith("ibench: no reference for ") for line in lines) == 6, r.stderr
    assert "crashed (SIGSEGV) while its reference was computed" in r.stderr
    assert _left_in_tmp(env) == []


@pytest.mark.parametrize("fault", ["segv", "spin"])
def test_stiffness_and_advise_name_the_fault_in_one_line(env, faulty_fmus, fault, tmp_path):
    spec = f"fmu:path={faulty_fmus[fault]}"
    said = "crashed (SIGSEGV)" if fault == "segv" else "gave no result"
    r = _ibench(env, "stiffness", "-p", spec, "--reference-timeout", "2", "--store",
                str(tmp_path / "s.sqlite"))
    assert r.returncode == 1 and r.stderr.strip().splitlines()[-1].startswith(
        f"ibench: no stiffness analysis for fmu:") and said in r.stderr, r.stderr
    r = _ibench(env, "advise", "-p", "bad_" + fault, "--target", "1e-3", "--budget", "6",
                "-i", "scipy-RK45", "--store", str(tmp_path / "s.sqlite"), "--json")
    assert r.returncode == 1, r.stderr[-2000:]
    answer = json.loads(r.stdout)
    assert said in json.dumps(answer), answer
    assert _left_in_tmp(env) == []


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_run_stuck_in_a_looping_model_stops_within_a_second(env, faulty_fmus, tmp_path,
                                                              signum):
    proc = subprocess.Popen([*IBENCH, "run", "-p", f"fmu:path={faulty_fmus['spin']}",
                             "-i", "scipy-RK45", "--rtol", "1e-3", "--store",
                             str(tmp_path / "s.sqlite")], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    time.sleep(8)   # past the set-up, into the reference's computation
    assert proc.poll() is None
    sent = time.monotonic()
    proc.send_signal(signum)
    said = []
    for line in proc.stderr:   # the lines before the signal are read at once
        said.append((time.monotonic() - sent, line))
    proc.wait(timeout=30)
    [(when, _)] = [(t, line) for t, line in said if line.startswith("ibench: interrupted")]
    assert when < 1.0 and time.monotonic() - sent < 10, said
    assert proc.returncode == 128 + signum
    assert _left_in_tmp(env) == []
