"""Seed 000's CPU ratios and seed 001's stiffness criterion run here
(harness/sources/runs.py, harness/sources/page.py): the preset runs their lines, the ratios follow the
records, and the criterion's verdict is set beside what the runs show."""

from __future__ import annotations

import json
import math

import pytest

from integrator_bench.harness.measure import stiffness
from integrator_bench.harness.sources import numbers as sn
from integrator_bench.harness.sources import runs as sr
from integrator_bench.harness.sources import claims, page
from records_frame import records_frame


def test_the_preset_runs_every_line_of_the_ratios_and_the_criterion():
    cases = sn.preset_cases()
    for ladder in (*sr.LADDERS, *sr.stiffness_ladders()):
        for case in ladder.cases():
            assert case in cases
    assert {r.num for r in sr.RATIOS} | {r.den for r in sr.RATIOS} <= set(sr.LADDERS)
    # every ratio the seminar states: chain and belt against HHT and Newmark, the two
    # large models, the 150-body belt and the crawler
    assert [round(r.published, 2) for r in sr.RATIOS] == [2.35, 2.31, 4.1, 3.74, 8.95, 4.04,
                                                          4.25, 3.19]


def _records(ladder: sr.Ladder, cpu, err, nfev=None, work=None) -> list[dict]:
    name, params = sn._params(ladder.problem)
    nfev = nfev or [100 * c for c in cpu]
    work = work or [None] * len(cpu)
    return [{"problem": name, "params": json.dumps(params), "formulation": ladder.formulation,
             "integrator": ladder.integrator, "settings": None, "rtol": r, "h": h,
             "status": "ok", "cpu_s": c, "err_max": e, "mescd": -math.log10(e),
             "final_degenerate": False, "nfev": f, "njev": f / 10, "nlu": f / 10, "work": w}
            for (_, _, _, r, h), c, e, f, w in zip(ladder.cases(), cpu, err, nfev, work)]


def test_the_ratios_at_the_seminars_error_and_at_matched_error():
    # IDA: 1 s at rtol 1e-2 (error 1e-1), 2 s at 1e-3 (error 1e-3) ...; HHT: 0.5 s at
    # 1e-2 (error 1e-1), 1 s at 1e-3 (error 1e-2), 4 s at 1e-4 (error 1e-3)
    si2 = _records(sr.SI2, [1, 2, 4, 8, 16], [1e-1, 1e-3, 1e-4, 1e-5, 1e-6])
    hht = _records(sr.HHT, [0.5, 1, 4, 8, 16, 32], [1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6])
    compared = page.compare_ratios(records_frame(si2 + hht))
    c = next(c for c in compared if c.row.den is sr.HHT)
    assert c.at_tol == pytest.approx(2.0)              # both at rtol 1e-3
    # to 1e-2: IDA halfway (in log error) from 1 s to 2 s, HHT 1 s at a point
    assert c.matched[1e-2] == (pytest.approx(math.sqrt(2)), "=")
    assert c.matched[1e-3] == (pytest.approx(0.5), "=")
    # CPU not reversed (2.0, 1.41 above 1) nor near the seminar's 2.35 at every point
    assert c.verdict == "differs, unexplained"
    assert c.counts["nfev"] == pytest.approx(0.5)      # 200 f against 400 at error 1e-3
    newmark = next(c for c in compared if c.row.den is sr.NEWMARK)
    assert newmark.verdict == "cannot test" and math.isnan(newmark.at_tol)
    header, rows = page.ratio_table(compared)
    assert len(rows) == len(sr.RATIOS) and rows[0][3] == "1.41"


@pytest.mark.parametrize("den_nfev, den_work", [
    ([10_000] * 6, [5, 10, 40, 80, 160, 320]),       # reversed on CPU, counts and work
    ([50] * 6, [0.05, 0.1, 0.4, 0.8, 1.6, 3.2])])    # reversed on CPU only
