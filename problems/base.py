"""The problem interface: what every registered problem declares.

Rules for implementers
----------------------
A problem is a class deriving from :class:`Problem`, registered under the
entry-point group ``integrator_bench.problems``. It knows physics only: it never
imports an integrator or the harness. It must

* set the class attributes ``name`` (lower_snake), ``description`` (one line),
  ``source`` (citation), ``components`` (canonical component names),
  ``t_span``, and ``parameters`` (a tuple of :class:`Parameter`);
* implement :meth:`initial_state` (consistent canonical initial values) and
  :meth:`formulate`, which returns a :class:`integrator_bench.problems.system.System` for each
  name in ``formulations``. Unconstrained problems get ``formulate`` for free by
  implementing :meth:`rhs` and :meth:`jac` (the analytic Jacobian, dense array
  or scipy sparse matrix) and keeping ``formulations = ("ode",)``;
* declare which canonical components count for the error (``error_components``,
  positions for mechanical systems, as the IVP Test Set scores them), and may
  declare ``velocity_components`` and ``lambda_components`` to have those
  errors reported separately;
* give ``atol_scale`` (the typical magnitude of each component, so that
  ``atol = rtol * atol_scale``) and may give :meth:`invariants` (quantities
  conserved by the exact flow), :meth:`constraint_residuals` (position and
  velocity constraint residuals, for drift) and :meth:`exact` (the exact
  solution, when known; it then serves as reference);
* may give ``reference_methods``, the two tight runs ``(formulation,
  integrator, rtol)`` that compute the reference and check it (independent
  methods; default Radau against DOP853 on ``ode``), and ``reference_digits``,
  the agreement of the two on the error components that the tests demand
  (10; a problem that cannot afford 10 says why beside a lower value);
* may give :meth:`monitor`, a scalar history such as a pin force, whose
  error the harness records as Orlov does (``monitor_err``).

Parameters are given as keyword arguments to the constructor, validated against
their declared ranges; ``benchmark_parameters`` lists the parameter sets the
benchmark matrix runs when a problem is named without parameters.

Every problem also takes the option ``rhs_cost_us`` (``two_mass:rhs_cost_us=500``):
a fixed, known CPU cost in microseconds added to every evaluation of the
model's right-hand side, residual or force (a busy loop on the process's CPU
clock, :func:`burn`, before each call), so that a cheap model can be made
expensive on purpose: as it grows, every code's CPU approaches the work its
counted evaluations imply (the harness's ``overhead`` tends to 1). Like
``score`` it is kept in ``params`` but not in :meth:`Problem.key_params`:
the solution, fingerprint and reference are the problem's without it.

Every problem also takes the option ``score`` (``two_mass:score=x1+v1``):
canonical component names joined by ``+`` that replace the declared
``error_components`` once the problem is built (:meth:`Problem.set_score`,
applied by the constructor of every subclass, whatever its own ``__init__``).
The option is kept in ``params``, so a scored problem is a case of its own, but
not in :meth:`Problem.key_params`: the problem's numbers, fingerprint and
reference are those of the problem without it. A problem whose constructor
takes ``score`` itself (an FMU, which may score its outputs) handles it alone.

A problem class may declare ``form_options``: options that change how a
formulation is generated and not the solution (a mechanism's Baumgarte
parameters, ``slider_crank:baumgarte_alpha=3``). Like ``score`` they are kept in
``params`` (a case of its own) and out of :meth:`Problem.key_params` (the
reference of the problem without them).
"""

from __future__ import annotations

import abc
import hashlib
import inspect
import dataclasses
import functools
import math
import time
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from integrator_bench.problems.system import OdeSystem, System


#: significant digits of the values hashed into a problem's fingerprint
FINGERPRINT_DIGITS = 9


