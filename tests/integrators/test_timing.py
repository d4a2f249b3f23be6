"""One solve, counted and timed; enough samples; ties in the report.

A case runs each integrator's ``timed_call``, the library's own loop where it
has one, on the system whose callables count their calls, and that solve is
both the record's counts and its first timing sample (its ``run`` alone
timed); the sampling rule; the
tie logic of the report, on a small hand-made store (the ranking never names a
cheapest line among lines whose CPU lies within their spread).
"""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.measure import tripwire
from integrator_bench.harness.measure.counting import COUNTED_CODES, counted
from integrator_bench.harness.run.execution import (MIN_CPU_S, execute, sample_record, samples,
                                                timing_mismatch)
from integrator_bench.harness.matrix.record import FIELDS, CaseStatus, empty_record
from integrator_bench.harness.ranking.reach import reach_line, target_table
from integrator_bench.harness.report import write_report
from integrator_bench.harness.report.sections import answer
from integrator_bench.harness.matrix.store import Store, load
from integrator_bench.integrators.base import TIMING_LOOPS, Solution, Status
from integrator_bench.integrators.driver import Budget
from integrator_bench.problems.system import convert

SMALL = "two_mass:c1=0.1,c2=1000,k1=10,k2=10000"   # cvode-bdf solves it in a few ms
COUNTS = ("nfev", "njev", "nlu", "nsteps", "nreject", "nniter", "nnfail")


def library_names():
    return [n for n, c in registry.integrators().items()
            if not c.has_stepper() and c.accepts & {"ode", "dae"}]


# --- count once, time bare ---------------------------------------------------------------

def assert_timed_agrees(name, counted, bare, dop853_extra):
    """The timed solve ``bare`` took the counted solve's steps: same outputs and
    states, the same counts, but for DOP853's dense output, which costs
    evaluations (at most ``dop853_extra``): solve_ivp builds it also where an
    output time is a step's end (t_end), the stepping loop takes the step's own
    state there (the record's ``timing_mismatch`` says so)."""
    assert bare.status is Status.SUCCESS and np.array_equal(bare.t, counted.t)
    np.testing.assert_allclose(bare.y, counted.y, rtol=1e-9, atol=1e-12)
    for key in set(counted.counts) & set(bare.counts):
        extra = bare.counts[key] - counted.counts[key]
        assert extra == 0 or (name == "scipy-DOP853" and key == "nfev"
                              and 0 < extra <= dop853_extra), (key, extra)


@pytest.mark.parametrize("name", library_names())
def test_library_codes_are_timed_through_their_own_loop_and_agree(name):
    """Every library integrator taking ODEs or DAEs runs its case through its
    library's loop, with the outputs of the segment-runner loop and its own
    counts equal to that loop's (steps too); the record's counts are the
    library loop's, counted at the model."""
    case, = expand(problems=[SMALL], formulations=["ode"], integrators=[name], rtols=[1e-6])
    icls = registry.get_integrator(name)
    problem = registry.get_problem_class("two_mass")(**case.params_dict)
    system = convert(problem.formulate("ode"), icls)
    assert icls().timing_loop(system) == "library"
    atol = system.atol(1e-6)
    counted, bare = (f(system, rtol=1e-6, atol=atol)
                     for f in (icls().solve, icls().timed_solve))
    assert_timed_agrees(name, counted, bare, 1e-3 * counted.counts.get("nfev", 0))
    record = execute(case, repeat=2)
    assert record["status"] == CaseStatus.OK and record["timing"] == "library"
    assert record["timing_mismatch"] is None        # both samples did the same work
    assert 1 <= record["repeat"] <= 2
    for key in ("nsteps", "nreject", "nlu", "nniter", "nnfail"):
        assert record[key] == bare.counts.get(key), key
    if "nfev" in bare.counts and name != "scipy-DOP853":
        assert record["nfev"] >= bare.counts["nfev"]  # the harness counts every call


