"""scipy.integrate's solve_ivp methods, driven step by step.

The ``OdeSolver`` classes behind ``solve_ivp`` are stepped directly so that the
accepted steps can be counted (``solve_ivp`` does not report them); output
times inside a step are filled from the method's dense output, exactly as
``solve_ivp(t_eval=...)`` does, and the final time is a step end.

The one-step methods (the explicit Runge-Kutta pairs and Radau IIA) also take
the ``projection`` formulation: after every accepted step the state (and the
dense-output values inside the step) is projected with ``system.project`` and
the stored ``f`` recomputed (counted in ``nfev`` beside scipy's own count), so the
next step starts on the manifold
(Hairer, Lubich, Wanner, Geometric Numerical Integration, sect. IV.4). The
multistep BDF and LSODA keep a history that a projection would invalidate, so
they do not declare ``projects``. scipy reports
``nfev``, ``njev`` and ``nlu``; rejected steps and Newton statistics are not
exposed and are left unknown.

Sparse systems. Radau and BDF take the system's ``jac`` as it comes: when it
returns a ``scipy.sparse`` matrix they keep their iteration matrices sparse
and factor them with SuperLU; a system with ``jac_sparsity`` and no ``jac``
gets scipy's grouped finite differences on that pattern. LSODA (ODEPACK)
has dense and banded linear algebra only: a sparse system whose Jacobian
structure (``jac_sparsity``, or that of one ``jac`` evaluation when the system
is larger than :data:`~integrator_bench.integrators.sparse.DENSE_LIMIT`) lies
in a narrow band gets LSODA's banded solver (``lband``, ``uband``; the band
LSODA stores, ``(2 ml + mu + 1) n`` numbers, must be at most half of a dense
matrix and at most a dense matrix of ``DENSE_LIMIT`` states); a wider
structure is densified up to ``DENSE_LIMIT`` states and declined above, with
status ``method_limit`` (LSODA would allocate two dense ``n x n`` arrays).

State events. Every method locates ``system.events`` as ``solve_ivp(events=...)``
does (sign changes at step ends, the root on the step's dense output): each
accepted step goes to the segment runner
(:class:`~integrator_bench.integrators.driver.Segments`), so the rules are
those of the stepping driver (the crossing is the end of the root's bracket
past the sign change, located to ``4 eps max(|t|, 1) + EVENT_ATOL``;
solve_ivp uses brentq to ``4 eps``); after a terminal event with a reset a
new solver starts from the reset state, its counts added.

Settings: every method takes ``max_step`` and ``first_step`` (scipy's
``OdeSolver`` options of the same names; ADAMS's HMAX and HINIT), LSODA also
``min_step`` (HMIN); at the code's own choice they are not passed.

Failures. A failed step's message is typed: scipy's "Required step size is
less than spacing between numbers." is ``step_size_underflow``; LSODA's
failures ("Unexpected istate in LSODA.") are read from ODEPACK's ``istate``
(:class:`LSODAFailure`); any other is ``solver_failure``. Near a blow-up LSODA's
step size can reach zero, after which its steps return without moving and
without failing: such returns are not steps, and the driver's
:class:`~integrator_bench.integrators.driver.Stall` ends the run as
``step_size_underflow``.

Timing. :meth:`ScipyIVP.timed_solve` calls ``solve_ivp`` itself, with the
solver options above (:meth:`ScipyIVP.solver_options`, from which :meth:`ScipyIVP.solve`
builds its solver too), as a user would (rule 8 of
:mod:`~integrator_bench.integrators.base`); systems with events or a projection
are timed through the stepping loop here.

References: Virtanen et al., "SciPy 1.0", Nature Methods 17 (2020); the
methods' own references are in scipy.integrate's documentation.
"""

from __future__ import annotations

import scipy
import scipy.integrate as si
import scipy.sparse as sp

from integrator_bench.integrators import library_call
from integrator_bench.integrators.base import Integrator, Solution, Status, TimedCall
from integrator_bench.integrators.driver import Segments, Stall
from integrator_bench.integrators.settings import FIRST_STEP, MAX_STEP, MIN_STEP
from integrator_bench.integrators.sparse import DENSE_LIMIT, bandwidths, dense, pattern, to_banded


