"""The report's "what the driving costs": a driven problem's records against its
undriven twin's (harness/report/driving.py), from records made by hand (the
findings follow the numbers either way) and from a real run of Kapitza's pendulum
and its twin through the report."""

import numpy as np
import pandas as pd
import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand, parse_problem_spec
from integrator_bench.harness.matrix.store import Store, load
from integrator_bench.harness.report import driving, markdown, write_report
from integrator_bench.harness.report.document import Group
from integrator_bench.harness.report.sections import comparison_part
from integrator_bench.harness.run.context import RunContext
from records_frame import records_frame

DRIVEN = '{"A": 0.1}'
TWIN = '{"A": 0.0}'


def records(params, nfev, mescd, forms=("i3", "projection"), cpu=1.0):
    """Three adaptive ok records per formulation (integrators a, b, c) and one
    fixed-step one; ``nfev[form]`` and ``mescd[form]`` the adaptive ones' values."""
    rows = []
    for form in forms:
        for label in ("a", "b", "c"):
            rows.append({"integrator": label, "formulation": form, "rtol": 1e-4, "h": None,
                         "status": "ok", "nfev": nfev[form], "nsteps": nfev[form] // 2,
                         "cpu_s": cpu * nfev[form] / 100, "mescd": mescd[form],
                         "drift_pos": 1e-9, "drift_vel": 1e-8})
        rows.append({"integrator": "d", "formulation": form, "rtol": None, "h": 0.01,
                     "status": "ok", "nfev": 400, "nsteps": 200, "cpu_s": 0.1,
                     "mescd": mescd[form], "drift_pos": 1e-9, "drift_vel": 1e-8})
    return records_frame(rows, problem="kapitza", params=params)


def driving_text(driven, twin) -> str:
    group = Group(rows=driven, ranked=pd.DataFrame(), families={}, figure=None, twin=twin)
    return "\n".join(markdown.part(comparison_part(group)))


def test_the_ratios_are_driven_over_twin_pair_by_pair():
    twin = records(TWIN, {"i3": 100, "projection": 100}, {"i3": 6.0, "projection": 6.0})
    driven = records(DRIVEN, {"i3": 300, "projection": 800}, {"i3": 5.0, "projection": 3.0})
    paired = driving.pairs(driven, twin)
    assert len(paired) == 8 and paired["adaptive"].sum() == 6
    i3 = paired[(paired.formulation == "i3") & paired.adaptive]
    assert np.allclose(i3["nfev"], 3.0) and np.allclose(i3["nsteps"], 3.0)
    assert np.allclose(i3["cpu_s"], 3.0) and np.allclose(i3["cpu_per_fev"], 1.0)
    assert np.allclose(i3["lost"], 1.0)
    fixed = paired[~paired.adaptive]
    assert fixed["nfev"].isna().all() and np.allclose(fixed["cpu_s"], 1.0)
    summary = driving.by_formulation(paired)
    assert list(summary.formulation) == ["i3", "projection"]
    assert summary.set_index("formulation").loc["projection", "nfev"] == 8.0


def test_a_record_not_ok_on_either_side_makes_no_pair():
    twin = records(TWIN, {"i3": 100, "projection": 100}, {"i3": 6.0, "projection": 6.0})
    driven = records(DRIVEN, {"i3": 300, "projection": 800}, {"i3": 5.0, "projection": 3.0})
    driven.loc[driven.integrator == "a", "status"] = "failed"
    twin.loc[twin.integrator == "b", "status"] = "timeout"
    assert set(driving.pairs(driven, twin)["label"]) == {"c", "d"}


@pytest.mark.parametrize("costly", ["i3", "projection"])
def test_the_findings_name_the_formulation_the_measurements_make_costly(costly):
    """The same records with the costs swapped: the sentence follows them, and calls
    the difference clear when the ranges are apart, not when they overlap."""
    other = {"i3": "projection", "projection": "i3"}[costly]
    twin = records(TWIN, {"i3": 100, "projection": 100}, {"i3": 6.0, "projection": 6.0})
    driven = records(DRIVEN, {costly: 900, other: 200}, {costly: 2.0, other: 5.5})
    text = driving_text(driven, twin)
    assert "### What the driving costs" in text
    assert (f"The driving costs {costly} the most in f-evals (median ×9) and {other} the "
            "least (×2): their ranges are apart") in text
    assert f"The driving costs {costly} the most in accuracy (median +4.0 digits lost)" in text
    assert f"| {costly} | 4 (3) | 9 | 9 |" in text
    spread = driven.copy()
    spread.loc[(spread.integrator == "a") & (spread.formulation == costly), "nfev"] = 150
    assert "their ranges overlap" in driving_text(spread, twin)


def test_no_driving_block_without_a_twin_and_a_line_when_nothing_paired():
    driven = records(DRIVEN, {"i3": 300, "projection": 800}, {"i3": 5.0, "projection": 3.0})
    assert "What the driving costs" not in driving_text(driven, None)
    twin = records(TWIN, {"i3": 100, "projection": 100}, {"i3": 6.0, "projection": 6.0})
    twin["status"] = "failed"
    assert "No pair: no case ended ok on both" in driving_text(driven, twin)


def test_a_bare_name_runs_the_twin_and_the_quick_preset_at_its_first_fixed_step():
    """``kapitza`` stands for its set and its twin (A = 0); a spec with values does
    not; the quick preset runs the twin's fixed-step codes at 1000 steps only."""
    cls = registry.get_problem_class("kapitza")
    assert [s.params_dict["A"] for s in parse_problem_spec("kapitza")] == [0.1, 0.0]
    assert [s.params_dict["A"] for s in parse_problem_spec("kapitza:A=0.2")] == [0.2]
    assert driving.twin_params(cls, {**cls().params, "A": 0.0}) is None
    assert driving.twin_params(registry.get_problem_class("pendulum"), {}) is None
    cases = [c for c in expand(problems=["kapitza"], integrators=["hht", "ida"])
             if not c.unsupported]
    steps = {a: {c.h for c in cases if dict(c.params)["A"] == a and c.h} for a in (0.1, 0.0)}
    assert steps == {0.1: {2.0 / 1000, 2.0 / 2000}, 0.0: {2.0 / 1000}}
    assert {c.rtol for c in cases if dict(c.params)["A"] == 0.0 and c.rtol} == {1e-3, 1e-6}


def test_kapitza_and_its_twin_through_the_report(tmp_path, run_cases):
    """A real run: the driven set's page says what the driving costs each formulation
    that ran on both sets, its twin's page does not (it has no twin of its own)."""
    cases = expand(problems=["kapitza"], formulations=["i3", "ggl"], integrators=["ida"],
                   rtols=[1e-4])
    assert len(cases) == 4
    with Store(tmp_path / "s.sqlite") as store:
        run_cases(cases, RunContext(store=store, jobs=2, progress=False))
    files = write_report(load(tmp_path / "s.sqlite"), tmp_path / "report")
    pages = {f.name.split("_")[1]: f.read_text() for f in files
             if f.suffix == ".md" and f.name.startswith("kapitza")}
    assert "What the driving costs" not in pages["A=0"]
    page = pages["A=0.1"]
    assert "### What the driving costs" in page and "twin's (A=0:" in page
    rows = [line for line in page.splitlines() if line.startswith(("| i3 | 1 (1) |",
                                                                  "| ggl | 1 (1) |"))]
    assert len(rows) == 2, page
    html = next(f for f in files if f.name == "index.html").read_text()
    assert "What the driving costs" in html