def test_seed_000_is_judged_on_cpu_the_quantity_its_claim_speaks_of(den_nfev, den_work):
    """IDA faster than HHT on CPU contradicts the seminar whatever the work and the
    counts say (shown, not voted), and the headline of a mixed set reads the same."""
    si2 = _records(sr.SI2, [1, 2, 4, 8, 16], [1e-1, 1e-3, 1e-4, 1e-5, 1e-6],
                   work=[0.1, 0.2, 0.4, 0.8, 1.6])
    hht = _records(sr.HHT, [5, 10, 40, 80, 160, 320], [1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6],
                   nfev=den_nfev, work=den_work)
    compared = page.compare_ratios(records_frame(si2 + hht))
    c = next(c for c in compared if c.row.den is sr.HHT)
    assert c.at_tol == pytest.approx(0.2) and c.verdict == "contradicts"
    assert c.status == "reversed on CPU, the claim's quantity"
    assert c.work[1e-3][0] == pytest.approx(0.2 / den_work[2])   # both at error 1e-3
    header, rows = page.ratio_table([c])
    assert "work at matched error 0.001" in header
    claim = claims._seminar_claim(compared)
    assert claim[-1] == "contradicts" and "CPU 0.05-0.20" in claim[3]
    assert "cause unknown" in claim[3] and "not voted" in claim[3]


@pytest.mark.parametrize("figures, verdict", [
    ([(0.6, "="), (0.62, "≥"), (math.nan, "")], "contradicts"),   # the crawler's: 0.60 counts
    ([(0.62, "≥")], "cannot test"),          # a lower bound is no value, nor a reversal
    ([(0.5, "≤"), (0.3, "=")], "contradicts"),
    ([(2.4, "="), (2.3, "=")], "agrees"),
    ([(2.4, "="), (1.5, "≤")], "differs, unexplained"),    # a bound outside 10 % of 2.35
    ([(0.5, "="), (1.5, "=")], "differs, unexplained")])
def test_seed_000_ratios_take_values_not_bounds(figures, verdict):
    assert page.cpu_verdict(figures, 2.35)[0] == verdict


def _orlov(integrator, settings, h, cpu, nfev, err, status="ok") -> dict:
    return {"problem": "cvt_chain", "params": json.dumps({"friction": 1.0}),
            "formulation": "ode", "integrator": integrator,
            "settings": json.dumps(settings) if settings else None, "rtol": None, "h": h,
            "status": status, "cpu_s": cpu, "nfev": nfev, "monitor_err": err,
            "work": nfev * 1e-5}


def test_orlov_compares_at_his_error_criterion_rk4_at_its_largest_step_meeting_it():
    records = [_orlov("rk4", None, 5e-8, 60.0, 400_000, 0.058),     # misses E <= 0.05
               _orlov("rk4", None, 2.5e-8, 120.0, 800_000, 4e-10),
               _orlov("dumka3", {"polynomial": "P5"}, 2e-6, 5.0, 67_500, 5e-6),
               _orlov("dumka3", {"polynomial": "P7"}, 3e-6, 130.0, 80_000, 1e-5),
               _orlov("dumka3", {"polynomial": "P8"}, 4e-6, 10.0, 80_000, 0.2)]
    by = {c.k: c for c in page.compare_orlov(records_frame(records))}
    assert by[5].rk4_h == 2.5e-8 and by[5].cpu == pytest.approx(24.0)
    assert by[5].edge_h == 5e-8 and by[5].edge_cpu == pytest.approx(12.0)
    assert by[5].nfev == pytest.approx(800_000 / 67_500)
    assert by[5].work == pytest.approx(800_000 / 67_500)   # the work of nfev at 10 us
    assert by[5].verdict == "differs, unexplained"       # 12-24 against the slides' 5.9
    assert by[7].verdict == "contradicts"                 # RK4 faster here
    assert by[8].verdict == "cannot test" and "misses" in by[8].status
    header, rows, note = page.orlov_table(list(by.values()), records_frame(records))
    assert "h 5e-08: ok, E 0.058" in note