@pytest.mark.parametrize("name", [n for n in library_names()
                                  if "max_step" in {s.name for s in
                                                    registry.get_integrator(n).settings}])
def test_the_timed_solve_runs_with_the_cases_settings(name):
    """A setting changes the timed solve as it changes the counted one (the bound
    changes the counted solve's counts; the timed one takes the same steps):
    ``-i scipy-RK45:max_step=...`` had timed the default step sizes."""
    icls = registry.get_integrator(name)
    problem = registry.get_problem_class("two_mass")(**expand(problems=[SMALL])[0].params_dict)
    system = convert(problem.formulate("ode"), icls)
    atol = system.atol(1e-3)
    counted, bare = (f(system, rtol=1e-3, atol=atol)
                     for f in (icls(max_step=1e-3).solve, icls(max_step=1e-3).timed_solve))
    assert counted.counts != icls().solve(system, rtol=1e-3, atol=atol).counts
    # DOP853's dense output: its 3 extra stages, at most once per output time
    assert_timed_agrees(name, counted, bare, 3 * system.t_eval.size)


def test_a_reset_at_an_event_is_timed_through_the_wrapper():
    case = next(c for c in expand(problems=["bouncing_ball"], integrators=["cvode-bdf"],
                                  rtols=[1e-4]) if not c.unsupported)
    record = execute(case, repeat=2)
    assert record["status"] == CaseStatus.OK and record["timing"] == "wrapper"


def test_steppers_are_timed_through_the_driver():
    case = next(c for c in expand(problems=["pendulum"], integrators=["rk4"], hs=[0.01])
                if not c.unsupported)
    record = execute(case, repeat=2)
    assert record["status"] == CaseStatus.OK and record["timing"] == "driver"
    assert record["timing"] in TIMING_LOOPS


def test_every_timed_solve_is_counted_at_the_model(monkeypatch):
    """Each sample solves a system whose callables count their calls at the model
    (the counting closures, the same code every time): the case's one solve is
    its counted solve."""
    icls = registry.get_integrator("cvode-bdf")
    seen = []
    original = icls.timed_call

    def timed_call(self, system, **kw):
        seen.append(getattr(system.fun, "__code__", None) in COUNTED_CODES)
        return original(self, system, **kw)
    monkeypatch.setattr(icls, "timed_call", timed_call)
    case, = expand(problems=[SMALL], integrators=["cvode-bdf"], rtols=[1e-6])
    record = execute(case, repeat=4)
    assert len(seen) == record["repeat"] >= 1 and all(seen)


def _burn(seconds):
    end = time.process_time() + seconds
    while time.process_time() < end:
        pass


@pytest.mark.parametrize("part", ["before", "finish"])
def test_only_the_library_call_is_timed(monkeypatch, part):
    """The CPU recorded is ``TimedCall.run``'s alone: work before it (the
    library's options) or in its ``finish`` (the counters read) is not the
    case's, however long it takes."""
    from integrator_bench.integrators.base import TimedCall

    icls = registry.get_integrator("cvode-bdf")
    original = icls.timed_call

    def timed_call(self, system, **kw):
        if part == "before":
            _burn(0.3)
        call = original(self, system, **kw)
        if part == "finish":
            return TimedCall(call.run, lambda out: (_burn(0.3), call.finish(out))[1])
        return call
    case, = expand(problems=[SMALL], integrators=["cvode-bdf"], rtols=[1e-6])
    plain = execute(case, repeat=1)
    monkeypatch.setattr(icls, "timed_call", timed_call)
    record = execute(case, repeat=1)
    assert record["status"] == plain["status"] == CaseStatus.OK
    assert plain["cpu_s"] < 0.1 and record["cpu_s"] < 0.1 + plain["cpu_s"]


