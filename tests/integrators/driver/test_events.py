"""State events: location, reset and restart, ignored crossings, directions, and
the refusal of integrators that cannot locate events.

The systems are written here: a bouncing ball ``y'' = -g`` with the impact law
``v -> -e v`` at ``y = 0`` (falling), whose event times are known in closed
form, and the harmonic oscillator ``x'' = -x``, ``x(0) = 1``, whose zeros
``x = cos t = 0`` fall at ``pi/2 + k pi`` (falling for even k, rising for odd).
"""

import numpy as np
import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.integrators.base import Status
from integrator_bench.integrators.driver import EVENT_ATOL, locate
from integrator_bench.integrators.fixed_step import RK4
from integrator_bench.problems.system import Event, OdeSystem, Unsupported, convert, takes

G, E, H0, SPAN = 9.81, 0.8, 1.0, 2.0


def bounce_times(k):
    """The first ``k`` impact times of a ball dropped from rest at height ``H0``:
    ``t_1 = sqrt(2 H0 / g)``, impact speed ``v_1 = g t_1``; after impact ``j``
    the ball leaves at ``e^j v_1`` and flies ``2 e^j v_1 / g = 2 e^j t_1``, so
    ``t_k = t_1 (1 + 2 sum_{j=1}^{k-1} e^j)``; it leaves impact ``k`` at
    ``e^k v_1``."""
    t1 = np.sqrt(2 * H0 / G)
    return t1 * (1 + 2 * np.concatenate([[0.0], np.cumsum(E ** np.arange(1, k))]))


def ball(terminal=True, reset=True, extra=()):
    impact = Event(lambda t, y: y[0], direction=-1, terminal=terminal,
                   reset=(lambda t, y: np.array([y[0], -E * y[1]])) if reset else None,
                   name="impact")
    return OdeSystem(t0=0.0, t_end=SPAN, y0=[H0, 0.0], t_eval=np.linspace(0.0, SPAN, 41),
                     atol_scale=1.0, fun=lambda t, y: np.array([y[1], -G]),
                     jac=lambda t, y: np.array([[0.0, 1.0], [0.0, 0.0]]),
                     events=(impact, *extra))


def oscillator(events=(), t_end=10.0):
    return OdeSystem(t0=0.0, t_end=t_end, y0=[1.0, 0.0], t_eval=np.linspace(0.0, t_end, 51),
                     atol_scale=1.0, fun=lambda t, y: np.array([y[1], -y[0]]),
                     jac=lambda t, y: np.array([[0.0, 1.0], [-1.0, 0.0]]), events=events)


# every registered integrator that declares events: scipy's and SUNDIALS' codes, and
# the in-house steppers with a dense output, through the driver's location
# every integrator that locates events on the systems built here (ODEs, taken as
# DAEs too); those of FMUs only are tested on FMUs (tests/problems/fmu/test_fmu_problem.py)
REGISTERED = sorted(name for name, cls in registry.integrators().items()
                    if cls.events and cls.accepts & {"ode", "dae"})
CASES = REGISTERED


def get(name):
    return registry.integrators()[name]


def run(cls, system, rtol=1e-8, h=1e-3):
    """Run ``cls`` on ``system`` under ``rtol`` when adaptive, else at ``h``;
    return the solution and the event-time tolerance: ``20 rtol`` (an adaptive
    code's global error on this 2 s span is a few rtol; BDF codes' start-up
    gives about 3 rtol on the ball) or ``20 h^p`` at a fixed step of order p."""
    s = convert(system, cls)
    if cls.adaptive:
        return cls().solve(s, rtol=rtol, atol=s.atol(rtol)), 20 * rtol
    return cls().solve(s, h=h), 20 * h ** (cls.order or 1)


def test_some_registered_integrators_declare_events():
    assert {"scipy-RK45", "scipy-Radau", "scipy-BDF", "scipy-LSODA", "cvode-bdf",
            "cvode-adams", "ida", "bdf3", "rkc", "dumka3"} <= set(REGISTERED)


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("rtol", [1e-6, 1e-9])
def test_bouncing_ball_event_times_and_states(name, rtol):
    cls = get(name)
    sol, tol = run(cls, ball(), rtol=rtol)
    exact = bounce_times(3)
    assert sol.status is Status.SUCCESS, sol.message
    assert sol.t[-1] == SPAN and sol.t.size == 41
    assert [e[1] for e in sol.events] == ["impact"] * 3 and sol.counts["nevents"] == 3
    times = np.array([e[0] for e in sol.events])
    assert np.abs(times - exact).max() <= tol
    v1 = G * exact[0]
    leave = np.array([e[2][1] for e in sol.events])          # the velocity after each reset
    assert np.abs(leave - v1 * E ** np.arange(1, 4)).max() <= tol * G * 10
    # between impacts the outputs follow the parabola of the flight
    t = sol.t
    k = np.searchsorted(exact, t)                             # flight number of each output
    start = np.concatenate([[0.0], exact])[k]
    v0 = np.concatenate([[0.0], v1 * E ** np.arange(1, 4)])[k]
    y0 = np.where(k == 0, H0, 0.0)
    y = y0 + v0 * (t - start) - 0.5 * G * (t - start) ** 2
    assert np.abs(sol.y[:, 0] - y).max() <= tol * G * 10


