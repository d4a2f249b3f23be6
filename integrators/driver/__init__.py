"""The segment runner every integrator feeds, and the stepping loop of the steppers.

One module per noun, their public names re-exported here:

* :mod:`.segments`: :class:`Segments`, the runner (and :class:`Stall`, a library
  code's steps that no longer advance);
* :mod:`.outputs`: :class:`Outputs`, the output times filled from the steps;
* :mod:`.events`: state events: the sign-change test, :func:`locate` and :func:`act`;
* :mod:`.budget`: a run's wall-time :class:`Budget` and :func:`budgeted`;
* :mod:`.stepping`: :func:`integrate`, the stepping loop of the steppers.

:class:`Segments` owns, once for every family, what happens between a code's
accepted steps and the :class:`~integrator_bench.integrators.base.Solution`:
output filling, state events (located here, or found by the library), their
action, terminal stops, resets and restarts. A code feeds it in one of two
ways (compare scipy's ``solve_ivp``, one loop over every ``OdeSolver``, and
diffrax's ``diffeqsolve``, one loop over every ``AbstractSolver.step``):

* **steps**: after each accepted step, :meth:`Segments.step` ``(t_old, t, y,
  dense)`` with the state kept at ``t`` and ``dense(s) -> y(s)`` on ``[t_old,
  t]`` (None: the driver's interpolation). The steppers of this package
  (:func:`integrate`), scipy's ``OdeSolver`` classes
  (:mod:`~integrator_bench.integrators.scipy_ivp`) and SUNDIALS
  (:mod:`~integrator_bench.integrators.sundials`, whose ``dense`` asks the
  solver for its interpolant) all do;
* **roots**: a code with root finding of its own (SUNDIALS; Assimulo would
  be another) builds its :class:`Segments` with ``locate=False`` and hands
  each root it returns to :meth:`Segments.roots` ``(t, y, indices, dense, h)``
  (the events found there, and the size of the step that holds the root)
  before it feeds that step.

The code's loop over one segment is ``advance(t, y) -> (status, message)``;
:meth:`Segments.run` calls it from the start and again after every reset,
with ``restart(t, y_after) -> y`` (a fresh code from the reset state) in
between. A stop or a reset found inside ``step``/``roots`` ends ``advance``
by an exception the runner catches, so the code's loop needs no event logic
(a ``try``/``finally`` there keeps the counts of the code that stopped).

The rules:

* **output** at ``system.t_eval`` without shortening steps: an output time
  within ``1e-9 h`` of a step end takes the step's value; one inside a step
  takes the step's dense output when the code gives one, else the driver's
  interpolation: the Lagrange polynomial of degree ``p + 1`` (``p`` the
  declared order, at least 1; degree at most 8) through ``p + 2`` consecutive
  accepted step values enclosing the output time, as centred as the steps
  taken allow (error ``O(h^(p+2))``, so that it stays well below the method's
  ``O(h^p)`` already at coarse steps; no function evaluations). When the
  system carries ``project`` (the ``projection`` and ``partitioning``
  formulations) every interpolated output is projected; the code feeds
  projected step values;
* **state events** (``system.events``, located here): at each step end every
  event function is evaluated; a strict sign change (respecting
  ``direction``) is located on the step's dense output by the Illinois method
  (regula falsi with halving, bisection when the bracket does not halve) to a
  bracket of width ``4 eps max(|t|, 1) + EVENT_ATOL``, and the crossing is the
  bracket's end past the sign change (as SUNDIALS returns its root), so the
  same crossing is never found again after a restart. A code without dense
  output cannot locate events (its integrator declares ``events = False``);
* **action** (:func:`act`, also on library roots): the earliest crossing is
  acted on first; a non-terminal one is recorded; a terminal one without
  reset ends the run successfully there ("stopped by the terminal event
  NAME at t=T"); a terminal one whose ``reset`` returns a state restarts the
  run from it with a fresh code (fresh stepper and controller; at a fixed
  step the grid restarts at the event), or ends it when the event lies within
  ``MIN_STEP max(span, |t|)`` of ``t_end`` (the outputs left take the reset
  state); one whose ``reset`` returns None is ignored. Outputs up to the
  event come from the dense output.
* **library events**: a code that locates and applies its events itself,
  inside its own loop (fmpy, whose FMU updates its own state), reports each
  with :meth:`Segments.applied`: recorded, and the output at its time takes
  the state after it; roots without a direction (Assimulo's) are kept only
  when crossed in the event's ``direction`` (``directions=False``);
* **non-finite states**: a code fed with ``finite=True`` ends at its first
  step to a non-finite state (``Status.NONFINITE_STATE``, :func:`nonfinite`);
* **budget**: a run started inside :func:`budgeted` is stopped at its first
  accepted step past its :class:`Budget` (``Status.OVER_BUDGET``, the progress
  in the message).

:func:`integrate` drives a :class:`~integrator_bench.integrators.base.Stepper`
from ``t0`` to ``t_end`` with one loop for fixed and adaptive runs:

* **step-size control** by the controller of the run, a
  :class:`~integrator_bench.integrators.control.StepSizeController`: a
  :class:`~integrator_bench.integrators.control.ConstantStep` for a run at
  ``h`` (steps ``t0 + k h``, the last one shortened to end exactly at
  ``t_end``), else a :class:`~integrator_bench.integrators.control.PIControl`
  built from the integrator's ``controller`` constants. The controller owns
  the error norm (a step is accepted when the weighted RMS of its error
  estimate over the stepper's ``error_mask`` is at most 1), the bound by the
  stepper's ``max_step``, the stretch of a last step that would end within
  10 % of its size before ``t_end`` (no sliver of a last step, the code RKC's
  rule) and the step-size underflow test;
* **projection**: when the system carries ``project``, every accepted step
  value is projected;
* **the state** the driver keeps (what ``start`` returns, each accepted step
  value) is made read-only (:func:`kept`): a stepper that writes into the state
  it is handed fails at that write, and the driver, trying the step once more on
  a writeable copy, names it (:class:`~integrator_bench.integrators.base.InputModified`);
* **failure**: a non-finite state (at a fixed step: the end of the run; under
  error control: a rejection by ``factor_min``), an ``OverflowError`` or
  ``FloatingPointError`` from the system (the solution blew up), a step size
  below ``MIN_STEP max(span, |t|)``, more than ``max_steps`` attempted steps,
  and a :class:`~integrator_bench.integrators.base.StepFailure` (retried at a
  quarter of the step when the controller allows) each end the run with a
  typed :class:`~integrator_bench.integrators.base.Status`;
* **counts**: ``nsteps`` (accepted steps) and ``nreject`` (rejected by the
  error test); the stepper adds its own (``njev``, ``nlu``, ...).
"""

from __future__ import annotations

from integrator_bench.integrators.driver.budget import Budget, budgeted  # noqa: F401
from integrator_bench.integrators.driver.events import (  # noqa: F401
    EVENT_ATOL, EventTracker, act, locate)
from integrator_bench.integrators.driver.outputs import SNAP, Outputs  # noqa: F401
from integrator_bench.integrators.driver.segments import (  # noqa: F401
    STALLED, Segments, Stall, ended_short, nonfinite)
from integrator_bench.integrators.driver.stepping import (  # noqa: F401
    FAILURE_FACTOR, initial_step, integrate, kept)

__all__ = ["Budget", "budgeted", "EVENT_ATOL", "EventTracker", "act", "locate", "SNAP",
           "Outputs", "STALLED", "Segments", "Stall", "ended_short", "nonfinite",
           "FAILURE_FACTOR", "initial_step", "integrate", "kept"]
