"""What a problem and a line are: :class:`ProblemSpec` and :class:`Line`.

A *problem spec* is a registered problem at one parameter set, written
``name:key=value,...`` by the user (:func:`parse_spec`, the one reader of that
text; :func:`integrator_bench.harness.matrix.cases.parse_problem_spec` completes
the values through the problem class) and built by :meth:`ProblemSpec.build`.
A *line* is what the report draws and the advice ranks: one problem spec, one
formulation, one integrator with its settings, and one mode (adaptive at a
tolerance, ``rtol``, or fixed at a step, ``h``); its cases differ only in the
tolerance or step. :attr:`Line.key` identifies it, :attr:`Line.label` names its
integrator, :attr:`Line.family` is the report's panel it goes to
(:data:`FAMILIES`). A case gives its line with :meth:`Line.of`, a stored record
with :meth:`Line.of_record`.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import itertools
import json
from dataclasses import dataclass, field

from integrator_bench.harness.errors import BadInput
from integrator_bench.harness.matrix import builds, registry
from integrator_bench.harness.matrix.record import mode_of
from integrator_bench.harness.matrix.stand_in import system_of
from integrator_bench.integrators.settings import variant_name
from integrator_bench.problems.base import format_label

#: the report's panels, in the order it draws them: family -> its title
FAMILIES = {"explicit": "Explicit", "implicit": "Implicit and stiff",
            "dae": "DAE and mechanical forms", "unknown": "Integrators no longer registered"}
#: how the advice names the families of its candidates (no candidate is ``unknown``)
FAMILY_WORDS = {"explicit": "explicit", "implicit": "implicit", "dae": "DAE/mechanical"}
#: the record's columns that hold a line's identity
LINE_FIELDS = ("problem", "params", "formulation", "integrator", "settings", "mode")
#: the record's columns that identify a case: its line's but the mode, and the tolerance or step
KEY_FIELDS = LINE_FIELDS[:-1] + ("rtol", "h")


def spec_name(spec: str) -> str:
    """The name of a spec ``name:key=value,...`` (``name`` alone for a bare name)."""
    return spec.partition(":")[0]


def parse_spec(spec: str, what: str = "parameter") -> tuple[str, list[dict] | None]:
    """``name:key=value,...`` -> ``(name, [dict of str values, ...])``.

    ``None`` for a bare name. A value ``a|b|c`` sweeps that key: one dict per
    combination of the swept values, in the order given. The one reader of
    problem specs and integrator specs (``cvode-bdf:max_order=2``; ``what``
    names the values in its errors).
    """
    name, _, rest = spec.partition(":")
    if not rest:
        return name, None
    keys, choices = [], []
    for item in rest.split(","):
        key, eq, value = item.partition("=")
        key = key.strip()
        if not eq or not key or any(not v.strip() for v in value.split("|")):
            raise BadInput(f"malformed {what} {item!r} in {spec!r}; expected key=value "
                           "or key=value|value|...")
        if key in keys:
            raise BadInput(f"{what} {key!r} given twice in {spec!r}")
        keys.append(key)
        choices.append([v.strip() for v in value.split("|")])
    return name, [dict(zip(keys, combo)) for combo in itertools.product(*choices)]


def _hashable(value):
    return tuple(_hashable(v) for v in value) if isinstance(value, list) else value


@dataclass(frozen=True)
class ProblemSpec:
    """A registered problem at one parameter set.

    Attributes
    ----------
    name : str
        The registry name (``two_mass``).
    params : tuple
        Sorted ``(name, value)`` pairs of the parameter values (every one, when
        it comes from :func:`~integrator_bench.harness.matrix.cases.parse_problem_spec`
        or a problem instance).
    """

    name: str
    params: tuple = ()

    @classmethod
    def of(cls, name: str, params: dict) -> ProblemSpec:
        """The spec of problem ``name`` at the values ``params`` (a dict)."""
        return cls(name, tuple(sorted(params.items())))

    @classmethod
    def of_problem(cls, problem) -> ProblemSpec:
        """The spec of a problem instance (its name and every parameter value)."""
        return cls.of(problem.name, problem.params)

    @property
    def params_dict(self) -> dict:
        return dict(self.params)

    @property
    def params_json(self) -> str:
        """The record's ``params``: JSON of the values, keys sorted."""
        return json.dumps(self.params_dict, sort_keys=True)

    @property
    def text(self) -> str:
        """The canonical text ``name:key=value,...`` (keys sorted; ``name`` alone
        without parameters), as problem labels write it."""
        return format_label(self.name, self.params_dict)

    def __str__(self) -> str:
        return self.text

    def build(self, here: bool = False):
        """The problem instance, through the registry (:class:`UnknownName` for a
        name not registered); for a problem from outside the project, the stand-in
        of its build in a process of its own
        (:func:`~integrator_bench.harness.matrix.builds.build`; its
        :class:`~integrator_bench.harness.errors.ModelFault` when that failed).
        With ``here``, the problem itself built in this process, whoever's code it
        is: what runs a case here does (a case's worker,
        :func:`~integrator_bench.harness.run.execution.execute`)."""
        cls = registry.get_problem_class(self.name)
        return cls(**self.params_dict) if here else builds.build(cls, self.params_dict)


