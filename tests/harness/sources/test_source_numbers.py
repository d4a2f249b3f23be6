"""The seeds' numbers beside the project's runs (harness/sources/numbers.py): the
``seeds`` preset runs every row's configuration, and the verdicts follow the
records."""

from __future__ import annotations

import json

import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.sources import numbers as sn
from integrator_bench.harness.matrix.cases import PRESETS, budget, expand
from integrator_bench.harness.matrix.line import parse_spec, spec_name
from integrator_bench.harness.sources import page
from records_frame import records_frame


def test_the_preset_runs_every_rows_configuration_once():
    cases = expand(preset="seeds", listed=sn.listed_cases("seeds"))
    registered = registry.integrators()
    wanted = [c for c in sn.preset_cases() if spec_name(c[2]) in registered]
    assert len(cases) == len(wanted) == len(set(wanted))
    assert not [c for c in cases if c.unsupported]
    for row in sn.ROWS:
        assert (row.problem, row.formulation, row.integrator, row.rtol, row.h) in \
            sn.preset_cases()
    # every table of seed 003 (3 problems x 4 approaches, PA twice, x 3 TOL) and of seed 002
    assert sum(r.seed == "003" for r in sn.ROWS) == 45
    assert {r.table.split(" (")[0] for r in sn.ROWS if r.seed == "002"} == {
        "Table 1", "Table 2", "Table 3", "Table 5"}


def test_the_preset_budget_holds_for_its_own_matrix_only():
    assert budget("seeds") == PRESETS["seeds"].budget_s == 900.0
    assert budget("seeds", problems=["two_mass"]) is None
    assert len(expand(preset="seeds", problems=["two_mass"])) > 0   # the ladder


def test_only_the_seeds_preset_lists_its_cases_and_its_run_needs_them():
    assert [name for name in PRESETS if sn.listed_cases(name) is not None] == ["seeds"]
    with pytest.raises(ValueError, match="seeds preset lists its cases"):
        expand(preset="seeds")


def test_ibench_run_hands_the_seeds_preset_its_cases(tmp_path, capsys):
    """``ibench run --preset seeds`` runs the list of the source documents' cases
    (the matrix knows no seed: the command hands it :func:`sn.listed_cases`)."""
    from integrator_bench.harness.cli import main

    store = tmp_path / "s.sqlite"
    assert main(["run", "--preset", "seeds", "--plan", "--json", "--store", str(store)]) == 0
    plan = json.loads(capsys.readouterr().out)
    assert plan["cases"]["runnable"] == len(expand(preset="seeds",
                                                   listed=sn.listed_cases("seeds")))
    assert not store.exists()


def _record(row: sn.SourceRow, scale: float, **extra) -> dict:
    name, params = sn._params(row.problem)
    base, sets = parse_spec(row.integrator, "setting")
    settings = sets[0] if sets else {}
    counts = {k: v * scale for k, v in row.published.items() if k != "speedup"}
    return {"problem": name, "params": json.dumps(params), "formulation": row.formulation,
            "integrator": base, "settings": json.dumps(settings) if settings else None,
            "rtol": row.rtol, "h": row.h, "status": "ok", "solver_counts": None,
            **counts, **extra}


def _row(seed, **match):
    return next(r for r in sn.ROWS if r.seed == seed
                and all(getattr(r, k) == v for k, v in match.items()))


@pytest.mark.parametrize("scale, differs, verdict", [
    (1.05, "", "agrees"), (1.3, "", "differs, unexplained"),
    (1.3, "another code", "differs, unexplained")])   # a named difference alone explains nothing
def test_verdicts_follow_the_numbers_not_the_named_difference(scale, differs, verdict,
                                                              monkeypatch):
    row = _row("002", row="CVODE (Adams)")
    changed = sn.SourceRow(**{**row.__dict__, "differs": differs})
    monkeypatch.setattr(sn, "ROWS", (changed,))
    (c,) = sn.compare(records_frame([_record(changed, scale)]))
    assert c.verdict == verdict and c.ratios["nsteps"] == pytest.approx(scale)
    assert sn.summary([c])[verdict] == 1 and set(sn.summary([c])) == set(sn.VERDICTS)


def _with_cause(monkeypatch, h=0.02):
    row = _row("002", row="BDF2", table=sn._T3)
    cause = sn.Cause("the step", row.problem, row.formulation, row.integrator, h=h)
    changed = sn.SourceRow(**{**row.__dict__, "cause": cause})
    monkeypatch.setattr(sn, "ROWS", (changed,))
    return changed


