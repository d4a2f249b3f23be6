"""The bouncing ball: closed form against a hand computation, the Zeno cut-off,
and a run through the harness (execute) with event measures in the record.

Hand computation (h0 = 1 m, g = 9.81 m/s^2, e = 0.8): the first impact at
t1 = sqrt(2/9.81) = 0.4515236409 s with speed v1 = g t1 = 4.429446918 m/s; the
ball leaves at e v1 = 3.543557535 m/s and flies 2 e v1 / g = 0.7224378255 s,
so the second impact is at t2 = t1 + 1.6 t1 = 1.173961467 s, where it leaves at e^2 v1 =
2.834846028 m/s, up to the apex e^2 h0 = 0.64 m. Zeno point t1 (1 + e) / (1 - e) = 9 t1 = 4.063712768 s.
"""

import json

import numpy as np
import pytest

from integrator_bench.harness.measure import references

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import Case
from integrator_bench.harness.run.execution import execute
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.problems.base import ProblemError
from integrator_bench.problems.models.bouncing_ball import BouncingBall

T1, T2 = 0.4515236410, 1.173961467           # by hand, 10 digits
V1, LEAVE1, LEAVE2 = 4.429446918, 3.543557535, 2.834846028


def test_first_two_impacts_match_the_hand_computation():
    ball = BouncingBall()
    times = ball.impact_times()
    assert abs(times[0] - T1) < 1e-9 and abs(times[1] - T2) < 1e-9
    events = ball.exact_events()
    assert [name for _, name, _ in events] == ["impact"] * 8          # 8 impacts to 3.4 s
    assert abs(events[0][2][1] - LEAVE1) < 1e-8 and abs(events[1][2][1] - LEAVE2) < 1e-8
    assert all(y[0] == 0.0 for _, _, y in events)
    assert abs(ball.zeno_time() - 4.063712768) < 1e-8


def test_exact_solution_is_continuous_in_y_and_jumps_in_v():
    ball = BouncingBall()
    for k, (t, _, after) in enumerate(ball.exact_events()):
        before, at = ball.exact([t - 1e-12, t])
        assert abs(before[0]) < 1e-10 and abs(at[0]) < 1e-10        # on the floor
        assert abs(at[1] - after[1]) < 1e-10                         # the state after
        assert abs(at[1] + ball.params["e"] * before[1]) < 1e-9      # v+ = -e v-
    # free fall before the first impact, and the apex of the first bounce
    t = np.linspace(0, 0.45, 7)
    np.testing.assert_allclose(ball.exact(t)[:, 0], 1 - 0.5 * 9.81 * t ** 2, atol=1e-14)
    apex = ball.exact([T1 + LEAVE1 / 9.81])[0]
    assert abs(apex[0] - 0.64) < 1e-12 and abs(apex[1]) < 1e-9


def test_exact_solution_solves_the_ode_between_impacts():
    ball = BouncingBall()
    t = np.linspace(1.2, 1.7, 11)                                    # inside the 2nd flight
    Y, dt = ball.exact(t), 1e-6
    dY = (ball.exact(t + dt) - ball.exact(t - dt)) / (2 * dt)
    np.testing.assert_allclose(dY[:, 0], Y[:, 1], atol=1e-8)
    np.testing.assert_allclose(dY[:, 1], -9.81, atol=1e-6)


def test_zeno_cut_off_and_bad_restitution_are_refused():
    with pytest.raises(ProblemError, match=r"t_end=3.4 is at or past the Zeno point .*1\.35457"):
        BouncingBall(e=0.5)
    with pytest.raises(ProblemError, match="Zeno point"):
        BouncingBall(t_end=4.063712768871579)
    assert BouncingBall(e=0.5, t_end=1.3).t_eval[-1] == 1.3
    with pytest.raises(ProblemError, match=r"e=0 is outside its range \(0, 1\]"):
        BouncingBall(e=0)
    with pytest.raises(ProblemError, match="outside its range"):
        BouncingBall(e=1.2)
    elastic = BouncingBall(e=1.0, t_end=10.0)                        # no Zeno point
    assert elastic.zeno_time() == np.inf
    np.testing.assert_allclose(np.diff(elastic.impact_times()), 2 * T1, rtol=1e-9)


