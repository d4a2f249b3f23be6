"""The certificate's parts as typed values: a line's measured run, its entry in the
ranking, the robustness check, the reference's facts and the reproduction recipe.

:mod:`.certificate` builds them, :mod:`.advice` picks the winner and the runner-up
among them, :mod:`.page` reads them as attributes; each one's ``to_dict`` is its
part of the ``--json`` object (:meth:`.answer.Advice.to_dict`), with the keys, in
the order, that ``docs/advise.md`` describes. A line's display name (its
integrator with its changed settings,
:attr:`~integrator_bench.harness.advise.candidates.Candidate.label`) is the
attribute ``label`` and the JSON key ``integrator``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass


@dataclass(frozen=True)
class Run:
    """One measured run of a line (:func:`~.certificate.run_facts`).

    Attributes
    ----------
    rtol, error, cpu_s : float
        The run's tolerance, its error in the advice's measure and its CPU seconds
        (the median of the timed solves; the method's work under ``--cost work``).
    cpu_s_iqr : float or None
        The interquartile range of the timed solves (None: timed once).
    repeat : float or None
        Timed solves.
    case_id : str or None
        The record's case.
    nfev, njev, nlu, nsteps, nreject : int or None
        The run's counters (None: the integrator does not count it).
    drift_pos, drift_vel : float or None
        The constraint drift of a constrained formulation.
    """

    rtol: float
    error: float
    cpu_s: float
    cpu_s_iqr: float | None = None
    repeat: float | None = None
    case_id: str | None = None
    nfev: int | None = None
    njev: int | None = None
    nlu: int | None = None
    nsteps: int | None = None
    nreject: int | None = None
    drift_pos: float | None = None
    drift_vel: float | None = None

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class LineEntry:
    """One line of the search as the ranking shows it (:func:`~.certificate.ranking`).

    Attributes
    ----------
    label : str
        The integrator with its changed settings (JSON ``integrator``).
    formulation, family : str
    runs : int
        Its runs in the search with a usable error.
    calibrated : bool
        Its rtol calibrated to the target.
    note : str or None
        Why it left the search.
    points : tuple of (float, float, float)
        ``(rtol, error, cpu_s)`` of each usable run.
    run : Run or None
        Its cheapest run at or below the target (None: it reached it nowhere).
    rank : int or None
        By its CPU to the target (a line that reached the target only): the
        order of the report's table of the advice's records
        (:func:`~integrator_bench.harness.ranking.reach.target_table`).
    to_target : float or None
        That CPU to the target (a line that reached the target only): the
        report's crossing, interpolated between its runs either side of the
        target, or the CPU of ``run`` as an upper bound when its loosest run
        reached it already (for a line re-tightened on the perturbed sets,
        its tighter run's).
    how : str or None
        How ``to_target`` was had: ``interpolated``, ``at a point`` or ``at
        most`` (:data:`~integrator_bench.harness.ranking.reach.HOW`).
    best_error : float or None
        Its least error (a line that did not reach the target only).
    retightened_from : float or None
        The rtol it missed at on a perturbed set, when it held at ``run.rtol`` tighter.
    robustness : str or None
        Its last robustness check: ``holds``, ``failed``, ``unfinished``, or None
        when it was not checked.
    """

    label: str
    formulation: str
    family: str
    runs: int = 0
    calibrated: bool = False
    note: str | None = None
    points: tuple = ()
    run: Run | None = None
    rank: int | None = None
    to_target: float | None = None
    how: str | None = None
    best_error: float | None = None
    retightened_from: float | None = None
    robustness: str | None = None

    @property
    def key(self) -> tuple:
        """``(label, formulation)``: its candidate's
        :attr:`~integrator_bench.harness.advise.candidates.Candidate.key`."""
        return self.label, self.formulation

    @property
    def name(self) -> str:
        """``label (formulation)``: how the answers name a line
        (:func:`~integrator_bench.harness.ranking.reach.line_name`)."""
        return f"{self.label} ({self.formulation})"

    def to_dict(self) -> dict:
        out = {"integrator": self.label, "formulation": self.formulation,
               "family": self.family, "runs": self.runs, "calibrated": self.calibrated,
               "note": self.note, "points": [list(p) for p in self.points],
               "run": None if self.run is None else self.run.to_dict()}
        if self.run is None:
            out.update(best_error=self.best_error)
        else:
            out.update(rank=self.rank, to_target=self.to_target, how=self.how)
        if self.retightened_from is not None:
            out.update(retightened_from=self.retightened_from)
        out.update(robustness=self.robustness)
        return out


@dataclass(frozen=True)
class CheckRun:
    """One run of a robustness check: the options its set changed, its error (None:
    not had) and its status (``ok``, a failure's, or ``not run``)."""

    params: dict
    error: float | None
    status: str

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class Checked:
    """A line checked at one rtol on every perturbed set: ``holds`` is True, False,
    or None when a run is missing (the budget spent)."""

    label: str
    formulation: str
    rtol: float
    holds: bool | None
    runs: tuple

    @property
    def key(self) -> tuple:
        return self.label, self.formulation

    def to_dict(self) -> dict:
        return {"integrator": self.label, "formulation": self.formulation, "rtol": self.rtol,
                "holds": self.holds, "runs": [r.to_dict() for r in self.runs]}


@dataclass(frozen=True)
class Perturbed:
    """What the robustness check perturbed and by how much
    (:func:`~.certificate.perturbed_facts`): ``what`` (parameters, initial states,
    or None), the option ``names``, the ``relative`` change at most and the
    ``seed``; for initial states the ``rule`` and each one's ``start`` and absolute
    ``scale`` (``starts``: name -> ``{"start", "scale"}``)."""

    what: str | None
    names: tuple
    relative: float
    seed: int
    rule: str | None = None
    starts: dict | None = None

    def to_dict(self) -> dict:
        out = {"what": self.what, "names": list(self.names), "relative": self.relative,
               "seed": self.seed}
        if self.rule is not None:
            out.update(rule=self.rule, starts=self.starts)
        return out


#: a line's robustness in the ranking, from its last check's ``holds``
ROBUSTNESS_WORDS = {True: "holds", False: "failed", None: "unfinished"}


@dataclass(frozen=True)
class Robustness:
    """The robustness check (:func:`~.certificate.robustness`).

    Attributes
    ----------
    perturbed : Perturbed or None
        None when the check was not asked for or no line reached the target.
    sets : tuple of dict
        The options each perturbed set changed.
    checked : tuple of Checked
        Per line and rtol, in the order tried.
    holders : tuple of LineEntry or None
        The lines that hold, in the order checked (rank order; a re-tightened
        one with its new run); None when no check was made. The advice names
        the cheapest of them (:func:`~.certificate.verdict`).
    why : str or None
        Why no check was made.
    """

    perturbed: Perturbed | None
    sets: tuple = ()
    checked: tuple = ()
    holders: tuple | None = None
    why: str | None = None

    @property
    def holds(self) -> LineEntry | None:
        """The first holder in rank order (None: none held, or nothing could be
        checked)."""
        return self.holders[0] if self.holders else None

    def verdicts(self) -> dict:
        """``(label, formulation)`` -> ``holds``, ``failed`` or ``unfinished`` (the
        budget spent) for every line checked, from its last try (a re-tightened
        one's)."""
        return {c.key: ROBUSTNESS_WORDS[c.holds] for c in self.checked}

    def to_dict(self) -> dict:
        out = {"perturbed": None if self.perturbed is None else self.perturbed.to_dict(),
               "sets": list(self.sets), "checked": [c.to_dict() for c in self.checked]}
        if self.holders is not None:
            out.update(holders=[h.to_dict() for h in self.holders])
        out.update(why=self.why)
        return out


@dataclass(frozen=True)
class ReferenceMethod:
    """One method of the reference: as the reference stores it (``given``: the exact
    solution's ``method``, or ``formulation``, ``integrator`` and ``rtol``), its
    ``family`` (exact, explicit or implicit) and its ``code`` (the integrator's
    declared ``event_locator``)."""

    given: dict
    family: str
    code: str

    @property
    def name(self) -> str:
        return self.given.get("integrator", self.given.get("method", "?"))

    @property
    def rtol(self) -> float | None:
        return self.given.get("rtol")

    def to_dict(self) -> dict:
        return {**self.given, "family": self.family, "code": self.code}


@dataclass(frozen=True)
class Reference:
    """The reference's facts (:func:`~.certificate.reference_check`): its ``id``,
    ``methods``, the digits its methods agree to on the scored components and the
    digits the target needs; ``tightened``: how much tighter than the stored one's
    its methods ran (None: the stored one)."""

    id: str
    methods: tuple
    claimed_digits: int
    needed_digits: int
    tightened: float | None = None

    def to_dict(self) -> dict:
        out = {"id": self.id, "methods": [m.to_dict() for m in self.methods],
               "claimed_digits": self.claimed_digits, "needed_digits": self.needed_digits}
        if self.tightened is not None:
            out.update(tightened=self.tightened)
        return out


@dataclass(frozen=True)
class OutputTimes:
    """The output times of the reproduction: first, last, how many, ``uniform`` or
    ``given`` spacing."""

    first: float
    last: float
    count: int
    spacing: str


@dataclass(frozen=True)
class Reproduction:
    """What a user needs to get the winner's error outside the harness
    (:func:`~.certificate.reproduction`): the integrator (its registry name) and
    every setting's value, the formulation (its kind, states, variables and the
    scored ones), rtol and atol's scale per state, the Jacobian's source, the
    output times, the loop the timed solve runs and the library call (the
    integrator's own description, None for one implemented in this project)."""

    integrator: str
    settings: dict
    formulation: str
    system_kind: str
    states: int
    rtol: float
    atol: str
    atol_scale_min: float
    atol_scale_max: float
    atol_scale: tuple
    jacobian: str
    loop: str | None
    library_call: dict | None
    output_times: OutputTimes
    variables: tuple
    scored: tuple

    def to_dict(self) -> dict:
        return {**asdict(self), "atol_scale": list(self.atol_scale),
                "variables": list(self.variables), "scored": list(self.scored)}
