"""studies/fmu_check.py at small cost: the spring_pendulum FMU (built into a
temporary directory), two tolerances, one timing each. Checks the JSON's
structure, the FMU reference against the native one and the same integrator
on both problems; not the speeds."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from integrator_bench.harness.matrix.record import CaseStatus

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "studies" / "fmu_check.py"
RTOLS = [1e-4, 1e-7]


def run(cwd, *args):
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    env.pop("IBENCH_REFERENCE_DIR", None)   # the native reference is the committed one
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True,
                          text=True, env=env, cwd=cwd, timeout=300)


def snapshot(folder: Path) -> dict:
    """path -> (size, mtime) of every file under ``folder`` (bytecode caches left out)."""
    return {str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in folder.rglob("*") if p.is_file() and "__pycache__" not in p.parts}


@pytest.fixture(scope="module")
def checked(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("fmu_check")
    watched = [ROOT / "results", ROOT / "studies", ROOT / "problems"]
    before = [snapshot(f) for f in watched], sorted(p.name for p in ROOT.iterdir())
    r = run(tmp, "--models", "spring_pendulum", "--rtols", *map(str, RTOLS),
            "--repeat", "1", "--json")
    after = [snapshot(f) for f in watched], sorted(p.name for p in ROOT.iterdir())
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout), before == after, tmp


def test_structure(checked):
    data, _, _ = checked
    assert data["models"] == ["spring_pendulum"] and data["repeat"] == 1
    assert data["rtols"] == sorted(RTOLS, reverse=True)
    (res,) = data["results"]
    assert res["model"] == "spring_pendulum" and res["params"] == {}
    assert set(res) >= {"cross_check", "same_integrator", "work_precision", "ref_fmu_s"}
    wp = res["work_precision"]
    assert {(p["integrator"], p["rtol"]) for p in wp["points"]} == \
        {(i, r) for i in data["wp_integrators"] for r in RTOLS}
    assert [r["rtol"] for r in wp["cpu_ratios"]] == data["rtols"]
    assert [e["integrator"] for e in wp["reach"]] == data["wp_integrators"]
    assert set(wp["target_ratios"]) == {str(d) for d in data["scd_targets"]}
    assert data["cases"] == 2 * len(data["integrators"]) + 2 * len(RTOLS)


def test_fmu_reference_agrees_with_native(checked):
    data, _, _ = checked
    c = data["results"][0]["cross_check"]
    assert c["components"] == ["x", "y", "vx", "vy"]
    assert len(c["digits"]) == 4 and min(c["digits"]) >= 10 and c["min_digits"] >= 10
    assert c["events"] is None            # the spring pendulum has no events


def test_same_integrator_same_digits(checked):
    data, _, _ = checked
    same = data["results"][0]["same_integrator"]
    assert [s["integrator"] for s in same] == data["integrators"]
    for s in same:
        assert s["status_fmu"] == s["status_native"] == CaseStatus.OK, s
        assert abs(s["scd_diff"]) <= 0.05, s
        assert s["scd_diff"] == pytest.approx(s["scd_fmu"] - s["scd_native"])
        assert s["nfev_fmu"] > 0 and s["nfev_native"] > 0
        assert ("rtol" in s) != ("h" in s)
    by = {s["integrator"]: s for s in same}
    assert by["rk4"]["h"] == pytest.approx(10.0 / data["same_steps"])
    assert by["scipy-RK45"]["rtol"] == data["same_rtol"]


def test_work_precision_points(checked):
    data, _, _ = checked
    wp = data["results"][0]["work_precision"]
    for p in wp["points"]:
        assert p["status"] == CaseStatus.OK, p
        assert p["nfev"] > 0 and p["cpu_s"] > 0 and p["repeat"] == 1
        if p["integrator"] == "cvode-bdf":
            assert p["nsteps"] > 0 and p["njev"] > 0
        else:                              # fmpy reports no steps or Jacobians
            assert p["nsteps"] is None and p["njev"] is None
    fm = {p["rtol"]: p for p in wp["points"] if p["integrator"] == "fmpy-cvode"}
    assert fm[1e-7]["scd"] > fm[1e-4]["scd"]
    for r in wp["cpu_ratios"]:
        assert r["cpu_ratio"] > 0


def test_leaves_no_file_in_the_checkout(checked):
    _, unchanged, tmp = checked
    assert unchanged
    assert list(tmp.iterdir()) == []      # nor in its working directory


@pytest.mark.parametrize("args, word", [(["--models", "pendulum"], "--models pendulum"),
                                        (["--rtols", "0"], "--rtols"),
                                        (["--repeat", "0"], "--repeat 0")])
def test_bad_input_exits_2_with_one_line(tmp_path, args, word):
    r = run(tmp_path, *args)
    assert r.returncode == 2 and word in r.stderr and len(r.stderr.strip().splitlines()) == 1
