"""An FMU as a problem: ``-p fmu:path=model.fmu[,name=value...]``.

Any FMI 2.0 or 3.0 model-exchange FMU (Functional Mock-up Interface 2.0.4,
Modelica Association 2022, chapter 3; FMI 3.0.1, 2023, chapter 3) runs as an
ordinary ODE problem. Everything is read from its ``modelDescription.xml``:

* the canonical components are the continuous states, in the order of
  ``ModelStructure/Derivatives`` (FMI 3.0: ``ContinuousStateDerivative``),
  named after the state variables;
* the parameters (``causality="parameter"``, ``fixed`` or ``tunable``;
  FMI 2.0 Real or Integer, FMI 3.0 Float32/64 or an integer type) with their
  start values as defaults and ``min``/``max`` as ranges, settable like any
  problem's (``fmu:path=m.fmu,k=1000``);
* FMI 3.0 arrays run as fmpy runs them: an array variable is its elements,
  named by :func:`element_names` (``x[1]``, ``A[1][2]``, row-major as FMI
  3.0 serializes them), each a state, parameter, ``start.`` option or output
  of its own; an array of state derivatives counts every element (fmpy's
  ``numberOfContinuousStates``); arrays are read and set whole, with
  ``nValues`` their number of elements, their start values from the model
  description. Their ``Dimension`` elements size them: a fixed ``start``, or
  a structural parameter (``causality="structuralParameter"``, an integer
  type), which is an integer parameter of the problem (``n=3``); a value
  other than its start is set in Configuration Mode (:func:`_configure`)
  and resizes the arrays, the elements their start values do not cover then
  taking the FMU's own values (fmpy's solvers, which size arrays by the
  structural parameters' start values, are refused then);
* the start value of each continuous state the standard lets the importer set
  before initialization (``initial="exact"`` or ``"approx"``, the attribute of
  FMI 2.0.4 sect. 2.2.7 and of FMI 3.0.1) is the option ``start.NAME``
  (``fmu:path=m.fmu,start.x=1.02``): the run starts from the state the FMU
  initializes to from it (:meth:`FmuProblem.settable_starts`); a state with
  ``initial="calculated"`` is computed by the FMU and cannot be given;
* ``nominal`` of each state is its absolute-tolerance scale;
* the time span is the ``DefaultExperiment``'s (start 0 and stop start + 1
  when not given, as fmpy does);
* the error is scored on every state, or on the states and outputs named in
  the ``score`` option (``score=x+y``); a scored output (``causality="output"``,
  a real scalar that is not a state) becomes a canonical component after the
  states, evaluated from the states at each output time (so only for an FMU
  without event indicators, whose outputs cannot depend on a discrete state);
* the Jacobian is the FMU's directional derivatives (one call per column)
  when it declares ``providesDirectionalDerivative`` (FMI 3.0:
  ``providesDirectionalDerivatives``); otherwise the
  system has none and integrators difference the right-hand side, each call
  counted as a function evaluation;
* each event indicator becomes a terminal state event (both directions) whose
  reset lets the FMU act (``fmi2EnterEventMode``, ``fmi2NewDiscreteStates``
  until it needs no more, ``fmi2EnterContinuousTimeMode``; in FMI 3.0
  ``fmi3UpdateDiscreteStates``): the crossing counts, as ``"state_event"``,
  when the FMU changed its states or its right-hand side there, and is
  ignored otherwise.

The FMU's own log lines (its logger callback) are written to standard error
(:func:`~integrator_bench.problems.system.fmu_instance`), never to standard
output, where a command's data goes.

A problem instance describes; each :meth:`FmuProblem.formulate` instantiates
the FMU afresh (parameters set, initialized), so every run starts from the
FMU's initial state and mode. The ``ode`` system also carries the FMU itself
(:class:`~integrator_bench.problems.system.FmuSystem`) for the FMU tool's own
solvers (``fmpy-cvode``, ``fmpy-euler``).

Refused, each with one line naming the file and why
(:class:`~integrator_bench.problems.base.ProblemError`): a missing file, one
that is not an FMU or whose model description does not read, an FMI version
other than 2.0 and 3.0, a co-simulation-only FMU, one without a binary for this
platform, one without continuous states, an unknown parameter or ``start.``
option (naming the valid ones), a structural parameter that is not an integer
in its range or that the FMU refuses, and (at initialization) an FMU that
schedules time events.

Parameters and state starts are set as fmpy's own simulation sets start values
(:func:`fmpy.simulation.apply_start_values`): those settable in the instantiated
state before ``fmi2EnterInitializationMode`` (``fmi3EnterInitializationMode``),
the rest of them in initialization mode.

A changed FMU file changes the problem: references are keyed by the file's
SHA-256 checksum and the parameters (:meth:`FmuProblem.key_params`), not by
its path. :func:`fmu_problem` makes a problem class of one FMU under a name of
its own, for registration through the ``integrator_bench.problems`` entry
points.
"""

