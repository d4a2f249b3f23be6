"""The one stepping loop of the steppers (:func:`integrate`): step-size control,
projection, the read-only state, failures and counts (rules: :mod:`.driver`)."""

from __future__ import annotations

import math

import numpy as np

from integrator_bench.integrators.control import ConstantStep, StepSizeUnderflow, rms
from integrator_bench.integrators.driver.segments import Segments
from integrator_bench.integrators.outcome import InputModified, Solution, Status, StepFailure

FAILURE_FACTOR = 0.25  # step cut after a failed step under error control


def initial_step(system, stepper, y0, rtol, atol, t0=None) -> float:
    """The first step of an adaptive run from ``t0`` (default ``system.t0``): the
    stepper's proposal, or Hairer's estimate (Hairer, Norsett and Wanner I,
    sect. II.4; two evaluations of ``f``)."""
    t0 = system.t0 if t0 is None else t0
    span = system.t_end - t0
    h = stepper.initial_step(t0, y0, rtol, atol)
    if h is not None:
        return min(h, span)
    fun = getattr(system, "fun", None)
    if fun is None:
        return 1e-3 * span
    order = (stepper.error_order or 1) + 1
    scale = atol + rtol * np.abs(y0)
    f0 = np.asarray(fun(t0, y0), float)
    d0, d1 = (rms(x / scale) for x in (y0, f0))
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, span)
    f1 = np.asarray(fun(t0 + h0, y0 + h0 * f0), float)
    d2 = rms((f1 - f0) / scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, 1e-3 * h0)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / order)
    return min(100 * h0, h1, span)


def integrate(integrator, system, *, rtol=None, atol=None, h=None) -> Solution:
    """Run ``integrator``'s stepper over ``system``: at the fixed step ``h``
    when given, else under error control with ``rtol``/``atol``."""
    counts = {"nsteps": 0, "nreject": 0}
    if h is not None:
        rtol = atol = None
    elif atol is not None:
        atol = np.broadcast_to(np.asarray(atol, float), (system.n,))

    def fresh():
        """A new stepper and controller (the start, and every restart after a reset)."""
        stepper = integrator.stepper(system, counts, rtol=rtol, atol=atol)
        if h is not None:
            return stepper, ConstantStep(h)
        if stepper.error_order is None or rtol is None:
            raise ValueError(f"{integrator.name} has no error estimate: give h, not rtol")
        return stepper, integrator.controller(stepper.error_order, rtol=rtol, atol=atol,
                                              mask=stepper.error_mask,
                                              span=(system.t0, system.t_end))

    segments = Segments(system, (integrator.order or 1) + 1)
    loop = _Loop(system, fresh, counts, segments, rtol, atol, integrator.max_steps)
    try:
        y0 = kept(loop.stepper.start(system.t0, np.array(system.y0, dtype=float)), "start")
        status, message = segments.run(system.t0, y0, loop.advance, loop.restart)
    except StepFailure as exc:        # from the stepper's start
        status, message = exc.status, str(exc)
    except (OverflowError, FloatingPointError) as exc:
        status, message = Status.DIVERGED, (f"overflow in the step from t={loop.t:.6g} "
                                            f"({exc}): the solution blew up")
    return segments.solution(status, message, counts)


def kept(y, source: str) -> np.ndarray:
    """``y`` as the state the driver keeps: a float array made read-only, so that a
    stepper writing into the state it is handed fails at that write (rule 10 of
    :mod:`integrator_bench.integrators.base`). ``source`` names the stepper's
    method that gave it, for the error when it gave None."""
    if y is None:
        raise TypeError(f"the stepper's {source}() returned None: it must return the state "
                        "the driver keeps (the base class's start returns y0)")
    y = np.asarray(y, float)
    y.flags.writeable = False
    return y


def _writes_state(stepper, t, y, h) -> bool:
    """Whether ``stepper.step`` writes into the state it is handed: tried once more
    on a writeable copy of ``y`` (after a ``ValueError`` from the read-only one)."""
    probe = np.array(y, dtype=float)
    try:
        stepper.step(t, probe, h)
    except Exception:  # the write shows in the probe whatever happens after it
        pass
    return not np.array_equal(probe, y, equal_nan=True)


class _Loop:
    """The stepping loop of one stepper-based run: one segment per :meth:`advance`."""

    def __init__(self, system, fresh, counts, segments, rtol, atol, max_steps):
        self.system, self.fresh, self.counts, self.segments = system, fresh, counts, segments
        self.rtol, self.atol, self.max_steps = rtol, atol, max_steps
        self.stepper, self.control = fresh()
        self.project = getattr(system, "project", None)
        self.attempts = 0
        self.t = system.t0            # start of the step under way, for messages

    def restart(self, t, y_after):
        """A fresh stepper and controller from the reset state."""
        self.stepper, self.control = self.fresh()
        return kept(self.stepper.start(t, y_after), "start")

    def advance(self, t, y) -> tuple[Status, str]:
        """Step from ``(t, y)`` to ``t_end``, feeding every accepted step to the segments."""
        system, stepper, control = self.system, self.stepper, self.control
        t_end = system.t_end
        self.t = t
        h = control.init(t, t_end, lambda: initial_step(system, stepper, y, self.rtol,
                                                        self.atol, t0=t))
        while t < t_end:
            self.t = t
            if control.adaptive:
                if self.attempts >= self.max_steps:
                    return Status.MAX_STEPS, f"more than {self.max_steps} steps"
                try:
                    h = control.attempt(t, h, stepper.max_step(t, y))
                except StepSizeUnderflow as exc:
                    return Status.STEP_SIZE_UNDERFLOW, str(exc)
                self.attempts += 1
            t_new = t_end if h == t_end - t else t + h
            try:
                step = stepper.step(t, y, h)
            except StepFailure as exc:
                h = control.failed(h, FAILURE_FACTOR) if exc.retry else None
                if h is None:
                    return exc.status, (f"{exc} (at the minimum step)"
                                        if exc.retry and control.adaptive else str(exc))
                continue
            except ValueError:
                if _writes_state(stepper, t, y, h):
                    raise InputModified(f"the stepper's step() wrote into the state y it was "
                                        f"handed (the step from t={t:.6g}); the driver keeps "
                                        "it read-only: compute a new array") from None
                raise
            err = control.norm(step.error, y, step.y)
            accept, h_next = control.adapt(h, err)
            if not accept:
                self.counts["nreject"] += 1
                stepper.reject()
                h = h_next
                continue
            if err == math.inf:
                return Status.NONFINITE_STATE, f"non-finite state at t={t_new:.6g}"
            y_new = step.y
            if self.project is not None:
                y_new = self.project(t_new, y_new)
            y_new = kept(y_new, "step" if self.project is None else "project")
            stepper.accept(t_new, y_new)
            self.counts["nsteps"] += 1
            self.segments.step(t, t_new, y_new, step.dense, h)
            t, y, h = t_new, y_new, h_next
        return Status.SUCCESS, ""
