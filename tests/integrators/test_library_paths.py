"""One path per library code: the counted and the timed solve of a wrapper build the
library's solver from one configuration (so they cannot disagree on options,
settings or Jacobian), and fmpy's and Assimulo's runs go through the segment
runner (outputs, events, budget, non-finite states)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import scipy.integrate as si
from sksundae import cvode

from integrator_bench.harness.matrix import registry
from integrator_bench.integrators import scipy_ivp, sundials
from integrator_bench.integrators.base import Status
from integrator_bench.integrators.driver import Budget, Segments, budgeted
from integrator_bench.problems.system import Event, OdeSystem, convert


def _system(name="two_mass", integrator="scipy-Radau"):
    problem = registry.get_problem_class(name)()
    return convert(problem.formulate("ode"), registry.get_integrator(integrator))


def _same(a: dict, b: dict):
    """Two option dicts with the same keys and equal values (arrays by value; a
    callable by identity or, for a wrapper built per call, by its value at a point)."""
    assert sorted(a) == sorted(b)
    for key in a:
        x, y = a[key], b[key]
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            np.testing.assert_array_equal(x, y, err_msg=key)
        elif not callable(x):
            assert x == y, key


# ------------------------------------------------------------------ scipy
def test_scipy_counted_and_timed_solves_give_the_solver_the_same_options():
    """The solver class records the options it is built with: ``solve`` builds it
    itself, ``timed_solve`` through ``solve_ivp``; both from ``solver_options``."""
    built = []

    class Recording(si.Radau):
        def __init__(self, fun, t0, y0, t_bound, **options):
            built.append(options)
            super().__init__(fun, t0, y0, t_bound, **options)

    class Radau(scipy_ivp.Radau):
        solver_class = Recording

    system = _system()
    integrator = Radau(max_step=0.5, first_step=1e-4)
    atol = system.atol(1e-5)
    counted = integrator.solve(system, rtol=1e-5, atol=atol)
    timed = integrator.timed_solve(system, rtol=1e-5, atol=atol)
    assert counted.success and timed.success and len(built) == 2
    counted_options, timed_options = built
    timed_options.pop("vectorized", None)    # solve_ivp's own default, not a setting
    _same(counted_options, timed_options)
    assert counted_options["max_step"] == 0.5 and counted_options["first_step"] == 1e-4
    assert counted_options["jac"] is system.jac and counted_options["rtol"] == 1e-5


# ------------------------------------------------------------------ SUNDIALS
def test_sundials_counted_and_timed_solves_build_the_solver_with_the_same_options():
    built = []

    class Recording(cvode.CVODE):
        def __init__(self, fn, **options):
            built.append(options)
            super().__init__(fn, **options)

    class Bdf(sundials.CvodeBDF):
        solver_class = Recording

    system = _system(integrator="cvode-bdf")
    integrator = Bdf(max_order=3, max_step=0.5)
    atol = system.atol(1e-6)
    counted = integrator.solve(system, rtol=1e-6, atol=atol)
    timed = integrator.timed_solve(system, rtol=1e-6, atol=atol)
    assert counted.success and timed.success and len(built) == 2
    _same(*built)
    assert built[0]["max_order"] == 3 and built[0]["max_step"] == 0.5 and "jacfn" in built[0]


# ------------------------------------------------------------------ Assimulo
def test_assimulo_counted_and_timed_solves_configure_the_solver_alike():
    """Both solves build their solver through ``configured``: the same options
    (tolerances, settings, ``usejac``) and a Jacobian of the same value and
    memory order (C, as Assimulo's callbacks require)."""
    assimulo = pytest.importorskip("integrator_bench.integrators.assimulo")
    made = []

    class Bdf(assimulo.CvodeBDF):
        def make_solver(self, system, problem):
            made.append(super().make_solver(system, problem))
            return made[-1]

    system = _system(integrator="assimulo-cvode-bdf")
    integrator = Bdf(max_step=0.5, max_order=3)
    atol = system.atol(1e-6)
    assert integrator.solve(system, rtol=1e-6, atol=atol).success
    assert integrator.timed_solve(system, rtol=1e-6, atol=atol).success
    counted, timed = made
    keys = ("rtol", "maxh", "maxord", "usejac", "discr", "iter", "report_continuously",
            "verbosity")
    for key in keys:
        assert np.array_equal(counted.options[key], timed.options[key]), key
    np.testing.assert_array_equal(counted.atol, timed.atol)
    assert counted.options["maxh"] == 0.5 and counted.options["usejac"]
    jacs = [s.problem.jac(system.t0, system.y0) for s in made]
    np.testing.assert_array_equal(*jacs)
    assert all(J.flags["C_CONTIGUOUS"] for J in jacs)


def test_assimulo_roots_are_filtered_by_direction_in_the_runner():
    """An event crossed downwards only (direction +1, a falling crossing) is not
    acted on: Assimulo reports every root, the runner keeps those in the
    event's direction."""
    assimulo = pytest.importorskip("integrator_bench.integrators.assimulo")
    falls = Event(lambda t, y: 0.5 - y[0], direction=1, terminal=True, name="falls")
    rises = Event(lambda t, y: y[0] - 0.5, direction=1, terminal=True, name="rises")
    for event, stops in ((falls, False), (rises, True)):
        system = OdeSystem(t0=0.0, t_end=1.0, y0=np.zeros(1), t_eval=np.linspace(0, 1, 11),
                           atol_scale=1.0, fun=lambda t, y: np.ones_like(y))
        system.events = (event,)
        sol = assimulo.Dopri5().solve(system, rtol=1e-8, atol=np.full(1, 1e-8))
        assert sol.success and bool(sol.t[-1] < 1.0) == stops, event.name
        assert [name for _, name, _ in sol.events] == ([event.name] if stops else [])


# ------------------------------------------------------------------ the runner
def test_the_runner_ends_a_run_at_a_non_finite_state_when_asked():
    system = OdeSystem(t0=0.0, t_end=1.0, y0=np.zeros(1), t_eval=np.linspace(0, 1, 11),
                       atol_scale=1.0, fun=lambda t, y: y)

    def advance(t, y):
        segments.step(0.0, 0.25, np.ones(1), None)
        segments.step(0.25, 0.5, np.full(1, np.nan), None)
        return Status.SUCCESS, ""

    for finite, status in ((True, Status.NONFINITE_STATE), (False, Status.SOLVER_FAILURE)):
        segments = Segments(system, locate=False, finite=finite)
        sol = segments.solution(*segments.run(0.0, np.zeros(1), advance, None), {})
        assert sol.status is status, finite
    assert "non-finite state at t=0.5" in sol.message or finite is False


def test_events_a_library_applies_itself_are_recorded_and_give_the_output():
    """``applied``: the event logged with the state after it, the output at its
    time takes that state, the steps after it interpolate from it."""
    system = OdeSystem(t0=0.0, t_end=1.0, y0=np.zeros(1), t_eval=np.linspace(0, 1, 5),
                       atol_scale=1.0, fun=lambda t, y: y)
    system.events = (Event(lambda t, y: y[0], name="kick"),)
    segments = Segments(system, locate=False)

    def advance(t, y):
        segments.step(0.0, 0.5, np.array([0.5]), None)
        segments.applied(0.5, "kick", np.array([2.0]))
        segments.step(0.5, 1.0, np.array([2.5]), None)
        return Status.SUCCESS, ""

    sol = segments.solution(*segments.run(0.0, np.zeros(1), advance, None), {})
    assert sol.success and sol.counts["nevents"] == 1
    assert sol.events[0][:2] == (0.5, "kick") and sol.events[0][2][0] == 2.0
    np.testing.assert_allclose(sol.y[:, 0], [0.0, 0.25, 2.0, 2.25, 2.5])


# ------------------------------------------------------------------ fmpy
def _fmpy_rows(system, rows):
    """fmpy's ``step_finished`` fed a recorder holding ``rows`` (time, variables)."""
    from integrator_bench.integrators.fmpy_solvers import _Rows

    segments = Segments(system, locate=False, finite=True)
    feed = _Rows(system, segments)
    recorder = SimpleNamespace(cols=[("time",)] + [(v,) for v in system.variables], rows=[])

    def advance(t, y):
        for row in rows:
            recorder.rows.append(row)
            feed(row[0], recorder)
        return Status.SUCCESS, ""
    sol = segments.solution(*segments.run(system.t0, system.y0, advance, None), {})
    return sol, feed


def _fmu_like(n_out=3):
    system = SimpleNamespace(t0=0.0, t_end=1.0, y0=np.zeros(2), n=2,
                             t_eval=np.linspace(0.0, 1.0, n_out), events=(None,),
                             variables=("x", "v"), elements=(("x", None), ("v", None)),
                             event_name="impact")
    return system


def test_fmpy_rows_feed_the_runner_with_outputs_and_events():
    """fmpy's rows: the start, output points, an event between them (the state
    before and after at one time): outputs at the output times, the event with
    the state after it; a row pair at one time with equal states is no event."""
    system = _fmu_like()
    rows = [(0.0, 1.0, 0.0), (0.3, 0.7, -1.0), (0.3, 0.7, 1.0), (0.5, 0.9, 1.0),
            (0.5, 0.9, 1.0), (1.0, 1.4, 1.0)]
    sol, feed = _fmpy_rows(system, rows)
    assert sol.success and feed.steps == 3
    assert [(t, name) for t, name, _ in sol.events] == [(0.3, "impact")]
    np.testing.assert_array_equal(sol.events[0][2], [0.7, 1.0])
    np.testing.assert_array_equal(sol.y, [[1.0, 0.0], [0.9, 1.0], [1.4, 1.0]])


def test_fmpy_rows_short_of_t_end_or_non_finite_fail_the_run():
    system = _fmu_like()
    short, _ = _fmpy_rows(system, [(0.0, 1.0, 0.0), (0.5, 0.9, 1.0)])
    assert short.status is Status.SOLVER_FAILURE and "outputs end at t=0.5" in short.message
    nan, _ = _fmpy_rows(system, [(0.0, 1.0, 0.0), (0.5, np.nan, 1.0), (1.0, 1.0, 1.0)])
    assert nan.status is Status.NONFINITE_STATE and nan.t[-1] == 0.0


def test_fmpy_runs_keep_to_their_budget(built_fmus):
    """A budget already spent stops fmpy's loop at its first row past the start."""
    pytest.importorskip("fmpy")
    from integrator_bench.problems.fmu import FmuProblem

    icls = registry.get_integrator("fmpy-cvode")
    system = convert(FmuProblem(path=str(built_fmus["bouncing_ball"])).formulate("ode"), icls)
    with budgeted(Budget(seconds=0.0)):
        sol = icls().solve(system, rtol=1e-6, atol=system.atol(1e-6))
    assert sol.status is Status.OVER_BUDGET and "past its budget" in sol.message
    free = icls().solve(system, rtol=1e-6, atol=system.atol(1e-6))
    assert free.success and free.counts["nevents"] > 0 and free.t.size == system.t_eval.size


@pytest.mark.parametrize("name, mode", [("fmpy-cvode", {"rtol": 1e-6}),
                                        ("fmpy-euler", {"h": 1e-3})])
def test_fmpy_cases_solve_once_through_the_counted_instance(built_fmus, monkeypatch,
                                                            name, mode):
    """fmpy reports no counts, so a case's one solve (``timed_solve``, timing
    ``wrapper``) is the counted one: ``simulate_fmu`` with the arguments of
    ``simulation`` plus the counted instance and the feed, its calls counted."""
    fmpy = pytest.importorskip("fmpy")
    from integrator_bench.problems.fmu import FmuProblem

    calls, original = [], fmpy.simulate_fmu

    def recording(**kwargs):
        calls.append(kwargs)
        return original(**kwargs)
    monkeypatch.setattr(fmpy, "simulate_fmu", recording)
    icls = registry.get_integrator(name)
    system = convert(FmuProblem(path=str(built_fmus["bouncing_ball"])).formulate("ode"), icls)
    atol = system.atol(mode["rtol"]) if "rtol" in mode else None
    assert icls().timing_loop(system) == "wrapper"
    timed = icls().timed_solve(system, atol=atol, **mode)
    assert timed.success and timed.counts["nfev"] > 0 and timed.counts["nevents"] > 0
    call, = calls
    assert call.pop("step_finished") is not None and call.pop("fmu_instance")
    _same(call, icls().simulation(system, mode.get("rtol"), mode.get("h")))
