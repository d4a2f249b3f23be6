"""studies/chain_scaling.py: its JSON, its figure and its manners (the slopes
themselves are measured by running it at full size, not here: timings flake in tests)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

from integrator_bench.harness.report.scaling import read_scaling

SCRIPT = Path(__file__).resolve().parents[2] / "studies" / "chain_scaling.py"
ROW_KEYS = {"n_links", "n_states", "rhs_s", "jac_s", "ggl_res_s", "ggl_jac_s", "i3_res_s",
            "i3_jac_s", "step_ida_s", "step_hht_s", "nsteps_ida", "nsteps_hht", "peak_mb"}
SLOPE_KEYS = {"rhs_s", "jac_s", "ggl_res_s", "ggl_jac_s", "i3_res_s", "i3_jac_s",
              "step_ida_s", "step_hht_s", "peak_mb"}


def run(*args):
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True,
                          timeout=300)


def test_tiny_sizes_give_the_json_the_report_reads_and_a_figure(tmp_path):
    r = run("--sizes", "20", "10", "--t-end", "0.003", "--min-time", "0.005", "--repeat", "1",
            "--out", str(tmp_path))
    # 1 would be a missed slope target, which tiny sizes may well give: not tested here
    assert r.returncode in (0, 1), r.stderr
    assert "log-log slopes, least squares over N = 10, 20" in r.stdout
    data = json.loads((tmp_path / "chain_drive.json").read_text())
    # the report's reader takes it (the schema is the report package's)
    assert read_scaling(tmp_path / "chain_drive.json").rows == data["rows"]
    assert set(data) == {"problem", "created", "machine", "rows", "slopes", "targets"}
    assert data["problem"] == "chain_drive" and data["machine"]
    assert data["targets"] == {"rhs_and_jac_slope_max": 1.1, "step_slope_max": 1.3}
    assert [row["n_links"] for row in data["rows"]] == [10, 20]
    for row in data["rows"]:
        assert set(row) == ROW_KEYS
        assert row["n_states"] == 2 * (3 * row["n_links"] + 2)
        for key in ROW_KEYS - {"n_links", "n_states", "nsteps_ida", "nsteps_hht"}:
            assert isinstance(row[key], float) and math.isfinite(row[key]) and row[key] > 0, key
        assert isinstance(row["nsteps_ida"], int) and row["nsteps_ida"] > 0
        assert isinstance(row["nsteps_hht"], int) and row["nsteps_hht"] > 0
    assert set(data["slopes"]) == SLOPE_KEYS
    assert all(math.isfinite(v) for v in data["slopes"].values())
    # the memory grows with the chain
    assert data["rows"][1]["peak_mb"] > data["rows"][0]["peak_mb"]
    assert (tmp_path / "chain_drive.svg").read_text().lstrip().startswith("<?xml")


def test_a_size_the_chain_cannot_take_is_one_line_and_exit_2(tmp_path):
    r = run("--sizes", "31", "--out", str(tmp_path))
    assert r.returncode == 2
    assert r.stdout == "" and len(r.stderr.strip().splitlines()) == 1
    assert "--sizes 31" in r.stderr and "valid" in r.stderr
    assert not (tmp_path / "chain_drive.json").exists()
