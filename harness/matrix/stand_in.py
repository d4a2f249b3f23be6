"""What the command's process holds of a problem whose code is not the project's.

A plugin's problem, a class registered at run time or an FMU
(:func:`~integrator_bench.harness.matrix.builds.foreign`) is never built in the
command's own process: its trial build in a process of its own
(:func:`~integrator_bench.harness.matrix.builds.trial`) gives back the facts the
command reads of it (:func:`facts`), and the command holds a :class:`StandIn`
carrying them. Its model's code (``rhs``, ``jac``, ``formulate``,
``initial_state``, ``fingerprint``, ...) is not there: asked for in the command's
process it raises :class:`ForeignCode`; in an isolated process (a case's worker, a
model's call in :func:`~integrator_bench.harness.forking.child.call`, a Dask
task's worker: :func:`~integrator_bench.harness.forking.isolated`), where the
stand-in arrives with the call that forked it, the problem is built there once
and answers (:meth:`StandIn.__getattr__`).
"""

from __future__ import annotations

import inspect
import pickle
import types
from dataclasses import dataclass

import numpy as np

from integrator_bench.harness.forking import isolated
from integrator_bench.problems.base import ProblemError


class ForeignCode(RuntimeError):
    """A foreign problem's code was asked for in the command's own process."""


@dataclass(frozen=True)
class SystemFacts:
    """What :func:`~integrator_bench.problems.system.convert` and the matrix read of a
    formulated system, without its functions: ``kind``, ``index`` (None but for a
    DAE), ``n`` states, ``t0`` and ``t_end``, why no integrator takes it
    (``unsupported``), whether it has ``events``, a projection (``project``: True
    or None), an analytic Jacobian or a sparsity pattern (``jac``,
    ``jac_sparsity``: True or None), its second-order form (``mechanical``, the
    facts of that form) and its FMU (``fmu``, a namespace with the FMU's
    ``refused``)."""

    kind: str
    index: int | None
    n: int
    t0: float
    t_end: float
    unsupported: str | None = None
    events: bool = False
    project: bool | None = None
    jac: bool | None = None
    jac_sparsity: bool | None = None
    mechanical: SystemFacts | None = None
    fmu: types.SimpleNamespace | None = None

    @classmethod
    def of(cls, system) -> SystemFacts:
        """The facts of ``system`` (a formulated system)."""
        def present(name):
            return True if getattr(system, name, None) is not None else None

        nested, fmu = getattr(system, "mechanical", None), getattr(system, "fmu", None)
        return cls(system.kind, getattr(system, "index", None), system.n, system.t0,
                   system.t_end, system.unsupported, bool(system.events), present("project"),
                   present("jac"), present("jac_sparsity"),
                   None if nested is None else cls.of(nested),
                   None if fmu is None else types.SimpleNamespace(refused=fmu.refused))

    def as_dae(self) -> SystemFacts:
        """The facts of the system's index-0 DAE form (an ODE's ``as_dae``)."""
        return SystemFacts("dae", 0, self.n, self.t0, self.t_end, events=self.events,
                           jac=self.jac, jac_sparsity=self.jac_sparsity)


