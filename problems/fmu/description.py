"""What an FMU file describes: its ``modelDescription.xml``, read and checked.

Any FMI 2.0 or 3.0 model-exchange FMU (Functional Mock-up Interface 2.0.4,
Modelica Association 2022, chapter 3; FMI 3.0.1, 2023, chapter 3) is read into an
:class:`FmuDescription` by :func:`describe_fmu`:

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
  other than its start is set in Configuration Mode (:func:`configure`)
  and resizes the arrays, the elements their start values do not cover then
  taking the FMU's own values (fmpy's solvers, which size arrays by the
  structural parameters' start values, are refused then);
* the start value of each continuous state the standard lets the importer set
  before initialization (``initial="exact"`` or ``"approx"``, the attribute of
  FMI 2.0.4 sect. 2.2.7 and of FMI 3.0.1) is the option ``start.NAME``
  (``fmu:path=m.fmu,start.x=1.02``): the run starts from the state the FMU
  initializes to from it (:meth:`~.problem.FmuProblem.settable_starts`); a state with
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
* the event indicators are counted (an array's every element), each a state
  event of the problem (:mod:`.problem`).

Refused, each with one line naming the file and why
(:class:`~integrator_bench.problems.base.ProblemError`): a missing file, one
that is not an FMU or whose model description does not read, an FMI version
other than 2.0 and 3.0, a co-simulation-only FMU, one without a binary for this
platform, one without continuous states, and a structural parameter the FMU
refuses. Each FMU is extracted into a folder of this command's own
(:func:`extraction_root`), removed when the command ends.
"""

from __future__ import annotations

import atexit
import contextlib
import hashlib
import math
import os
import shutil
import tempfile
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from integrator_bench.problems.base import SCORE, Parameter, ProblemError
from integrator_bench.problems.system import fmu_instance

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


def configure(fmu, structural: dict, changed: dict) -> None:
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
            configure(fmu, structural, changed)
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