def test_a_plugin_overriding_timed_solve_is_timed_through_it(monkeypatch):
    """A plugin written before ``timed_call`` overrides ``timed_solve``: the
    default ``timed_call`` runs that override, not ``solve``."""
    from integrator_bench.integrators.base import Integrator

    class Old(registry.get_integrator("rk4")):
        calls = []

        def timed_solve(self, system, **kw):
            self.calls.append(system)
            return self.solve(system, **kw)
    assert Old.timed_call is Integrator.timed_call
    problem = registry.get_problem_class("two_mass")(**expand(problems=[SMALL])[0].params_dict)
    system = convert(problem.formulate("ode"), Old)
    call = Old().timed_call(system, h=1e-3)
    assert not Old.calls
    sol = call.finish(call.run())
    assert sol.success and Old.calls == [system]


def test_a_timed_solve_that_counts_otherwise_is_recorded():
    t = np.linspace(0, 1, 3)
    a = Solution(t, np.zeros((3, 1)), counts={"nfev": 10, "nsteps": 4})
    b = Solution(t, np.zeros((3, 1)), counts={"nfev": 12})
    assert timing_mismatch(a, b) == "nfev: counted 10, timed 12"
    c = Solution(t[:2], np.zeros((2, 1)), status=Status.MAX_STEPS)
    assert "max_steps with 2 outputs" in timing_mismatch(a, c)


# --- enough samples ----------------------------------------------------------------------

def fake_run(cpu):
    calls = []

    def run():
        calls.append(cpu)
        return cpu, cpu
    return run, calls


@pytest.mark.parametrize("cpu, max_samples, expected", [
    (0.001, 10, 10),                        # short solves: the number of runs ends it
    (MIN_CPU_S / 3, 10, 3),                 # the minimum of CPU is reached first
    (2 * MIN_CPU_S, 10, 1),                 # one long solve is enough
    (0.001, 1, 1)])                         # --repeat 1
def test_samples_until_min_cpu_or_runs_whichever_first(cpu, max_samples, expected):
    run, calls = fake_run(cpu)
    cpus, walls = samples(run, max_samples, MIN_CPU_S)
    assert len(cpus) == len(calls) == expected


def test_samples_stay_within_the_budget():
    run, calls = fake_run(0.05)
    cpus, _ = samples(run, 10, min_cpu=10.0, budget_s=0.0)
    assert len(cpus) == 1     # a sample that would end past the budget is not started


def test_sample_record_keeps_least_median_spread_and_number():
    got = sample_record([4.0, 1.0, 2.0, 3.0, 5.0], [1.0] * 5)
    assert got == dict(cpu_s=3.0, cpu_s_min=1.0, cpu_s_iqr=2.0, wall_s=1.0, repeat=5,
                       cpu_samples="[4.0, 1.0, 2.0, 3.0, 5.0]")
    assert sample_record([1.0, 2.0], [1.0, 1.0])["cpu_s_iqr"] is None


# --- ties --------------------------------------------------------------------------------

def line(integrator, cpus, noise, errs=(1e-4, 1e-6), n=12):
    """Two ok points of one line of chain_drive (errors ``errs``), each with ``n``
    timed solves around its CPU (lognormal, ``noise`` their log spread, seeded
    per line), as alternating rounds leave them."""
    rng = np.random.default_rng(sum(map(ord, integrator)))
    rows = []
    for i, (e, c) in enumerate(zip(errs, cpus)):
        samples = [] if noise is None else list(c * np.exp(noise * rng.standard_normal(n)))
        rows.append(empty_record(
            problem="chain_drive", params='{"n_links": 30}', formulation="ode",
            integrator=integrator, rtol=10.0 ** -(3 + 3 * i), status="ok",
            scd=-math.log10(e), mescd=-math.log10(e), err_max=e,
            cpu_s=float(np.median(samples)) if samples else c,
            cpu_samples=json.dumps(samples or [c]), repeat=len(samples) or 1,
            created="2026-01-01T00:00:00+00:00"))
    return rows