@pytest.mark.parametrize("moved, verdict", [
    (None, "differs, unexplained"),          # the cause's run is not in the store
    (1.6, "differs, unexplained"),           # it moves the numbers away
    (1.2, "differs, cause explains part"),   # toward the source's, still outside 10 %
    (1.05, "differs, cause measured")])      # within the row's own 10 %: both runs shown
def test_a_cause_is_measured_only_by_its_run_bringing_the_row_within_tolerance(
        moved, verdict, monkeypatch):
    row = _with_cause(monkeypatch)
    records = [_record(row, 1.5)]
    if moved is not None:
        records.append({**_record(row, moved), "h": row.cause.h})
    (c,) = sn.compare(records_frame(records))
    assert c.verdict == verdict
    assert ("the step" in c.status) and (moved is None) == (not c.measured)
    if moved is not None:
        assert c.measured_ratios["nsteps"] == pytest.approx(moved)
    (_, rows), = sn.tables([c])
    shown = dict(zip(sn.TABLE_HEADER, rows[0]))["the cause's run"]
    assert shown.startswith("the step:") and ("h 0.02" in shown)


@pytest.mark.parametrize("diverged", ["own", "cause"])
def test_a_diverged_run_measures_no_cause(diverged, monkeypatch):
    """A run that ended over the divergence bound is compared by its counts, but it
    is no evidence for a cause, even one that would bring the row within 10 %."""
    row = _with_cause(monkeypatch)
    bad = {"status": "failed", "reason": "diverged", "mescd": -0.3}
    records = [{**_record(row, 1.5), **(bad if diverged == "own" else {})},
               {**_record(row, 1.0), "h": row.cause.h, **(bad if diverged == "cause" else {})}]
    (c,) = sn.compare(records_frame(records))
    assert c.verdict == "differs, unexplained" and "no evidence" in c.status


def test_a_row_whose_configuration_never_ran_borrows_no_run(monkeypatch):
    row = _row("002", row="index 2, high ATOL on lambda")
    assert row.not_run
    monkeypatch.setattr(sn, "ROWS", (row,))
    (c,) = sn.compare(records_frame([_record(row, 1.0)]))   # the algvar row's configuration
    assert c.verdict == "cannot test" and not c.ours and c.status == row.not_run


def test_counts_that_cannot_agree_are_shown_and_the_codes_ratios_judged(monkeypatch):
    """Seed 002's Table 2 runs 30 s, ours 1 s: the counts are shown, not judged; the
    ratios between the codes are (NS and NF within 10 %)."""
    rows = tuple(r for r in sn.ROWS if r.table == sn._T2)
    assert all(r.ratios_only for r in rows)
    monkeypatch.setattr(sn, "ROWS", rows)
    scale = {"Lsodar": 0.04, "Dassl": 0.04, "Dopri45": 0.04, "Sdirk34": 0.06}
    got = sn.compare(records_frame([_record(r, scale[r.row]) for r in rows]))
    assert all(c.verdict == "cannot test" and c.ours for c in got)
    verdicts = {r[1]: r[-1] for r in sn.within_table_ratios(got)}
    assert verdicts == {"Dassl": "agrees", "Dopri45": "agrees",
                        "Sdirk34": "differs, unexplained"}


@pytest.mark.parametrize("parts, verdict", [
    ([], "cannot test"), (["cannot test"], "cannot test"), (["agrees"] * 3, "agrees"),
    (["agrees", "differs, unexplained", "contradicts"], "contradicts"),
    (["agrees", "differs, cause measured"], "differs, cause measured"),
    (["differs, cause measured", "differs, cause explains part"],
     "differs, cause explains part"),
    (["agrees", "differs, unexplained", "cannot test"], "differs, unexplained")])
def test_one_rule_combines_every_claims_parts(parts, verdict):
    assert sn.combine(parts) == verdict


def test_the_preset_runs_every_cause_and_orlovs_cells_and_rk4s_steps():
    cases = sn.preset_cases()
    assert all(r.cause.case in cases for r in sn.ROWS if r.cause is not None)
    assert all(sn.rk4_case(h) in cases for h in sn.RK4_HS)
    assert all(sn.orlov_cell(k, h) in cases for k in sn.ORLOV_POLYNOMIALS
               for h in sn.SEED004_ACCURATE)


