"""The integrator interface: what every registered integrator declares and does.

Rules for implementers
----------------------
An integrator is a class deriving from :class:`Integrator`, registered under the
entry-point group ``integrator_bench.integrators`` with its registry name (for
example ``scipy-RK45 = "integrator_bench.integrators.scipy_ivp:RK45"``).
Built-ins and plugins are registered the same way. It knows numerics only: it
never imports a particular problem or the harness.

1. **Declare what it is**, as class attributes (the harness reads these and
   never branches on an integrator's identity):

   ``accepts``
       the system kinds it takes (:mod:`integrator_bench.problems.system`):
       ``"ode"`` (``y' = f(t, y)``, :class:`OdeSystem`), ``"dae"``
       (``F(t, y, y') = 0``, :class:`DaeSystem`) and ``"mechanical"``
       (``M(q) q'' = f(t, q, v) - G(q)^T lam``, ``g(q) = 0``,
       :class:`MechanicalSystem`, the second-order index-3 form), and
       ``"fmu"`` (:class:`FmuSystem`, a model-exchange FMU as a file, for a
       tool that simulates FMUs itself, such as fmpy). An ODE is handed as an
       index-0 DAE to an integrator taking DAEs only.
   ``max_index``
       the highest DAE index it handles (0 when it takes no DAE).
   ``order``
       its classical order of convergence, or None when it varies (variable
       order codes); ``ibench verify`` compares it with the observed order.
   ``implicit``, ``events``, ``uses_jacobian``
       booleans.
   ``adaptive``
       True when it can be driven by ``rtol``/``atol`` (it has an error
       estimate, or it is a library code with its own control).
   ``fixed_step``
       True when it can be driven by a step size ``h``. A stepper-based
       integrator (rule 2a) takes ``h`` always; one that brings its own
       :meth:`solve` takes ``h`` when it is not adaptive, unless it says so.
   ``stability``
       ``"A"``, ``"L"`` or None, for the stability check of ``ibench verify``.
   ``stability_intervals``
       for an explicit method, the real stability interval ``[-beta, 0]``
       of ``h lambda``: a dict from a label of the method's variant (``""``
       for a method with one; ``"s=10"`` for 10 stages, a polynomial's name)
       to ``beta``, so that ``h <= beta / rho`` is stable for eigenvalues
       on the negative real axis up to ``rho`` in size (``ibench
       stiffness`` predicts stable steps from it). Empty when not known. A
       mapping that computes its values on first use (:class:`Intervals`)
       serves as well.
   ``stability_variants``
       for the labels of ``stability_intervals`` that a setting selects, the
       settings that run that variant (``{"s=10": {"stages": 10}}``): ``ibench
       verify`` then measures the interval on the running integrator.
   ``projects``
       True when ``system.project(t, y)`` may be applied after every accepted
       step (the ``projection`` and ``partitioning`` formulations): true for
       one-step methods, false for methods that keep a history the projection
       would invalidate. Such systems go only to these integrators.
   ``dense_output``
       True when its steps come with a continuous extension.
   ``event_locator``
       whose code locates its state events: ``"driver"`` (the default: the
       segment runner locates them on the steps' dense output) or the name of
       the library code that finds the roots itself (``"sundials"``,
       ``"odepack"``, ``"assimulo"``, ``"fmpy"``). Two references that must
       locate events independently are taken from integrators of different
       locators.
   ``description``, ``reference``
       one line each: what it is and the publication it implements.
   ``settings``
       a tuple of :class:`~integrator_bench.integrators.settings.Setting`:
       the controls a user may set (``-i cvode-bdf:max_order=2``), each with
       its type, default, valid range and meaning. An instance is made with
       the chosen values (``Integrator(**values)``, checked, defaults filled)
       and reads them from ``self.setting_values`` or the instance attribute
       of each setting's name.

2. **Implement one of**

   a. :meth:`stepper` (preferred): return a :class:`Stepper` that does *one*
      step. The shared driver (:mod:`integrator_bench.integrators.driver`)
      owns the loop: step-size control (a constant step for ``h``, I/PI
      control for ``rtol`` with the constants of the class attribute
      ``controller``), output at ``system.t_eval`` by dense output,
      projection after accepted steps, state events, non-finite and blow-up
      detection, step-size underflow, the step limit and the step counts.
   b. :meth:`solve`: the whole integration, for a library code with a loop
      of its own. Return a :class:`Solution` with the state at every time in
      ``system.t_eval`` that was reached.

   Either way, call only the callables of the system you are given
   (``fun``/``jac``, ``residual``/``jac``, ``force``/``tangent``, ``project``,
   the mass and constraint functions, the events' ``value`` and ``reset``):
   the harness hands a copy whose every callable counts its calls,
   finite-difference calls included, and carries no other path to the model
   (:mod:`integrator_bench.harness.measure.counting`); ``ibench check-plugin`` watches
   the problem's code and fails an integrator that evaluates it otherwise.

3. **Tolerances.** ``rtol`` is a float; ``atol`` is an array of the state's
   size, ``rtol * system.atol_scale`` (the problem's scale of each component).
   ``system.t_eval`` holds the output times, ``t_eval[0] = t0`` and
   ``t_eval[-1] = t_end``.

4. **Report, never invent, counts** in ``Solution.counts`` with the n-prefix
   vocabulary: ``nfev``, ``njev``, ``nlu``, ``nsteps`` (accepted steps),
   ``nreject`` (steps rejected by the error test), ``nniter``, ``nnfail``.
   Leave out a count it cannot know; the record then says null. The harness
   counts ``nfev`` and ``njev`` itself and records a disagreement. A code
   that keeps further counters of its own (CVODE's STALD order reductions)
   may report them too, each declared with its meaning in
   ``extra_counters``; they are kept in the record's ``solver_counts``.

5. **Fail by returning**, not by raising: when the method gives up, the
   Solution has a :class:`Status` other than ``SUCCESS``, a message, and
   whatever was reached. A stepper raises :class:`StepFailure` with a
   status instead. A library wrapper types the library's failure itself,
   from its flag or message (steps exhausted ``MAX_STEPS``, corrector
   ``NEWTON_FAILURE``, ``ERROR_TEST_FAILURE``, ``STEP_SIZE_UNDERFLOW``,
   ``LINEAR_SOLVER_FAILURE``; ``SOLVER_FAILURE`` when none fits): the harness
   reads the status, never the message. Any other exception is recorded as
   status ``error``.

6. **Sparse systems.** ``jac`` (and the blocks of a mechanical system) may
   return ``scipy.sparse`` matrices, and ``jac_sparsity`` may name the
   structure. Keep them sparse (:mod:`integrator_bench.integrators.sparse`:
   SuperLU factorizations, grouped finite differences); a code that can only
   densify declines such a system above ``sparse.DENSE_LIMIT`` states with
   status ``METHOD_LIMIT`` and a message, instead of allocating ``n x n``.

7. **State events.** An integrator declaring ``events = True`` honours
   ``system.events`` (:class:`~integrator_bench.problems.system.Event`); one
   declaring False is never given a system with events (``convert`` records
   it ``unsupported``). A stepper-based integrator gets events from the
   driver, which locates crossings on ``Step.dense``: declare ``events =
   True`` only when every step carries a dense output. An integrator with its
   own :meth:`solve` feeds its accepted steps (and, with root finding of its
   own, its roots) to the segment runner
   :class:`~integrator_bench.integrators.driver.Segments`, as the scipy and
   SUNDIALS wrappers do, which applies the rules: a crossing is a strict sign change in the event's
   ``direction`` over an accepted step, located to about ``4 eps max(|t|,
   1)``; the earliest is acted on first; a non-terminal one is recorded; a
   terminal one without ``reset`` ends the run with ``SUCCESS`` there
   (outputs after it absent); a terminal one whose ``reset`` returns a state
   restarts the method from it (no history kept); a ``reset`` returning None
   ignores the crossing. Report every crossing acted on in
   ``Solution.events`` and their number in ``counts["nevents"]``.

8. **One solve, counted and timed.** The harness solves a case once, through
   :meth:`timed_call`, on a system whose callables count their calls at the
   model (rule 2), and times that solve. :meth:`timed_call` returns a
   :class:`TimedCall`: its ``run()``, the only part timed, must solve the
   system with the ``rtol``, ``atol``, ``h``, output times and Jacobian given,
   and hold nothing a user calling the library would not pay; its
   ``finish(out)``, not timed, turns what ``run()`` returned into the
   :class:`Solution`. Translating the system into the library's options
   (and any Jacobian evaluation spent choosing them) belongs before ``run``;
   reading the library's counters and wrapping its arrays, in ``finish``. A
   library code runs through the library's own loop over the output times
   (scipy's ``solve_ivp``, SUNDIALS' ``solve``, Assimulo's ``simulate``), with
   no per-step Python round trip, and reports the library's own counts
   (rule 4: those the library keeps, read after the run, not counted by
   stepping it from Python). Where the library's loop cannot honour the system
   (a reset at an event needs a restart, a projection after every step) or
   reports no counts at all (fmpy), it falls back to :meth:`solve`;
   :meth:`timing_loop` says which loop runs (:data:`TIMING_LOOPS`). Build both
   from one configuration of the library (the built-ins:
   ``ScipyIVP.solver_options``, ``SundialsIntegrator.library_options``,
   ``AssimuloIntegrator.configured``), so that they cannot drift apart. The
   default, for stepper-based integrators, runs :meth:`solve` itself: the
   shared driver is their loop. :meth:`timed_solve` is the two parts in turn.

9. **Time budget.** The harness runs the solve inside
   :func:`~integrator_bench.integrators.driver.budgeted`, a budget of the
   process's CPU seconds: the
   :class:`~integrator_bench.integrators.driver.Segments` of the run stop it
   (``Status.OVER_BUDGET``, raised from ``Segments.step`` as a
   :class:`StepFailure` through the code's loop) at its first accepted step
   past the budget. A code fed through ``Segments`` needs nothing more (the
   shared driver and every built-in wrapper's own stepping loop are; fmpy's
   solvers feed it from ``simulate_fmu``'s ``step_finished``). Any other loop,
   a library's own, is stopped at the budget by the harness (its tripwire raises
   a ``BaseException`` in the Python code running, and in every call of the
   counted model from then on: let it pass); one that never returns to Python
   is killed with its worker 0.05 s of CPU past the budget.

10. **Inputs are read-only.** The system's arrays (``y0``, ``t_eval``,
    ``atol_scale``, ``error_mask``, ``yp0``, ...) and its other fields must not
    be changed nor replaced: the harness compares them after the run, and a run
    that changed one is recorded ``failed`` with reason ``input_modified``,
    naming it. The state the shared driver hands a stepper (``start``'s result,
    each accepted step) is a read-only array: a stepper writing into it fails
    at that write, and the driver raises :class:`InputModified` naming it.
    ``Stepper.start`` must return the state (None fails the run at once).

11. **Describe the library call.** A wrapper of a library code says, in
    :meth:`Integrator.library_call`, the call its timed solve makes (rule 8):
    the library, the function or class, the method, and every option passed
    (tolerances per state, linear solver, Jacobian, order, step bounds, modes
    such as Assimulo's ``report_continuously``), made from the same
    configuration as both solves (``solver_options``, ``library_options``,
    ``configured``) so that it cannot drift from them; the options as JSON
    (:mod:`integrator_bench.integrators.library_call`). The advice's
    reproduction recipe is this description: a user calling the plain library
    so gets the recorded error. What the wrapper sets past the library's own
    interface (a Fortran work array the Python library does not expose) goes in
    ``beyond_options``, a list of sentences, each naming the setting and its
    value, so that the recipe stays complete. The default, None, is an integrator implemented
    in this project (the shared driver's steppers): its name and settings are
    the recipe.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Callable, ClassVar

import numpy as np

from integrator_bench.integrators.control import PI
from integrator_bench.integrators.driver import integrate
from integrator_bench.integrators.outcome import (  # noqa: F401  (the interface's names)
    InputModified, Solution, Status, StepFailure)
from integrator_bench.integrators.settings import Setting, resolve
from integrator_bench.problems.system import System

COUNTERS = ("nfev", "njev", "nlu", "nsteps", "nreject", "nniter", "nnfail")

#: how :meth:`Integrator.timed_solve` runs (rule 8), the record's ``timing``:
#: ``library`` the library's own loop over the output times, as a user calls it;
#: ``driver`` the shared stepping driver, the loop of a stepper-based integrator;
#: ``wrapper`` the integrator's :meth:`~Integrator.solve` (the library stepped from
#: Python, where its own loop cannot honour the system or reports no counts)
TIMING_LOOPS = ("library", "driver", "wrapper")


class Intervals(Mapping):
    """``stability_intervals`` computed on first use: label -> ``beta``, each
    value from its function of no argument, called once when first read (the
    labels are known at once, so ``len`` and iteration cost nothing). Measuring
    an interval on the stability polynomial takes a scan and a bisection; at
    import, every command paid it for every stabilized method."""

    def __init__(self, compute: dict[str, Callable[[], float]]):
        self._compute, self._values = dict(compute), {}

    def __getitem__(self, label: str) -> float:
        if label not in self._values:
            self._values[label] = float(self._compute[label]())
        return self._values[label]

    def __iter__(self):
        return iter(self._compute)

    def __len__(self) -> int:
        return len(self._compute)


@dataclass
class Step:
    """The outcome of one step attempt of a :class:`Stepper`.

    Attributes
    ----------
    y : ndarray
        The state at ``t + h``.
    error : ndarray or None
        The local error estimate, in the units of ``y`` (the driver weighs it
        with ``atol + rtol max(|y_n|, |y_{n+1}|)`` over the stepper's
        ``error_mask`` and takes the RMS); None when the method has none.
    dense : callable or None
        ``dense(t) -> y(t)`` for ``t`` in ``[t_n, t_{n+1}]``, the method's
        continuous extension; None to leave the output to the driver's
        interpolation.
    """

    y: np.ndarray
    error: np.ndarray | None = None
    dense: Callable | None = None


class Stepper:
    """One run of a one-step (or multistep) method, one step at a time.

    Rules for implementers
    ----------------------
    * ``__init__(system, counts, rtol, atol)`` takes the (converted) system,
      a dict of counters to update in place (``njev``, ``nlu``, ``nniter``,
      ``nnfail``; the driver keeps ``nsteps`` and ``nreject``) and the run's
      tolerances (None at a fixed step: an iteration inside the step then
      solves to its own tight tolerance).
    * :meth:`step` ``(t, y, h)`` attempts a step and returns a :class:`Step`;
      it raises :class:`StepFailure` when the step cannot be completed. It
      must not commit anything: the driver may reject the step.
    * :meth:`accept` ``(t_new, y_new)`` commits the last attempt, with the
      state the driver keeps (projected, when the formulation projects);
      :meth:`reject` forgets it.
    * ``error_order`` is ``q`` where the error estimate is ``O(h^(q+1))``
      (the controller's exponent is ``1/(q+1)``); None when :meth:`step`
      returns no error estimate (the method then runs at fixed steps only).
    * ``error_mask`` (None: every component) is the set of components the
      error estimate covers.
    * ``dense_order`` is the order of the dense output the steps carry (None:
      the driver interpolates, see :mod:`integrator_bench.integrators.driver`).
    * :meth:`max_step` bounds the step at a state (inf: no bound);
      :meth:`initial_step` proposes the first step of an adaptive run (None:
      the driver's estimate).
    """

    error_order: ClassVar[int | None] = None
    dense_order: ClassVar[int | None] = None
    error_mask: np.ndarray | None = None

    def __init__(self, system, counts: dict, rtol: float | None = None, atol=None):
        self.system, self.counts, self.rtol, self.atol = system, counts, rtol, atol

    def start(self, t0: float, y0: np.ndarray) -> np.ndarray:
        """Prepare the run from ``(t0, y0)``; return the state the driver keeps."""
        return y0

    def step(self, t: float, y: np.ndarray, h: float) -> Step:
        raise NotImplementedError

    def accept(self, t_new: float, y_new: np.ndarray) -> None:
        """The last step was accepted with state ``y_new`` at ``t_new``."""

    def reject(self) -> None:
        """The last step was rejected by the error test."""

    def max_step(self, t: float, y: np.ndarray) -> float:
        return np.inf

    def initial_step(self, t0, y0, rtol, atol) -> float | None:
        return None


def _as_is(out):
    return out


@dataclass(frozen=True)
class TimedCall:
    """A case's solve split at the timer (rule 8 of the module's docstring).

    Attributes
    ----------
    run : callable
        ``run()``: the solve as a user calls the library, the only part the
        harness times; returns whatever ``finish`` takes.
    finish : callable
        ``finish(out)``: the :class:`Solution` of ``run``'s result, the
        library's counters read (not timed). The default returns ``out``: a
        ``run`` that returns the :class:`Solution` itself.
    """

    run: Callable[[], object]
    finish: Callable[[object], Solution] = _as_is


class Integrator:
    """Base class of every integrator; see the module docstring for the rules."""

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    reference: ClassVar[str] = ""
    accepts: ClassVar[frozenset[str]] = frozenset({"ode"})
    max_index: ClassVar[int] = 0
    order: ClassVar[int | None] = None
    implicit: ClassVar[bool] = False
    adaptive: ClassVar[bool] = True
    fixed_step: ClassVar[bool | None] = None   # None: see takes_h()
    events: ClassVar[bool] = False
    uses_jacobian: ClassVar[bool] = False
    stability: ClassVar[str | None] = None
    stability_intervals: ClassVar[dict[str, float]] = {}
    stability_variants: ClassVar[dict[str, dict]] = {}
    projects: ClassVar[bool] = False
    dense_output: ClassVar[bool] = False
    #: whose code locates its state events (rule 7): ``"driver"`` (the segment
    #: runner's locator, fed the steps' dense output) unless the library finds the
    #: roots itself
    event_locator: ClassVar[str] = "driver"
    #: the constants of the adaptive step-size control of a stepper-based
    #: integrator (:class:`~integrator_bench.integrators.control.PI`: safety,
    #: factor_min, factor_max, k_i, k_p, hold_band)
    controller: ClassVar[PI] = PI()
    max_steps: ClassVar[int] = 500_000
    #: counters beyond ``COUNTERS`` that ``Solution.counts`` may hold: name -> meaning
    extra_counters: ClassVar[dict[str, str]] = {}
    #: the controls a user may set (module docstring, rule 1)
    settings: ClassVar[tuple[Setting, ...]] = ()
    #: the numerical code a library wrapper runs, named alike by every wrapper of it
    #: (``"SUNDIALS CVODE (Adams)"`` for scikit-sundae's and Assimulo's): two lines
    #: that tie on one code are said to be the same code; None: a code of its own
    code: ClassVar[str | None] = None

    def __init__(self, **values):
        """An integrator running with the settings ``values`` (names of
        ``settings``; strings are converted), the others at their defaults.

        Raises
        ------
        SettingError
            One line naming the bad setting or value and the valid ones.
        """
        self.setting_values = resolve(self.name or type(self).__name__, self.settings, values)
        for key, value in self.setting_values.items():
            setattr(self, key, value)

    def stepper(self, system: System, counts: dict, rtol: float | None = None,
                atol: np.ndarray | None = None) -> Stepper:
        """A :class:`Stepper` for ``system`` (rule 2a); not implemented by
        integrators that bring their own :meth:`solve`. ``rtol`` and ``atol``
        are None for a run at a fixed step."""
        raise NotImplementedError

    def solve(self, system: System, *, rtol: float | None = None,
              atol: np.ndarray | float | None = None,
              h: float | None = None) -> Solution:
        """Integrate ``system`` over ``[system.t0, system.t_end]``.

        The default drives :meth:`stepper` with the shared driver: at the
        constant step ``h`` when it is given, else under error control with
        ``rtol``/``atol``.

        Parameters
        ----------
        system : System
            A system of a kind listed in ``accepts``.
        rtol, atol : float, array
            Tolerances (adaptive runs).
        h : float
            Step size (fixed-step runs).
        """
        if not self.has_stepper():
            raise NotImplementedError(f"{type(self).__name__} implements neither stepper() "
                                      "nor solve()")
        return integrate(self, system, rtol=rtol, atol=atol, h=h)

    def timed_call(self, system: System, *, rtol: float | None = None,
                   atol: np.ndarray | float | None = None,
                   h: float | None = None) -> "TimedCall":
        """The case's one solve, split at the timer (rule 8): ``run()`` solves
        ``system`` as a user of the library would and is timed; ``finish`` makes
        its :class:`Solution`. Parameters as :meth:`solve`.

        The default runs :meth:`solve` (the shared driver for a stepper-based
        integrator, the wrapper's own loop otherwise), or the class's own
        :meth:`timed_solve` where a plugin written before this method overrides
        that one.
        """
        solve = (self.timed_solve if type(self).timed_solve is not Integrator.timed_solve
                 else self.solve)
        return TimedCall(lambda: solve(system, rtol=rtol, atol=atol, h=h))

    def timed_solve(self, system: System, *, rtol: float | None = None,
                    atol: np.ndarray | float | None = None,
                    h: float | None = None) -> Solution:
        """:meth:`timed_call`'s two parts in turn: the :class:`Solution` of the
        case's one solve. Parameters as :meth:`solve`."""
        call = self.timed_call(system, rtol=rtol, atol=atol, h=h)
        return call.finish(call.run())

    def library_call(self, system: System, rtol: float,
                     atol: np.ndarray) -> dict | None:
        """The library call :meth:`timed_call` makes on ``system`` at ``rtol``/``atol``
        (rule 11), JSON-ready: ``library``, ``call`` (how it is made), ``function``
        (the system's function it integrates), ``options`` (every option passed,
        callables named by the system's function they call), ``callbacks`` (how
        those are written for the library), ``jacobian`` (its source:
        :func:`~integrator_bench.integrators.library_call.jacobian_source`); None
        for an integrator implemented in this project, or a system it declines."""
        return None

    def timing_loop(self, system: System) -> str:
        """Which loop :meth:`timed_solve` runs on ``system``: one of
        :data:`TIMING_LOOPS`."""
        return "driver" if self.has_stepper() else "wrapper"

    @classmethod
    def has_stepper(cls) -> bool:
        return cls.stepper is not Integrator.stepper

    @classmethod
    def takes_h(cls) -> bool:
        """Whether a run at a fixed step ``h`` is possible."""
        if cls.fixed_step is not None:
            return bool(cls.fixed_step)
        return cls.has_stepper() or not cls.adaptive

    @classmethod
    def mode_unsupported(cls, rtol, h) -> str | None:
        """Why a run with this ``rtol`` or ``h`` is impossible, or None."""
        if h is not None and not cls.takes_h():
            return (f"{cls.name} cannot take a fixed step h (a code with its own step-size "
                    "control); give rtol")
        if h is None and not cls.adaptive:
            return f"{cls.name} has no error estimate and runs at a fixed step only; give h"
        return None

    @classmethod
    def capabilities(cls) -> dict:
        """What the integrator declares, for ``ibench list integrators``."""
        return {
            "accepts": sorted(cls.accepts),
            "max_index": cls.max_index,
            "order": cls.order,
            "implicit": cls.implicit,
            "adaptive": cls.adaptive,
            "fixed_step": cls.takes_h(),
            "events": cls.events,
            "uses_jacobian": cls.uses_jacobian,
            "stability": cls.stability,
            "projects": cls.projects,
            "dense_output": cls.dense_output,
            "stepper": cls.has_stepper(),
            "settings": [s.as_dict() for s in cls.settings],
        }