class ScipyIVP(Integrator):
    """Common driver; subclasses name the ``scipy.integrate`` solver class."""

    solver_class: type = None
    events = True
    settings = (MAX_STEP, FIRST_STEP)

    def jacobian_options(self, system):
        """``(options, njev, refusal)``: the Jacobian options of the solver class,
        the Jacobian evaluations spent choosing them, and why the system is
        declined (None when it is not)."""
        options = {}
        if not self.uses_jacobian:
            return options, 0, None
        if system.jac is not None:
            options["jac"] = system.jac
        elif system.jac_sparsity is not None:
            options["jac_sparsity"] = system.jac_sparsity
        return options, 0, None

    def solver_options(self, system, rtol, atol):
        """``(options, njev, refusal)``: the solver's keyword options on ``system`` at
        ``rtol``/``atol``, the tolerances, :meth:`jacobian_options` and the settings
        (a step bound left at the code's own choice is not passed). The one
        configuration of the solver: :meth:`solve` builds it with these options and
        :meth:`timed_solve` hands them to ``solve_ivp``."""
        options, probes, refusal = self.jacobian_options(system)
        options.update(rtol=rtol, atol=atol)
        options.update({k: v for k, v in self.setting_values.items() if v is not None})
        return options, probes, refusal

    def library_call(self, system, rtol, atol):
        """``solve_ivp`` with :meth:`solver_options` (rule 11 of
        :mod:`~integrator_bench.integrators.base`); LSODA's ``jac`` is the system's
        Jacobian as a dense or (with ``lband``/``uband``) banded array."""
        options, _, refusal = self.solver_options(system, rtol, atol)
        if refusal is not None:
            return None
        jac = options.get("jac")
        names = {id(system.fun): "system.fun", id(jac): "system.jac"}
        return {"library": f"scipy {scipy.__version__}",
                "call": "scipy.integrate.solve_ivp(system.fun, (t0, t_end), y0, "
                        "method=METHOD, t_eval=output times, **options)",
                "method": self.solver_class.__name__, "function": "system.fun",
                "options": library_call.described(options, names),
                "callbacks": "none" if jac is None else "jac(t, y): system.jac(t, y)" + (
                    "" if jac is system.jac else
                    ", as a dense array (banded, LSODA's layout, with lband/uband)"),
                "jacobian": library_call.jacobian_source(self.uses_jacobian, jac is not None)}

    def solve(self, system, *, rtol=None, atol=None, h=None):
        options, probes, refusal = self.solver_options(system, rtol, atol)
        if refusal is not None:
            return Solution(system.t_eval[:1], system.y0[None, :], message=refusal,
                            counts={"njev": probes}, status=Status.METHOD_LIMIT)
        project = system.project if self.projects else None
        counts = {"nsteps": 0, "nfev": 0, "njev": probes, "nlu": 0}
        segments = Segments(system, (self.order or 1) + 1, batch=True)

        def advance(t, y):
            """One solver over one segment (a new one after each reset), its counts
            added however the segment ends."""
            solver = self.solver_class(system.fun, t, y, system.t_end, **options)
            stall = Stall()
            try:
                while solver.status == "running":
                    t_old = solver.t
                    message = solver.step()
                    if solver.status == "failed":
                        return self.failure(solver, message)
                    stalled = stall(t_old, solver.t)
                    if stalled is not None:
                        return stalled
                    if solver.t <= t_old:    # LSODA at a zero step size: no step taken
                        continue
                    counts["nsteps"] += 1
                    # the step's interpolant, built before an event's reset can change the
                    # mode its function reads (DOP853 evaluates fun to build it) and before
                    # the projection moves solver.y (DOP853's reads it); only when events or
                    # outputs need it, so that plain runs count as before
                    dense = (solver.dense_output()
                             if system.events or segments.outputs.inside(solver.t,
                                                                           solver.t - t_old)
                             else None)
                    if project is not None:
                        solver.y = project(solver.t, solver.y)
                        solver.f = system.fun(solver.t, solver.y)  # the next step starts from f(y)
                        counts["nfev"] += 1
                    segments.step(t_old, solver.t, solver.y, dense)
                return Status.SUCCESS, ""
            finally:
                for key in ("nfev", "njev", "nlu"):
                    counts[key] += int(getattr(solver, key))

        status, message = segments.run(system.t0, system.y0, advance, lambda t, y: y)
        return segments.solution(status, message, counts)

    def timing_loop(self, system):
        """``library`` (``solve_ivp``) unless the system has events, whose resets
        ``solve_ivp`` cannot apply, or a projection after every step: then
        ``wrapper``."""
        projects = self.projects and system.project is not None
        return "wrapper" if system.events or projects else "library"

    def timed_call(self, system, *, rtol=None, atol=None, h=None):
        """``solve_ivp`` on ``system`` with the options :meth:`solve` gives the solver
        (rule 8 of :mod:`~integrator_bench.integrators.base`), the options made
        before the timed call; :meth:`solve` where :meth:`timing_loop` says
        ``wrapper`` or the system is declined. scipy's ``nfev``, ``njev``,
        ``nlu``, and the accepted steps, counted by the solver class
        ``solve_ivp`` is handed (:func:`stepping`: one counter per step, the
        steps that advance ``t``, as :meth:`solve` counts them); a failure is
        typed from the solver as :meth:`solve` types it."""
        options, probes, refusal = self.solver_options(system, rtol, atol)
        if refusal is not None or self.timing_loop(system) != "library":
            return super().timed_call(system, rtol=rtol, atol=atol, h=h)
        method, made = stepping(self.solver_class)
        span = (system.t0, system.t_end)

        def run():
            return si.solve_ivp(system.fun, span, system.y0, method=method,
                                t_eval=system.t_eval, **options)

        def finish(res):
            counts = {"nsteps": made[-1].nsteps, "nfev": int(res.nfev),
                      "njev": int(res.njev) + probes, "nlu": int(res.nlu)}
            status, message = Status.SUCCESS, res.message
            if res.status != 0:
                status, message = self.failure(made[-1], res.message)
            return Solution(res.t, res.y.T, message=message, counts=counts, status=status)
        return TimedCall(run, finish)

    @staticmethod
    def failure(solver, message) -> tuple[Status, str]:
        """The typed failure of a solver whose step failed with ``message``: scipy's
        "Required step size is less than spacing between numbers." (every
        ``OdeSolver``) is a step-size underflow; LSODA's failures are read from its
        ODEPACK ``istate`` (:class:`LSODAFailure`)."""
        if message == solver.TOO_SMALL_STEP:
            return Status.STEP_SIZE_UNDERFLOW, message
        return Status.SOLVER_FAILURE, str(message)