def test_system_carries_the_terminal_impact_event():
    system = BouncingBall().formulate("ode")
    (event,) = system.events
    assert event.name == "impact" and event.direction == -1 and event.terminal
    np.testing.assert_array_equal(event.reset(1.0, np.array([0.0, -2.0])), [0.0, 1.6])


@pytest.fixture
def ball_refdir(tmp_path):
    """``bouncing_ball`` (registered by its entry point), its exact reference
    computed into a tmp dir."""
    assert registry.get_problem_class("bouncing_ball") is BouncingBall
    problem = BouncingBall()
    references.save(references.compute(problem), problem, tmp_path)
    return tmp_path


def run_case(refdir, integrator, rtol=None, h=None):
    params = tuple(sorted(BouncingBall().params.items()))
    return execute(Case("bouncing_ball", params, "ode", integrator, rtol=rtol, h=h),
                   reference_dir=refdir)


def test_exact_reference_records_the_exact_events(ball_refdir):
    ref = references.read(BouncingBall(), ball_refdir)[0]
    assert ref.meta["methods"][0] == {"method": "exact"}
    exact = BouncingBall().exact_events()
    assert [name for _, name in ref.meta["events"]] == ["impact"] * 8
    np.testing.assert_array_equal([t for t, _ in ref.meta["events"]], [t for t, _, _ in exact])
    np.testing.assert_array_equal(ref.meta["event_states"], [y for _, _, y in exact])
    # DOP853 at 1e-13 finds the same impacts: the exact times check the location
    assert ref.meta["event_digits"] >= 12


@pytest.mark.parametrize("integrator, bound", [("scipy-Radau", 1e-9), ("cvode-bdf", 1e-4),
                                               ("cvode-adams", 1e-5), ("ida", 1e-6)])
def test_run_records_event_measures(ball_refdir, integrator, bound):
    """At rtol 1e-6 every impact is found, none spurious, times within ``bound``
    (100 rtol for CVODE BDF, whose low-order start after each restart costs
    accuracy: measured 2.0e-5; Radau is exact on the parabolas up to round-off);
    at 1e-9 the errors shrink by at least 100."""
    loose, tight = run_case(ball_refdir, integrator, 1e-6), run_case(ball_refdir, integrator, 1e-9)
    for rec in (loose, tight):
        assert rec["status"] == CaseStatus.OK, rec["message"]
        assert json.loads(rec["events_by_kind"]) == {"impact": 8} and rec["nevents"] == 8
        assert rec["events_missed"] == 0 and rec["events_spurious"] == 0
    assert loose["event_time_err"] <= bound and loose["event_state_err"] <= bound
    assert tight["event_time_err"] <= max(bound / 100, 1e-12)
    assert tight["event_state_err"] <= max(bound / 100, 1e-12)


def test_integrator_without_events_is_unsupported_with_the_reason(ball_refdir):
    rec = run_case(ball_refdir, "rk4", h=0.01)
    assert rec["status"] == CaseStatus.UNSUPPORTED and rec["reason"] == "unsupported"
    assert rec["message"] == "ode: rk4 cannot locate state events, which this problem has"
    assert rec["event_time_err"] is None and rec["events_by_kind"] is None


def test_problem_without_events_leaves_the_event_fields_null(tmp_path):
    from integrator_bench.problems.models.two_mass import TwoMass

    problem = TwoMass(c2=1000)
    references.save(references.compute(problem), problem, tmp_path)
    assert "events" not in references.read(problem, tmp_path)[0].meta
    rec = execute(Case("two_mass", tuple(sorted(problem.params.items())), "ode", "scipy-Radau",
                       rtol=1e-4), reference_dir=tmp_path)
    assert rec["status"] == CaseStatus.OK
    assert all(rec[k] is None for k in ("events_by_kind", "event_time_err", "events_missed",
                                        "events_spurious", "event_state_err"))
