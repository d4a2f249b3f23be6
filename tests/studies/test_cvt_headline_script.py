"""studies/cvt_headline.py at tiny cost: cvt_chain over 1.2 ms (its reference
computed into a temporary directory), two lines; checks the table's structure
and the E measure, not the speeds."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from integrator_bench.harness.matrix.record import CaseStatus

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "studies" / "cvt_headline.py"


def run(tmp_path, *args):
    env = {**os.environ, "IBENCH_DATA_DIR": str(tmp_path / "data"),
           "IBENCH_REFERENCE_DIR": str(tmp_path / "ref")}
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True,
                          text=True, env=env, timeout=600)


@pytest.fixture(scope="module")
def headline(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("cvt_headline")
    r = run(tmp, "--friction", "1", "--t-end", "0.0012", "--compute-reference",
            "--lines", "dumka3-P5", "cvode-bdf", "--rtol", "1e-3", "--jobs", "2", "--json",
            "--store", str(tmp / "records.sqlite"))
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout), tmp / "records.sqlite"


def test_json_has_the_lines_their_e_targets_and_counts(headline):
    data, _ = headline
    assert data["targets"] == [0.05, 1e-3] and data["orlov_speedup"] == [4.4, 5.9]
    (res,) = data["results"]
    assert res["friction"] == 1 and res["law"] == "smooth" and 5e7 < res["rho"] < 5e8
    lines = {r["integrator"] for r in res["rows"]}
    assert lines == {"dumka3-P5", "cvode-bdf"}
    p5 = next(r for r in res["rows"] if r["integrator"] == "dumka3-P5")
    # three steps at 0.95, 0.7 and 0.5 of P5's stable step reach Orlov's E <= 0.05
    assert p5["how_5e-02"] in ("at most", "interpolated") and p5["cpu_5e-02"] > 0
    assert p5["nfev_5e-02"] > 0 and 0 < p5["best_err"] < 0.05
    assert data["cases"] == 4 and data["failed"] == 0
    (p5_big,) = res["largest"]                   # P5 at 0.95 beta_5 / rho, as Orlov ran it
    assert p5_big["integrator"] == "dumka3-P5" and p5_big["status"] == CaseStatus.OK
    assert p5_big["h"] == pytest.approx(0.95 * 226.9 / res["rho"], rel=1e-9)
    assert 0 < p5_big["E"] < 0.05 and math.isnan(p5_big["rk4_over"] or math.nan)


def test_records_carry_orlovs_error(headline):
    from integrator_bench.harness.matrix.store import load

    _, store = headline
    df = load(store)
    assert (df["status"] == CaseStatus.OK).all()
    assert ((df["monitor_err"] > 0) & (df["monitor_err"] < 1)).all()
    assert df["h"].notna().sum() == 3 and set(df["integrator"]) == {"dumka3-P5", "cvode-bdf"}


@pytest.mark.parametrize("args, word", [(["--friction", "2"], "--friction 2"),
                                        (["--lines", "rk5"], "--lines rk5"),
                                        (["--h", "-1"], "positive")])
def test_bad_input_exits_2_with_one_line(tmp_path, args, word):
    r = run(tmp_path, *args)
    assert r.returncode == 2 and word in r.stderr and len(r.stderr.strip().splitlines()) == 1
