"""The summary page's performance and data profiles against hand-computed ones."""

import json
import math

import numpy as np
import pandas as pd
import pytest

from integrator_bench.harness.report import profiles
from integrator_bench.harness.report.write import write_report
from integrator_bench.harness.matrix.store import Store, load
from records_frame import records_frame

INF = math.inf


def _rec(problem, integrator, rtol, mescd, cpu, nfev, status="ok"):
    return {"case_id": f"{problem}-{integrator}-{rtol}", "problem": problem,
            "params": json.dumps({"k": 1}), "formulation": "ode", "integrator": integrator,
            "rtol": rtol, "h": None, "status": status, "mescd": mescd if status == "ok" else None,
            "err_max": 10.0 ** -mescd if status == "ok" else None,
            "cpu_s": cpu if status == "ok" else None, "nfev": nfev, "created": "2026-01-01"}


# problem A: x 1 s, y 2 s, z fails; B: x 4, y 1, z 8 (interpolated: 1 s at 1e-2, 16 s at
# 1e-6 -> 8 s at 1e-5 and 2 s at 1e-3); C: x 3, y times out, z 3; D: nobody.
RECORDS = [
    _rec("A", "x", 1e-3, 6, 1.0, 10), _rec("A", "y", 1e-3, 6, 2.0, 50),
    _rec("A", "z", 1e-3, None, None, None, "failed"),
    _rec("B", "x", 1e-3, 6, 4.0, 100), _rec("B", "y", 1e-3, 6, 1.0, 10),
    _rec("B", "z", 1e-2, 2, 1.0, 10), _rec("B", "z", 1e-6, 6, 16.0, 160),
    _rec("C", "x", 1e-3, 6, 3.0, 20), _rec("C", "y", 1e-3, None, None, None, "timeout"),
    _rec("C", "z", 1e-3, 6, 3.0, 200),
    _rec("D", "x", 1e-3, 1, 1.0, 5), _rec("D", "y", 1e-3, None, None, None, "skipped"),
]
KEYS = [(p, json.dumps({"k": 1})) for p in "ABCD"]


def test_cost_matrix_is_the_least_cpu_to_reach_the_target():
    cpu, nfev = profiles.costs(records_frame(RECORDS), 1e-5)
    want = pd.DataFrame([[1, 2, INF], [4, 1, 8], [3, INF, 3], [INF, INF, INF]],
                        index=pd.MultiIndex.from_tuples(KEYS), columns=list("xyz"), dtype=float)
    np.testing.assert_allclose(cpu.loc[KEYS, list("xyz")].to_numpy(), want.to_numpy())
    assert nfev.loc[KEYS[1], "z"] == pytest.approx(80)  # 10 * (160 / 10) ** 0.75, geometric
    assert profiles.costs(records_frame(RECORDS), 1e-3)[0].loc[KEYS[1], "z"] == pytest.approx(2)


def test_an_integrator_with_settings_is_a_curve_named_by_its_label():
    variant = dict(_rec("A", "x", 1e-3, 6, 0.5, 5), case_id="A-x-a", settings='{"a": 1}')
    cpu, _ = profiles.costs(records_frame([*RECORDS, variant]), 1e-5)
    assert list(cpu.columns) == ["x", "x (a=1)", "y", "z"]
    assert cpu.loc[KEYS[0], "x (a=1)"] == 0.5 and cpu.loc[KEYS[0], "x"] == 1.0


def test_performance_profile_against_hand_computed():
    cpu, _ = profiles.costs(records_frame(RECORDS), 1e-5)
    # ratios: A (1, 2, inf), B (4, 1, 8), C (1, inf, 1); D has no best and is left out
    rho = profiles.performance_profile(cpu, [1, 2, 4, 8, 100])
    assert list(rho["x"]) == pytest.approx([2 / 3, 2 / 3, 1, 1, 1])
    assert list(rho["y"]) == pytest.approx([1 / 3, 2 / 3, 2 / 3, 2 / 3, 2 / 3])
    assert list(rho["z"]) == pytest.approx([1 / 3, 1 / 3, 1 / 3, 2 / 3, 2 / 3])
    shares = profiles.share_table(cpu)
    assert shares.loc["x"].tolist() == pytest.approx([3, 2 / 3, 1])
    assert shares.loc["y"].tolist() == pytest.approx([2, 2 / 3, 2 / 3])
    assert shares.loc["z"].tolist() == pytest.approx([2, 1 / 3, 2 / 3])


def test_data_profile_against_hand_computed():
    _, nfev = profiles.costs(records_frame(RECORDS), 1e-5)
    dim = pd.Series([9.0, 4.0, 1.0, 1.0], index=nfev.index)   # n + 1: 10, 5, 2
    solved = profiles.ratios(profiles.costs(records_frame(RECORDS), 1e-5)[0]).index
    # nfev / (n + 1): x (1, 20, 10), y (5, 2, inf), z (inf, 16, 100)
    d = profiles.data_profile(nfev, dim, [1, 5, 16, 20, 100], solved)
    assert list(d["x"]) == pytest.approx([1 / 3, 1 / 3, 2 / 3, 1, 1])
    assert list(d["y"]) == pytest.approx([0, 2 / 3, 2 / 3, 2 / 3, 2 / 3])
    assert list(d["z"]) == pytest.approx([0, 0, 1 / 3, 1 / 3, 2 / 3])


def test_report_opens_with_the_summary(tmp_path):
    with Store(tmp_path / "s.sqlite") as store:
        for r in RECORDS:
            store.add(r)
    files = write_report(load(tmp_path / "s.sqlite"), tmp_path / "out", scaling_dir=tmp_path)
    assert tmp_path / "out" / "profiles.png" in files
    page = (tmp_path / "out" / "index.html").read_text()
    first_h2 = page.index("<h2")
    assert page.index("Summary: every integrator", first_h2) < page.index("Status", first_h2)
    assert 'src="profiles.png"' in page and "log2 tau" in page
    md = (tmp_path / "out" / "index.md").read_text()
    assert "| x | 3 of 4 | 67 % | 100 % |" in md.replace("  ", " ")