def stepping(solver_class):
    """A subclass of the ``OdeSolver`` class ``solver_class`` for one ``solve_ivp``
    call, and the list its instances are kept in (one per call: ``solve_ivp`` makes
    one solver). Each instance has ``nsteps``, its accepted steps (a step counts
    when it advances ``t``: LSODA at a zero step size returns without one), as
    :meth:`ScipyIVP.solve` counts them. ``solve_ivp`` takes an ``OdeSolver``
    subclass as its ``method``. LSODA keeps the count itself (ODEPACK's ``NST``,
    ``IWORK(11)``: Hindmarsh 1983, the optional outputs of ``lsoda.f``), read
    after the run, so its subclass adds nothing to scipy's loop; the others'
    adds one counter a step (kept on the instance: setting a class attribute at
    every step would invalidate the class's attribute caches and slow every
    lookup; the parent's ``step`` called directly, not through ``super()``:
    both cost per step, 4 % of LSODA's millisecond solve when it counted so)."""
    made = []

    if issubclass(solver_class, si.LSODA):
        class Stepping(solver_class):
            def __init__(self, *args, **kwargs):
                super().__init__(*args, **kwargs)
                made.append(self)

            @property
            def nsteps(self):
                return int(self._lsoda_solver._integrator.iwork[10])
    else:
        class Stepping(solver_class):
            def __init__(self, *args, **kwargs):
                super().__init__(*args, **kwargs)
                self.nsteps = 0
                made.append(self)

            def step(self, _step=solver_class.step):
                t = self.t
                message = _step(self)
                if self.t != t and self.status != "failed":
                    self.nsteps += 1
                return message

    Stepping.__name__ = Stepping.__qualname__ = solver_class.__name__
    return Stepping, made


class LSODAFailure:
    """LSODA's failures by ODEPACK's ``istate`` (Hindmarsh, "ODEPACK, a systematized
    collection of ODE solvers", IMACS Trans. Sci. Comput. 1 (1983) 55-64; the
    ``istate`` table of ``lsoda.f``), which scipy's ``LSODA.step`` reports only as
    "Unexpected istate in LSODA."; the message is then ODEPACK's own."""

    STATUS = {-1: Status.MAX_STEPS,              # excess work done on this call
              -2: Status.ERROR_TEST_FAILURE,     # excess accuracy requested
              -4: Status.ERROR_TEST_FAILURE,     # repeated error test failures
              -5: Status.NEWTON_FAILURE}         # repeated convergence failures

    @classmethod
    def of(cls, solver, message) -> tuple[Status, str]:
        ode = solver._lsoda_solver._integrator
        istate = int(ode.istate)
        return (cls.STATUS.get(istate, Status.SOLVER_FAILURE),
                f"LSODA istate {istate}: {ode.messages.get(istate, message)}")


class ScipyOneStep(ScipyIVP):
    """One-step methods: projection after each step is sound."""

    projects = True