def family(icls, kind: str | None) -> str:
    """The report's panel of a line (a key of :data:`FAMILIES`): ``dae`` for a DAE
    or mechanical system (``kind``), else what the integrator class ``icls``
    declares (``dae`` when it takes neither an ODE nor an FMU, else ``implicit``
    or ``explicit`` by its ``implicit``); ``unknown`` for an integrator no longer
    registered (None)."""
    if kind in ("dae", "mechanical"):
        return "dae"
    if icls is None:
        return "unknown"
    if not icls.accepts & {"ode", "fmu"}:
        return "dae"
    return "implicit" if icls.implicit else "explicit"


def _settings_of(text) -> tuple:
    """The sorted pairs of a record's ``settings`` JSON (``()`` when null or empty)."""
    if not isinstance(text, str) or not text:
        return ()
    return tuple(sorted((k, _hashable(v)) for k, v in json.loads(text).items()))


def _params_of(text) -> tuple:
    """The sorted pairs of a record's ``params`` JSON (``(("params", text),)`` when
    it is not a JSON object, as the report reads such a value)."""
    try:
        value = json.loads(text)
    except (TypeError, ValueError):
        value = None
    if not isinstance(value, dict):
        value = {"params": text if value is None else value}
    return tuple(sorted((k, _hashable(v)) for k, v in value.items()))


@dataclass(frozen=True)
class Line:
    """One line: a problem spec, a formulation, an integrator with its settings, a mode.

    Attributes
    ----------
    problem : ProblemSpec
    formulation : str
    integrator : str
        The registry name.
    settings : tuple
        Sorted ``(name, value)`` pairs of the settings not at their default.
    mode : str
        ``rtol`` (adaptive) or ``h`` (fixed step): :func:`~integrator_bench.harness.matrix.record.mode_of`.
    kind : str or None
        The kind of system the formulation gives (ode, dae, mechanical, fmu), when
        known; it decides :attr:`family`, not the identity.
    """

    problem: ProblemSpec
    formulation: str
    integrator: str
    settings: tuple = ()
    mode: str = "rtol"
    kind: str | None = field(default=None, compare=False)

    @classmethod
    def of(cls, case) -> Line:
        """The line a :class:`~integrator_bench.harness.matrix.cases.Case` is a point of."""
        return cls(case.spec, case.formulation, case.integrator, case.settings,
                   mode_of(case.rtol, case.h), case.kind)

    @classmethod
    def of_record(cls, row) -> Line:
        """The line of a stored record (a mapping with the record's fields; its
        ``mode`` the stored one, else :func:`mode_of` of its ``rtol`` and ``h``)."""
        get = row.get
        mode = get("mode")
        if not isinstance(mode, str):
            mode = mode_of(_number(get("rtol")), _number(get("h")))
        kind = get("kind")
        return cls(ProblemSpec(get("problem"), _params_of(get("params"))), get("formulation"),
                   get("integrator"), _settings_of(get("settings")), mode,
                   kind if isinstance(kind, str) else None)

    @property
    def key(self) -> tuple:
        """``(problem, params, formulation, integrator, settings, mode)``: hashable, the
        line's identity."""
        return (self.problem.name, self.problem.params, self.formulation, self.integrator,
                self.settings, self.mode)

    @property
    def text(self) -> str:
        """The record's ``line``: :attr:`key` as JSON (parameters and settings as objects)."""
        return json.dumps([self.problem.name, self.problem.params_dict, self.formulation,
                           self.integrator, dict(self.settings), self.mode], sort_keys=True)

    @property
    def label(self) -> str:
        """``cvode-bdf`` or ``cvode-bdf (max_order=2)``: the integrator with its settings."""
        return variant_name(self.integrator, dict(self.settings))

    def case_id(self, rtol: float | None, h: float | None) -> str:
        """The stored key (``case_id``) of the line's case at ``rtol`` or ``h``: 16 hex
        digits of the SHA-256 of the JSON of problem, params, formulation, integrator,
        rtol and h, and the settings when there are any (so a case at the defaults
        keeps the id it had before settings were part of a case)."""
        key = [self.problem.name, self.problem.params_dict, self.formulation, self.integrator,
               rtol, h]
        if self.settings:
            key.append(dict(self.settings))
        return hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:16]

    @property
    def family(self) -> str:
        """The report's panel (:func:`family` of the registered integrator and :attr:`kind`)."""
        return family(registry.integrators().get(self.integrator), self.kind)


