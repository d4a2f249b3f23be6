"""studies/chain_headline.py at tiny cost: chain_drive at 30 links (its committed
reference), a short ladder; checks the table's structure, not the speeds."""

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
SCRIPT = ROOT / "studies" / "chain_headline.py"
sys.path.insert(0, str(ROOT / "studies"))
import chain_headline as ch  # noqa: E402


def run(tmp_path, *args, reference_dir=ROOT / "results" / "reference"):
    env = {**os.environ, "IBENCH_DATA_DIR": str(tmp_path / "data"),
           "IBENCH_REFERENCE_DIR": str(reference_dir)}
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True,
                          text=True, env=env, timeout=300)


@pytest.fixture(scope="module")
def headline(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("headline")
    store = tmp / "records.sqlite"
    r = run(tmp, "--n-links", "30", "--rtol", "1e-2", "1e-4", "1e-6", "--h", "1e-4",
            "--jobs", "2", "--json", "--store", str(store))
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout), store


def test_json_has_the_four_lines_and_their_targets(headline):
    data, _ = headline
    assert data["n_links"] == 30 and data["targets"] == [1e-3, 1e-5]
    assert data["cases"] == 3 * 3 + 1 and data["cpu_total_s"] > 0
    lines = {(r["integrator"], r["formulation"]) for r in data["rows"]}
    assert lines == set(ch.LINES)
    for r in data["rows"]:
        for tag in ("1e-03", "1e-05"):
            assert r[f"how_{tag}"] in ("interpolated", "at a point", "at most", "not reached")
            if r[f"how_{tag}"] == "not reached":
                assert r[f"cpu_{tag}"] is None and r[f"nsteps_{tag}"] is None
            else:
                assert r[f"cpu_{tag}"] > 0 and r[f"nsteps_{tag}"] >= 1
                assert r["best_err"] <= 1.0001 * float(tag)
    # IDA at rtol 1e-6 is well below 1e-3 on this chain; its loosest point is not
    ida = next(r for r in data["rows"] if (r["integrator"], r["formulation"]) == ("ida", "ggl"))
    assert ida["how_1e-03"] == "interpolated" and ida["nfev_1e-03"] > ida["nsteps_1e-03"] / 2
    cpus = [r["cpu_1e-05"] for r in data["rows"] if r["cpu_1e-05"] is not None]
    assert cpus == sorted(cpus)                             # sorted by the tighter target


def test_ratios_and_seed(headline):
    data, _ = headline
    assert len(data["ratios"]) == 2 * 2 * 2
    rows = {(r["numerator"], r["denominator"], r["target"]): r for r in data["ratios"]}
    assert ("ida (ggl)", "hht (i3)", 1e-3) in rows and ("ida (i2)", "newmark (i3)", 1e-5) in rows
    by = {(r["integrator"], r["formulation"]): r for r in data["rows"]}

    def line(label):                                        # "ida (ggl)" -> ("ida", "ggl")
        return tuple(label[:-1].split(" ("))

    for (num, den, t), r in rows.items():
        a, b = by[line(num)], by[line(den)]
        tag = f"{t:.0e}"
        if r["bound"] == "=":
            assert r["ratio"] == pytest.approx(a[f"cpu_{tag}"] / b[f"cpu_{tag}"])
        else:
            assert r["ratio"] is None or r["bound"] in ("≤", "≥")
    seed = data["seed"]["generic chain, 3759 equations, 40 ms"]
    assert seed["si2_bdf_over_hht"] == pytest.approx(1030.6 / 438.6)


def test_markdown_table_structure(headline):
    import pandas as pd

    from integrator_bench.harness.matrix.store import load

    _, store = headline
    df = load(store)
    text = ch.markdown(ch.headline(df), {"n_links": 30, "cases": len(df), "failed": 0,
                                         "cpu_total_s": 1.0, "wall_s": 2.0, "jobs": 2,
                                         "code_version": "x"})
    lines = text.splitlines()
    head = next(line for line in lines if line.startswith("| integrator"))
    cells = [c.strip() for c in head.strip("|").split("|")]
    assert cells == ["integrator", "formulation", "CPU [s] to 1e-03", "at (to 1e-03)", "nsteps",
                     "nfev", "njev", "nlu", "CPU [s] to 1e-05", "at (to 1e-05)", "nsteps",
                     "nfev", "njev", "nlu", "least error"]
    start = lines.index(head) + 2
    assert len([x for x in lines[start:start + 4] if x.startswith("|")]) == 4
    assert "| target | ratio | here | seed (chain / belt) |" in text
    assert "2.35 / 4.10" in text and "2.31 / 3.74" in text
    assert isinstance(df, pd.DataFrame) and set(df["status"]) <= {CaseStatus.OK, CaseStatus.FAILED, CaseStatus.TIMEOUT}


def test_ratio_bounds():
    assert ch.ratio(4.0, "interpolated", 2.0, "at a point") == (2.0, "=")
    assert ch.ratio(4.0, "at most", 2.0, "interpolated") == (2.0, "≤")
    assert ch.ratio(4.0, "interpolated", 2.0, "at most") == (2.0, "≥")
    assert math.isnan(ch.ratio(4.0, "at most", 2.0, "at most")[0])
    assert math.isnan(ch.ratio(math.nan, "not reached", 2.0, "interpolated")[0])


def test_bad_input_exits_2(tmp_path):
    r = run(tmp_path, "--n-links", "31")
    assert r.returncode == 2 and "--n-links 31" in r.stderr and len(r.stderr.splitlines()) == 1
    empty = tmp_path / "no-references"
    empty.mkdir()
    r = run(tmp_path, "--n-links", "40", reference_dir=empty)
    assert r.returncode == 2 and "no usable reference" in r.stderr, r.stderr
    assert not list(empty.iterdir())                        # nothing computed
