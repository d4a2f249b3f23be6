"""Event measures: matching by kind and order, missed and spurious events, the
state error after the last matched event, and references that carry events.

The non-exact problem is written here: a ball with quadratic air drag,
``y' = v``, ``v' = -g - c v |v|``, bouncing with restitution e, which has no
closed form, so its reference comes from two tight runs of two integrator
families (scipy's Radau, SUNDIALS' CVODE).
"""

import json

import numpy as np
import pytest

from integrator_bench.harness.measure import references

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.errors import ReferenceFailure
from integrator_bench.harness.measure.metrics import event_measures, event_time_digits, match_events
from integrator_bench.problems.base import Parameter, Problem
from integrator_bench.problems.system import Event

SCALE, ERR = np.array([1.0, 1.0]), np.array([0])


def ev(t, name="impact", y=(0.0, 1.0)):
    return (t, name, np.array(y, float))


REF = [ev(0.5), ev(0.8, "stick"), ev(1.2), ev(1.5, "slip"), ev(1.9, y=(0.0, 0.5))]


def test_identical_sequences_match_exactly():
    m = event_measures(REF, REF, SCALE, ERR)
    assert m == {"events_by_kind": json.dumps({"impact": 3, "slip": 1, "stick": 1}),
                 "events_matched": 5, "events_missed": 0, "events_spurious": 0,
                 "event_time_err": 0.0,
                 "event_state_err": 0.0}


def test_time_and_state_errors_of_matched_events():
    run = [ev(0.5 + 1e-7), ev(0.8, "stick"), ev(1.2 - 3e-7), ev(1.5, "slip"),
           ev(1.9, y=(2e-6, 0.5))]
    m = event_measures(run, REF, SCALE, ERR)
    assert m["event_time_err"] == pytest.approx(3e-7, rel=1e-6)
    # mixed error of y after the last event: 2e-6 / (1 + |0|)
    assert m["event_state_err"] == pytest.approx(2e-6)
    assert m["events_missed"] == m["events_spurious"] == 0


def test_a_missed_event_is_counted_and_shifts_the_later_matches():
    run = [e for e in REF if e[0] != 1.2]                   # the second impact is missed
    m = event_measures(run, REF, SCALE, ERR)
    assert m["events_missed"] == 1 and m["events_spurious"] == 0
    assert json.loads(m["events_by_kind"]) == {"impact": 2, "slip": 1, "stick": 1}
    # by kind and order the third impact of the run's is matched with the reference's second
    assert m["event_time_err"] == pytest.approx(0.7)
    assert match_events(run, REF) == [(0, 0), (1, 1), (2, 3), (3, 2)]


def test_a_spurious_event_is_counted():
    run = REF[:3] + [ev(1.3, "stick")] + REF[3:]           # a second stick the reference lacks
    m = event_measures(run, REF, SCALE, ERR)
    assert m["events_spurious"] == 1 and m["events_missed"] == 0
    assert m["event_time_err"] == pytest.approx(0.0)
    run = REF + [ev(2.1), ev(2.2, "jam")]                  # two more at the end, one of a new kind
    m = event_measures(run, REF, SCALE, ERR)
    assert (m["events_missed"], m["events_spurious"]) == (0, 2)
    assert json.loads(m["events_by_kind"])["jam"] == 1


def test_no_events_in_the_run():
    m = event_measures([], REF, SCALE, ERR)
    assert (m["events_missed"], m["events_spurious"]) == (5, 0)
    assert m["event_time_err"] is None and m["event_state_err"] is None
    assert m["events_by_kind"] == "{}"


def test_event_time_digits():
    a = [ev(1.0), ev(2.0, "stick")]
    b = [ev(1.0 + 1e-9), ev(2.0, "stick")]
    assert event_time_digits(a, b, span=10.0) == pytest.approx(10.0, abs=1e-6)
    assert event_time_digits([], [], span=1.0) == 16.0
    with pytest.raises(ValueError, match="differ in count: 2 against 1"):
        event_time_digits(a, b[:1], span=1.0)
    with pytest.raises(ValueError, match=r"event 2 differs in kind: 'stick' against 'impact'"):
        event_time_digits(a, [ev(1.0), ev(2.0)], span=1.0)