@pytest.fixture
def tied_store(tmp_path):
    """A, B within the noise of each other at 1e-5; C clearly dearer but within 2x;
    D as cheap as A but timed once (no interval); E beyond 2x."""
    rows = (line("cvode-bdf", [1.0, 2.0], 0.3) + line("scipy-BDF", [1.05, 2.1], 0.3)
            + line("scipy-Radau", [1.6, 3.2], 0.01) + line("scipy-RK45", [9.0, 18.0], 0.01))
    path = tmp_path / "store.sqlite"
    with Store(path) as store:
        for r in rows:
            store.add(r)
    return load(path)


def test_reach_line_interpolates_the_spread_as_a_share_of_the_cpu():
    got = reach_line([1e-4, 1e-6], [1.0, 4.0], 1e-5, spread=[0.1, 0.4])
    assert got["cpu_s"] == pytest.approx(2.0) and got["spread"] == pytest.approx(0.2)
    assert math.isnan(reach_line([1e-4, 1e-6], [1.0, 4.0], 1e-5)["spread"])


def test_reach_line_interpolates_the_samples_sample_by_sample():
    got = reach_line([1e-4, 1e-6], [1.0, 4.0], 1e-5,
                     samples=["[9.0, 1.0, 1.0]", "[4.0, 16.0]"])
    assert got["samples"] == pytest.approx([2.0, 4.0])     # paired from the end
    assert got["points"] == (0, 1)


def test_the_table_and_the_answer_say_tie_from_a_store(tied_store, tmp_path):
    table = target_table(tied_store)
    by = table.set_index("label")
    first, second = table["label"].iloc[:2]      # A and B, in the order their medians fell
    assert {first, second} == {"cvode-bdf", "scipy-BDF"}
    assert by.loc[second, "tie_1e-05"] and not by.loc[first, "tie_1e-05"]
    assert not by.loc["scipy-Radau", "tie_1e-05"] and not by.loc["scipy-RK45", "tie_1e-05"]
    got = answer(table)
    assert got.verdict == "tie" and got.lines == f"tie: {first} (ode), {second} (ode)"
    assert got.why.startswith("margin 1.0") and "95 %" in got.why
    # the dearer line alone beside the cheapest: a winner, its margin's interval above 1
    clear = answer(target_table(tied_store[tied_store.integrator != "scipy-BDF"]))
    assert clear.verdict == "winner" and clear.lines == "cvode-bdf (ode)"
    low = float(clear.why.split("95 % ")[1].split("-")[0])
    assert low > 1
    # one sample per point: no interval, and the answer says so
    once = tied_store.assign(cpu_samples=[json.dumps([c]) for c in tied_store.cpu_s])
    alone = answer(target_table(once))
    assert alone.verdict == "tie" and "interval not measured" in alone.why
    write_report(tied_store, tmp_path / "report", scaling_dir=tmp_path / "none")
    page = (tmp_path / "report" / "chain_drive_n_links=30.md").read_text(encoding="utf-8")
    assert "a tie to reach" in page and f"{first} (ode), {second} (ode)" in page
    rows = [x for x in page.splitlines() if x.startswith(f"| {second} | ode |")]
    assert any(" tie |" in x for x in rows)
    assert not any(" tie |" in x for x in page.splitlines() if x.startswith("| scipy-Radau"))


# --- the time budget ---------------------------------------------------------------------

def budgeted_names():
    """Every integrator but fmpy's solvers (the FMU tool's own loop: only the
    worker's backstop stops them)."""
    return [n for n, c in registry.integrators().items() if c.accepts - {"fmu"}]


