"""The schedule: lines loose to tight, one case at a time, skipped on evidence,
the most expensive line first; a run with skipping, --no-skip and --resume."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import Case, expand
from integrator_bench.harness.matrix.line import ProblemSpec
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.harness.run.schedule import (
    AFTER_DIVERGENCE, AFTER_TIMEOUT, POLICY, CostModel, Schedule, implied)
from integrator_bench.harness.matrix.store import Store, load, load_runs
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits

P = (("k", 1.0),)


def _line(integrator="x", rtols=(), hs=(), problem="p", form="ode"):
    return ([Case(problem, P, form, integrator, rtol=r) for r in rtols]
            + [Case(problem, P, form, integrator, h=h) for h in hs])


def _record(case, status="ok", reason=None, cpu_s=1.0):
    return {"case_id": case.case_id, "rtol": case.rtol, "h": case.h, "status": status,
            "reason": reason, "cpu_s": cpu_s}


def test_a_line_runs_loose_to_tight_one_case_at_a_time():
    cases = _line(rtols=(1e-6, 1e-2, 1e-4)) + _line(hs=(0.001, 0.1, 0.01))
    s = Schedule(cases)
    first = [s.next(), s.next()]
    assert s.next() is None  # both lines wait for their running case
    assert {(c.rtol, c.h) for c in first} == {(1e-2, None), (None, 0.1)}
    order = list(first)
    while s:
        for c in list(order[-2:]):
            s.done(_record(c))
        nxt = [c for c in (s.next(), s.next()) if c is not None]
        order += nxt
    rtols = [c.rtol for c in order if c.rtol is not None]
    hs = [c.h for c in order if c.h is not None]
    assert rtols == [1e-2, 1e-4, 1e-6] and hs == [0.1, 0.01, 0.001]


def test_a_timeout_skips_the_tighter_tolerances_of_its_line_only():
    line = _line(rtols=(1e-2, 1e-4, 1e-6))
    other = _line("y", rtols=(1e-2, 1e-4))
    s = Schedule(line + other)
    got = {s.next(), s.next()}
    loose = next(c for c in got if c.integrator == "x")
    s.done(_record(loose, "timeout", "timeout", None))
    skipped = s.skips()
    assert {r["rtol"] for r in skipped} == {1e-4, 1e-6}
    for r in skipped:
        assert r["status"] == CaseStatus.SKIPPED and r["reason"] == AFTER_TIMEOUT
        assert r["decided_by"] == loose.case_id and r["skip_policy"] == POLICY
        assert "rtol=0.01" in r["message"] and "timed out" in r["message"]
    assert len(s) == 1  # y's tighter case still runs


def test_a_divergence_at_a_step_skips_the_larger_steps_not_the_smaller():
    small, mid, large = _line(hs=(0.001, 0.01, 0.1))
    assert implied(_record(mid, "failed", "diverged"), large)[0] == AFTER_DIVERGENCE
    assert implied(_record(mid, "failed", "diverged"), small) is None
    # a larger step diverging says nothing of the smaller ones; an adaptive one neither
    assert implied(_record(large, "failed", "diverged"), mid) is None
    r1, r2 = _line(rtols=(1e-2, 1e-4))
    assert implied(_record(r2, "failed", "diverged"), r1) is None
    # a failure of another kind proves nothing
    assert implied(_record(mid, "failed", "newton_failure"), large) is None


def test_stored_evidence_skips_before_anything_runs():
    small, mid, large = _line(hs=(0.001, 0.01, 0.1))
    s = Schedule([small, large], evidence=[(mid, _record(mid, "failed", "nonfinite_state"))])
    assert [r["h"] for r in s.skips()] == [0.1]
    assert s.next() == small


def test_no_skip_runs_every_case():
    line = _line(rtols=(1e-2, 1e-4, 1e-6))
    s = Schedule(line, skip=False)
    ran = []
    while s:
        c = s.next()
        ran.append(c)
        s.done(_record(c, "timeout", "timeout", None))
        assert not s.skips()
    assert len(ran) == 3


def test_the_most_expensive_line_goes_first_and_the_model_learns():
    sizes = {ProblemSpec("small", P): (2, 1.0), ProblemSpec("big", P): (200, 1.0)}
    cases = _line("a", hs=(0.1,), problem="small") + _line("a", hs=(0.1,), problem="big")
    assert Schedule(cases, model=CostModel(sizes)).next().problem == "big"
    # measured: the small problem's integrator is 1000x slower per unit of work
    model = CostModel(sizes)
    model.learn(Case("small", P, "ode", "a", h=0.5), 1.0)
    model.learn(Case("big", P, "ode", "a", h=0.5), 0.01)
    assert Schedule(cases, model=model).next().problem == "small"
    assert model.predict(cases[0]) == pytest.approx(1.0 * 5)  # 5x the steps of h=0.5


def test_a_line_holds_every_identity_field_but_the_tolerance():
    a, b = _line(rtols=(1e-2, 1e-4))
    assert a.line == b.line and a.line.key == b.line.key and a.case_id != b.case_id
    assert a.line != _line("y", rtols=(1e-2,))[0].line
    assert a.line != _line(hs=(0.1,))[0].line


@pytest.fixture
def hanging_line(broken_integrators):
    cases = expand(problems=["two_mass"], integrators=["test-hangs", "scipy-RK45"],
                   rtols=[1e-3, 1e-4, 1e-5])
    return [c for c in cases if c.params == cases[0].params]  # one parameter set


#: the hanging line's timeout: long enough that the scipy-RK45 cases beside it (half of
#: it for their counted solve) finish on a loaded machine (1 s did not, at load 10)
HANG_TIMEOUT = 3.0


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_run_skips_after_a_timeout_and_resume_keeps_the_policy(hanging_line, tmp_path,
                                                                      jobs, run_cases):
    path = tmp_path / "s.sqlite"
    with Store(path) as store:
        df = run_cases(hanging_line,
                       RunContext(store=store, jobs=jobs, progress=False,
                                  limits=Limits(budget_s=HANG_TIMEOUT)))
    hang = df[df.integrator == "test-hangs"].set_index("rtol")
    assert hang.loc[1e-3, "status"] == "timeout"
    assert (hang.loc[[1e-4, 1e-5], "status"] == "skipped").all()
    assert (hang.loc[[1e-4, 1e-5], "decided_by"] == hang.loc[1e-3, "case_id"]).all()
    assert (df[df.integrator == "scipy-RK45"].status == "ok").all()
    # resumed under the same policy: nothing runs again
    with Store(path) as store:
        again = run_cases(hanging_line,
                          RunContext(store=store, jobs=jobs, progress=False, resume=True,
                                     limits=Limits(budget_s=HANG_TIMEOUT)))
    assert len(load(path)) == len(hanging_line) and len(again) == len(hanging_line)
    # resumed with --no-skip: the skipped cases run (and time out)
    with Store(path) as store:
        run_cases(hanging_line,
                  RunContext(store=store, jobs=jobs, progress=False, resume=True, skip=False,
                             limits=Limits(budget_s=HANG_TIMEOUT)))
    stored = load(path)
    assert len(stored) == len(hanging_line) + 2
    assert stored[stored.integrator == "test-hangs"].status.value_counts().to_dict() \
        == {"timeout": 3, "skipped": 2}


def test_stiffness_bound_takes_its_reference_from_the_runs_folder(tmp_path):
    from integrator_bench.harness.measure import references
    from integrator_bench.harness.run.schedule import StiffnessBound

    (case,) = expand(problems=["two_mass:k2=321"], integrators=["scipy-RK45"], rtols=[1e-3])
    assert StiffnessBound(budget_s=60.0, reference_dir=tmp_path)(case) is None
    problem = registry.get_problem_class("two_mass")(**case.params_dict)
    assert references.paths(problem, tmp_path)[0].is_file()
    assert not references.paths(problem)[0].exists()  # nothing in the default folder


def test_stiffness_bound_rules_out_an_explicit_method_over_the_budget():
    from integrator_bench.harness.run.schedule import STIFFNESS_BUDGET, StiffnessBound

    (params,) = [p for p in (c.params for c in expand(problems=["two_mass"], rtols=[1e-3],
                                                          integrators=["scipy-RK45"]))
                 if dict(p)["c2"] == 1000]
    case = Case("two_mass", params, "ode", "scipy-RK45", rtol=1e-3)
    tight = StiffnessBound(budget_s=1e-4)   # rho ~ 2e3 over 10 s: thousands of steps
    why = tight(case)
    assert why and "spectral radius" in why and "budget of 0.0001 s of CPU" in why
    assert StiffnessBound(budget_s=60.0)(case) is None
    # implicit, stabilized (its interval grows with its stages) and fixed-step cases: no claim
    for other in (Case("two_mass", params, "ode", "scipy-Radau", rtol=1e-3),
                  Case("two_mass", params, "ode", "rkc", rtol=1e-3),
                  Case("two_mass", params, "ode", "rk4", h=0.1)):
        assert registry.get_integrator(other.integrator) and tight(other) is None
    s = Schedule([case], bound=tight)
    assert s.next() is None
    (record,) = s.skips()
    assert record["reason"] == STIFFNESS_BUDGET and record["decided_by"] is None
    assert Schedule([case], bound=tight, skip=False).next() == case  # --no-skip


def test_a_larger_steps_cpu_scaled_over_the_budget_skips_the_smaller_steps():
    from integrator_bench.harness.run.schedule import PREDICTED_TIMEOUT

    small, mid, large = _line(hs=(0.001, 0.01, 0.1))
    # 10x the steps of 2.5 s, halved for margin: at least 12.5 s, over a 10 s budget
    assert implied(_record(large, cpu_s=2.5), mid, budget_s=10.0)[0] == PREDICTED_TIMEOUT
    assert implied(_record(large, cpu_s=2.5), small, budget_s=10.0)[0] == PREDICTED_TIMEOUT
    assert implied(_record(large, cpu_s=1.5), mid, budget_s=10.0) is None   # 7.5 s: runs
    assert implied(_record(large, cpu_s=1.5), small, budget_s=10.0)[0] == PREDICTED_TIMEOUT
    assert implied(_record(large, cpu_s=30.0), mid) is None       # no budget, no prediction
    r1, r2 = _line(rtols=(1e-2, 1e-4))
    assert implied(_record(r1, cpu_s=30.0), r2, budget_s=10.0) is None  # adaptive: no claim
    s = Schedule([small, mid, large], budget_s=10.0)
    s.done(_record(s.next(), cpu_s=0.8))
    assert [r["h"] for r in s.skips()] == [0.001] and s.next() == mid


def test_a_resumed_run_skips_on_the_stored_records_of_a_line(hanging_line, tmp_path, run_cases):
    path = tmp_path / "s.sqlite"
    loose = [c for c in hanging_line if c.rtol == 1e-3 and c.integrator == "test-hangs"]
    with Store(path) as store:
        run_cases(loose,
                  RunContext(store=store, jobs=1, progress=False, limits=Limits(budget_s=1.0)))
    hang = [c for c in hanging_line if c.integrator == "test-hangs"]
    with Store(path) as store:
        df = run_cases(hang,
                       RunContext(store=store, jobs=1, progress=False, resume=True,
                                  limits=Limits(budget_s=1.0)))
    stored = load(path).set_index("rtol")
    assert stored.loc[1e-3, "status"] == "timeout"
    assert (stored.loc[[1e-4, 1e-5], "status"] == "skipped").all()
    assert (stored.loc[[1e-4, 1e-5], "decided_by"] == stored.loc[1e-3, "case_id"]).all()
    assert len(df) == 3


@pytest.mark.parametrize("flag, policy", [([], POLICY), (["--no-skip"], None)])
def test_cli_no_skip_is_the_runs_policy(flag, policy, tmp_path):
    store = tmp_path / "s.sqlite"
    r = subprocess.run([str(Path(sys.executable).parent / "ibench"), "run", "-p",
                        "two_mass:c2=1000", "-i", "scipy-RK45", "--rtol", "1e-3",
                        "--store", str(store), *flag],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "skipped 0 % of 1 runnable" in r.stdout and "cases: 1 ok" in r.stdout
    assert json.loads(load_runs(store).options.iloc[-1])["skip_policy"] == policy
