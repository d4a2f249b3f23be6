"""The advice's answer as typed values, turned into its JSON object only at the edge.

:class:`Advice` is what :func:`~integrator_bench.harness.advise.advice.advise`
returns; :meth:`Advice.to_dict` is the ``--json`` object and ``advice.json``
(a contract: ``docs/advise.md`` and ``docs/command-line.md`` describe its keys),
and :mod:`.page` renders the same values as text and HTML. The lines of the
ranking (``lines``, ``winner``, ``runner_up``), the reference's facts, the
robustness check and the reproduction recipe are the certificate's parts
(:mod:`.evidence`), each turned into its JSON by its own ``to_dict``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from integrator_bench.harness.advise.evidence import (LineEntry, Reference, Reproduction,
                                                      Robustness)


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
    """The best line of a family that reached the target: its ``label`` (the
    integrator with its changed settings, JSON ``integrator``), formulation, rtol
    and CPU."""

    label: str
    formulation: str
    rtol: float
    cpu_s: float

    def to_dict(self) -> dict:
        return {"integrator": self.label, "formulation": self.formulation, "rtol": self.rtol,
                "cpu_s": self.cpu_s}


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
    ruled_out : tuple of RuledOut
        The lines ruled out before running, each with why
        (:class:`~integrator_bench.harness.advise.candidates.RuledOut`).
    status : str
        One of :data:`STATUSES`.
    cost : Cost
    why : str or None
        Why the answer is partial, unverified or none.
    reference : Reference or None
        The reference's verification (None: no good one, the advice stopped there).
    lines : tuple of LineEntry
        Every line of the search, best first (the certificate's entries).
    families : dict
        Family -> :class:`FamilyBest`.
    robustness : Robustness or None
        The robustness check (its perturbed sets, what was checked, why not).
    winner, runner_up : LineEntry or None
        Entries of ``lines`` (the winner's ``run`` at the rtol it held at).
    margin : Margin or None
    verified_sets : int or None
        Perturbed sets the winner held on (0 when it was not checked).
    reproduce : Reproduction or None
        What a user needs to get the winner's error outside the harness.
    """

    asked: Asked
    candidates: int
    ruled_out: tuple
    status: str
    cost: Cost
    why: str | None = None
    reference: Reference | None = None
    lines: tuple = ()
    families: dict | None = None
    robustness: Robustness | None = None
    winner: LineEntry | None = None
    runner_up: LineEntry | None = None
    margin: Margin | None = None
    verified_sets: int | None = None
    reproduce: Reproduction | None = None

    def __post_init__(self):
        if self.status not in STATUSES:
            raise ValueError(f"status {self.status!r}; valid: {', '.join(STATUSES)}")

    def is_winner(self, entry: LineEntry) -> bool:
        """Whether ``entry`` (one of :attr:`lines`) is the winner's line."""
        return self.winner is not None and entry.key == self.winner.key

    def is_runner_up(self, entry: LineEntry) -> bool:
        """Whether ``entry`` (one of :attr:`lines`) is the runner-up's line."""
        return self.runner_up is not None and entry.key == self.runner_up.key

    def to_dict(self) -> dict:
        """The ``--json`` object: its keys in the order they have always had (an
        advice without a reference stops after ``cost``; one without a winner has
        no ``winner`` ... ``reproduce``)."""
        a = self.asked
        out = {"problem": a.problem, "target": a.target, "measure": a.measure,
               "ranked_by": a.ranked_by, "scored": list(a.scored), "budget_s": a.budget_s,
               "candidates": self.candidates, "ruled_out": [asdict(r) for r in self.ruled_out]}
        if self.reference is None:
            return {**out, "status": self.status, "cost": self.cost.to_dict(), "why": self.why}
        out.update(reference=self.reference.to_dict(), lines=[e.to_dict() for e in self.lines],
                   families={f: b.to_dict() for f, b in (self.families or {}).items()},
                   robustness=_dict_of(self.robustness), cost=self.cost.to_dict())
        if self.winner is not None:
            out.update(winner=self.winner.to_dict(), runner_up=_dict_of(self.runner_up),
                       margin=_dict_of(self.margin), verified_sets=self.verified_sets,
                       reproduce=_dict_of(self.reproduce))
        out.update(status=self.status, why=self.why)
        return out


def _dict_of(part) -> dict | None:
    """``part.to_dict()``, or None for no part."""
    return None if part is None else part.to_dict()