@dataclass(frozen=True, eq=False)
class StandIn:
    """A foreign problem as the command's process holds it (module docstring).

    Attributes
    ----------
    cls : type
        The problem class.
    data : dict
        The built problem's own attributes that are data (not callable, picklable:
        an FMU's ``reference_methods``); with the class's declarations that are
        data (``description``, ``benchmark_parameters``, ``origin``, ...) what
        the stand-in answers beside its other fields (:meth:`__getattr__`).
    name : str
        The built problem's.
    params : dict
        Every parameter value, as the built problem holds them.
    parameters : tuple of Parameter
        As the built problem declares them (an FMU's are its file's).
    components, error_components : tuple
        The built problem's (``error_components`` None: all).
    score : str or None
    t_span : tuple
    t_eval : ndarray
    formulations : tuple of str
        The built problem's.
    systems : dict
        Per formulation the :class:`SystemFacts` of its system, or the
        ProblemError with which it refused these parameters.
    described, key : dict
    starts, steps : tuple
    scale : ndarray
    text : str
        What the built problem's :meth:`describe`, :meth:`key_params`,
        :meth:`settable_starts`, :meth:`default_step_sizes`,
        :meth:`atol_scale_vector` and :meth:`label` return, which the stand-in's
        return.
    """

    cls: type
    data: dict
    name: str
    params: dict
    parameters: tuple
    components: tuple
    error_components: tuple | None
    score: str | None
    t_span: tuple
    t_eval: np.ndarray
    formulations: tuple
    systems: dict
    described: dict
    key: dict
    starts: tuple
    scale: np.ndarray
    steps: tuple
    text: str

    @property
    def dimension(self) -> int:
        return len(self.components)

    def label(self) -> str:
        return self.text

    def describe(self) -> dict:
        return dict(self.described)

    def key_params(self) -> dict:
        return dict(self.key)

    def settable_starts(self) -> tuple:
        return self.starts

    def atol_scale_vector(self) -> np.ndarray:
        return self.scale.copy()

    def default_step_sizes(self) -> tuple:
        return self.steps

    def __getattr__(self, name: str):
        """In an isolated process anything of the problem, built there once; else
        one of its ``data``, or a declaration of its class that is data
        (``description``, ``origin``), else :class:`ForeignCode` for the problem's
        code (its methods and properties) and AttributeError for what it does not
        have."""
        if name.startswith("__") or name in ("cls", "data"):
            raise AttributeError(name)
        if isolated():
            return getattr(_built(self), name)
        if name in self.data:
            return self.data[name]
        found = inspect.getattr_static(self.cls, name, _MISSING)
        if found is _MISSING:
            raise AttributeError(f"{self.cls.__name__!r} has no attribute {name!r}")
        if callable(found) or hasattr(found, "__get__"):
            raise ForeignCode(
                f"{name} of problem {self.text} is its own code (not the project's), which "
                "runs only in a process of its own, never in the command's")
        return getattr(self.cls, name)


_MISSING = object()
_real: dict = {}   # (class, label) -> the problem built in this isolated process


def _built(stand_in: StandIn):
    """The problem ``stand_in`` stands for, built once in this (isolated) process."""
    key = (stand_in.cls, stand_in.text)
    if key not in _real:
        _real[key] = stand_in.cls(**stand_in.params)
    return _real[key]


def facts(problem) -> dict:
    """The fields of a :class:`StandIn` but ``cls``, read of the built ``problem`` in
    the process that built it (each formulation formulated: a refusal kept)."""
    systems = {}
    for form in problem.formulations:
        try:
            systems[form] = SystemFacts.of(problem.formulate(form))
        except ProblemError as exc:
            systems[form] = exc
    err = problem.error_components
    return dict(data={k: v for k, v in vars(problem).items() if _data(v)},
                name=problem.name, params=dict(problem.params),
                parameters=tuple(problem.parameters), components=tuple(problem.components),
                error_components=None if err is None else tuple(err), score=problem.score,
                t_span=tuple(problem.t_span), t_eval=np.asarray(problem.t_eval),
                formulations=tuple(problem.formulations), systems=systems,
                described=problem.describe(), key=problem.key_params(),
                starts=tuple(problem.settable_starts()), scale=problem.atol_scale_vector(),
                steps=tuple(problem.default_step_sizes()), text=problem.label())


def _data(value) -> bool:
    """Whether ``value`` is data a stand-in may carry: not callable, and picklable."""
    if callable(value):
        return False
    try:
        pickle.dumps(value)
    except Exception:  # noqa: BLE001  whatever the value's own pickling raises
        return False
    return True


def system_of(problem, formulation: str):
    """``problem`` in ``formulation``: the system, formulated here, of a problem
    built here; the :class:`SystemFacts` of a :class:`StandIn`'s (its refusal, a
    ProblemError, raised)."""
    if not isinstance(problem, StandIn):
        return problem.formulate(formulation)
    got = problem.systems[formulation]
    if isinstance(got, ProblemError):
        raise got
    return got
