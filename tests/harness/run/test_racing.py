"""Racing (harness/ranking/racing.py, harness/run/raced.py): once a line of a problem
reaches the race target, its other cases get tau times that line's CPU; a case past
it is ``dominated``, never an answer, beyond tau in the profiles."""

from __future__ import annotations

import json
import math

import pytest

from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.matrix.record import AFTER_DOMINATED, RACE_BOUND, CaseStatus
from integrator_bench.harness.matrix.store import Store
from integrator_bench.harness.ranking.racing import TAU, Race
from integrator_bench.harness.report import profiles
from integrator_bench.harness.report.sections import status_part
from integrator_bench.harness.run.execution import base_record, execute
from integrator_bench.harness.run.raced import policy_of
from integrator_bench.harness.run.runner import to_dataframe
from integrator_bench.harness.run.schedule import POLICY, Schedule
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits

SMALL = "two_mass:c1=0.1,c2=1000,k1=10,k2=10000"


def _cases(integrators, rtols=(1e-3, 1e-6)):
    return expand(problems=[SMALL], integrators=list(integrators), rtols=list(rtols),
                  formulations=["ode"])


def _ok(case, cpu_s, err):
    """An ok record of ``case`` that took ``cpu_s`` and reached the mixed error ``err``."""
    record = base_record(case)
    record.update(status="ok", cpu_s=cpu_s, err_max=err, cpu_samples=json.dumps([cpu_s]),
                  budget_s=5.0, budget_edge=0)
    return record


def _timeout(case):
    record = base_record(case)
    record.update(status="timeout", reason="over_budget", message="past the budget")
    return record


def _hand_out(schedule):
    """Every case the schedule hands out now, by line label."""
    out = {}
    while (case := schedule.next()) is not None:
        out[case.line.label] = case
    return out


def test_a_line_that_reaches_the_target_leads_its_problem():
    best, other = _cases(["scipy-DOP853", "scipy-RK45"], rtols=(1e-6,))
    race = Race(target=1e-5)
    race.learn(_ok(other, 0.5, 1e-4))       # not reached: no lead
    assert race.bound(best) is None
    race.learn(_ok(best, 0.01, 1e-7))        # below the target at its first point: at most
    bound = race.bound(other)
    assert bound["race_cpu_s"] == 0.01 and bound["race_bound_s"] == TAU * 0.01
    assert bound["race_line"] == "scipy-DOP853 (ode)" and bound["race_target"] == 1e-5
    race.learn(_ok(other, 0.002, 1e-6))     # a cheaper line takes the lead
    assert race.bound(best)["race_line"] == "scipy-RK45 (ode)"


def _failed(case):
    record = base_record(case)
    record.update(status="failed", reason="newton_failure", cpu_s=0.001)
    return record


def test_a_case_100_times_the_best_is_cut_one_at_2_times_is_not():
    cases = _cases(["scipy-DOP853", "scipy-RK45", "scipy-RK23"], rtols=(1e-3, 1e-6, 1e-8))
    race = Race(target=1e-5)
    s = Schedule(cases, budget_s=5.0, race=race)
    first = _hand_out(s)
    assert all(c.budget_s is None for c in first.values())    # no lead yet
    s.done(_ok(first["scipy-DOP853"], 0.01, 1e-6))            # the lead: 0.01 s
    s.done(_failed(first["scipy-RK45"]))                      # no point yet
    s.done(_ok(first["scipy-RK23"], 0.02, 1e-6))              # reached, at 2 times the best
    second = _hand_out(s)
    assert {c.budget_s for c in second.values()} == {TAU * 0.01}
    # RK45 at 100 times the best: its worker stops it at the bound, a timeout
    cut = _timeout(second["scipy-RK45"])
    s.done(cut)
    assert cut["status"] == CaseStatus.DOMINATED and cut["reason"] == RACE_BOUND
    assert cut["race_bound_s"] == TAU * 0.01 and cut["race_line"] == "scipy-DOP853 (ode)"
    assert cut["budget_s"] == 5.0 and "race bound" in cut["message"]
    # RK23 at twice the best: ok, ranked as an exhaustive run's record
    kept = _ok(second["scipy-RK23"], 0.03, 1e-8)
    s.done(kept)
    assert kept["status"] == CaseStatus.OK and kept["budget_s"] == 5.0
    assert kept["budget_edge"] == 0 and kept["race_bound_s"] == TAU * 0.01
    # the tighter case of the cut line is dominated without running
    later = s.skips()
    assert [(r["reason"], r["rtol"], r["decided_by"]) for r in later] == \
        [(AFTER_DOMINATED, 1e-8, cut["case_id"])]
    assert later[0]["status"] == CaseStatus.DOMINATED
    assert later[0]["skip_policy"] == policy_of(POLICY, race)


def test_a_line_that_could_still_cross_within_tau_is_not_raced():
    """A loose point above the target and under the bound: the line's crossing would
    interpolate between it and its next case, below tau whatever that case costs."""
    cases = _cases(["scipy-DOP853", "scipy-RK45"], rtols=(1e-3, 1e-6))
    race = Race(target=1e-5)
    s = Schedule(cases, budget_s=5.0, race=race)
    first = _hand_out(s)
    s.done(_ok(first["scipy-DOP853"], 0.01, 1e-6))
    s.done(_ok(first["scipy-RK45"], 0.004, 1e-3))      # above the target, under the bound
    assert _hand_out(s)["scipy-RK45"].budget_s is None
    # a line already dearer than the bound is raced
    line = _cases(["scipy-RK23"], rtols=(1e-3, 1e-6))
    race.learn(_ok(line[0], 1.0, 1e-3))
    assert race.bound(line[1])["race_bound_s"] == TAU * 0.01