class RK23(ScipyOneStep):
    name = "scipy-RK23"
    description = "Explicit Runge-Kutta 3(2), Bogacki-Shampine (scipy)"
    reference = "Bogacki and Shampine, Appl. Math. Lett. 2 (1989) 321-325"
    solver_class = si.RK23
    order = 3
    #: real stability interval of R(z) = 1 + z + z^2/2 + z^3/6 (3 stages, order 3):
    #: |R(-beta)| = 1 with R from scipy's tableau (scipy.integrate._ivp.rk.RK23.A, B);
    #: cf. Hairer and Wanner II, sect. IV.2, Fig. 2.1; checked in tests/harness/measure/test_stiffness.py
    stability_intervals = {"": 2.5127453266183286}


class RK45(ScipyOneStep):
    name = "scipy-RK45"
    description = "Explicit Runge-Kutta 5(4), Dormand-Prince (scipy)"
    reference = "Dormand and Prince, J. Comput. Appl. Math. 6 (1980) 19-26"
    solver_class = si.RK45
    order = 5
    #: real stability interval of the 6-stage order-5 solution of DOPRI5:
    #: |R(-beta)| = 1 with R from scipy's tableau (scipy.integrate._ivp.rk.RK45.A, B);
    #: cf. Hairer and Wanner II, sect. IV.2, Fig. 2.1; checked in tests/harness/measure/test_stiffness.py
    stability_intervals = {"": 3.3065678926349458}


class DOP853(ScipyOneStep):
    name = "scipy-DOP853"
    description = "Explicit Runge-Kutta 8(5,3), Dormand-Prince (scipy)"
    reference = "Hairer, Norsett, Wanner, Solving ODEs I, 2nd ed., sect. II.10"
    solver_class = si.DOP853
    order = 8
    #: real stability interval of the 12-stage order-8 solution of DOP853:
    #: |R(-beta)| = 1 with R from scipy's tableau (scipy.integrate._ivp.rk.DOP853.A, B);
    #: cf. Hairer and Wanner II, sect. IV.2, Fig. 2.1; checked in tests/harness/measure/test_stiffness.py
    stability_intervals = {"": 6.393651522851179}


class Radau(ScipyOneStep):
    name = "scipy-Radau"
    description = "Implicit Runge-Kutta Radau IIA, order 5 (scipy)"
    reference = "Hairer and Wanner, Solving ODEs II, 2nd ed., sect. IV.8"
    solver_class = si.Radau
    order = 5
    implicit = True
    uses_jacobian = True
    stability = "L"


class BDF(ScipyIVP):
    name = "scipy-BDF"
    description = "Variable-order BDF / NDF, orders 1-5 (scipy)"
    reference = "Shampine and Reichelt, SIAM J. Sci. Comput. 18 (1997) 1-22"
    solver_class = si.BDF
    implicit = True
    uses_jacobian = True


class LSODA(ScipyIVP):
    name = "scipy-LSODA"
    code = "ODEPACK LSODA (LSODAR: with root finding)"
    description = "Adams/BDF with automatic stiffness switching, ODEPACK LSODA (scipy)"
    reference = "Petzold, SIAM J. Sci. Stat. Comput. 4 (1983) 136-148"
    solver_class = si.LSODA
    implicit = True     # its BDF mode solves with a Newton iteration, as assimulo-lsodar's
    uses_jacobian = True
    settings = (MAX_STEP, FIRST_STEP, MIN_STEP)

    @staticmethod
    def failure(solver, message):
        return LSODAFailure.of(solver, message)

    def jacobian_options(self, system):
        """Dense ``jac`` as before for a dense system; for a sparse one (see the
        module docstring) LSODA's band, a dense copy, or a refusal."""
        jac, n, probes = system.jac, system.n, 0
        structure = system.jac_sparsity
        if structure is None and jac is not None and n > DENSE_LIMIT:
            J0 = jac(system.t0, system.y0)     # one evaluation, to see its structure
            probes = 1
            structure = pattern(J0) if sp.issparse(J0) else None
        if structure is None:
            return ({} if jac is None else {"jac": lambda t, y: dense(jac(t, y))}), probes, None
        ml, mu = bandwidths(pattern(structure))
        band = (2 * ml + mu + 1) * n
        if band <= min(n * n / 2, DENSE_LIMIT ** 2):
            options = {"lband": ml, "uband": mu}
            if jac is not None:
                options["jac"] = lambda t, y: to_banded(jac(t, y), ml, mu)
            return options, probes, None
        if n <= DENSE_LIMIT:
            return ({} if jac is None else {"jac": lambda t, y: dense(jac(t, y))}), probes, None
        return {}, probes, (f"{self.name}: the sparse Jacobian of {n} states has bandwidths "
                            f"({ml}, {mu}); LSODA has dense and banded linear algebra only "
                            f"and declines a dense {n} x {n} above {DENSE_LIMIT} states")