class DragBall(Problem):
    """A ball with quadratic air drag bouncing with restitution 0.8 (no closed form)."""

    name = "drag_ball"
    description = "test: bouncing ball with quadratic drag"
    components = ("y", "v")
    t_span = (0.0, 2.5)
    n_output = 50
    parameters = (Parameter("c", 0.1, 0.0, 10.0, "drag per unit mass (1/m)"),)
    error_components = ("y",)
    reference_methods = (("ode", "scipy-Radau", 1e-12), ("ode", "cvode-bdf", 1e-12))

    def initial_state(self):
        return np.array([1.0, 0.0])

    def rhs(self, t, y):
        return np.array([y[1], -9.81 - self.params["c"] * y[1] * abs(y[1])])

    def jac(self, t, y):
        return np.array([[0.0, 1.0], [0.0, -2 * self.params["c"] * abs(y[1])]])

    def formulate(self, formulation="ode"):
        system = super().formulate(formulation)
        system.events = (Event(lambda t, y: y[0], direction=-1, terminal=True,
                               reset=lambda t, y: np.array([y[0], -0.8 * y[1]]),
                               name="impact"),)
        return system


def test_reference_of_a_problem_with_events_carries_them(tmp_path):
    problem = DragBall()
    ref = references.compute(problem)
    meta = ref.meta
    assert [m["integrator"] for m in meta["methods"]] == ["scipy-Radau", "cvode-bdf"]
    names = [name for _, name in meta["events"]]
    assert names == ["impact"] * len(names) and 4 <= len(names) <= 6
    times = np.array([t for t, _ in meta["events"]])
    assert np.all(np.diff(times) > 0) and times[-1] < 2.5
    # drag makes the first fall slower than the free fall's sqrt(2/g)
    assert times[0] > np.sqrt(2 / 9.81)
    assert meta["event_digits"] >= 8                     # the demand
    assert len(meta["event_states"]) == len(names)
    assert all(abs(y) < 1e-9 and v > 0 for y, v in meta["event_states"])
    references.save(ref, problem, tmp_path)
    back = references.read(problem, tmp_path)[0]
    assert back.has_events and [e[0] for e in back.events] == list(times)
    ok, detail = references.check(problem, tmp_path)
    assert ok and "events, claimed" in detail, detail


def test_check_fails_when_the_stored_events_are_off(tmp_path):
    problem = DragBall()
    references.save(references.compute(problem), problem, tmp_path)
    _, js = references.paths(problem, tmp_path)
    meta = json.loads(js.read_text())
    meta["events"][1][0] += 1e-5
    js.write_text(json.dumps(meta))
    ok, detail = references.check(problem, tmp_path)
    assert not ok and "stored vs recomputed 5.4" in detail, detail
    meta["events"].pop()
    meta["event_states"].pop()
    js.write_text(json.dumps(meta))
    ok, detail = references.check(problem, tmp_path)
    assert not ok and "differ in count" in detail


def test_reference_runs_of_one_family_are_refused(monkeypatch):
    monkeypatch.setattr(DragBall, "reference_methods",
                        (("ode", "scipy-Radau", 1e-12), ("ode", "scipy-DOP853", 1e-12)))
    with pytest.raises(ReferenceFailure, match="one integrator family of event location"):
        references.compute(DragBall())


def test_independence_is_who_locates_the_events_not_the_module(monkeypatch):
    """scipy's codes and the in-house steppers live in other modules but share the
    segment runner's locator: one event locator, refused; SUNDIALS' root finding
    against the segment runner is two."""
    monkeypatch.setattr(DragBall, "reference_methods",
                        (("ode", "scipy-Radau", 1e-12), ("ode", "bdf3", 1e-12)))
    with pytest.raises(ReferenceFailure, match=r"of event location \(driver\)"):
        references.compute(DragBall())
    assert {registry.get_integrator(n).event_locator
            for n in ("scipy-Radau", "bdf3", "rkc", "cvode-bdf", "ida")} == {"driver", "sundials"}


def test_reference_runs_that_disagree_on_the_count_fail(monkeypatch):
    """The second run at rtol 1e-1 against the first at 1e-12: an event count
    that differs is a reference failure naming both counts."""
    real = references.solve_canonical

    def one_less(problem, formulation, integrator, rtol):
        Y, events = real(problem, formulation, integrator, rtol)
        return Y, events[:-1] if integrator == "cvode-bdf" else events

    monkeypatch.setattr(references, "solve_canonical", one_less)
    with pytest.raises(ReferenceFailure, match=r"events of scipy-Radau against cvode-bdf: "
                                               r"the event sequences differ in count: \d+ "
                                               r"against \d+"):
        references.compute(DragBall())


def test_stored_reference_without_events_means_none(tmp_path):
    from integrator_bench.problems.models.two_mass import TwoMass

    problem = TwoMass(c2=1000)
    ref = references.compute(problem)
    assert not {"events", "event_states", "event_digits"} & set(ref.meta)
    assert not ref.has_events and ref.events == []