def significant_digits(values, digits: int = FINGERPRINT_DIGITS) -> str:
    """``values`` as text with ``digits`` significant digits each, for hashing.

    Round-off (a few units in the last of 16 digits) survives rounding to a
    fixed number of decimal places for large values (quick_return's forces
    near 1e6 kept it at 12 places, so its fingerprint differed between
    machines); rounding to significant digits drops it, except in the rare
    value that lies within round-off of a rounding boundary. Values below
    ``1e-12`` times the largest of the array are written as 0, so a component
    that is zero on one machine and 1e-17 on another hashes alike.
    """
    arr = np.asarray(values, float).ravel()
    floor = 1e-12 * float(np.max(np.abs(arr), initial=0.0))
    arr = np.where(np.abs(arr) <= floor, 0.0, arr) + 0.0     # + 0.0 turns -0.0 into 0.0
    return ",".join(f"{x:.{digits - 1}e}" for x in arr)


class ProblemError(ValueError):
    """Invalid problem parameters or an impossible formulation request."""


#: the option naming the components the error is scored on, and its separator
SCORE, SCORE_SEPARATOR = "score", "+"


def score_names(score, valid, what: str) -> tuple[str, ...]:
    """The names of a ``score`` option (``"x1+v1"``), each one of ``valid``.

    Raises
    ------
    ProblemError
        One line naming the unknown names (or an empty one), ``what`` they are
        not, and the valid names.
    """
    names = tuple(s.strip() for s in str(score).split(SCORE_SEPARATOR))
    unknown = [s for s in names if s not in valid]
    if unknown or not all(names):
        raise ProblemError(f"score={score!r} names {', '.join(map(repr, unknown))}, "
                           f"not a {what}; valid: {', '.join(valid)}")
    return names


#: the option adding a fixed CPU cost, in microseconds, to every model evaluation
MODEL_COST = "rhs_cost_us"
#: the options every problem takes beside its parameters, kept out of its key
OPTIONS = (SCORE, MODEL_COST)


def burn(microseconds: float) -> None:
    """Spin until this process has used ``microseconds`` more CPU time."""
    end = time.process_time_ns() + int(microseconds * 1000)
    while time.process_time_ns() < end:
        pass


def with_model_cost(system, microseconds: float):
    """``system`` (and its nested second-order form) with :func:`burn` of
    ``microseconds`` before every call of the callable the harness counts as
    ``nfev`` (``fun``, ``residual`` or ``force``)."""
    changes = {}
    for name, key in system.counted.items():
        fn = getattr(system, name, None)
        if key == "nfev" and fn is not None:
            changes[name] = _costly(fn, microseconds)
    nested = getattr(system, "mechanical", None)
    if nested is not None:
        changes["mechanical"] = with_model_cost(nested, microseconds)
    return dataclasses.replace(system, **changes) if changes else system


def _costly(fn, microseconds):
    @functools.wraps(fn)
    def costly(*args):
        burn(microseconds)
        return fn(*args)
    return costly


class Scorable(abc.ABCMeta):
    """The metaclass of :class:`Problem`: ``cls(score=..., **params)`` builds the
    problem from ``params`` and then applies the score (:meth:`Problem.set_score`),
    so the names are checked against the components a subclass sets in its own
    ``__init__`` (a chain's, which depend on its links). A class whose ``__init__``
    takes ``score`` gets it unchanged. Derived from ``abc.ABCMeta``, so that a
    problem plugin may also derive from ``abc.ABC``."""

    def __call__(cls, *args, **params):
        cost = params.pop(MODEL_COST, None)
        form = {o.name: params.pop(o.name) for o in cls.form_options if o.name in params}
        if SCORE not in params or SCORE in inspect.signature(cls.__init__).parameters:
            problem = super().__call__(*args, **params)
        else:
            score = params.pop(SCORE)
            problem = super().__call__(*args, **params)
            problem.set_score(score)
        if cost is not None:
            problem.set_model_cost(cost)
        if form:
            problem.set_form_options(form)
        return problem


