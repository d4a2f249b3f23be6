"""An FMU as a problem: ``-p fmu:path=model.fmu[,name=value...]``.

:class:`FmuProblem` runs any FMU that :mod:`.description` reads as an ordinary
ODE problem: its canonical components the continuous states (then the outputs
scored, ``score=x+y``), its parameters and ``start.NAME`` options those of the
description, its right-hand side, Jacobian and events those of an
:class:`~.instance.FmuInstance`. Each event indicator becomes a terminal state
event (both directions) whose reset lets the FMU act: the crossing counts, as
``"state_event"``, when the FMU changed its states or its right-hand side there,
and is ignored otherwise.

A problem instance describes; each :meth:`FmuProblem.formulate` instantiates
the FMU afresh (parameters set, initialized), so every run starts from the
FMU's initial state and mode. The ``ode`` system also carries the FMU itself
(:class:`~integrator_bench.problems.system.FmuSystem`) for the FMU tool's own
solvers (``fmpy-cvode``, ``fmpy-euler``).

Refused, each with one line (:class:`~integrator_bench.problems.base.ProblemError`):
what :func:`~.description.describe_fmu` refuses, an unknown parameter or ``start.``
option (naming the valid ones), a structural parameter that is not an integer in
its range, and an FMU whose calls fail at set-up.

A changed FMU file changes the problem: references are keyed by the file's
SHA-256 checksum and the parameters (:meth:`FmuProblem.key_params`), not by
its path. :func:`fmu_problem` makes a problem class of one FMU under a name of
its own, for registration through the ``integrator_bench.problems`` entry
points.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np

from integrator_bench.problems.base import (SCORE, SCORE_SEPARATOR, Parameter, Problem,
                                         ProblemError, Start, score_names)
from integrator_bench.problems.fmu.description import (INTEGER_TYPES, PATH, START,
                                                    FmuDescription, describe_fmu)
from integrator_bench.problems.fmu.instance import FmuInstance
from integrator_bench.problems.system import Event, FmuSystem, OdeSystem

#: the kind recorded for every state event an FMU acts on, whichever indicator
#: crossed (FMI 2.0 does not name indicators, and fmpy's results do not say which)
STATE_EVENT = "state_event"

#: (FMU checksum, parameters) whose set-up succeeded in this process (FmuProblem._check_calls)
_SET_UP: set = set()


class FmuProblem(Problem):
    """An FMU file as a problem (see the module docstring).

    Parameters
    ----------
    path : str
        The ``.fmu`` file (a named FMU problem fixes it in ``fmu_path``).
    score : str, optional
        State names joined by ``+``: the components the error is scored on
        (default every state, or the class's ``error_components``).
    **params
        Values of the FMU's parameters, and ``start.NAME`` values of the
        states whose start the FMU lets the importer set.
    """

    name = "fmu"
    description = "Any FMI 2.0/3.0 model-exchange FMU: fmu:path=FILE.fmu[,param=value...]"
    source = "the FMU's modelDescription.xml (FMI 2.0.4 and 3.0.1, Modelica Association)"
    benchmark_parameters = ()     # nothing to run without a path
    file_params = (PATH,)         # a Dask worker runs it on its own copy of the file
    fmu_path: str | None = None   # set by fmu_problem()

    def __init__(self, path: str | None = None, score: str | None = None, **params):
        if self.fmu_path is None and path is None:
            raise ProblemError("problem fmu needs the FMU file: fmu:path=FILE.fmu"
                               "[,param=value...]")
        if self.fmu_path is not None and path is not None:
            raise ProblemError(f"problem {self.name} is the FMU {self.fmu_path!r}; "
                               "it takes no path")
        self.fmu = self._described(self.fmu_path or path, params)
        self.parameters = self.fmu.parameters
        self.components = self.fmu.states
        self.t_span = self.fmu.t_span
        self.atol_scale = self.fmu.nominals
        starts = {k: params.pop(k) for k in list(params) if k.startswith(START)}
        self._check_starts(starts)
        self._check_elements(params)
        super().__init__(**params)
        for name, (_, kind) in self.fmu.parameter_types.items():
            value = self.params[name]
            if kind in INTEGER_TYPES and value != int(value):
                raise ProblemError(f"parameter {name}={value:g} of an {kind} variable is "
                                   "not an integer")
        self.scored_outputs = ()
        if score is not None:
            names = score_names(score, (*self.fmu.states, *self.fmu.outputs),
                                "state or output")
            self.scored_outputs = tuple(n for n in names if n in self.fmu.outputs)
            if self.scored_outputs and self.fmu.n_indicators:
                raise ProblemError(
                    f"score={score!r} names outputs ({', '.join(self.scored_outputs)}) of an "
                    "FMU with event indicators, whose outputs may depend on its discrete "
                    f"state; score its states: {', '.join(self.fmu.states)}")
            self.components = (*self.fmu.states, *self.scored_outputs)
            self.atol_scale = (*self.fmu.nominals,
                               *(self.fmu.outputs[n][3] for n in self.scored_outputs))
            self.error_components = names
        self.options = {}
        if self.fmu_path is None:
            self.options[PATH] = self.fmu.path
        if score is not None:
            self.options[SCORE] = SCORE_SEPARATOR.join(self.error_components)
        self.starts = {k: Parameter(k, *self.fmu.starts[k[len(START):]]).check(v)
                       for k, v in sorted(starts.items())}
        self.params = {**self.options, **self.params, **self.starts}
        if self.fmu.n_indicators:
            # a problem with events needs reference methods of two families of event
            # location (SUNDIALS' root finding, scipy's); both implicit, since nothing
            # tells beforehand whether an FMU is stiff (the Reference FMUs' Roberts, which
            # has event indicators, is: docs/advise.md)
            self.reference_methods = (("ode", "cvode-bdf", 1e-12), ("ode", "scipy-Radau", 1e-12))
        self._check_calls()

    @staticmethod
    def _described(path, params: dict) -> FmuDescription:
        """The FMU described at the structural parameters ``params`` gives (each
        an integer in its range), which size its arrays and so name its
        parameters and states."""
        fmu = describe_fmu(path)
        given = {}
        for p in fmu.parameters:
            if p.name in fmu.structural and p.name in params:
                value = p.check(params[p.name])
                if value != int(value):
                    raise ProblemError(f"structural parameter {p.name}={value:g} is not "
                                       "an integer")
                given[p.name] = int(value)
        return describe_fmu(path, given) if given else fmu

    def _check_elements(self, params: dict) -> None:
        """An element past an array's size (``A[3][3]`` of a 2 x 2 ``A``) is refused
        with one line naming the array's elements and what sizes it (any other
        unknown parameter is refused by :class:`Problem`)."""
        for key in params:
            array = key.split("[", 1)[0]
            elements = self.fmu.arrays.get(array, ())
            if "[" in key and key not in elements and key not in self.fmu.parameter_types:
                sizes = ", ".join(f"{k}={v}" for k, v in self.fmu.structural_values.items())
                raise ProblemError(
                    f"parameter {key!r} is no element of {array} "
                    f"({elements[0]} .. {elements[-1]} at {sizes or 'its fixed size'}); "
                    "the structural parameters size the arrays" if elements else
                    f"unknown parameter {key!r} for problem {self.name}; valid: "
                    f"{', '.join([*self.fmu.parameter_types, *self.other_options()])}")

    def _check_starts(self, starts: dict) -> None:
        """A ``start.`` option of no settable state is refused with one line naming
        the valid ones (an unknown parameter is refused by :class:`Problem`, which
        names these too, :meth:`other_options`)."""
        bad = [k for k in starts if k[len(START):] not in self.fmu.starts]
        if bad:
            calculated = [k for k in bad if k[len(START):] in self.fmu.states]
            why = (f"state {calculated[0][len(START):]!r} has initial=\"calculated\": "
                   "the FMU computes its start" if calculated else "no such state")
            raise ProblemError(f"{bad[0]!r} sets no state start of FMU {self.fmu.path!r} "
                               f"({why}); valid: {', '.join(self.other_options()) or 'none'}")

    def other_options(self) -> tuple[str, ...]:
        """The ``start.NAME`` options of the states whose start may be set."""
        return tuple(START + name for name in self.fmu.starts)

    def settable_starts(self) -> tuple[Start, ...]:
        """The ``start.NAME`` options: each settable state's start (the value
        given, else the model description's), its ``min``/``max`` and its
        ``nominal`` as absolute scale."""
        nominal = dict(zip(self.fmu.states, self.fmu.nominals))
        return tuple(Start(START + name, self.starts.get(START + name, start), low, high,
                           f"start value of state {name}", nominal[name])
                     for name, (start, low, high) in self.fmu.starts.items())

    def _check_calls(self) -> None:
        """Set the FMU up once (instantiate, initialize, read its states, outputs and
        derivatives): an FMU whose calls fail there (array variables the harness
        cannot map, a state count its binary refuses) is refused here with one
        line, as the FMUs it cannot read are, rather than failing in every case;
        what the FMU logged meanwhile is on that line (on standard error as it
        came when the set-up works).
        Done once per FMU file and parameter values in a process."""
        key = (self.fmu.checksum, tuple(sorted(self.params.items(), key=str)))
        if key in _SET_UP:
            return
        import io
        import sys

        said = io.StringIO()   # the FMU's log lines: on the refusal's one line if it fails
        try:
            with contextlib.redirect_stderr(said):
                fmu = self.instance()
                fmu.derivatives(self.t_span[0], fmu.y0)
                self.initial_state()
        except ProblemError:
            raise
        except Exception as exc:  # the FMU's own call failed: it cannot be run
            why = f"{type(exc).__name__}: {exc}".splitlines()[0]
            logged = "; ".join(line.strip() for line in said.getvalue().splitlines()
                               if line.strip())
            raise ProblemError(f"FMU {self.fmu.path!r} fails at set-up ({why}"
                               f"{'; it logged: ' + logged[:300] if logged else ''}); the "
                               "harness cannot run it") from None
        sys.stderr.write(said.getvalue())   # a set-up that worked: what it logged, as logged
        _SET_UP.add(key)

    @property
    def fmu_values(self) -> dict:
        """The start values the FMU is given, by variable name: the parameters',
        then the states' of the ``start.`` options (the other options and the
        structural parameters left out, :func:`~.description.configure` sets those); an
        array's value is the list of its elements, a state array's given when
        any of its elements' starts is."""
        values = {**{k: v for k, v in self.params.items()
                     if k not in self.options and k not in self.starts
                     and k not in self.fmu.structural},
                  **{k[len(START):]: v for k, v in self.starts.items()}}
        for name, elements in self.fmu.arrays.items():   # an array: all its elements
            if elements[0] in self.fmu.parameter_types:
                values[name] = [values.pop(e) for e in elements]
            elif any(START + e in self.starts for e in elements):
                values[name] = [values.pop(e, self.fmu.starts[e][0]) for e in elements]
        return values

    def key_params(self) -> dict:
        """The parameters with the file's checksum in place of its path."""
        return {"fmu": self.fmu.checksum[:16], **{k: v for k, v in self.params.items()
                                                   if k != PATH}}

    def instance(self) -> FmuInstance:
        """A fresh, initialized instance of the FMU with this problem's parameters."""
        return FmuInstance(self.fmu, self.fmu_values)

    def initial_state(self):
        """The canonical values at the start: the states, then the scored outputs."""
        if not hasattr(self, "_y0"):
            fmu = self.instance()
            self._y0 = self._canonical(fmu)(np.array([self.t_span[0]]), fmu.y0[None, :])[0]
        return self._y0.copy()

    def _canonical(self, fmu: FmuInstance):
        """``output(t, Y)`` of a system: the states ``Y``, then the scored outputs
        the FMU gives at each ``(t, y)``."""
        if not self.scored_outputs:
            return lambda t, Y: Y
        names = self.scored_outputs
        return lambda t, Y: np.column_stack([Y, fmu.outputs(t, Y, names)])

    def formulate(self, formulation: str = "ode") -> OdeSystem:
        if formulation not in self.formulations:
            raise ProblemError(f"problem {self.name} has no formulation {formulation!r}; "
                               f"valid: {', '.join(self.formulations)}")
        fmu = self.instance()
        events = tuple(Event(fmu.indicator(i), direction=0, terminal=True, reset=fmu.event,
                             name=STATE_EVENT) for i in range(self.fmu.n_indicators))
        common = dict(t0=self.t_span[0], t_end=self.t_span[1], t_eval=self.t_eval,
                      events=events)
        system = OdeSystem(**common, y0=fmu.y0, atol_scale=self.fmu.nominals,
                           fun=fmu.derivatives, output=self._canonical(fmu),
                           jac=fmu.jacobian if self.fmu.directional else None)
        # fmpy records the canonical components itself, states and scored outputs
        system.fmu = FmuSystem(**common, y0=self.initial_state(),
                               atol_scale=self.atol_scale_vector(),
                               unzipdir=self.fmu.unzipdir, start_values=self.fmu_values,
                               variables=self.components, event_name=STATE_EVENT,
                               elements=tuple(self.fmu.elements[c] for c in self.components),
                               refused=self._fmu_tool_refuses())
        system.instance = fmu    # keeps the FMU alive as long as the system
        return system

    def _fmu_tool_refuses(self) -> str:
        """Why fmpy's own solvers cannot run the FMU as this problem has it: fmpy
        sizes its arrays by the structural parameters' start values
        (``numberOfContinuousStates`` of its model description), so not after
        they are changed; "" when they are not."""
        changed = self.fmu.reconfigured
        if not changed:
            return ""
        return ("fmpy sizes an FMU's arrays by its structural parameters' start values, "
                f"and this problem changes {', '.join(f'{k}={v}' for k, v in changed.items())}")

    def describe(self) -> dict:
        out = super().describe()
        out["fmu"] = {"path": self.fmu.path, "sha256": self.fmu.checksum,
                      "model_name": self.fmu.model_description.modelName,
                      "event_indicators": self.fmu.n_indicators,
                      "directional_derivatives": self.fmu.directional,
                      "structural_parameters": dict(self.fmu.structural_values)}
        return out


def fmu_problem(name: str, path, *, description: str = "", source: str = "",
                error_components=None, velocity_components=()) -> type[FmuProblem]:
    """A problem class of the FMU at ``path`` under a name of its own.

    For a plugin's entry point (``my_model = "my_pkg.problems:MyModel"`` with
    ``MyModel = fmu_problem("my_model", Path(__file__).parent / "model.fmu")``)
    or a test's registry. The path is resolved now; the file is read when the
    problem is made.
    """
    attrs = {"name": name, "fmu_path": str(Path(path).expanduser().resolve()),
             "description": description or f"FMU {Path(path).name}",
             "source": source or FmuProblem.source,
             "benchmark_parameters": ({},),
             "error_components": tuple(error_components) if error_components else None,
             "velocity_components": tuple(velocity_components)}
    return type(f"Fmu_{name}", (FmuProblem,), attrs)