from __future__ import annotations

import atexit
import contextlib
import hashlib
import math
import os
import shutil
import tempfile
import weakref
from ctypes import POINTER, c_double
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from integrator_bench.problems.base import (SCORE, SCORE_SEPARATOR, Parameter, Problem,
                                         ProblemError, Start, score_names)
from integrator_bench.problems.system import Event, FmuSystem, OdeSystem, fmu_instance

#: the kind recorded for every state event an FMU acts on, whichever indicator
#: crossed (FMI 2.0 does not name indicators, and fmpy's results do not say which)
STATE_EVENT = "state_event"
#: the FMI versions read, and the variable types of each taken as parameters
#: (real ones, and integer ones, whose values must be integral)
VERSIONS = ("2.0", "3.0")
REAL_TYPES = ("Real", "Float64", "Float32")
INTEGER_TYPES = ("Integer", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32",
                 "Int64", "UInt64")
#: options of ``fmu:`` that are not FMU parameters
PATH = "path"
#: the prefix of the option that sets a state's start value: ``start.x=1.02``
START = "start."


def _fmpy():
    try:
        import fmpy
    except ImportError:
        raise ProblemError("FMU problems need fmpy: pip install fmpy") from None
    return fmpy


@dataclass(frozen=True)
class FmuDescription:
    """What the harness reads from an FMU file (see the module docstring), at
    the values ``structural`` of its structural parameters (FMI 3.0), which
    size its arrays: every array is read as its elements, named
    :func:`element_names`."""

    path: str
    checksum: str
    unzipdir: str
    model_description: object
    states: tuple[str, ...]          # the continuous states' elements, in the FMU's order
    state_refs: tuple[int, ...]      # value references of the state variables
    derivative_refs: tuple[int, ...]  # ... and of their derivatives
    nominals: tuple[float, ...]      # per state element
    parameters: tuple[Parameter, ...]
    parameter_types: dict            # parameter name -> (value reference, variable type)
    t_span: tuple[float, float]
    n_indicators: int
    directional: bool
    outputs: dict                    # element name -> (value reference, size, index, nominal)
    starts: dict                     # settable state element -> (start, min, max)
    arrays: dict                     # array variable -> its element names (row-major)
    elements: dict                   # state or output element -> (variable, flat index)
    structural: dict                 # structural parameter -> (value reference, type, start)
    structural_values: dict          # structural parameter -> the value described at

    @property
    def fmi3(self) -> bool:
        return self.model_description.fmiVersion.startswith("3.")

    @property
    def reconfigured(self) -> dict:
        """The structural parameters whose value differs from their start value."""
        return {k: v for k, v in self.structural_values.items()
                if v != self.structural[k][2]}


def element_names(name: str, shape: tuple) -> list[str]:
    """The names of the elements of variable ``name`` of ``shape`` in row-major
    order (the order in which FMI 3.0's getters, setters and start values
    serialize an array: FMI 3.0.1, chapter 2, "Serialization of Array
    Variables"): ``name`` for a scalar, ``x[1]``, ``x[2]`` for a vector,
    ``A[1][2]`` for row 1, column 2 of a matrix. Indices count from 1, as in
    Modelica and the examples of the standard's structured naming convention
    ("Variable Naming Conventions", which writes ``A[1,2]``; ``A[1][2]`` here, so
    that an element's name holds no comma and is an option of ``-p fmu:...``)."""
    if not shape:
        return [name]
    return [name + "".join(f"[{i + 1}]" for i in index) for index in np.ndindex(*shape)]


