"""The shared stepping driver and its step-size controllers, on small steppers
written here (so a change in any registered method cannot hide a driver bug)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from integrator_bench.integrators.base import Integrator, Status, Step, Stepper, StepFailure
from integrator_bench.harness.matrix import registry
from integrator_bench.integrators.control import (PI, ConstantStep, PIControl,
                                                   StepSizeController, StepSizeUnderflow)
from integrator_bench.problems.system import OdeSystem


def ode(fun, y0, t_end=1.0, n_out=11, project=None):
    return OdeSystem(t0=0.0, t_end=t_end, y0=np.atleast_1d(np.asarray(y0, float)),
                     t_eval=np.linspace(0.0, t_end, n_out), atol_scale=1.0, fun=fun,
                     project=project)


class EulerHeunStepper(Stepper):
    """Explicit Euler with the Euler-Heun difference as its error estimate."""

    error_order = 1

    def step(self, t, y, h):
        f0 = np.asarray(self.system.fun(t, y), float)
        y1 = y + h * f0
        heun = y + h / 2 * (f0 + np.asarray(self.system.fun(t + h, y1), float))
        return Step(y1, error=heun - y1)


class RK4Stepper(Stepper):
    def step(self, t, y, h):
        f = self.system.fun
        k1 = f(t, y)
        k2 = f(t + h / 2, y + h / 2 * k1)
        k3 = f(t + h / 2, y + h / 2 * k2)
        k4 = f(t + h, y + h * k3)
        return Step(y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4))


def integrator(stepper_cls, order=1, adaptive=True, **attrs):
    def stepper(self, system, counts, rtol=None, atol=None):
        return stepper_cls(system, counts, rtol, atol)
    return type("Test" + stepper_cls.__name__, (Integrator,),
                {"name": "test", "order": order, "adaptive": adaptive, "stepper": stepper,
                 **attrs})


def test_fixed_steps_lie_on_the_grid_and_the_last_one_ends_at_t_end():
    sizes = []

    class Recording(EulerHeunStepper):
        def step(self, t, y, h):
            sizes.append((t, h))
            return super().step(t, y, h)

    sol = integrator(Recording)().solve(ode(lambda t, y: -y, 1.0), h=0.3)
    assert sol.status is Status.SUCCESS and sol.counts["nsteps"] == 4
    np.testing.assert_allclose([t for t, _ in sizes], [0.0, 0.3, 0.6, 0.9], atol=1e-15)
    np.testing.assert_allclose([h for _, h in sizes], [0.3, 0.3, 0.3, 0.1], atol=1e-15)
    assert sol.t.size == 11


@pytest.mark.parametrize("order", [1, 4])
def test_outputs_inside_steps_keep_the_method_order(order):
    """Outputs between step ends (101 of them, steps of span/8 ... span/64) carry the
    method's order: the interpolation is of the method's degree."""
    stepper = EulerHeunStepper if order == 1 else RK4Stepper
    icls = integrator(stepper, order=order, adaptive=False)
    errs = []
    for n in (8, 16, 32, 64):
        system = ode(lambda t, y: np.cos(t) * y, 1.0, t_end=2.0, n_out=101)
        sol = icls().solve(system, h=2.0 / n)
        assert sol.counts["nsteps"] == n              # no step shortened at an output time
        err = np.abs(sol.y[:, 0] - np.exp(np.sin(sol.t)))
        errs.append(np.max(err))
    slopes = np.log2(np.array(errs[:-1]) / errs[1:])
    assert np.all(slopes[1:] > order - 0.3), slopes
    on_grid = np.isclose((sol.t * 32) % 1, 0) | np.isclose((sol.t * 32) % 1, 1)
    assert np.max(err) <= 3 * np.max(err[on_grid])    # interpolation adds little to the method


def test_error_control_meets_the_tolerance_and_counts_rejections():
    icls = integrator(EulerHeunStepper)
    steps, errors = [], []
    for rtol in (1e-3, 1e-5):
        system = ode(lambda t, y: -(y - np.cos(t)), 0.0, n_out=21)
        sol = icls().solve(system, rtol=rtol, atol=system.atol(rtol))
        assert sol.status is Status.SUCCESS and sol.t.size == 21
        exact = (np.cos(sol.t) + np.sin(sol.t) - np.exp(-sol.t)) / 2
        steps.append(sol.counts["nsteps"])
        errors.append(np.max(np.abs(sol.y[:, 0] - exact)))
    # local error h^2 ~ rtol: 100x tighter takes ~10x the steps, and the error follows
    assert 5 < steps[1] / steps[0] < 20
    assert errors[1] < errors[0] / 5


def test_rejected_steps_are_counted_and_not_kept():
    class Greedy(EulerHeunStepper):
        def initial_step(self, t0, y0, rtol, atol):
            return 0.5                         # far too large for lambda = -50

    system = ode(lambda t, y: -50.0 * y, 1.0)
    sol = integrator(Greedy)().solve(system, rtol=1e-4, atol=system.atol(1e-4))
    assert sol.counts["nreject"] >= 1
    assert abs(sol.y[-1, 0] - math.exp(-50.0)) < 1e-3


@pytest.mark.parametrize("mode", [{"h": 0.1}, {"rtol": 1e-6}])
def test_projection_after_every_accepted_step_and_on_interpolated_outputs(mode):
    project = lambda t, y: y / np.linalg.norm(y)           # noqa: E731
    system = ode(lambda t, y: np.array([-y[1], y[0]]), [1.0, 0.0], n_out=37, project=project)
    if "rtol" in mode:
        mode["atol"] = system.atol(mode["rtol"])
    sol = integrator(EulerHeunStepper)().solve(system, **mode)
    np.testing.assert_allclose(np.linalg.norm(sol.y, axis=1), 1.0, atol=1e-14)


def test_a_non_finite_state_at_a_fixed_step_ends_the_run():
    sol = integrator(EulerHeunStepper)().solve(ode(lambda t, y: y * y, 10.0, t_end=3.0), h=0.25)
    assert sol.status in (Status.NONFINITE_STATE, Status.DIVERGED)
    assert not sol.success and 0 < sol.t.size < 11


def test_an_overflow_in_the_right_hand_side_is_divergence():
    def fun(t, y):
        if t > 0.5:
            raise OverflowError("math range error")
        return -y
    sol = integrator(EulerHeunStepper)().solve(ode(fun, 1.0), h=0.1)
    assert sol.status is Status.DIVERGED and "blew up" in sol.message
    assert sol.t.size == 6                     # the outputs up to t = 0.5 are kept


def test_a_step_failure_ends_a_fixed_step_run_with_its_status():
    class Failing(EulerHeunStepper):
        def step(self, t, y, h):
            if t >= 0.4:
                raise StepFailure(Status.NEWTON_FAILURE, f"no convergence at t={t:.3g}")
            return super().step(t, y, h)
    sol = integrator(Failing)().solve(ode(lambda t, y: -y, 1.0), h=0.1)
    assert sol.status is Status.NEWTON_FAILURE and sol.t.size == 5


def test_a_retryable_step_failure_cuts_the_step_under_error_control():
    tried = []

    class FailsAboveTenth(EulerHeunStepper):
        def step(self, t, y, h):
            tried.append(h)
            if h > 0.1:
                raise StepFailure(Status.NEWTON_FAILURE, "too large")
            return super().step(t, y, h)

        def initial_step(self, *args):
            return 0.8

    system = ode(lambda t, y: -y, 1.0)
    sol = integrator(FailsAboveTenth, controller=PI(factor_max=1.0))().solve(system, rtol=1e-2,
                                                             atol=system.atol(1e-2))
    assert sol.status is Status.SUCCESS
    assert tried[:3] == pytest.approx([0.8, 0.2, 0.05])


def test_step_size_underflow_and_maximum_steps():
    class Hopeless(EulerHeunStepper):
        def step(self, t, y, h):
            return Step(y + h, error=np.ones_like(y) * 1e3)
    system = ode(lambda t, y: -y, 1.0)
    sol = integrator(Hopeless)().solve(system, rtol=1e-6, atol=system.atol(1e-6))
    assert sol.status is Status.STEP_SIZE_UNDERFLOW and sol.t.size == 1
    sol = integrator(EulerHeunStepper, max_steps=10)().solve(system, rtol=1e-8,
                                                              atol=system.atol(1e-8))
    assert sol.status is Status.MAX_STEPS


def test_pi_control_factors():
    c = PI(safety=0.9, factor_min=0.2, factor_max=2.0, hold_band=(1.0, 1.2))(order=2)
    assert c.adapt(1.0, 0.0) == (True, 2.0)                       # err 0: the largest growth
    assert c.adapt(1.0, 0.9 ** 3 / 1.1 ** 3) == (True, 1.0)       # factor 1.1: held
    accept, h = c.adapt(1.0, 8.0)
    assert not accept and h == pytest.approx(0.45)                # 0.9 * 8^(-1/3)
    assert c.adapt(1.0, 1e-6) == (True, 1.0)                      # no growth after a rejection
    assert c.adapt(1.0, math.inf) == (False, 0.2)
    pi = PI(k_i=0.7, k_p=0.4)(order=4)
    pi.adapt(1.0, 0.5)
    assert pi.adapt(1.0, 0.5)[1] == pytest.approx(0.9 * 0.5 ** (-0.7 / 5) * 0.5 ** (0.4 / 5))
    with pytest.raises(ValueError, match="h=-1"):
        ConstantStep(-1)


def test_the_constant_step_walks_the_grid_and_accepts_everything():
    c = ConstantStep(0.1)
    t, h, ends = 0.3, c.init(0.3, 1.0, estimate=None), []
    while t < 1.0:
        accept, h_next = c.adapt(h, math.inf)
        assert accept
        t = 1.0 if h == 1.0 - t else t + h
        ends.append(t)
        h = h_next
    assert ends == list(0.3 + 0.1 * np.arange(1, 7)) + [1.0]      # t0 + k h exactly, then t_end
    assert c.failed(0.1, 0.25) is None


class _RecordingPI(PI):
    """PI constants whose controllers log every ``adapt(h, err)`` and its answer."""

    def __call__(self, order, **kw):
        control, log = super().__call__(order, **kw), self.log
        adapt = control.adapt

        def logged(h, err):
            accept, h_next = adapt(h, err)
            log.append((h, err, accept, h_next))
            return accept, h_next
        control.adapt = logged
        return control


def test_pi_control_takes_the_pi_step_sequence_and_meets_the_tolerance():
    """Under Gustafsson's PI constants (k_i 0.7, k_p 0.4) every step of a real run
    is the one the PI formula gives from the logged errors, which differs from I
    control's; the error stays that of I control (Euler's global error at rtol
    1e-4 is about 5e-3 here)."""
    runs, errors = {}, {}
    for label, k in {"I": (1.0, 0.0), "PI": (0.7, 0.4)}.items():
        constants = _RecordingPI(k_i=k[0], k_p=k[1])
        object.__setattr__(constants, "log", [])
        system = ode(lambda t, y: -(y - np.cos(t)), 0.0, n_out=21)
        sol = integrator(EulerHeunStepper, controller=constants)().solve(
            system, rtol=1e-4, atol=system.atol(1e-4))
        exact = (np.cos(sol.t) + np.sin(sol.t) - np.exp(-sol.t)) / 2
        assert sol.status is Status.SUCCESS
        errors[label], runs[label] = np.max(np.abs(sol.y[:, 0] - exact)), constants.log
        err_old, after_reject = None, False
        for h, err, accept, h_next in constants.log:      # q + 1 = 2: Euler's estimate
            assert accept == (err <= 1.0)
            if not accept:
                assert h_next == pytest.approx(h * max(0.2, min(1.0, 0.9 * err ** -0.5)))
                after_reject = True
                continue
            fac = (0.9 * err ** -0.5 if err_old is None
                   else 0.9 * err ** (-k[0] / 2) * err_old ** (k[1] / 2))
            fac = min(5.0, max(0.2, fac))
            assert h_next == pytest.approx(h * (min(fac, 1.0) if after_reject else fac))
            err_old, after_reject = max(err, 1e-4), False
    assert len(runs["I"]) > 10 and len(runs["PI"]) > 10
    assert [r[0] for r in runs["I"]] != [r[0] for r in runs["PI"]]
    assert errors["I"] < 1e-2 and errors["PI"] < 2 * errors["I"]


def test_predictive_control_is_rkcs():
    """RKC's constants give the factor of the code rkc.f: ``0.8 err^(-1/3)`` on the
    first accepted step, then ``0.8 (h/h_old) err_old^(1/3) / err^(2/3)`` within
    [0.1, 10]."""
    c = registry.get_integrator("rkc").controller(2, rtol=1e-3, atol=1e-6, span=(0.0, 1.0))
    accept, h1 = c.adapt(0.01, 0.5)
    assert accept and h1 == pytest.approx(0.01 * 0.8 * 0.5 ** (-1 / 3))
    accept, h2 = c.adapt(h1, 0.2)
    assert accept and h2 == pytest.approx(h1 * 0.8 * (h1 / 0.01) * 0.5 ** (1 / 3) / 0.2 ** (2 / 3))
    accept, h3 = c.adapt(h2, 1e-9)
    assert h3 == pytest.approx(10 * h2)                           # the largest growth
    accept, h4 = c.adapt(h3, 27.0)
    assert not accept and h4 == pytest.approx(h3 * 0.8 / 3)      # a rejection: 0.8 err^(-1/3)


def test_the_controller_owns_the_norm_the_clipping_and_the_underflow_test():
    c = PI()(1, rtol=1e-3, atol=np.array([1e-6, 1.0]), mask=np.array([True, False]),
             span=(0.0, 2.0))
    y, y_new = np.array([1.0, 1.0]), np.array([2.0, 5.0])
    # weighted by atol + rtol max(|y|, |y_new|) over the mask only
    assert c.norm(np.array([2e-3, 1e3]), y, y_new) == pytest.approx(2e-3 / (1e-6 + 2e-3))
    assert c.norm(np.zeros(2), y, np.array([np.nan, 1.0])) == math.inf
    assert c.attempt(0.0, 0.5, cap=0.1) == 0.1                    # the stepper's max_step
    assert c.attempt(1.0, 0.95, cap=np.inf) == 1.0                # stretched to t_end
    assert c.attempt(1.0, 0.8, cap=np.inf) == 0.8                 # more than 10 % short
    with pytest.raises(StepSizeUnderflow, match="too small at t=1"):
        c.attempt(1.0, 1e-13, cap=np.inf)
    # a NaN step (a NaN first-step estimate from a model's NaN) ends the run at
    # once: it would pass the underflow test and be rejected forever (ROS3P spent
    # 500000 attempts and 40 s of CPU on the conformance check's NaN model)
    with pytest.raises(StepSizeUnderflow, match="not finite at t=0"):
        c.attempt(0.0, math.nan, cap=np.inf)
    assert c.failed(1e-12, 0.25) is None                          # below the smallest step
    assert c.failed(0.1, 0.25) == pytest.approx(0.025)
    fixed = ConstantStep(0.1)
    assert fixed.attempt(0.0, 0.1, cap=0.01) == 0.1               # a fixed step is not clipped
    assert fixed.norm(None, y, y_new) == 0.0
    assert fixed.norm(None, y, np.array([np.inf, 0.0])) == math.inf


@pytest.mark.parametrize("name", sorted(registry.integrators()))
def test_every_stepper_based_integrators_controller_is_a_step_size_controller(name):
    cls = registry.get_integrator(name)
    if not cls.has_stepper():
        pytest.skip(f"{name} has its own loop")
    control = cls.controller(2, rtol=1e-6, atol=np.ones(3), span=(0.0, 1.0))
    assert control.adaptive
    _keeps_the_controller_protocol(control)
    _keeps_the_controller_protocol(ConstantStep(0.1))


def _keeps_the_controller_protocol(control):
    """``control`` has StepSizeController's methods with its parameters and answers
    as the protocol says (``isinstance`` on a Protocol sees the method names only)."""
    import inspect

    for name, member in inspect.getmembers(StepSizeController, inspect.isfunction):
        if name.startswith("_"):
            continue
        wanted = list(inspect.signature(member).parameters)[1:]
        got = list(inspect.signature(getattr(control, name)).parameters)
        assert got[:len(wanted)] == wanted, (type(control).__name__, name, got)
    h = control.init(0.0, 1.0, lambda: 1e-3)
    assert 0 < h <= 1.0 and math.isfinite(h)
    h = control.attempt(0.0, h, cap=1.0)
    assert 0 < h <= 1.0
    y, y_new = np.ones(3), np.full(3, 1.0 + 1e-9)
    err = control.norm(np.full(3, 1e-9), y, y_new)
    assert err >= 0 and math.isfinite(err)
    assert control.norm(np.full(3, 1e-9), y, np.array([np.inf, 1.0, 1.0])) == math.inf
    accept, h_next = control.adapt(h, err)
    assert isinstance(accept, bool) and h_next > 0 and math.isfinite(h_next)
    retry = control.failed(h, 0.5)
    assert retry is None or 0 < retry < h


def test_the_protocol_check_sees_a_wrong_signature_and_a_wrong_answer():
    class Renamed(ConstantStep):
        def adapt(self, step, error):
            return super().adapt(step, error)

    class Negative(ConstantStep):
        def adapt(self, h, err):
            return True, -h

    for wrong in (Renamed(0.1), Negative(0.1)):
        assert isinstance(wrong, StepSizeController)      # what isinstance alone would pass
        with pytest.raises(AssertionError):
            _keeps_the_controller_protocol(wrong)


def test_one_method_runs_either_way_and_unsupported_modes_are_named():
    icls = integrator(EulerHeunStepper)
    assert icls.takes_h() and icls.adaptive and icls.mode_unsupported(1e-6, None) is None
    fixed = integrator(RK4Stepper, order=4, adaptive=False)
    assert "no error estimate" in fixed.mode_unsupported(1e-6, None)

    class OwnLoop(Integrator):
        name = "own-loop"

        def solve(self, system, *, rtol=None, atol=None, h=None):
            raise AssertionError("not called")
    assert "cannot take a fixed step" in OwnLoop.mode_unsupported(None, 0.1)


def test_a_code_with_its_own_root_finding_feeds_the_segment_runner():
    """A code that steps by 0.3 and finds its roots itself (as SUNDIALS, or Assimulo)
    feeds steps and roots; the runner acts on the events: a reset to 0 at y = 0.5
    restarts the code at t = 0.5, the second crossing (within round-off of t_end)
    ends the run there instead of restarting."""
    from integrator_bench.integrators.driver import Segments
    from integrator_bench.problems.system import Event

    half = Event(lambda t, y: y[0] - 0.5, direction=1, terminal=True,
                 reset=lambda t, y: np.zeros_like(y), name="half")
    system = ode(lambda t, y: np.ones_like(y), 0.0)
    system.events = (half,)
    segments, starts = Segments(system, locate=False), []

    def advance(t, y):
        starts.append(t)
        while t < 1.0:
            t_new = min(t + 0.3, 1.0)

            def dense(s, t=t, y=y):
                return y + (s - t)
            if y[0] < 0.5 <= dense(t_new)[0]:
                t_root = t + (0.5 - y[0])
                segments.roots(t_root, dense(t_root), [0], dense, t_new - t)
            segments.step(t, t_new, dense(t_new), dense)
            t, y = t_new, dense(t_new)
        return Status.SUCCESS, ""

    status, message = segments.run(0.0, np.zeros(1), advance, lambda t, y: y)
    sol = segments.solution(status, message, {})
    assert sol.status is Status.SUCCESS and message == "" and starts == [0.0, 0.5]
    assert [name for _, name, _ in sol.events] == ["half", "half"] and sol.counts["nevents"] == 2
    assert sol.events[1][0] == pytest.approx(1.0, abs=1e-15) and sol.t.size == 11
    np.testing.assert_allclose(sol.y[:6, 0], sol.t[:6], atol=1e-15)          # up to the reset
    np.testing.assert_allclose(sol.y[6:10, 0], sol.t[6:10] - 0.5, atol=1e-15)  # after it


@pytest.mark.parametrize("t_stop, status, last", [(float("nan"), Status.NONFINITE_STATE, 0.3),
                                                  (0.45, Status.SOLVER_FAILURE, 0.4)])
def test_success_short_of_t_end_is_a_failure(t_stop, status, last):
    """A code that says it succeeded but whose steps end before ``t_end`` without a
    terminal event (Assimulo's RungeKutta34 leaves its loop when a diverged step
    makes ``t`` NaN) failed: the harness must not see a shortened solution as ok."""
    from integrator_bench.integrators.driver import Segments

    system = ode(lambda t, y: np.ones_like(y), 0.0)
    segments = Segments(system, locate=False)

    def advance(t, y):
        segments.step(0.0, 0.3, y + 0.3, None)
        segments.step(0.3, t_stop, y + 0.4, None)
        return Status.SUCCESS, ""

    sol = segments.solution(*segments.run(0.0, np.zeros(1), advance, lambda t, y: y), {})
    assert sol.status is status and f"outputs end at t={last:g}" in sol.message
    assert sol.t[-1] == pytest.approx(last)