def test_a_row_without_its_record_cannot_be_tested_and_other_settings_do_not_match():
    row = _row("003", row="ECS, TOL 0.0001", problem="slider_crank")
    other = _record(row, 1.0)
    other["settings"] = json.dumps({"max_order": "2"})
    compared = sn.compare(records_frame([other]))
    assert all(c.verdict == "cannot test" and c.status in ("not in the store", c.row.not_run)
               for c in compared)
    assert page.part(records_frame([other])) is None


def test_seed_003_nj_is_shown_not_compared_and_the_part_lists_the_tables():
    row = _row("003", row="ECS, TOL 0.0001", problem="slider_crank")
    (c,) = [c for c in sn.compare(records_frame([_record(row, 2.0, njev=1)])) if c.row is row]
    assert set(c.ours) == {"nsteps"} and c.verdict == "differs, unexplained"
    part = page.part(records_frame([_record(row, 2.0)]))
    assert part.key == "sources" and "1 differs, unexplained" in part.caption
    titles = [b.title for b in part.blocks]
    assert titles[:2] == ["The rule", "The sources' claims, side by side"]
    assert "seed 003, Table 1 (slider-crank)" in titles and any("Table 5" in t for t in titles)


def test_a_failed_run_cannot_be_tested_and_says_why():
    row = _row("003", row="PA, TOL 0.01", problem="quick_return")
    rec = {**_record(row, 1.0), "status": "failed", "reason": "step_size_underflow"}
    (c,) = [c for c in sn.compare(records_frame([rec])) if c.row is row]
    assert c.verdict == "cannot test" and "step_size_underflow" in c.status
    assert sn.summary([c])["cannot test"] == 1


def test_the_sources_self_contradictions_are_flagged_on_their_rows():
    flagged = {(r.seed, r.table.split(" (")[0], r.row) for r in sn.ROWS if r.flag}
    assert ("002", "Table 1", "BDF4") in flagged             # ΔF 133, not 153
    assert ("002", "Table 2", "Lsodar") in flagged           # "fewest steps" vs Dopri45
    assert ("003", "Table 1", "TP, TOL 0.01") in flagged     # "PA best" vs TP's counts
    assert 16214 - 16061 == 153 and "153" in _row("002", row="BDF4").flag


def _sweep(problem, table):
    """ICS sweep records: ``table[alpha] = (drift_pos, failed steps)`` at every TOL,
    None for a run that failed."""
    out = []
    for alpha, got in table.items():
        for tol in sn.ICS_TOLS:
            spec, form, integrator, rtol, _ = sn.ics_case(problem, alpha, tol)
            name, params = sn._params(spec)
            params["baumgarte_beta"] = alpha
            drift, failed = got or (float("nan"), 0)
            out.append({"problem": name, "params": json.dumps(params), "formulation": form,
                        "integrator": integrator, "settings": None, "rtol": rtol, "h": None,
                        "status": "ok" if got else "failed", "reason": None, "mescd": None,
                        "nsteps": 10, "nfev": 20, "nreject": failed, "nnfail": 0,
                        "drift_pos": drift})
    return records_frame(out)


def test_the_ics_alpha_ranks_violation_and_failed_steps_equally_among_runs_that_ended():
    """Alpha 0 fails a run (not admissible); 100 has the least violation, 1 the
    fewest failed steps, 3 the least rank sum; with every rank sum equal the
    smallest alpha wins (the paper raises alpha from 0); a record at another alpha
    never stands for the default row."""
    df = _sweep("manipulator", {0.0: None, 1.0: (1e-2, 0), 3.0: (1e-3, 0), 10.0: (1e-4, 1),
                                30.0: (1e-5, 5), 100.0: (1e-6, 9)})
    t = sn.tune_alpha(df, "manipulator")
    assert 0.0 not in t.rank_sum and t.runs[0.0][1e-2] is None
    assert t.chosen == 3.0 and t.rank_sum == {1.0: 6, 3.0: 5, 10.0: 6, 30.0: 6, 100.0: 6}
    tied = _sweep("manipulator", {1.0: (1e-2, 0), 3.0: (1e-3, 1), 10.0: (1e-4, 2)})
    assert sn.tune_alpha(tied, "manipulator").chosen == 1.0
    assert sn.match(df, "manipulator", "baumgarte", "cvode-adams", 1e-2, None) is None
