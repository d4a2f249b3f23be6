"""Cases: one (problem, parameters, formulation, integrator, tolerance or step).

``expand`` builds the benchmark matrix from the live registries and the user's
selections. One parser (:func:`~integrator_bench.harness.matrix.line.parse_spec`)
reads ``name:key=value,...`` for both problems (parameters,
:func:`parse_problem_spec`, giving :class:`~integrator_bench.harness.matrix.line.ProblemSpec`)
and integrators
(settings, :func:`parse_integrator_spec`: ``cvode-bdf:max_order=2``); a value
``a|b|c`` sweeps that key (``cvode-bdf:max_order=1|2|3|5`` names four).

An integrator's settings are part of its case: :attr:`Case.settings` holds the
values that differ from the defaults. A case is a point of its line
(:attr:`Case.line`, a :class:`~integrator_bench.harness.matrix.line.Line`), which
gives its stored key, ``case_id``, and the record's line fields.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
from dataclasses import dataclass, field

from integrator_bench.harness.matrix import builds, registry
from integrator_bench.harness.errors import BadInput, ModelFault
from integrator_bench.harness.matrix.line import Line, ProblemSpec, parse_spec, spec_name
from integrator_bench.harness.matrix.record import mode_of
from integrator_bench.harness.matrix.stand_in import system_of
from integrator_bench.integrators.settings import SettingError, changed
from integrator_bench.problems.base import OPTIONS, ProblemError
from integrator_bench.problems.system import Unsupported, convert

@dataclass(frozen=True)
class Preset:
    """A named benchmark matrix: what ``ibench run --preset NAME`` runs by default.

    Attributes
    ----------
    rtol : tuple of float
        Tolerances of adaptive runs (``atol = rtol * atol_scale``).
    h_per_span : tuple of int
        Fixed-step runs take ``h = span / n`` for each ``n``.
    formulations : tuple of str or None
        The formulations run when none is named (None: every one).
    first_set_only : bool
        A run that names no problem takes each problem's first benchmark
        parameter set only; a problem named by bare name (``-p chain_drive``)
        always runs all its sets.
    budget_s : float or None
        Per-case budget in CPU seconds of the preset's own matrix (the default
        ``--timeout``; see :func:`budget`): a case over it is stopped and
        recorded ``timeout``, so no combination dominates the run.
    max_dimension : int or None
        When no problem is named, the problems whose first parameter set has
        more states than this are left out (:func:`left_out` names them); a
        problem named with ``-p`` always runs.
    samples : int or None
        The most timed solves of a case when ``--repeat`` is not given (None:
        the run's default,
        :attr:`~integrator_bench.harness.run.limits.Limits.repeat`); the quick
        preset's first look takes one, the others sample for a spread.
    variants : tuple of str
        Integrator specs with settings (``cvode-bdf:max_order=2``) run beside
        every registered integrator when no integrator is named (those of an
        integrator not installed are left out).
    problems : tuple of str or None
        The problem specs run when none is named (None: every registered problem,
        less those :func:`left_out` names).
    listed : bool
        Whether the preset's own matrix is a list of cases made above the matrix
        (the seeds preset's, by the source documents,
        :func:`integrator_bench.harness.sources.numbers.preset_cases`), which
        :func:`expand` is handed (``listed``) and runs instead of the ladder for a
        run that names no problem, formulation, integrator, tolerance or step.
    h_per_span_of : tuple
        ``(problem name, steps)`` pairs: a problem's own fixed-step ladder in
        place of ``h_per_span`` (:meth:`steps_of`).
    race : bool
        Whether ``ibench run`` races the preset by default (``--exhaustive``
        does not; harness/ranking/racing.py): the full and IFToMM presets, whose
        dearest cases cannot change an answer; not the quick preset (its first
        look keeps every status) nor the seeds' (each row's own configuration).
    twin_steps : int or None
        A driven problem's undriven twin (:func:`with_twins`) runs the first this
        many of its problem's fixed steps (None: all of them): enough fixed-step
        pairs for the report's "what the driving costs" at a fraction of the CPU.
    """

    rtol: tuple
    h_per_span: tuple
    formulations: tuple | None = None
    first_set_only: bool = False
    budget_s: float | None = None
    max_dimension: int | None = None
    samples: int | None = None
    variants: tuple = ()
    problems: tuple | None = None
    listed: bool = False
    h_per_span_of: tuple = ()
    race: bool = False
    twin_steps: int | None = None

    def steps_of(self, problem: str, twin: bool = False) -> tuple:
        """The numbers of fixed steps over the span the preset runs ``problem`` at
        (its undriven twin's, with ``twin``: :attr:`twin_steps`)."""
        steps = dict(self.h_per_span_of).get(problem, self.h_per_span)
        return steps[:self.twin_steps] if twin and self.twin_steps else steps


#: the variants the seeds advise: CVODE's and IDA's maximum order 2 (the ADAMS
#: seminar's KMAX "recommended then to reduce to 2" for contact and very stiff
#: elements), also through Assimulo when it is installed, and HHT at both ends of
#: its alpha range beside its default -0.3
SEED_VARIANTS = ("cvode-bdf:max_order=2", "ida:max_order=2", f"hht:alpha=0|{-1 / 3!r}",
                 "assimulo-cvode-bdf:max_order=2", "assimulo-ida:max_order=2")

PRESETS = {
    # The first look, a minute on two cores: every problem (its first parameter
    # set), one formulation of each family (the underlying ODE; the index-3 DAE and
    # the mechanical form; the stabilized index-2 GGL (ADAMS's SI2); projection onto
    # the constraint manifolds; the index-3 augmented Lagrangian form), every integrator, a loose and a tight tolerance or
    # 100 and 200 fixed steps, and a budget of 2.5 s of CPU per case (the share a
    # case's counted solve had of the 5 s of wall time once given, when a case was
    # solved twice: no case that ended ok then runs out of it now). Problems of more than
    # 100 states (the chain drive) run when named: `ibench run -p chain_drive` (both sets).
    # Kapitza's pendulum, whose drive has 32 periods in its span, at 1000 and 2000 steps
    # (31 and 63 a period; at 100 and 200 the fixed-step codes but the projected ones failed).
    # Its undriven twin (A = 0, for the report's "what the driving costs") at 1000 steps
    # only: 5.8 s of solves' CPU in one run where its whole ladder took 12.9 s.
    "quick": Preset(rtol=(1e-3, 1e-6), h_per_span=(100, 200),
                    formulations=("ode", "i3", "ggl", "projection", "al3"), first_set_only=True,
                    budget_s=2.5, max_dimension=100, samples=1,
                    h_per_span_of=(("kapitza", (1000, 2000)),), twin_steps=1),
    # The seeds' tables, number by number (harness/sources/numbers.py): each row's closest
    # configuration once (Sudarsan and Keerthi's approaches at TOL 1e-2, 1e-4, 1e-6, the
    # student report's runs, Orlov's DUMKA3 cells and RK4); named selections run the
    # ladder of Sudarsan and Keerthi's tolerances instead. 900 s a case (RK4 on cvt_chain,
    # 100,000 steps, takes 1-5 minutes of it).
    "seeds": Preset(rtol=(1e-2, 1e-4, 1e-6), h_per_span=(100, 1000), budget_s=900.0,
                    samples=1, listed=True),
    # every problem, parameter set and formulation over rtol 1e-2 ... 1e-8 (three decades
    # each side of the report's 1e-5) and 100, 1000, 10000 steps, 5 s of CPU a case (the
    # share a case's counted solve had of the 10 s of wall time once given, when a case was
    # solved twice: no case that ended ok then runs out of it now): a run that learns as it
    # goes (harness/run/schedule.py) skips the tighter cases of a line that timed out.
    "full": Preset(rtol=tuple(10.0 ** -e for e in range(2, 9)), h_per_span=(100, 1000, 10000),
                   budget_s=5.0, variants=SEED_VARIANTS, race=True),
    # the IFToMM multibody benchmark's problems (docs/problems.md): A01 the pendulum, A02 the
    # N-four-bar at the specified N = 40, A03 Andrews' squeezer, A04 Bricard's mechanism,
    # A05 the stiff flyball governor, every formulation and integrator, three tolerances
    # and 1000, 4000, 10000 steps (A02's al3 needs 10000, 2 ms, for the high precision
    # level: 4.1-4.5 s of CPU, the costliest run a high-level result here needs). 5 s of
    # CPU a case, as `full`: at 10 s the preset took more than the 30 minutes of two
    # cores its issue allows, the time going to A02's fixed-step implicit codes on its
    # 245-state `ode` and `baumgarte` forms (5-10 s a case at 1000 steps, ending off the
    # physical branch, error 1, or in Newton failures; measured, docs/problems.md): over
    # 5 s they are timeouts, and the smaller steps of their lines are skipped. A04 and
    # A05 take 1000 and 4000 steps only (10 and 2.5 ms over their 10 s): their 10000-step
    # rung cost 262 s of the 622 s of CPU their solves took (measured), and at 2.5 ms the
    # fixed-step codes already reach the high level on both (no pair of either reached it
    # at 1 ms alone)
    "iftomm": Preset(rtol=(1e-3, 1e-5, 1e-7), h_per_span=(1000, 4000, 10000), budget_s=5.0,
                     samples=1, problems=("pendulum", "n_four_bar:n=40", "squeezer", "bricard",
                                          "flyball"),
                     h_per_span_of=(("bricard", (1000, 4000)), ("flyball", (1000, 4000))),
                     race=True),
}


@dataclass(frozen=True)
class Case:
    problem: str
    params: tuple  # sorted (name, value) pairs: hashable
    formulation: str
    integrator: str
    rtol: float | None = None
    h: float | None = None
    unsupported: str | None = field(default=None, compare=False)
    settings: tuple = ()  # sorted (name, value) pairs of the settings not at their default
    #: the kind of system the formulation gives (ode, dae, mechanical, fmu), when the
    #: expansion formulated it; the worker sets the record's from the system it runs
    kind: str | None = field(default=None, compare=False)
    #: a budget of CPU seconds below the run's (a race bound, harness/ranking/racing.py):
    #: the worker stops the case at the lesser of the two; not part of its identity
    budget_s: float | None = field(default=None, compare=False)
    #: ``(status, message)`` when the problem failed to build in its trial
    #: (:mod:`~integrator_bench.harness.matrix.builds`): the case is recorded so, not run
    fault: tuple | None = field(default=None, compare=False)

    @property
    def settled(self) -> bool:
        """Whether the case is recorded where it was decided, with no process:
        ``unsupported``, or its problem failed to build."""
        return bool(self.unsupported or self.fault)

    @property
    def mode(self) -> str:
        """``"rtol"`` (adaptive) or ``"h"`` (fixed step): :func:`~integrator_bench.harness.matrix.record.mode_of`."""
        return mode_of(self.rtol, self.h)

    @property
    def spec(self) -> ProblemSpec:
        """The problem and its parameter values."""
        return ProblemSpec(self.problem, self.params)

    @functools.cached_property
    def line(self) -> Line:
        """The line the case is a point of (:meth:`Line.of`): its identity but
        ``rtol`` and ``h``."""
        return Line.of(self)

    def identity(self, kind: str | None = None) -> dict:
        """The record's fields the case decides: its key, its line and mode, the
        integrator's label and origin, the system's kind (``kind``, else the
        case's) and the report's family (:attr:`Line.family`)."""
        line = dataclasses.replace(self.line, kind=kind or self.kind)
        icls = registry.integrators().get(self.integrator)
        return dict(case_id=self.case_id, problem=self.problem, params=self.params_json,
                    formulation=self.formulation, integrator=self.integrator,
                    settings=self.settings_json, rtol=self.rtol, h=self.h, mode=line.mode,
                    line=line.text, label=line.label, kind=line.kind,
                    family=line.family, origin=getattr(icls, "origin", None))

    @property
    def settings_dict(self) -> dict:
        return dict(self.settings)

    @property
    def settings_json(self) -> str | None:
        """The record's ``settings``: JSON of the changed settings, None (empty)
        at the defaults."""
        return json.dumps(self.settings_dict, sort_keys=True) if self.settings else None

    @property
    def params_dict(self) -> dict:
        return dict(self.params)

    @property
    def params_json(self) -> str:
        return self.spec.params_json

    @property
    def case_id(self) -> str:
        """The stored case key (:meth:`Line.case_id` at the case's ``rtol`` or ``h``)."""
        return self.line.case_id(self.rtol, self.h)

    def label(self) -> str:
        tol = f"rtol={self.rtol:g}" if self.rtol is not None else f"h={self.h:g}"
        return (f"{self.spec.text} {self.formulation} "
                f"{self.line.label} {tol}")


def parse_integrator_spec(spec: str) -> list[tuple[str, type, tuple]]:
    """``name`` or ``name:key=value,...`` (``|`` sweeps) -> ``[(name, class,
    settings)]``, ``settings`` the sorted ``(name, value)`` pairs that differ
    from their defaults, each value checked by the integrator's declaration.
    A bad setting raises :class:`BadInput` naming the valid settings."""
    name, sets = parse_spec(spec, "setting")
    icls = registry.get_integrator(name)
    out = []
    for given in sets or ({},):
        try:
            values = icls(**given).setting_values
        except SettingError as exc:
            raise BadInput(f"{exc} (in {spec!r})") from None
        pairs = tuple(sorted(changed(icls.settings, values).items()))
        if (name, icls, pairs) not in out:
            out.append((name, icls, pairs))
    return out


def parse_problem_spec(spec: str, first_set_only: bool = False) -> list[ProblemSpec]:
    """``name`` or ``name:key=value,...`` -> one :class:`ProblemSpec` per parameter
    set, each with every parameter value.

    A bare name stands for every parameter set in the problem's
    ``benchmark_parameters`` (the first only with ``first_set_only``, which
    :func:`expand` sets for a run of the quick preset that names no problem),
    each followed by its undriven twin when the problem declares one
    (:func:`with_twins`);
    ``key=a|b`` gives one set per value (:func:`parse_spec`). A spec that gives
    only the options every problem takes (``score``, ``rhs_cost_us``:
    ``two_mass:score=x1``) names no parameter set: it stands for the sets the
    bare name does, each with those options.
    """
    name, given_sets = parse_spec(spec)
    cls = registry.get_problem_class(name)
    if given_sets is None or all(set(given) <= set(OPTIONS) for given in given_sets):
        sets = cls.benchmark_parameters[:1] if first_set_only else cls.benchmark_parameters
        if not sets:         # a problem family (an FMU) needs its parameters
            sets = ({},)
        sets = [{**params, **given} for given in given_sets or ({},)
                for params in with_twins(cls, sets)]
    else:
        sets = given_sets
    out = []
    for given in sets:
        try:   # a problem from outside the project built in a process of its own first
            out.append(ProblemSpec.of(name, builds.params_of(cls, given)[0]))
        except ProblemError as exc:
            raise BadInput(f"{exc} (in {spec!r})") from None
    return out


def with_twins(cls, sets) -> list[dict]:
    """``sets``, each followed by its undriven twin (``{**set, **cls.undriven}``) when
    the problem declares one (a driven problem's ``undriven``) and it is not a set
    already: the records the report's "what the driving costs" compares with."""
    undriven, out = getattr(cls, "undriven", None), []
    for params in sets:
        twin = {**params, **(undriven or {})}
        out += [dict(params)] + ([twin] if undriven and twin not in sets else [])
    return [params for i, params in enumerate(out) if params not in out[:i]]


def is_twin(problem) -> bool:
    """Whether ``problem`` (built) is at its class's undriven values (a driven
    problem's twin, :func:`with_twins`)."""
    undriven = getattr(problem, "undriven", None)
    return bool(undriven) and all(problem.params.get(k) == v for k, v in undriven.items())


def check_positive(name: str, values) -> tuple[float, ...]:
    for v in values:
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise BadInput(f"{name} {v!r} must be a positive finite number")
    return tuple(float(v) for v in values)


def formulated(problem, form: str, spec: str):
    """``problem`` in formulation ``form`` (the facts of a stand-in's:
    :func:`~integrator_bench.harness.matrix.stand_in.system_of`); :class:`BadInput`
    naming ``spec`` (what the user gave) when it cannot be formulated at these
    parameters, such as a mechanism whose given start is no longer consistent."""
    try:
        return system_of(problem, form)
    except ProblemError as exc:
        raise BadInput(f"{exc} (in {spec!r})") from None


def converted(system, icls, form, rtol=None, h=None):
    """``(system as icls takes it, None)``, or ``(None, why)`` when ``icls`` cannot
    run ``system`` (formulation ``form``) at ``rtol`` or ``h``: the one decision
    of "unsupported", which the expansion records without a process and the
    worker repeats only on cases built elsewhere."""
    why = icls.mode_unsupported(rtol, h)
    if why:
        return None, why
    try:
        return convert(system, icls), None
    except Unsupported as exc:
        return None, f"{form}: {exc}"


def unsupported_reason(system, icls, form, rtol=None, h=None) -> str | None:
    """Why ``icls`` cannot run ``system`` (formulation ``form``) at ``rtol`` or
    ``h``, in one line (:func:`converted`); None when it can."""
    return converted(system, icls, form, rtol, h)[1]


def expand(problems=None, formulations=None, integrators=None, rtols=None, hs=None,
           preset: str = "quick", listed=None) -> list[Case]:
    """The matrix of cases for the selections (None: everything registered).

    ``listed``: the cases of a preset that lists them (:attr:`Preset.listed`),
    ``(problem spec, formulation, integrator spec, rtol, h)`` each, run when
    nothing is selected (those of an integrator not installed are left out);
    such a preset's run that selects nothing needs them.
    """
    if preset not in PRESETS:
        raise BadInput(f"unknown preset {preset!r}; valid: {', '.join(PRESETS)}")
    ladder = PRESETS[preset]
    explicit = {"rtol": bool(rtols), "h": bool(hs)}
    rtols = check_positive("rtol", rtols) if rtols else ladder.rtol
    if hs:
        hs = check_positive("h", hs)
    specs = problems or list(ladder.problems or [name for name in registry.built_problems()
                                                 if name not in left_out(preset)])
    all_forms = registry.formulations()
    for f in formulations or ():
        if f not in all_forms:
            raise BadInput(f"unknown formulation {f!r}; valid: {', '.join(all_forms)}")
    integ = [entry for spec in (integrators or [*registry.integrators(), *variants(preset)])
             for entry in parse_integrator_spec(spec)]

    if ladder.listed and not (problems or formulations or integrators or explicit["rtol"]
                              or explicit["h"]):
        if listed is None:
            raise ValueError(f"the {preset} preset lists its cases: expand needs them")
        return _preset_cases(listed)
    cases = []
    for spec in specs:
        for pspec in parse_problem_spec(spec, ladder.first_set_only and not problems):
            problem, fault = _built(pspec)
            name = pspec.name
            if problems and formulations and not set(formulations) & set(problem.formulations):
                raise BadInput(f"problem {name} offers no formulation {', '.join(formulations)}"
                               f"; it offers: {', '.join(problem.formulations)}")
            steps = hs or tuple(problem.t_span[1] / n - problem.t_span[0] / n
                                for n in ladder.steps_of(name, is_twin(problem)))
            for form in problem.formulations:
                if form not in (formulations or ladder.formulations or problem.formulations):
                    continue
                system = None if fault else formulated(problem, form, spec)
                for iname, icls, settings in integ:
                    for tol in _tolerances(icls, rtols, steps, explicit):
                        cases.append(_case(pspec, system, form, iname, icls, settings, tol,
                                           fault))
    return cases


def _built(pspec: ProblemSpec) -> tuple:
    """``(the problem, None)``, or, when it failed to build in its trial
    (:mod:`~integrator_bench.harness.matrix.builds`), ``(its class, (status,
    message))``: the class's declared formulations and span stand for the
    instance's."""
    try:
        return pspec.build(), None
    except ModelFault as fault:
        return registry.get_problem_class(pspec.name), (fault.status, str(fault))


def _preset_cases(matrix) -> list[Case]:
    """The cases of a preset's list (:attr:`Preset.listed`): ``(problem spec,
    formulation, integrator spec, rtol, h)`` each, those of an integrator not
    installed left out."""
    registered = registry.integrators()
    cases = []
    for problem, form, integrator, rtol, h in matrix:
        if spec_name(integrator) not in registered:
            continue
        (iname, icls, settings), = parse_integrator_spec(integrator)
        (pspec,) = parse_problem_spec(problem)
        built, fault = _built(pspec)
        tol = {"rtol": rtol} if rtol is not None else {"h": h}
        system = None if fault else formulated(built, form, problem)
        cases.append(_case(pspec, system, form, iname, icls, settings, tol, fault))
    return cases


def _case(pspec: ProblemSpec, system, form, iname, icls, settings, tol: dict,
          fault: tuple | None = None) -> Case:
    """The case of integrator ``iname`` (class ``icls``, ``settings``) on ``system``
    (the problem of ``pspec``, formulation ``form``) at ``tol`` (``rtol`` or
    ``h``), with why it is unsupported and the system's kind: the one place
    :func:`expand` and a preset's list make a case. With a ``fault``
    (its problem failed to build: no system) the case carries it instead."""
    if fault is not None:
        return Case(pspec.name, pspec.params, form, iname, settings=settings, fault=fault,
                    **tol)
    return Case(pspec.name, pspec.params, form, iname,
                unsupported=unsupported_reason(system, icls, form, **tol),
                settings=settings, kind=system.kind, **tol)


def variants(preset: str) -> list[str]:
    """The preset's integrator specs with settings whose integrator is installed."""
    registered = registry.integrators()
    return [v for v in PRESETS[preset].variants if spec_name(v) in registered]


def budget(preset: str, integrators=None, rtols=None, hs=None, problems=None,
           formulations=None) -> float | None:
    """The per-case time budget of a run of ``preset``, in seconds.

    The preset's ``budget_s`` holds for its own matrix, whose cases it was
    sized for. A run that names integrators, tolerances or steps is not that
    matrix (a tight ``--rtol`` can take far longer than the preset's loosest
    runs): it gets None, the general default timeout
    (:data:`integrator_bench.harness.run.limits.DEFAULT_BUDGET_S`), unless the
    user gives ``--timeout``. Naming problems or formulations keeps the budget,
    except for a preset that lists its cases (:attr:`Preset.listed`), whose
    budget is that list's.
    """
    if integrators or rtols or hs or (PRESETS[preset].listed and (problems or formulations)):
        return None
    return PRESETS[preset].budget_s


def left_out(preset: str) -> list[str]:
    """The registered problems a run of ``preset`` that names none leaves out:
    those whose first benchmark parameter set has more states than the
    preset's ``max_dimension``."""
    limit = PRESETS[preset].max_dimension
    if limit is None:
        return []
    out = []
    for name, problem in registry.built_problems().items():
        cls = builds.class_of(problem)
        params = cls.benchmark_parameters[0] if cls.benchmark_parameters else {}
        try:
            if builds.build(cls, params).dimension > limit:
                out.append(name)
        except (ProblemError, ModelFault):   # a broken plugin problem is reported when it runs
            continue
    return out


def _tolerances(icls, rtols, steps, explicit) -> list[dict]:
    """The runs of one integrator. By default the ``rtol`` ladder when it is
    adaptive and the ``h`` ladder when it takes a fixed step (both for a
    stepper with an error estimate). A tolerance or step the user names is
    given to every selected integrator: one that cannot run it is recorded
    ``unsupported`` with the reason, never silently left out."""
    if not (explicit["rtol"] or explicit["h"]):
        return ([dict(rtol=r) for r in rtols] if icls.adaptive else []) + \
               ([dict(h=h) for h in steps] if icls.takes_h() else [])
    return ([dict(rtol=r) for r in rtols] if explicit["rtol"] else []) + \
           ([dict(h=h) for h in steps] if explicit["h"] else [])