@pytest.mark.parametrize("low, high, verdict", [
    (5.99, 6.98, "cannot test"),        # the page's P5: across 10 % of 5.9, the edge decides
    (5.24, 6.11, "differs, unexplained"), (5.5, 6.2, "agrees"), (0.5, 0.9, "contradicts"),
    (math.nan, 7.0, "cannot test")])    # no larger RK4 step ran: a bound only
def test_a_speed_up_between_two_rk4_steps_is_judged_on_both_ends(low, high, verdict):
    assert page._bracket_verdict(low, high, 5.9 if low != 5.24 else 4.7)[0] == verdict


def test_seed_004s_own_verdicts_on_p4_to_p9_beside_ours():
    records = [_orlov("dumka3", {"polynomial": "P4"}, 2e-6, 1.0, 1, 0.028),   # accurate here
               _orlov("dumka3", {"polynomial": "P8"}, 4e-6, 1.0, 1, 4e-5),
               _orlov("dumka3", {"polynomial": "P9"}, 4e-6, 1.0, 1, None, status="failed")]
    by = {(c.k, c.h): c for c in page.compare_cells(records_frame(records))}
    assert len(by) == 12 and by[(4, 2e-6)].seed004 == "not accurate"
    assert by[(4, 2e-6)].verdict == "contradicts" and by[(4, 2e-6)].slides == "bad"
    assert by[(8, 4e-6)].verdict == "agrees" and by[(9, 4e-6)].verdict == "agrees"
    assert by[(6, 2e-6)].verdict == "cannot test"
    # a cell the slides mark untested is no claim of seed 004's measured: not judged
    untested = [_orlov("dumka3", {"polynomial": "P6"}, 4e-6, 1.0, 1, 0.047)]
    (c,) = [c for c in page.compare_cells(records_frame(untested)) if c.ours != "–"]
    assert c.slides == "untested" and c.ours == "accurate" and c.verdict == "cannot test"


@pytest.mark.parametrize("verdict, explicit, implicit, physical, expected", [
    ("stiff", 900, 50, False, "struggles, as the criterion says"),
    ("non-stiff", 900, 50, True, "physical stiffness"),
    ("moderate", 900, 50, False, "struggles; the criterion says moderate"),
    ("non-stiff", 900, 100, False, "keeps up, as the criterion (non-stiff)"),
    ("stiff", 10, 5, False, "keeps up at this"),
    ("non-stiff", 10, 5, True, "resolved by both"),
    ("stiff", 600, None, False, "struggles, as the criterion says"),   # T rho / beta 1000
    ("moderate", None, 5, False, "not in the store")])
def test_what_the_runs_show_beside_the_criterion(verdict, explicit, implicit, physical,
                                                 expected):
    assert expected in page.shows(verdict, explicit, implicit, bound=1000, physical=physical)


def test_the_criterion_classes_the_courses_two_mass_example():
    assert stiffness.classify(None) == "no underdamped mode"
    assert [stiffness.classify(x) for x in (0.0, 19.9, 20, 200, 200.1)] == [
        "non-stiff", "non-stiff", "moderate", "moderate", "stiff"]
    header, rows = page.stiffness_rows(records_frame(_records(
        sr.Ladder("two_mass:c2=1000", "ode", sr.EXPLICIT, rtols=(sr.STIFFNESS_RTOL,)),
        [1.0], [1e-4])).assign(nsteps=5000))
    by = {r[0]: dict(zip(header, r)) for r in rows}
    assert by["two_mass:c2=1000"]["criterion"] == "stiff"       # ratio 890
    assert by["two_mass:c2=0.1"]["criterion"] == "non-stiff"    # physical stiffness only
    assert by["two_mass:c2=1000"][f"{sr.EXPLICIT} steps"] == "5000"
    assert "struggles, as the criterion says" in by["two_mass:c2=1000"]["what the runs show"]