@pytest.mark.parametrize("name", budgeted_names())
def test_every_code_is_stopped_past_its_budget(name):
    """Under a budget of CPU no run can keep, every case is a ``timeout`` (reason
    ``over_budget``), not a failure: a run fed through the segment runner or
    the driver is stopped at its first accepted step, the progress in its
    message; a library's own loop by the tripwire (its timer rings a millisecond
    after the start at the earliest: every solve here takes longer), where the
    model was last called in its message (none when it rang before the model first
    returned), its counts left null."""
    # the pendulum where the code takes it (a stiff mechanism, the flyball, can fail a
    # first Newton iteration before any budget is checked), else the first it takes
    cases = [*expand(problems=["pendulum"], integrators=[name]), *expand(integrators=[name])]
    case = next(c for c in cases if not c.unsupported)
    record = execute(case, budget_s=1e-7)
    assert record["status"] == CaseStatus.TIMEOUT and record["reason"] == "over_budget", record
    assert record["message"].startswith("stopped") and "of CPU" in record["message"]
    if record["message"].startswith("stopped at t="):
        assert "% of the span" in record["message"]
    assert record["nfev"] is None and record["mescd"] is None
    assert record["repeat"] == 1 and record["cpu_s_over"] == pytest.approx(record["cpu_s"] - 1e-7)


def test_a_solve_that_ends_past_its_budget_is_a_timeout_and_keeps_its_errors(
        monkeypatch):
    """A solve that ends having used more CPU than its budget (its last step
    ended past it, before the tripwire's timer rang) is a ``timeout`` with its
    errors and counts, not sampled again."""
    monkeypatch.setattr(Budget, "verdict", lambda self, t0, t_end, t: None)
    monkeypatch.setattr(tripwire, "MIN_S", 600.0)     # its timer rings 10 minutes on
    case, = expand(problems=[SMALL], integrators=["rk4"], hs=[1e-3])
    record = execute(case, budget_s=1e-9, repeat=3)
    assert record["status"] == CaseStatus.TIMEOUT and record["reason"] == "over_budget"
    assert record["message"].startswith("the solve took") and "of CPU" in record["message"]
    assert record["mescd"] is not None and record["nsteps"] > 0
    assert record["timing"] == "driver" and record["repeat"] == 1
    assert execute(case, budget_s=60.0)["status"] == CaseStatus.OK


def test_the_budget_stops_a_run_past_its_seconds_only():
    start = time.perf_counter() - 2.0     # two seconds into the run
    assert Budget(5.0, start).verdict(0.0, 1.0, 0.01) is None
    message = Budget(1.5, start).verdict(1.0, 3.0, 1.2)
    assert message.startswith("stopped at t=1.2 (10 % of the span) after 2")
    assert message.endswith("past its budget of 1.5 s")


def quick_sample():
    """A sample of the quick preset's cases run by library codes: the pendulum's
    ``ode`` form at its tight tolerance, and its ``ggl`` form (the DAE codes)."""
    for name in library_names():
        accepts = registry.get_integrator(name).accepts
        form = "ode" if "ode" in accepts else "ggl"
        yield pytest.param(name, form, id=f"{name}-{form}")


@pytest.mark.parametrize("name, form", list(quick_sample()))
def test_the_one_solves_counts_equal_the_stepping_loops(name, form):
    """The record's counts, from the library's own loop, equal those of the
    wrapper's stepping loop fed to the segment runner (the counted solve of the
    code that solved every case twice), case by case: every counter both report,
    and the harness's nfev and njev, but DOP853's dense output (scipy's
    ``solve_ivp`` builds it where an output time is a step's end: 3 evaluations
    each)."""
    case, = expand(problems=["pendulum"], formulations=[form], integrators=[name],
                   rtols=[1e-6])
    record = execute(case, repeat=1)
    assert record["status"] == CaseStatus.OK and record["timing"] == "library", record["message"]
    icls = registry.get_integrator(name)
    problem = registry.get_problem_class("pendulum")(**case.params_dict)
    system, counters = counted(convert(problem.formulate(form), icls))
    stepped = icls().solve(system, rtol=1e-6, atol=system.atol(1e-6))
    own = {**stepped.counts, "nfev": counters["nfev"].n}
    if counters["njev"] is not None and "njev" not in stepped.counts:
        own["njev"] = counters["njev"].n
    for key in COUNTS:
        if own.get(key) is None:
            continue
        if name == "scipy-DOP853" and key == "nfev":
            assert 0 <= record[key] - own[key] <= 3 * system.t_eval.size
        else:
            assert record[key] == own[key], (key, record[key], own[key])