def _numbers(text, count: int, what: str, path: str) -> list[float]:
    """An attribute (``start``, ``nominal``, ``min``, ``max``) of ``count``
    elements: a list of values, or one value for all."""
    values = [float(x) for x in str(text).split()]
    if len(values) == 1:
        return values * count
    if len(values) != count:
        raise ProblemError(f"FMU {path!r} gives {what} {len(values)} values for "
                           f"{count} elements")
    return values


#: ``(pid of the process that made it, path)`` of the folder FMUs are extracted into
_ROOT: tuple[int, Path] | None = None


def extraction_root() -> Path:
    """The folder this command extracts FMUs into, ``ibench-fmu-*`` in the system's
    temporary directory: made once, by the first process that needs it, and
    removed by that process when it exits (``atexit``) or when
    :func:`extraction_folder` ends. A process forked after it was made (a case's
    worker, a report's page) extracts into the same folder and leaves it to its
    maker, so nothing outlives the command; ``ibench`` makes it before any work
    (:func:`extraction_folder`), so that every forked process shares it."""
    global _ROOT
    if _ROOT is None or not _ROOT[1].is_dir():
        _ROOT = (os.getpid(), Path(tempfile.mkdtemp(prefix="ibench-fmu-")))
        atexit.register(remove_extractions)
    return _ROOT[1]


def remove_extractions() -> None:
    """Remove the extraction folder, when this process made it (a forked one
    leaves its parent's); the FMUs described so far are forgotten."""
    global _ROOT
    if _ROOT is not None and _ROOT[0] == os.getpid():
        shutil.rmtree(_ROOT[1], ignore_errors=True)
        _ROOT = None
        _describe.cache_clear()


@contextlib.contextmanager
def extraction_folder():
    """The extraction folder made now and removed on the way out, however the
    block ends (``ibench`` runs every command in one); one this process had made
    before is left to it."""
    made = _ROOT is None or _ROOT[0] != os.getpid() or not _ROOT[1].is_dir()
    extraction_root()
    try:
        yield
    finally:
        if made:
            remove_extractions()


