"""The outputs of a run at ``system.t_eval``: filled from the accepted steps' values,
their dense output, or the driver's interpolation (the rules: :mod:`.driver`)."""

from __future__ import annotations

import numpy as np

from integrator_bench.integrators.interpolation import Interpolation

SNAP = 1e-9            # output times this close (relative to h) to a step end take its value


class Outputs:
    """The output array and the output times still to fill."""

    def __init__(self, system, degree, batch=False):
        self.t_eval, self.batch = system.t_eval, batch
        self.ys = np.empty((self.t_eval.size, system.n))
        self.done = np.zeros(self.t_eval.size, bool)
        self.next = 1                 # the first output time no step has reached yet
        self.pending: list[int] = []  # reached, waiting for the interpolation
        self.interp = Interpolation(degree)
        self.project = getattr(system, "project", None)

    @property
    def filled(self) -> int:
        """How many output times from the first on have their values."""
        return int(np.argmin(self.done)) if not self.done.all() else self.done.size

    def start(self, t0, y0):
        self.ys[0], self.done[0] = y0, True
        self.interp.add(t0, y0)

    def restart(self, t, y):
        """The run restarts from ``(t, y)`` after a reset: no interpolation across it."""
        self.interp = Interpolation(self.interp.degree)
        self.interp.add(t, y)

    def step(self, t_new, h, y_new, dense):
        """Fill the outputs up to ``t_new`` after an accepted step."""
        self.interp.add(t_new, y_new)
        self.fill(t_new, h, y_new, dense)

    def fill(self, t_new, h, y_new, dense):
        """Fill the outputs up to ``t_new``, where the state is ``y_new``; those
        inside the step from ``dense`` (one call on all of them when ``batch``)."""
        if self.next >= self.t_eval.size or self.t_eval[self.next] > t_new + SNAP * h:
            if self.pending:                   # no output time reached: the common case
                self.flush(final=False)
            return
        inner = []
        while self.next < self.t_eval.size and self.t_eval[self.next] <= t_new + SNAP * h:
            i, te = self.next, self.t_eval[self.next]
            self.next += 1
            if abs(te - t_new) <= SNAP * h:
                self._set(i, y_new, project=False)
            else:
                inner.append(i)
        if dense is None:
            self.pending.extend(inner)
        elif self.batch and inner:
            for i, value in zip(inner, np.asarray(dense(self.t_eval[inner]), float).T):
                self._set(i, value)
        else:
            for i in inner:
                self._set(i, np.asarray(dense(self.t_eval[i]), float))
        self.flush(final=False)

    def inside(self, t_new, h) -> bool:
        """Whether an output time lies inside the step ending at ``t_new`` (so that
        :meth:`fill` will call its dense output)."""
        return (self.next < self.t_eval.size
                and self.t_eval[self.next] < t_new - SNAP * h)

    def flush(self, final: bool):
        while self.pending and self.interp.ready(self.t_eval[self.pending[0]], final):
            i = self.pending.pop(0)
            self._set(i, self.interp(self.t_eval[i]))

    def replace(self, t, y):
        """The output already filled at ``t`` (if one: to ``SNAP`` of the span) takes ``y``."""
        i = self.next - 1
        span = max(abs(self.t_eval[-1] - self.t_eval[0]), 1.0)
        if i >= 0 and self.done[i] and abs(self.t_eval[i] - t) <= SNAP * span:
            self._set(i, y, project=False)

    def rest(self, y):
        """Every output not filled takes ``y`` (a reset at ``t_end``)."""
        for i in np.flatnonzero(~self.done):
            self._set(i, y, project=False)

    def _set(self, i, value, project=True):
        if project and self.project is not None:
            value = np.asarray(self.project(self.t_eval[i], value), float)
        self.ys[i], self.done[i] = value, True