def _crashes(problem):
    import ctypes
    ctypes.string_at(0)


def test_a_stiffness_analysis_that_crashes_is_its_rows_not_the_reports_end(monkeypatch):
    """The analysis runs in a process of its own: one whose model crashes there (a
    segfault) says so in its row, and the report's process lives on."""
    monkeypatch.setattr(page, "_checked_analysis", _crashes)
    monkeypatch.setattr(page, "_ANALYSED", {})
    header, rows = page.stiffness_rows(records_frame(_records(
        sr.Ladder("two_mass:c2=1000", "ode", sr.EXPLICIT, rtols=(sr.STIFFNESS_RTOL,)),
        [1.0], [1e-4])).assign(nsteps=5000))
    by = {r[0]: dict(zip(header, r)) for r in rows}
    assert by["two_mass:c2=1000"]["criterion"] == (
        "no analysis: the model crashed (SIGSEGV) while its stiffness was analysed")


def test_a_run_that_reached_the_end_over_the_divergence_bound_is_compared_by_counts():
    row = next(r for r in sn.ROWS if r.seed == "003" and r.row == "PA, TOL 0.01"
               and r.problem == "quick_return")
    name, params = sn._params(row.problem)
    rec = {"problem": name, "params": json.dumps(params), "formulation": row.formulation,
           "integrator": row.integrator, "settings": None, "rtol": row.rtol, "h": None,
           "status": "failed", "reason": "diverged", "mescd": -0.01, "nsteps": 356.0,
           "nfev": 712.0, "solver_counts": None}
    (c,) = [c for c in sn.compare(records_frame([rec])) if c.row is row]
    assert c.verdict == "agrees" and "ran to the end, final error 1" in c.status
    stopped = {**rec, "mescd": math.nan}                 # stopped early: no error kept
    (c,) = [c for c in sn.compare(records_frame([stopped])) if c.row is row]
    assert c.verdict == "cannot test" and c.status.startswith("failed here")
    part = page.part(records_frame([rec]))
    titles = [b.title for b in part.blocks]
    assert any(t.startswith("seed 000") for t in titles)
    assert any(t.startswith("seed 001") for t in titles)


def test_a_criterion_run_that_ended_over_the_divergence_bound_shows_its_steps():
    ladder = sr.Ladder("two_mass:c2=0.1", "ode", sr.EXPLICIT, rtols=(sr.STIFFNESS_RTOL,))
    (rec,) = _records(ladder, [1.0], [2.0])
    rec.update(status="failed", reason="diverged", nsteps=70)
    assert page._steps(records_frame([rec]), ladder.problem, sr.EXPLICIT) == (70.0,
                                                                        " (final error 2)")
    rec.update(mescd=math.nan)                     # stopped early: nothing to show
    assert page._steps(records_frame([rec]), ladder.problem, sr.EXPLICIT) == (None, "")


@pytest.mark.parametrize("pa_steps, verdict", [(20, "agrees"), (40, "contradicts")])
def test_pa_best_is_judged_on_pa_with_its_projection_against_tp_and_ecs(pa_steps, verdict):
    """TP as the paper runs it: the TP row's cause run, the tangent formulation (the
    row's own coordinate partitioning does not count)."""
    def rec(approach, nsteps, nfev, cause=False):
        row = next(r for r in sn.ROWS if r.seed == "003" and r.problem == "slider_crank"
                   and r.row == f"{approach}, TOL 0.01")
        problem, formulation, integrator, rtol, _ = row.cause.case if cause else row.case
        name, params = sn._params(problem)
        return {"problem": name, "params": json.dumps(params), "formulation": formulation,
                "integrator": integrator, "settings": None, "rtol": rtol, "h": None,
                "status": "ok", "nsteps": nsteps, "nfev": nfev, "solver_counts": None}
    compared = sn.compare(records_frame([rec("PA projected", pa_steps, 3 * pa_steps),
                                        rec("TP", 10, 30), rec("TP", 30, 90, cause=True),
                                        rec("ECS", 35, 70)]))
    claim = claims._pa_best_claim(compared)
    assert claim[-1] == verdict and "of 3 comparisons" in claim[3]