def file_checksum(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def describe_fmu(path, structural: dict | None = None) -> FmuDescription:
    """Read and check the FMU at ``path`` (cached while the file is unchanged),
    its arrays sized by the structural parameters ``structural`` (name ->
    value; the others at their start values).

    Raises
    ------
    ProblemError
        One line naming the file and what is wrong with it.
    """
    p = Path(path).expanduser().resolve()
    if p.is_dir():
        raise ProblemError(f"FMU file {str(path)!r} is a directory, not an FMU file")
    if not p.is_file():
        raise ProblemError(f"FMU file {str(path)!r} does not exist")
    stat = p.stat()
    return _describe(str(p), stat.st_mtime_ns, stat.st_size,
                     tuple(sorted((structural or {}).items())))


def _configure(fmu, structural: dict, changed: dict) -> None:
    """Give an instantiated FMU the structural parameters ``changed`` (name ->
    value) in Configuration Mode, the only state in which FMI 3.0 lets an
    importer change them (FMI 3.0.1, chapter 2, "State Machine and Semantics":
    ``fmi3EnterConfigurationMode`` from Instantiated, ``fmi3ExitConfigurationMode``
    back to it)."""
    if not changed:
        return
    fmu.enterConfigurationMode()
    for name, value in changed.items():
        vr, kind, _ = structural[name]
        getattr(fmu, "set" + kind)([vr], [int(value)])
    fmu.exitConfigurationMode()


def _configured_values(md, unzipdir: str, structural: dict, changed: dict,
                       shapes: dict) -> dict:
    """The values an FMU holds, after its structural parameters ``changed`` were
    set, of its real and integer arrays whose start the model description gives (its
    parameters' and its states'), read in Initialization Mode: the start values
    at sizes the description does not spell out. The standard calls a resized
    array's values invalidated (FMI 3.0.1, "Array variables and structural
    parameters"): they are defaults only, which the problem's parameters
    override. An FMU that refuses the change is refused with one line."""
    arrays = [v for v in md.modelVariables if v.dimensions and v.start is not None
              and v.type in REAL_TYPES + INTEGER_TYPES]
    try:
        fmu = fmu_instance(unzipdir, md)     # its log lines on standard error
        try:
            _configure(fmu, structural, changed)
            fmu.enterInitializationMode()    # where every FMU lets its values be read
            return {v.name: [float(x) for x in getattr(fmu, "get" + v.type)(
                        [v.valueReference], nValues=math.prod(shapes[v.name]))]
                    for v in arrays}
        finally:
            fmu.freeInstance()
    except Exception as exc:  # the FMU's call failed: fmpy raises plain Exceptions
        given = ", ".join(f"{k}={v}" for k, v in changed.items())
        raise ProblemError(f"FMU {md.modelName!r} refuses the structural parameters "
                           f"{given} ({type(exc).__name__}: {exc})") from None


def _read(path: str):
    """The model description of the FMU at ``path``, checked (one line naming the
    file and what is wrong)."""
    fmpy = _fmpy()
    try:
        md = fmpy.read_model_description(path, validate=True)
    except Exception as exc:  # fmpy raises plain Exceptions, zipfile BadZipFile, lxml errors
        why = "; ".join(line.strip() for line in str(exc).splitlines() if line.strip())
        why = (why or type(exc).__name__)[:300]
        raise ProblemError(f"FMU {path!r} is malformed: cannot read its model description "
                           f"({why})") from None
    version = "3.0" if str(md.fmiVersion).startswith("3.") else md.fmiVersion
    if version not in VERSIONS:
        raise ProblemError(f"FMU {path!r} is FMI {md.fmiVersion}; supported: FMI "
                           f"{' and '.join(VERSIONS)} model exchange")
    if md.modelExchange is None:
        raise ProblemError(f"FMU {path!r} is co-simulation only; the harness needs a "
                           "model-exchange FMU (its own integrators step the model)")
    platforms = fmpy.supported_platforms(path)
    if fmpy.platform not in platforms:
        has = ", ".join(x for x in platforms if x != "c-code") or "none"
        raise ProblemError(f"FMU {path!r} has no binary for this platform ({fmpy.platform}); "
                           f"binaries: {has}")
    if not md.derivatives:
        raise ProblemError(f"FMU {path!r} has no continuous states: nothing to integrate")
    return md


def _shape(variable, structural: dict) -> tuple[int, ...]:
    """The shape of ``variable`` with the structural parameters at ``structural``
    (value reference -> value): each ``Dimension`` a fixed ``start`` or the value
    of the structural parameter it names (FMI 3.0.1, chapter 2, "Array
    variables and structural parameters")."""
    return tuple(int(d.start) if d.start is not None
                 else int(structural.get(d.valueReference, d.variable.start))
                 for d in variable.dimensions)


@lru_cache(maxsize=32)
def _describe(path: str, mtime_ns: int, size: int, structural_items: tuple = ()
              ) -> FmuDescription:
    md = _read(path)
    structural = {v.name: (v.valueReference, v.type, int(v.start))
                  for v in md.modelVariables
                  if v.causality == "structuralParameter" and v.type in INTEGER_TYPES
                  and v.start is not None}
    values = {name: start for name, (_, _, start) in structural.items()}
    values.update(structural_items)
    by_ref = {structural[name][0]: value for name, value in values.items()}
    shapes = {v.name: _shape(v, by_ref) for v in md.modelVariables}
    unzipdir = tempfile.mkdtemp(prefix="fmu-", dir=extraction_root())
    _fmpy().extract(path, unzipdir=unzipdir)
    # fmpy 0.3 leaves min and max of FMI 3.0 integer variables unread: read them here
    root = ElementTree.parse(Path(unzipdir) / "modelDescription.xml").getroot()
    written = {e.get("name"): e.attrib for e in root.iterfind("ModelVariables/*")}

    def attribute(v, key):
        value = getattr(v, key)
        return value if value is not None else written.get(v.name, {}).get(key)
    changed = {k: v for k, v in values.items() if v != structural[k][2]}
    current = _configured_values(md, unzipdir, structural, changed, shapes) if changed else {}

    def starts_of(v) -> list[float]:
        """The start values of ``v``'s elements: the model description's, or
        the FMU's own after its reconfiguration when the size changed."""
        n = math.prod(shapes[v.name])
        if v.name in current:
            return current[v.name]
        return _numbers(v.start, n, f"{v.name} start", path)

    def bound(key, v, default):
        """Attribute ``key`` of ``v``, per element (``default`` when not given)."""
        n, text = math.prod(shapes[v.name]), attribute(v, key)
        return [default] * n if text is None else _numbers(text, n, f"{v.name} {key}", path)

    states = [d.variable.derivative for d in md.derivatives]
    state_names = {s.name for s in states}
    parameters, types, arrays = [], {}, {}
    for name, (vr, kind, start) in structural.items():
        v = next(x for x in md.modelVariables if x.name == name)
        low, high = attribute(v, "min"), attribute(v, "max")
        parameters.append(Parameter(name, float(values[name]),
                                    float(low) if low is not None else 0.0,
                                    float(high) if high is not None else math.inf,
                                    v.description or "structural parameter"))
        types[name] = (vr, kind)
    for v in md.modelVariables:
        if (v.causality == "parameter" and v.variability in ("fixed", "tunable")
                and v.type in REAL_TYPES + INTEGER_TYPES and v.start is not None):
            names = element_names(v.name, shapes[v.name])
            if v.dimensions:
                arrays[v.name] = tuple(names)
            for name, start, low, high in zip(names, starts_of(v),
                                              bound("min", v, -math.inf),
                                              bound("max", v, math.inf)):
                parameters.append(Parameter(name, start, low, high, v.description or ""))
                types[name] = (v.valueReference, v.type)
    outputs, elements = {}, {}
    for v in md.modelVariables:
        if v.causality == "output" and v.type in REAL_TYPES and v.name not in state_names:
            names = element_names(v.name, shapes[v.name])
            for index, (name, nominal) in enumerate(zip(names, bound("nominal", v, 1.0))):
                outputs[name] = (v.valueReference, len(names), index, nominal)
                elements[name] = (v.name, index if v.dimensions else None)
    for name in (PATH, SCORE):
        if name in types:
            raise ProblemError(f"FMU {path!r} has a parameter named {name!r}, which the "
                               "harness reserves for its own option")
    for name in types:
        if name.startswith(START):
            raise ProblemError(f"FMU {path!r} has a parameter named {name!r}; the harness "
                               f"reserves the prefix {START!r} for its state-start options")
    from fmpy.simulation import settable_in_instantiated

    state_elements, nominals, starts = [], [], {}
    for s in states:
        names = element_names(s.name, shapes[s.name])
        state_elements += names
        elements.update((name, (s.name, index if s.dimensions else None))
                        for index, name in enumerate(names))
        nominals += bound("nominal", s, 1.0)
        if s.dimensions:
            arrays[s.name] = tuple(names)
        if s.start is not None and settable_in_instantiated(s):
            for name, start, low, high in zip(names, starts_of(s), bound("min", s, -math.inf),
                                              bound("max", s, math.inf)):
                starts[name] = (start, low, high)
    for name, value in [*((p.name, p.default) for p in parameters),
                        *((name, start) for name, (start, _, _) in starts.items())]:
        if not math.isfinite(value):
            raise ProblemError(f"FMU {path!r} gives {name!r} the start value {value:g}, "
                               "which is not a finite number")
    if not state_elements:
        raise ProblemError(f"FMU {path!r} has no continuous states at "
                           f"{', '.join(f'{k}={v}' for k, v in values.items())}: "
                           "nothing to integrate")
    ex = md.defaultExperiment
    t0 = float(ex.startTime) if ex is not None and ex.startTime is not None else 0.0
    t1 = float(ex.stopTime) if ex is not None and ex.stopTime is not None else t0 + 1.0
    return FmuDescription(
        path=path, checksum=file_checksum(path), unzipdir=unzipdir, model_description=md,
        states=tuple(state_elements),
        state_refs=tuple(s.valueReference for s in states),
        derivative_refs=tuple(d.variable.valueReference for d in md.derivatives),
        nominals=tuple(nominals), parameters=tuple(parameters), parameter_types=types,
        t_span=(t0, t1),
        n_indicators=(sum(math.prod(shapes[z.variable.name]) for z in md.eventIndicators)
                      if str(md.fmiVersion).startswith("3.")
                      else int(md.numberOfEventIndicators or 0)),
        directional=_provides_directional(md, unzipdir), outputs=outputs, starts=starts,
        arrays=arrays, elements=elements, structural=structural, structural_values=values)


def _provides_directional(md, unzipdir: str) -> bool:
    """Whether the FMU gives directional derivatives. fmpy 0.3 reads FMI 2.0's
    attribute name (``providesDirectionalDerivative``) for FMI 3.0 too, whose
    is ``providesDirectionalDerivatives``: read that one from the file."""
    if not str(md.fmiVersion).startswith("3."):
        return bool(md.modelExchange.providesDirectionalDerivative)
    root = ElementTree.parse(Path(unzipdir) / "modelDescription.xml").getroot()
    element = root.find("ModelExchange")
    return element is not None and element.get("providesDirectionalDerivatives") == "true"


def _apply_start_values(fmu, desc: FmuDescription, values: dict, settable) -> dict:
    """Set the start values ``values`` (variable name -> value, a list of its
    elements for an array) of the variables ``settable`` says may be set now, as
    :func:`fmpy.simulation.apply_start_values` does (which it does for the
    scalars; an array is set here, at the size its structural parameters give
    it, which that function takes from their start values); the values left."""
    from fmpy.simulation import apply_start_values

    left = {k: v for k, v in values.items() if k not in desc.arrays}
    left = apply_start_values(fmu, desc.model_description, left, settable=settable)
    for v in desc.model_description.modelVariables:
        if v.name in desc.arrays and v.name in values:
            if settable(v):
                cast = int if v.type in INTEGER_TYPES else float
                getattr(fmu, "set" + v.type)([v.valueReference],
                                             [cast(x) for x in values[v.name]])
            else:
                left[v.name] = values[v.name]
    return left


class FmuInstance:
    """One initialized instance of a model-exchange FMU in continuous-time mode.

    Parameters
    ----------
    desc : FmuDescription
    values : dict
        Start values by variable name: every parameter's, and the state starts
        given (:attr:`FmuProblem.fmu_values`).
    """

    def __init__(self, desc: FmuDescription, values: dict):
        _fmpy()
        from fmpy.simulation import settable_in_initialization_mode, settable_in_instantiated

        md = desc.model_description
        self.desc = desc
        self.fmu = fmu_instance(desc.unzipdir, md)   # its log lines on standard error
        weakref.finalize(self, _free, self.fmu)
        t0, t1 = desc.t_span
        if desc.fmi3:
            self._get_derivatives = self.fmu.getContinuousStateDerivatives
            self._update_discrete = self.fmu.updateDiscreteStates
        else:
            self.fmu.setupExperiment(startTime=t0, stopTime=t1)
            self._get_derivatives = self.fmu.getDerivatives
            self._update_discrete = self.fmu.newDiscreteStates
        _configure(self.fmu, desc.structural, desc.reconfigured)
        # as fmpy's simulate_fmu sets them: first those settable before initialization
        left = _apply_start_values(self.fmu, desc, values, settable_in_instantiated)
        if desc.fmi3:
            self.fmu.enterInitializationMode(startTime=t0, stopTime=t1)
        else:
            self.fmu.enterInitializationMode()
        left = _apply_start_values(self.fmu, desc, left, settable_in_initialization_mode)
        if left:   # FmuProblem checks the names: a value no mode takes is a bug
            raise ProblemError(f"FMU {desc.path!r} takes no start value for "
                               f"{', '.join(left)}")
        self.fmu.exitInitializationMode()
        self._discrete_update(t0)
        self.fmu.enterContinuousTimeMode()
        n, nz = len(desc.states), desc.n_indicators
        self._x, self._dx, self._z = np.zeros(n), np.zeros(n), np.zeros(max(nz, 1))
        self._px, self._pdx, self._pz = (a.ctypes.data_as(POINTER(c_double))
                                         for a in (self._x, self._dx, self._z))
        self.fmu.getContinuousStates(self._px, n)
        self.y0 = self._x.copy()

    def _discrete_update(self, t) -> bool:
        """``fmi2NewDiscreteStates`` (``fmi3UpdateDiscreteStates``) until the
        FMU needs no more; whether the continuous states changed."""
        needed, changed = True, False
        while needed:
            needed, terminate, _, values_changed, time_event, _ = self._update_discrete()
            changed |= values_changed
            if terminate:
                raise RuntimeError(f"the FMU requested termination at t = {t:.17g}")
            if time_event:
                raise ProblemError(f"FMU {self.desc.path!r} schedules a time event at "
                                   f"t = {t:g}; time events are not supported")
        return changed

    def _set(self, t, y):
        self.fmu.setTime(float(t))
        self._x[:] = y
        self.fmu.setContinuousStates(self._px, self._x.size)

    def derivatives(self, t, y) -> np.ndarray:
        """The FMU's state derivatives at ``(t, y)``."""
        self._set(t, y)
        self._get_derivatives(self._pdx, self._dx.size)
        return self._dx.copy()

    def jacobian(self, t, y) -> np.ndarray:
        """``d der(x) / d x`` by the FMU's directional derivatives, a column per
        call: every derivative and state variable, the seed and the sensitivity
        an entry per element (an array's elements in row-major order)."""
        self._set(t, y)
        n = self._x.size
        J = np.empty((n, n))
        unknowns, knowns = list(self.desc.derivative_refs), list(self.desc.state_refs)
        sizes = {"nSensitivity": n} if self.desc.fmi3 else {}
        seed = [0.0] * n
        for j in range(n):
            seed[j] = 1.0
            J[:, j] = self.fmu.getDirectionalDerivative(unknowns, knowns, seed, **sizes)
            seed[j] = 0.0
        return J

    def outputs(self, t, Y, names) -> np.ndarray:
        """The output elements ``names`` (:attr:`FmuDescription.outputs`) at each
        time of ``t`` and row of ``Y``: their variables read in one call, an
        array's with all its elements."""
        sizes = {}                    # value reference -> (first value, size)
        for name in names:
            vr, size, _, _ = self.desc.outputs[name]
            if vr not in sizes:
                sizes[vr] = (sum(n for _, n in sizes.values()), size)
        refs = list(sizes)
        columns = [sizes[self.desc.outputs[n][0]][0] + self.desc.outputs[n][2] for n in names]
        n_values = sum(n for _, n in sizes.values())
        out = np.empty((len(t), len(names)))
        for k, (tk, y) in enumerate(zip(t, Y)):
            self._set(tk, y)
            values = (self.fmu.getFloat64(refs, nValues=n_values) if self.desc.fmi3
                      else self.fmu.getReal(refs))
            out[k] = np.asarray(values)[columns]
        return out

    def indicator(self, i: int):
        """``value(t, y)`` of event indicator ``i``."""
        def value(t, y):
            self._set(t, y)
            self.fmu.getEventIndicators(self._pz, self.desc.n_indicators)
            return float(self._z[i])
        return value

    def event(self, t, y) -> np.ndarray | None:
        """Let the FMU act on an event at ``(t, y)``: the state to restart from,
        or None when it changed neither its states nor its right-hand side."""
        before = self.derivatives(t, y)
        self.fmu.enterEventMode()
        changed = self._discrete_update(t)
        self.fmu.enterContinuousTimeMode()
        self.fmu.getContinuousStates(self._px, self._x.size)
        y_new = self._x.copy()
        if changed or not np.array_equal(before, self.derivatives(t, y_new)):
            return y_new
        return None


def _free(fmu):
    try:
        fmu.terminate()
    except Exception:  # already terminated or in error: free it all the same
        pass
    fmu.freeInstance()


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
            # a problem with events needs reference methods of two families
            self.reference_methods = (("ode", "cvode-bdf", 1e-12), ("ode", "scipy-DOP853", 1e-12))
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
        structural parameters left out, :func:`_configure` sets those); an
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
