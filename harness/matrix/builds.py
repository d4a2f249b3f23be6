"""A problem whose code is not the project's is built only in a process of its own.

Building a problem runs its code: the class's constructor, its consistent start, an
FMU's set-up (its C library loaded and called), a symbolic model compiled as it is
formulated. The rule: **the project's own pure-Python problems** (a built-in whose
class is not an FMU) are project code and are built in the command's process as
they are; **any other** (a plugin's problem, a class registered at run time, an FMU,
whose model is C code the user brought: :func:`foreign`) is never built in the
command's process. Its trial build runs in a forked process
(:func:`~integrator_bench.harness.forking.child.call`) within
:data:`BUILD_TIMEOUT` CPU seconds (the environment variable ``IBENCH_BUILD_TIMEOUT``
sets another budget) and a case's memory cap: its constructor, its initial state
and every formulation it offers, which gives back what the command reads of the
problem (:func:`~integrator_bench.harness.matrix.stand_in.facts`); :func:`build`
then returns a :class:`~integrator_bench.harness.matrix.stand_in.StandIn` carrying
those facts, whose model code runs only in an isolated process. A trial that
raises, crashes or hangs is a :class:`~integrator_bench.harness.errors.ModelFault`
(``the model crashed (SIGSEGV) while the problem was built``), raised by
:func:`build`, and the problem's cases are recorded with it
(:func:`~integrator_bench.harness.matrix.cases.expand`). A ProblemError from the
constructor (a bad parameter) is raised as such, the user's input error.

Each trial runs once per process and parameter set (kept here: a forked worker
inherits the verdict). In a process that is already isolated (a case's worker, a
model's call, a Dask task's worker: :func:`~integrator_bench.harness.forking.isolated`)
no trial is made and the problem itself is built: a fault there is that process's own.

What the trial cannot see: a build that succeeded in its trial and fails later in
a case's worker or a model's call (that process's fault, recorded as the case's).
"""

from __future__ import annotations

import functools
import math
import os

from integrator_bench.harness.errors import BadInput, ModelFault
from integrator_bench.harness.forking import isolated
from integrator_bench.harness.forking.child import call
from integrator_bench.harness.matrix.stand_in import StandIn, facts
from integrator_bench.problems.base import Problem, ProblemError
from integrator_bench.problems.fmu import FmuProblem

#: CPU seconds a problem's trial build (constructor, initial state, every formulation)
#: may take in its process, unless the environment variable :data:`BUDGET_VAR` gives
#: another number
BUILD_TIMEOUT = 60.0
BUDGET_VAR = "IBENCH_BUILD_TIMEOUT"
#: what a fault's message says the model was doing
BUILDING = "the problem was built"
#: the origin the registry gives the project's own problems (registry.BUILT_IN)
BUILT_IN = "built-in"

# (class, params key) -> the facts of the problem built, a ProblemError or a ModelFault
_trials: dict = {}


def forget() -> None:
    """Forget every trial's verdict (the registry's ``refresh``)."""
    _trials.clear()


def foreign(cls: type[Problem]) -> bool:
    """Whether building ``cls`` runs code that is not the project's: a class from a
    plugin or registered at run time (its ``origin`` is not the built-ins'), or an
    FMU (its model is the user's C code)."""
    return getattr(cls, "origin", None) != BUILT_IN or issubclass(cls, FmuProblem)


def build(cls: type[Problem], params: dict) -> Problem | StandIn:
    """``cls`` at ``params``: built here (``cls(**params)``) for the project's own
    problems and in an isolated process; else the
    :class:`~integrator_bench.harness.matrix.stand_in.StandIn` of its trial build
    (:func:`trial`). Raises ProblemError (bad parameters) or the trial's ModelFault."""
    if not foreign(cls) or isolated():
        return cls(**params)
    got = trial(cls, params)
    if isinstance(got, Exception):
        raise got
    stand_in = StandIn(cls, **got)
    _trials.setdefault((cls, _key(stand_in.params)), got)   # its full parameters: tried
    return stand_in


def params_of(cls: type[Problem], given: dict) -> tuple[dict, ModelFault | None]:
    """``(every parameter value of cls at given, None)`` from the problem built
    (:func:`build`), or, when its build failed, ``(the values its declarations
    give, the fault)`` (:func:`declared_params`; the fault kept for them too).
    Raises ProblemError for bad parameters."""
    try:
        return build(cls, given).params, None
    except ModelFault as fault:
        params = declared_params(cls, given)
        _trials[(cls, _key(params))] = fault
        return params, fault


def trial(cls: type[Problem], params: dict) -> dict | Exception:
    """The trial build of foreign ``cls`` at ``params`` in a process of its own, made
    once: the facts of the problem built (:func:`_build_all`), or why it did not
    build: the ProblemError its constructor raised, or the
    :class:`~integrator_bench.harness.errors.ModelFault` of a trial that raised,
    crashed or hung."""
    key = (cls, _key(params))
    if key not in _trials:
        try:
            _trials[key] = call(functools.partial(_build_all, cls, params), BUILDING,
                                budget(), expected=(ProblemError,))
        except (ProblemError, ModelFault) as exc:
            _trials[key] = exc
    return _trials[key]


def class_of(problem) -> type[Problem]:
    """The problem class of ``problem`` (built, or a stand-in)."""
    return problem.cls if isinstance(problem, StandIn) else type(problem)


def budget() -> float:
    """A trial build's budget in CPU seconds: :data:`BUILD_TIMEOUT`, or the value of the
    environment variable :data:`BUDGET_VAR` (:class:`~integrator_bench.harness.errors.BadInput`
    when it is not a positive finite number)."""
    given = os.environ.get(BUDGET_VAR)
    if not given:
        return BUILD_TIMEOUT
    try:
        seconds = float(given)
    except ValueError:
        seconds = math.nan
    if not (math.isfinite(seconds) and seconds > 0):
        raise BadInput(f"{BUDGET_VAR}={given!r} must be a positive number of CPU seconds")
    return seconds


def _key(params: dict) -> str:
    return repr(sorted(params.items()))


def _build_all(cls: type[Problem], params: dict) -> dict:
    """What the trial's process does: build, make the initial state, formulate every
    formulation offered (one that refuses these parameters with a ProblemError is
    refused again where it is asked for), and give back the problem's
    :func:`~integrator_bench.harness.matrix.stand_in.facts`."""
    problem = cls(**params)
    problem.initial_state()
    return facts(problem)


def declared_params(cls: type[Problem], given: dict) -> dict:
    """The parameter values of ``cls`` at ``given`` as its declarations check them
    (:meth:`~integrator_bench.problems.base.Parameter.check`), without running its
    constructor: the identity of the cases of a problem whose build failed. The
    options every problem takes (``score``) are kept as given."""
    declared = {p.name: p.check(given.get(p.name, p.default)) for p in cls.parameters}
    return {**declared, **{k: v for k, v in given.items() if k not in declared}}