def _student(row_name: str, table: str, **counts) -> dict:
    row = next(r for r in sn.ROWS if r.seed == "002" and r.row == row_name
               and r.table.startswith(table))
    name, params = sn._params(row.problem)
    return {"problem": name, "params": json.dumps(params), "formulation": row.formulation,
            "integrator": row.integrator, "settings": None, "rtol": row.rtol, "h": row.h,
            "status": "ok", "solver_counts": None, **counts}


@pytest.mark.parametrize("i3, verdict", [
    ({"njev": 784, "nnfail": 120}, "agrees"), ({"njev": 145, "nnfail": 0}, "differs, unexplained"),
    ({"njev": 100, "nnfail": 0}, "contradicts")])
def test_index_3_worst_is_judged_on_jacobians_and_convergence_failures(i3, verdict):
    records = [_student("index 2, algvar", "Table 5", nsteps=615, nfev=1592, njev=114,
                        nnfail=0),
               _student("index 3, high ATOL on v, lambda", "Table 5", nsteps=238, nfev=1001,
                        **i3)]
    t5 = claims._by_row(sn.compare(records_frame(records)), "002", "Table 5")
    claim = claims._index3_claim(t5["index 3, high ATOL on v, lambda"], t5["index 2, algvar"])
    assert claim[-1] == verdict


@pytest.mark.parametrize("lsodar_f, verdict", [(2215, "agrees"), (5000, "contradicts")])
def test_table_3s_adaptive_codes_take_fewer_calls_than_the_fixed_step_bdfs(lsodar_f, verdict):
    records = [_student(f"BDF{p}", "Table 3", nsteps=1000, nfev=4000 + p) for p in (2, 3, 4)]
    records += [_student("CVODE (Adams)", "Table 3", nsteps=1007, nfev=1227),
                _student("Lsodar", "Table 3", nsteps=1063, nfev=lsodar_f)]
    claim = claims._fewer_calls_claim(claims._by_row(sn.compare(records_frame(records)),
                                                       "002", "Table 3"))
    assert claim[-1] == verdict


@pytest.mark.parametrize("kinds, verdict", [
    ({"beak_hit": 21, "jam_up": 21}, "agrees"), ({"beak_hit": 25}, "differs, unexplained"),
    (None, "cannot test")])
def test_the_woodpeckers_beak_hits_are_judged_on_its_run(kinds, verdict):
    problem, formulation, integrator, rtol, h = sr.WOODPECKER
    rec = {"problem": problem, "params": "{}", "formulation": formulation,
           "integrator": integrator, "settings": None, "rtol": rtol, "h": h, "status": "ok",
           "events_by_kind": None if kinds is None else json.dumps(kinds)}
    claim = claims._woodpecker_claim(records_frame([rec]))
    assert claim[-1] == verdict and ("21 hits in 2 s" in claim[3]) == (verdict == "agrees")
    assert sr.WOODPECKER in sn.preset_cases()


@pytest.mark.parametrize("nfev, verdict", [((300, 200, 100), "contradicts"),
                                           ((100, 200, 300), "agrees")])
def test_higher_order_more_f_evaluations_is_judged_at_each_order(nfev, verdict):
    records = [_student(f"BDF{p}", "Table 1", nfev=f) for p, f in zip((2, 3, 4), nfev)]
    t1 = claims._by_row(sn.compare(records_frame(records)), "002", "Table 1")
    assert claims._higher_order_claim(t1)[-1] == verdict


