"""The seeds' numbers beside the project's runs (harness/model/seed_numbers.py): the
``seeds`` preset runs every row's configuration, and the verdicts follow the
records."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from integrator_bench.harness.model import registry, seed_numbers as sn
from integrator_bench.harness.model.cases import PRESETS, budget, expand
from integrator_bench.harness.report.sections import sources_part


def test_the_preset_runs_every_rows_configuration_once():
    cases = expand(preset="seeds")
    registered = registry.integrators()
    wanted = [c for c in sn.preset_cases() if c[2].partition(":")[0] in registered]
    assert len(cases) == len(wanted) == len(set(wanted))
    assert not [c for c in cases if c.unsupported]
    for row in sn.ROWS:
        assert (row.problem, row.formulation, row.integrator, row.rtol, row.h) in \
            sn.preset_cases()
    # every table of seed 003 (3 problems x 4 approaches x 3 TOL) and of seed 002
    assert sum(r.seed == "003" for r in sn.ROWS) == 36
    assert {r.table.split(" (")[0] for r in sn.ROWS if r.seed == "002"} == {
        "Table 1", "Table 2", "Table 3", "Table 5"}


def test_the_preset_budget_holds_for_its_own_matrix_only():
    assert budget("seeds") == PRESETS["seeds"].budget_s == 900.0
    assert budget("seeds", problems=["two_mass"]) is None
    assert len(expand(preset="seeds", problems=["two_mass"])) > 0   # the ladder


def _record(row: sn.SourceRow, scale: float, **extra) -> dict:
    name, params = sn._params(row.problem)
    base, _, sets = row.integrator.partition(":")
    settings = dict(kv.split("=") for kv in sets.split(",") if kv)
    counts = {k: v * scale for k, v in row.published.items() if k != "speedup"}
    return {"problem": name, "params": json.dumps(params), "formulation": row.formulation,
            "integrator": base, "settings": json.dumps(settings) if settings else None,
            "rtol": row.rtol, "h": row.h, "status": "ok", "solver_counts": None,
            **counts, **extra}


def _row(seed, **match):
    return next(r for r in sn.ROWS if r.seed == seed
                and all(getattr(r, k) == v for k, v in match.items()))


@pytest.mark.parametrize("scale, differs, verdict", [
    (1.05, "", "agrees"), (1.3, "", "unexplained"), (1.3, "another code", "explained")])
def test_verdicts_follow_the_numbers_and_the_named_difference(scale, differs, verdict,
                                                              monkeypatch):
    row = _row("002", row="CVODE (Adams)")
    changed = sn.SourceRow(**{**row.__dict__, "differs": differs})
    monkeypatch.setattr(sn, "ROWS", (changed,))
    (c,) = sn.compare(pd.DataFrame([_record(changed, scale)]))
    assert c.verdict == verdict and c.ratios["nsteps"] == pytest.approx(scale)
    assert sn.summary([c])[verdict] == 1


def test_a_row_without_its_record_is_not_run_and_other_settings_do_not_match():
    row = _row("004", h=2e-6)
    other = _record(row, 1.0)
    other["settings"] = json.dumps({"polynomial": "P4"})
    compared = sn.compare(pd.DataFrame([other]))
    assert all(c.verdict == "not run" for c in compared)
    assert sources_part(pd.DataFrame([other])) is None


def test_orlov_speedup_is_rk4s_evaluations_over_the_cells():
    row = _row("004", h=2e-6)
    rk4 = {**_record(row, 1.0), "integrator": "rk4", "settings": None, "h": sn.RK4_H,
           "nfev": 800_000}
    cell = {**_record(row, 1.0), "nfev": 800_000 / 6.0}
    (c,) = [c for c in sn.compare(pd.DataFrame([rk4, cell])) if c.row is row]
    assert c.ours["speedup"] == pytest.approx(6.0) and c.verdict == "agrees"
    # the report's cleaned records name the variant with its settings
    cell["integrator"] = "dumka3 (polynomial=P5)"
    (c,) = [c for c in sn.compare(pd.DataFrame([rk4, cell])) if c.row is row]
    assert c.verdict == "agrees"


def test_seed_003_nj_is_shown_not_compared_and_the_part_lists_the_tables():
    row = _row("003", row="ECS, TOL 0.0001", problem="slider_crank")
    (c,) = [c for c in sn.compare(pd.DataFrame([_record(row, 2.0, njev=1)])) if c.row is row]
    assert set(c.ours) == {"nsteps"} and c.verdict == "explained"
    part = sources_part(pd.DataFrame([_record(row, 2.0)]))
    assert part.key == "sources" and "1 differ with the difference" in part.caption
    titles = [b.title for b in part.blocks]
    assert "seed 003, Table 1 (slider-crank)" in titles and any("Table 5" in t for t in titles)


def test_a_failed_run_is_shown_with_its_status():
    row = _row("003", row="PA, TOL 0.01", problem="quick_return")
    rec = {**_record(row, 1.0), "status": "failed", "reason": "step_size_underflow"}
    (c,) = [c for c in sn.compare(pd.DataFrame([rec])) if c.row is row]
    assert c.verdict == "failed here" and "step_size_underflow" in c.status
    assert sn.summary([c])["failed here"] == 1