def test_exhaustive_hands_every_case_out_at_the_runs_budget():
    cases = _cases(["scipy-DOP853", "scipy-RK45"], rtols=(1e-3, 1e-6))
    s = Schedule(cases, budget_s=5.0)             # no race: --exhaustive
    first = _hand_out(s)
    s.done(_ok(first["scipy-DOP853"], 0.01, 1e-6))
    s.done(_ok(first["scipy-RK45"], 0.004, 1e-3))
    second = _hand_out(s)
    assert second and all(c.budget_s is None for c in second.values())
    record = _timeout(second["scipy-RK45"])
    s.done(record)
    assert record["status"] == CaseStatus.TIMEOUT


@pytest.mark.parametrize("ratio, status", [(100.0, CaseStatus.DOMINATED), (2.0, CaseStatus.OK)])
def test_the_worker_stops_a_case_at_its_race_bound(ratio, status, run_cases):
    """End to end: a lead set at 1/ratio of the case's own CPU; its worker gets the bound."""
    case, = expand(problems=[SMALL], integrators=["rk4"], hs=[2e-4])
    cpu = execute(case, repeat=1)["cpu_s"]
    race = Race(target=1e-5)
    race.leads[(case.problem, case.params_json)] = (cpu / ratio, "a line (ode)")
    df = run_cases([case],
                   RunContext(jobs=1, progress=False, race=race,
                              limits=Limits(budget_s=60.0, repeat=1)))
    row = df.iloc[0]
    assert row.status == status, row.message
    assert row.race_bound_s == pytest.approx(TAU * cpu / ratio) and row.budget_s == 60.0


def _store_rows(records):
    return to_dataframe([r.to_dict() if hasattr(r, "to_dict") else r for r in records])


def test_dominated_is_no_answer_and_beyond_tau_in_the_profiles_and_the_report_says_so():
    best, cut_case = _cases(["scipy-DOP853", "scipy-RK45"], rtols=(1e-6,))
    cut = _timeout(cut_case)
    cut.update(status="dominated", reason=RACE_BOUND, race_target=1e-5, race_cpu_s=0.01,
               race_bound_s=0.16, race_line="scipy-DOP853 (ode)")
    rows = _store_rows([_ok(best, 0.01, 1e-7), cut])
    cpu, _ = profiles.costs(rows, 1e-5)
    assert cpu.loc[:, "scipy-DOP853"].iloc[0] == 0.01
    assert math.isinf(cpu.loc[:, "scipy-RK45"].iloc[0])
    assert math.isinf(profiles.ratios(cpu)["scipy-RK45"].iloc[0])
    part = status_part(rows, targets=(1e-7,))
    text = " ".join(" ".join(b.text) for b in part.blocks)
    assert "cut by the race" in text and "exact at every target at or looser than 1e-05" in text
    assert "1e-07 is tighter than the race target" in text
    assert status_part(rows, targets=(1e-3, 1e-5)).blocks[-1].text[-1].startswith("The store")
    table = part.blocks[-1].tables[0]
    assert table.rows[0][2:5] == ("1", "0", "scipy-DOP853 (ode)")


def test_a_dominated_record_is_done_for_a_resumed_run_under_the_same_race_only(tmp_path):
    case, = _cases(["scipy-RK45"], rtols=(1e-6,))
    race = Race()
    record = _timeout(case)
    record.update(status="dominated", skip_policy=policy_of(POLICY, race))
    with Store(tmp_path / "s.sqlite") as store:
        store.add(record)
        version = record["code_version"]
        assert store.done_case_ids(version, policy_of(POLICY, race)) == {case.case_id}
        assert store.done_case_ids(version, POLICY) == set()    # --exhaustive runs it


def test_the_quick_preset_is_not_raced_the_full_one_is():
    from integrator_bench.harness.cli import build_parser
    from integrator_bench.harness.cli.run import _race

    parse = build_parser().parse_args
    assert _race(parse(["run"])) is None
    assert _race(parse(["run", "--preset", "full", "--exhaustive"])) is None
    assert _race(parse(["run", "--preset", "full"])).target == 1e-5
    assert _race(parse(["run", "--race-target", "1e-4"])).target == 1e-4


def test_the_race_reads_a_lines_reach_as_the_ranking_does():
    """The lead after every record is the least CPU to the target of the lines of
    :func:`~integrator_bench.harness.ranking.reach.cpu_to_reach` on the same records:
    points at the budget's edge, failed ones and those that missed an event left out,
    the Pareto front and the interpolated crossing alike."""
    from integrator_bench.harness.ranking.reach import cpu_to_reach

    cases = _cases(["scipy-DOP853", "scipy-RK45", "scipy-RK23", "scipy-LSODA"],
                   rtols=(1e-2, 1e-4, 1e-6, 1e-8))
    rng = __import__("random").Random(3)
    race, records = Race(target=1e-5), []
    for case in cases:
        record = _ok(case, rng.uniform(0.001, 1.0), 10 ** rng.uniform(-9, -1))
        record.update(status=rng.choice(["ok"] * 5 + ["failed"]),
                      budget_edge=int(rng.random() < 0.1),
                      events_missed=int(rng.random() < 0.1))
        race.learn(record)
        records.append(record)
        table = cpu_to_reach(_store_rows(records), 1e-5)
        reached = table[table["how"] != "not reached"]
        key = (case.problem, case.params_json)
        if reached.empty:
            assert key not in race.leads
        else:
            assert race.leads[key][0] == pytest.approx(float(reached["cpu_s"].min()))