def test_lsodar_fewest_jacobians_is_judged_among_the_codes_that_use_them():
    records = [_student("Lsodar", "Table 2", nsteps=10, nfev=20, njev=125),
               _student("Dassl", "Table 2", nsteps=10, nfev=20, njev=85),
               _student("Dopri45", "Table 2", nsteps=10, nfev=20, njev=0),
               _student("Sdirk34", "Table 2", nsteps=10, nfev=20, njev=300)]
    t2 = claims._by_row(sn.compare(records_frame(records)), "002", "Table 2")
    rows = {n: c for n, c in t2.items() if c.row.published.get("njev")}
    assert set(rows) == {"Lsodar", "Dassl", "Sdirk34"}
    claim = claims._lsodar_claim(rows, "njev", "Jacobians")
    assert claim[-1] == "contradicts" and "fewest here: Dassl" in claim[3]


@pytest.mark.parametrize("status, verdict", [("ok", "contradicts"), ("failed", "cannot test")])
def test_a_diverged_run_is_no_evidence_for_a_claim(status, verdict):
    """ECS with fewer steps than PA contradicts 'ECS takes more steps', unless its run
    diverged (it ran to the end over the divergence bound: its counts are shown, but
    no claim rests on them)."""
    def rec(approach, nsteps, **extra):
        row = next(r for r in sn.ROWS if r.seed == "003" and r.problem == "slider_crank"
                   and r.row == f"{approach}, TOL 0.01")
        name, params = sn._params(row.problem)
        return {"problem": name, "params": json.dumps(params), "formulation": row.formulation,
                "integrator": row.integrator, "settings": None, "rtol": row.rtol, "h": None,
                "status": "ok", "nsteps": nsteps, "nfev": 2 * nsteps, "solver_counts": None,
                **extra}
    bad = {} if status == "ok" else {"status": "failed", "reason": "diverged", "mescd": -0.1}
    compared = sn.compare(records_frame([rec("PA", 20), rec("ECS", 10, **bad)]))
    assert claims._ecs_claim(compared)[-1] == verdict


@pytest.mark.parametrize("nniter, verdict", [(7500, "agrees"), (30_000, "differs, unexplained")])
def test_newtons_iterations_per_step_are_judged_on_the_trapezoidal_run(nniter, verdict):
    problem, formulation, integrator, rtol, h = sr.TRAPEZOIDAL
    name, params = sn._params(problem)
    base, sets = sn.parse_spec(integrator, "setting")
    rec = {"problem": name, "params": json.dumps(params), "formulation": formulation,
           "integrator": base, "settings": json.dumps(sets[0]), "rtol": rtol, "h": h,
           "status": "ok", "nsteps": 2500, "nniter": nniter, "monitor_err": 7e-4}
    claim = claims._newton_claim(records_frame([rec]))
    assert claim[-1] == verdict and "Broyden-like (not tested)" in claim[3]
    assert claims._newton_claim(records_frame([{**rec, "h": 4e-6}]))[-1] == \
        "cannot test"


@pytest.mark.parametrize("versions, trap_cpu, verdict", [
    (("a", "a"), 20.0, "contradicts"), (("a", "a"), 100.0, "agrees"),
    (("a", "b"), 20.0, "cannot test")])        # timed in different runs: no comparison
def test_the_trapezoidal_rule_against_rk4_only_timed_side_by_side(versions, trap_cpu, verdict):
    problem, formulation, integrator, rtol, h = sr.TRAPEZOIDAL
    name, params = sn._params(problem)
    base, sets = sn.parse_spec(integrator, "setting")
    trap = {"problem": name, "params": json.dumps(params), "formulation": formulation,
            "integrator": base, "settings": json.dumps(sets[0]), "rtol": rtol, "h": h,
            "status": "ok", "cpu_s": trap_cpu, "code_version": versions[0]}
    rk4 = {**_orlov("rk4", None, 4e-8, 80.0, 500_000, 0.03), "code_version": versions[1]}
    orlov = [page.OrlovCompared(5, 2e-6, 5.9, rk4_h=4e-8)]
    claim = claims._trapezoidal_speed_claim(records_frame([trap, rk4]), orlov)
    assert claim[-1] == verdict