@pytest.mark.parametrize("name", CASES)
def test_terminal_event_without_reset_stops_there(name):
    sol, tol = run(get(name), ball(reset=False))
    t1 = bounce_times(1)[0]
    assert sol.status is Status.SUCCESS and "impact" in sol.message
    assert len(sol.events) == 1 and abs(sol.events[0][0] - t1) <= tol
    assert sol.t[-1] <= t1 and sol.t.size == np.searchsorted(np.linspace(0, SPAN, 41), t1)
    assert np.abs(sol.y[:, 0] - (H0 - 0.5 * G * sol.t ** 2)).max() <= tol * G * 10


@pytest.mark.parametrize("name", CASES)
def test_ignored_crossing_does_not_count_and_the_next_does(name):
    calls = []

    def reset(t, y):                    # the "mode" ignores the first zero of x
        calls.append(t)
        return None if len(calls) == 1 else y

    event = Event(lambda t, y: y[0], direction=0, terminal=True, reset=reset, name="zero")
    sol, tol = run(get(name), oscillator((event,)))
    zeros = np.pi / 2 + np.pi * np.arange(3)                 # pi/2, 3pi/2, 5pi/2 in [0, 10]
    assert sol.status is Status.SUCCESS, sol.message
    bound = located_within(sol, tol)
    assert len(calls) == 3 and abs(calls[0] - zeros[0]) <= bound
    times = np.array([e[0] for e in sol.events])
    assert times.size == 2 and np.abs(times - zeros[1:]).max() <= bound
    assert sol.counts["nevents"] == 2


def located_within(sol, tol):
    """How far an event time of ``x = 0`` on the oscillator ``x = cos t`` may be off:
    the location tolerance plus the run's own error in x (|x'| = 1 at the zeros, so
    an error e in x moves a zero by about e). RKC, whose stability region is thin
    around the imaginary axis, has a global error of about 1e-5 at rtol 1e-8 here;
    the other codes are within 10 tol of the exact solution."""
    return 10 * tol + 2 * float(np.abs(sol.y[:, 0] - np.cos(sol.t)).max())


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("direction, expected", [(1, [1]), (-1, [0, 2]), (0, [0, 1, 2])])
def test_event_directions(name, direction, expected):
    event = Event(lambda t, y: y[0], direction=direction, name="x=0")
    sol, tol = run(get(name), oscillator((event,)))
    times = np.array([e[0] for e in sol.events])
    assert sol.status is Status.SUCCESS and sol.t[-1] == 10.0
    assert times.size == len(expected)
    bound = located_within(sol, tol)
    assert np.abs(times - (np.pi / 2 + np.pi * np.array(expected))).max() <= bound
    # a non-terminal event changes nothing: its state is the solution's there
    for t, _, y in sol.events:
        assert abs(y[0]) <= 10 * tol and abs(y[1] + np.sin(t)) <= bound


@pytest.mark.parametrize("name", CASES)
def test_an_event_that_never_fires_leaves_the_outputs_unchanged(name):
    never = Event(lambda t, y: y[0] + 10.0, direction=0, terminal=True, name="never")
    cls = get(name)
    plain, _ = run(cls, oscillator())
    with_event, _ = run(cls, oscillator((never,)))
    assert with_event.events == [] and with_event.counts["nevents"] == 0
    np.testing.assert_array_equal(with_event.t, plain.t)
    np.testing.assert_array_equal(with_event.y, plain.y)


def test_integrator_without_events_is_unsupported():
    system = ball()
    assert not RK4.events
    with pytest.raises(Unsupported, match=r"^rk4 cannot locate state events, which this "
                                          r"problem has$"):
        convert(system, RK4)
    assert not takes(system, RK4) and takes(oscillator(), RK4)
    unable = [name for name, cls in registry.integrators().items()
              if not cls.events and not takes(system, cls)]
    assert "rk4" in unable and all(takes(system, get(n)) for n in CASES)


def test_driver_cannot_locate_without_dense_output():
    forced = type("ForcedRK4", (RK4,), {"events": True, "name": "rk4+events"})
    sol = forced().solve(convert(ball(), forced), h=1e-2)
    assert sol.status is Status.METHOD_LIMIT and "dense output" in sol.message


def test_reset_needs_a_terminal_event():
    with pytest.raises(ValueError, match="terminal"):
        Event(lambda t, y: y[0], reset=lambda t, y: y)
    with pytest.raises(ValueError, match="direction"):
        Event(lambda t, y: y[0], direction=2)


def test_locate_brackets_the_root_past_the_sign_change():
    for root in (0.3, 1.0 / 3.0, 0.999999):
        g = lambda s: np.tanh(50 * (root - s))                # falling through the root
        t = locate(g, 0.0, 1.0, g(0.0), g(1.0))
        assert g(t) <= 0 and 0 <= t - root <= 4 * np.finfo(float).eps + EVENT_ATOL