@functools.lru_cache(maxsize=None)
def formulation_facts(problem: str, formulation: str) -> tuple:
    """``(kind, index)`` of the system a registered problem's formulation gives with
    its default parameters: as the project's own problem class declares it
    (``formulation_facts``, nothing built or compiled), else formulated once per
    process (one from outside the project: as its trial build formulated it, its
    class's code never called here); ``(None, None)`` when the problem is not
    registered, does not offer the formulation or fails to build."""
    cls = registry.problems().get(problem)
    declared = cls.formulation_facts(formulation) \
        if cls is not None and not builds.foreign(cls) else None
    if declared is not None:
        return declared
    inst = _default_instance(problem)
    if inst is None or formulation not in inst.formulations:
        return None, None
    try:
        system = system_of(inst, formulation)
    except Exception:  # a problem that fails to build only loses its panel placement
        return None, None
    return system.kind, getattr(system, "index", None)


@functools.lru_cache(maxsize=None)
def _default_instance(problem: str):
    """The registered problem with its default parameters, built once (its
    consistent start and compiled model serve every formulation; one from outside
    the project: its stand-in, :func:`~integrator_bench.harness.matrix.builds.build`);
    None when it is not registered or cannot be built without parameters (an FMU)."""
    cls = registry.problems().get(problem)
    try:
        return None if cls is None else builds.build(cls, {})
    except Exception:
        return None


#: the columns of a line a store written before them lacks, which :func:`backfill` fills
BACKFILLED = ("mode", "line", "label", "family")


def backfill(rows):
    """``rows`` (a DataFrame of records) with :data:`BACKFILLED` filled in where a
    record lacks them (a store written before these fields): its :class:`Line`'s
    mode, text and label, and its family from the stored ``kind``, else the kind
    the problem's formulation gives today (:func:`formulation_facts`). Records that
    have them keep them; rows without a problem column are returned as they are."""
    if rows.empty or "problem" not in rows.columns:
        return rows
    import pandas as pd

    missing = pd.Series(False, index=rows.index)
    for name in BACKFILLED:
        missing |= rows[name].isna() if name in rows.columns else True
    if not missing.any():
        return rows
    rows = rows.copy()
    for name in BACKFILLED:
        if name not in rows.columns:
            rows[name] = None
        rows[name] = rows[name].astype(object)
    for index, row in rows[missing].iterrows():
        line = Line.of_record(row)
        if line.kind is None:
            line = dataclasses.replace(line, kind=formulation_facts(line.problem.name,
                                                                    line.formulation)[0])
        for name, value in (("mode", line.mode), ("line", line.text), ("label", line.label),
                            ("family", line.family)):
            if not isinstance(row[name], str):
                rows.at[index, name] = value
    return rows


def _number(value):
    """A stored tolerance or step as a float, None when null."""
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    return None if value != value else value