@dataclass(frozen=True)
class Parameter:
    """A problem parameter with its default and valid closed range."""

    name: str
    default: float
    low: float = -math.inf
    high: float = math.inf
    description: str = ""

    def check(self, value) -> float:
        """``value`` as a float; ProblemError when it is not a number, not finite
        (``inf``, ``nan``, ``1e400``, which overflows) or outside the range."""
        given = value
        try:
            value = float(value)
        except (TypeError, ValueError):
            raise ProblemError(
                f"parameter {self.name}={value!r} is not a number") from None
        if not math.isfinite(value):
            raise ProblemError(f"parameter {self.name}={given} is not a finite number")
        if not (self.low <= value <= self.high):
            raise ProblemError(
                f"parameter {self.name}={value:g} is outside its range "
                f"[{self.low:g}, {self.high:g}]")
        return value


@dataclass(frozen=True)
class Start(Parameter):
    """An initial state a problem lets its user set, as the option ``name``: its
    start value (``default``), valid range, and absolute scale (``atol_scale``'s)."""

    scale: float = 1.0


class Problem(metaclass=Scorable):
    """Base class of every problem; see the module docstring for the rules."""

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    source: ClassVar[str] = ""
    components: ClassVar[tuple[str, ...]] = ()
    t_span: ClassVar[tuple[float, float]] = (0.0, 1.0)
    n_output: ClassVar[int] = 100
    parameters: ClassVar[tuple[Parameter, ...]] = ()
    benchmark_parameters: ClassVar[tuple[dict, ...]] = ({},)
    formulations: ClassVar[tuple[str, ...]] = ("ode",)
    error_components: ClassVar[tuple[str, ...] | None] = None  # None: all
    velocity_components: ClassVar[tuple[str, ...]] = ()
    lambda_components: ClassVar[tuple[str, ...]] = ()
    atol_scale: ClassVar[float | tuple[float, ...]] = 1.0
    step_sizes: ClassVar[tuple[float, ...] | None] = None  # fixed-step ladder
    reference_digits: ClassVar[int] = 10  # agreement of the two reference runs
    monitor_name: ClassVar[str] = ""      # what monitor() returns, with its unit
    monitor_start: ClassVar[float | None] = None  # t* of monitor_err (None: t0)
    # parameters naming a file the problem reads (an FMU's ``path``): a Dask worker
    # gets the file's bytes with the case and runs it on its own copy
    file_params: ClassVar[tuple[str, ...]] = ()
    #: options that change how a formulation is generated, not the problem's
    #: solution (a mechanism's ``baumgarte_alpha``): each sets the attribute of its
    #: name (:meth:`set_form_options`), is kept in ``params`` and left out of
    #: :meth:`key_params`, so the problem shares the reference of the one without it
    form_options: ClassVar[tuple[Parameter, ...]] = ()
    #: the components the user named with ``score=``, joined by ``+``, as
    #: :meth:`set_score` applied them (None: the declared ones, or a problem whose
    #: constructor takes ``score`` itself and keeps it in its own way, an FMU)
    score: str | None = None

    def __init__(self, **params):
        known = {p.name: p for p in self.parameters}
        for key in params:
            if key not in known:
                choices = ", ".join([*known, *self.other_options(),
                                     *(o.name for o in self.form_options)]) or "none"
                raise ProblemError(
                    f"unknown parameter {key!r} for problem {self.name}; valid: {choices}")
        self.params = {p.name: p.check(params.get(p.name, p.default))
                       for p in self.parameters}

    # ------------------------------------------------------------ to implement
    def initial_state(self) -> np.ndarray:
        """Consistent initial values of the canonical components."""
        raise NotImplementedError

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """Right-hand side of the ODE form (unconstrained problems)."""
        raise NotImplementedError

    def jac(self, t: float, y: np.ndarray):
        """Analytic Jacobian ``d rhs / d y`` (dense array or sparse matrix)."""
        raise NotImplementedError

    def exact(self, t: np.ndarray) -> np.ndarray | None:
        """Exact canonical solution at times ``t`` (shape ``(len(t), n)``), if known."""
        return None

    def invariants(self) -> dict:
        """Conserved quantities: ``{name: f(t, Y) -> ndarray}`` over canonical rows."""
        return {}

    def constraint_residuals(self, t: np.ndarray, Y: np.ndarray):
        """Position and velocity constraint residual norms along ``Y``, or None."""
        return None

    def monitor(self, t: np.ndarray, Y: np.ndarray) -> np.ndarray | None:
        """A scalar history the engineer watches (a joint or pin force), or None.

        ``(m,)`` values at the output times ``t`` from the canonical rows ``Y``
        ``(m, n)``. When given, the harness records Orlov's error of it
        (``monitor_err``, see :func:`integrator_bench.harness.measure.metrics.monitor_error`)
        over ``[monitor_start, t_end]``; name it in ``monitor_name``.
        """
        return None

    def other_options(self) -> tuple[str, ...]:
        """Options the constructor takes beside the parameters, named with them
        when an unknown one is refused (an FMU's ``start.NAME``); none by default."""
        return ()

    def settable_starts(self) -> tuple[Start, ...]:
        """The initial states given as options (a problem whose start is free,
        such as an FMU's ``start.NAME``), each with its current start; none by
        default: a mechanism's start must be consistent, so it is not an option."""
        return ()

    # ------------------------------------------------------------ derived
    @property
    def dimension(self) -> int:
        return len(self.components)

    @property
    def t_eval(self) -> np.ndarray:
        t0, t1 = self.t_span
        return np.linspace(t0, t1, self.n_output + 1)

    def component_index(self, names) -> np.ndarray:
        if names is None:
            return np.arange(self.dimension)
        return np.array([self.components.index(c) for c in names], dtype=int)

    def set_score(self, score) -> None:
        """Score the error on the components named in ``score`` (``"x1+v1"``,
        :func:`score_names`) instead of the declared ``error_components``; kept in
        ``params`` as ``score``. :class:`ProblemError` on an unknown name."""
        names = score_names(score, self.components, f"component of {self.name}")
        self._declared_error_components = self.declared_error_components
        self.error_components = names
        self.score = SCORE_SEPARATOR.join(names)
        self.params = {**self.params, SCORE: self.score}

    def set_model_cost(self, microseconds) -> None:
        """Add :func:`burn` of ``microseconds`` (>= 0) to every model evaluation
        of every formulation (the option ``rhs_cost_us``, kept in ``params``);
        :class:`ProblemError` on a value that is not a number >= 0."""
        try:
            value = float(microseconds)
        except (TypeError, ValueError):
            value = math.nan
        if not value >= 0 or not math.isfinite(value):
            raise ProblemError(f"{MODEL_COST}={microseconds!r} is not a valid cost; valid: "
                               "a number of microseconds >= 0")
        self.model_cost_us = value
        self.params = {**self.params, MODEL_COST: value}
        formulate = type(self).formulate.__get__(self)
        self.formulate = lambda formulation="ode": with_model_cost(formulate(formulation), value)

    @property
    def declared_error_components(self) -> tuple[str, ...] | None:
        """``error_components`` as the problem declares them, whatever ``score=``
        names (the event state error and the reference's claim are taken on these)."""
        return self.__dict__.get("_declared_error_components", self.error_components)

    def unscored(self) -> "Problem":
        """This problem without the user's ``score=``, ``rhs_cost_us=`` and
        :attr:`form_options` (itself when it has none): the one whose reference it
        shares."""
        left_out = {*OPTIONS, *(o.name for o in self.form_options)}
        if self.score is None and not (left_out - {SCORE}) & set(self.params):
            return self  # (an FMU keeps its own score in params: its reference is its own)
        return type(self)(**{k: v for k, v in self.params.items() if k not in left_out})

    def atol_scale_vector(self) -> np.ndarray:
        return np.broadcast_to(np.asarray(self.atol_scale, float), (self.dimension,)).copy()

    def default_step_sizes(self) -> tuple[float, ...]:
        """Step-size ladder for fixed-step integrators."""
        if self.step_sizes is not None:
            return tuple(self.step_sizes)
        length = self.t_span[1] - self.t_span[0]
        return tuple(length / n for n in (100, 1000, 10000))

    @classmethod
    def formulation_facts(cls, formulation: str) -> tuple | None:
        """``(kind, index)`` of the system :meth:`formulate` gives for ``formulation``,
        known without building the problem (an ``ode`` form gives an ODE, index 0);
        None when not known so (a subclass that formulates otherwise says it here)."""
        return ("ode", 0) if formulation == "ode" and formulation in cls.formulations else None

    def formulate(self, formulation: str = "ode") -> System:
        """The problem in formulation ``formulation`` as a system."""
        if formulation not in self.formulations:
            raise ProblemError(
                f"problem {self.name} has no formulation {formulation!r}; "
                f"valid: {', '.join(self.formulations)}")
        return OdeSystem(
            t0=self.t_span[0], t_end=self.t_span[1], y0=self.initial_state(),
            t_eval=self.t_eval, atol_scale=self.atol_scale_vector(),
            fun=self.rhs, jac=self.jac)

    def fingerprint(self) -> str:
        """Hash of the problem definition as the numbers see it.

        The name, parameters, time grid, initial state and the right-hand side
        at a few seeded points near the initial state: any change to the
        equations changes it, an edit of comments or docstrings does not. The
        numbers are hashed to :data:`FINGERPRINT_DIGITS` significant digits
        (see :func:`significant_digits`), so the round-off of another machine
        or library build does not change it.
        """
        h = hashlib.sha256()
        h.update(repr((self.name, sorted(self.key_params().items()))).encode())
        y0 = np.asarray(self.initial_state(), float)
        for arr in (self.t_eval, y0, *self._probe_values(y0)):
            h.update(significant_digits(arr).encode())
        return h.hexdigest()[:16]

    def _probe_values(self, y0):
        rng = np.random.default_rng(12345)
        out = []
        system = self.formulate(self.formulations[0])  # override for other kinds
        for _ in range(3):
            t = self.t_span[0] + rng.uniform() * (self.t_span[1] - self.t_span[0])
            y = system.y0 * (1 + 0.01 * rng.standard_normal(system.n)) \
                + 0.01 * rng.standard_normal(system.n)
            if system.kind == "ode":
                out.append(np.asarray(system.fun(t, y), float))
            else:
                out.append(np.asarray(system.residual(t, y, system.yp0), float))
        return out

    def key_params(self) -> dict:
        """The parameters that identify this problem's numbers, for its
        fingerprint and the name of its reference: ``params`` without the
        ``score`` option, unless a problem read from a file puts the file's
        checksum in place of its path."""
        left_out = {*OPTIONS, *(o.name for o in self.form_options)}
        return {k: v for k, v in self.params.items() if k not in left_out}

    def set_form_options(self, values: dict) -> None:
        """Set each of :attr:`form_options` named in ``values`` (checked against
        its range) as the attribute of its name, kept in ``params``;
        :class:`ProblemError` on a value out of range."""
        options = {o.name: o for o in self.form_options}
        for name, value in values.items():
            value = options[name].check(value)
            setattr(self, name, value)
            self.params = {**self.params, name: value}

    def label(self) -> str:
        """``name:key=value,...`` with every parameter, as on the command line."""
        return format_label(self.name, self.params)

    def describe(self) -> dict:
        """Metadata for ``ibench list problems --json``."""
        return {
            "name": self.name,
            "description": self.description,
            "source": self.source,
            "dimension": self.dimension,
            "t_span": list(self.t_span),
            "parameters": [
                {"name": p.name, "default": p.default,
                 "low": p.low if math.isfinite(p.low) else None,
                 "high": p.high if math.isfinite(p.high) else None,
                 "description": p.description} for p in self.parameters],
            "benchmark_parameters": list(self.benchmark_parameters),
            "components": list(self.components),
            "initial_values": dict(zip(self.components,
                                       map(float, self.initial_state()))),
            "error_components": list(self.error_components or self.components),
            "formulations": list(self.formulations),
        }


def format_value(value) -> str:
    """A parameter value as the command line writes it: numbers ``:g``, text as is."""
    return f"{value:g}" if isinstance(value, (int, float)) else str(value)


def format_label(name: str, params: dict) -> str:
    if not params:
        return name
    return name + ":" + ",".join(f"{k}={format_value(v)}" for k, v in sorted(params.items()))
