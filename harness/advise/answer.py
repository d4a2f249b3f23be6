"""The advice's answer as typed values, turned into its JSON object only at the edge.

:class:`Advice` is what :func:`~integrator_bench.harness.advise.advice.advise`
returns; :meth:`Advice.to_dict` is the ``--json`` object and ``advice.json``
(a contract: ``docs/advise.md`` and ``docs/command-line.md`` describe its keys),
and :mod:`.page` renders the same values as text and HTML. The lines of the
ranking (``lines``, ``winner``, ``runner_up``) are the certificate's entries
(:func:`~integrator_bench.harness.advise.certificate.ranking`), kept as they
are built there.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass


@dataclass(frozen=True)
class Cost:
    """What the advice cost: from the command's start to the answer (references,
    search and robustness check; the CPU of this process and its workers), its
    cases and rounds, and the search's own wall and CPU seconds."""

    wall_s: float
    cpu_s: float
    cases: int
    search_cases: int
    robustness_cases: int
    rounds: int = 0
    search_wall_s: float = 0.0
    search_cpu_s: float = 0.0

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class Margin:
    """The runner-up's CPU over the winner's, and whether the two tie (None: a
    spread unknown, a run timed once)."""

    ratio: float
    tie: bool | None

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class FamilyBest:
    """The best line of a family that reached the target."""

    integrator: str
    formulation: str
    rtol: float
    cpu_s: float

    def to_dict(self) -> dict:
        return asdict(self)


#: an advice's statuses: a verified answer, a partial one (the budget ran out first),
#: none that held on every perturbed set, none at all
STATUSES = ("answer", "partial", "unverified", "none")


@dataclass(frozen=True)
class Asked:
    """What the answer answers, as it says it: the problem's label, the target and
    its measure, what lines are ranked by, the scored components and the budget."""

    problem: str
    target: float
    measure: str
    ranked_by: str
    scored: tuple
    budget_s: float


@dataclass(frozen=True)
class Advice:
    """One advice's answer (module docstring).

    Attributes
    ----------
    asked : Asked
    candidates : int
        Lines considered, the ruled-out ones included.
    ruled_out : tuple of dict
        The lines ruled out before running, each with why.
    status : str
        One of :data:`STATUSES`.
    cost : Cost
    why : str or None
        Why the answer is partial, unverified or none.
    reference : dict or None
        The reference's verification (None: no good one, the advice stopped there).
    lines : list of dict
        Every line of the search, best first (the certificate's entries).
    families : dict
        Family -> :class:`FamilyBest`.
    robustness : dict or None
        The robustness check (its perturbed sets, what was checked, why not).
    winner, runner_up : dict or None
        Entries of ``lines`` (the winner's ``run`` at the rtol it held at).
    margin : Margin or None
    verified_sets : int or None
        Perturbed sets the winner held on (0 when it was not checked).
    reproduce : dict or None
        What a user needs to get the winner's error outside the harness.
    """

    asked: Asked
    candidates: int
    ruled_out: tuple
    status: str
    cost: Cost
    why: str | None = None
    reference: dict | None = None
    lines: list | None = None
    families: dict | None = None
    robustness: dict | None = None
    winner: dict | None = None
    runner_up: dict | None = None
    margin: Margin | None = None
    verified_sets: int | None = None
    reproduce: dict | None = None

    def __post_init__(self):
        if self.status not in STATUSES:
            raise ValueError(f"status {self.status!r}; valid: {', '.join(STATUSES)}")

    def to_dict(self) -> dict:
        """The ``--json`` object: its keys in the order they have always had (an
        advice without a reference stops after ``cost``; one without a winner has
        no ``winner`` ... ``reproduce``)."""
        a = self.asked
        out = {"problem": a.problem, "target": a.target, "measure": a.measure,
               "ranked_by": a.ranked_by, "scored": list(a.scored), "budget_s": a.budget_s,
               "candidates": self.candidates, "ruled_out": list(self.ruled_out)}
        if self.reference is None:
            return {**out, "status": self.status, "cost": self.cost.to_dict(), "why": self.why}
        out.update(reference=self.reference, lines=self.lines,
                   families={f: b.to_dict() for f, b in (self.families or {}).items()},
                   robustness=self.robustness, cost=self.cost.to_dict())
        if self.winner is not None:
            out.update(winner=self.winner, runner_up=self.runner_up,
                       margin=self.margin.to_dict() if self.margin else None,
                       verified_sets=self.verified_sets, reproduce=self.reproduce)
        out.update(status=self.status, why=self.why)
        return out
