"""One advice from start to end: candidates, reference, search, certificate.

:func:`advise` returns the answer as one JSON-ready dict (the ``--json``
object; :mod:`.page` renders it as text and HTML). Its ``status`` is
``answer`` (a line reached the target and held on the perturbed sets),
``partial`` (the budget ran out first: what was found so far, marked so),
``unverified`` (no line held on every perturbed set) or ``none`` (no line
reached the target, or no reference good enough: ``why`` says which).
"""

from __future__ import annotations

import contextlib
import os
import re
import tempfile
import time
from pathlib import Path

from integrator_bench.harness.advise import certificate, search
from integrator_bench.harness.advise.candidates import candidates
from integrator_bench.harness.errors import BadInput
from integrator_bench.harness.run.runner import run_matrix
from integrator_bench.harness.model.store import Store

#: the search's share of the budget; the rest is the robustness check's
SEARCH_SHARE = 0.75
#: the budget of an advice when none is given: a small model in a few minutes on 2 cores
DEFAULT_BUDGET = "5m"
#: the share of the budget a tighter reference may take, when one is needed
REFERENCE_SHARE = 0.25
#: the folder, beside the store, of the references the advice computes tighter
OWN_REFERENCES = "advice-reference"


def advise(problem, target: float, measure: str = "max", budget_s: float = 300.0,
           integrators=None, formulations=None, store=None, jobs=None, dask=None,
           reference_dir=None, resume: bool = True, perturbed: int = certificate.PERTURBED_SETS,
           progress: bool = False, command: str | None = None, log=None) -> dict:
    """The cheapest line to ``target`` on ``problem`` (an instance), with its certificate.

    Parameters
    ----------
    problem : Problem
    target : float
        The error to reach, in ``measure`` (``max``: over the output times;
        ``final``: at the final time), 0 < target < 1.
    budget_s : float
        Wall seconds for the whole advice (search and robustness check).
    integrators, formulations : list of str, optional
        Restrict the candidates (``-i``, ``-f``).
    store : Store or path, optional
        Where every run is recorded (a path is opened once the candidates are
        known, so that bad input writes nothing).
    jobs, dask, reference_dir, progress, command
        As :func:`~integrator_bench.harness.run.runner.run_matrix` takes them.
    resume : bool
        Reuse the store's records of the same cases and code version.
    perturbed : int
        Perturbed sets of the robustness check (0: none): of the parameters, or
        of the initial states of a model with no parameter to perturb.
    log : callable, optional
        Progress lines (standard error).
    """
    started = time.monotonic()
    # the stiffness bound holds each candidate against the timeout its case will have
    # in the first round, when every candidate runs
    parallel = jobs or os.cpu_count() or 1

    def first_round(n):
        return search.case_timeout(budget_s * SEARCH_SHARE, parallel, n)
    cands, ruled_out = candidates(problem, integrators, formulations, first_round,
                                  reference_dir)
    with contextlib.ExitStack() as stack:
        if store is not None and not isinstance(store, Store):  # opened once the input is good
            store = stack.enter_context(Store(Path(store)))
        # where a tighter reference goes, when one is needed: beside the store, never
        # among the committed references
        own = (Path(store.path).resolve().parent if store is not None
               else Path(stack.enter_context(tempfile.TemporaryDirectory()))) / OWN_REFERENCES
        return _advise(problem, target, measure, budget_s, cands, ruled_out, store, jobs, dask,
                       reference_dir, resume, perturbed, progress, command, log, started, own)


def _advise(problem, target, measure, budget_s, cands, ruled_out, store, jobs, dask,
            reference_dir, resume, perturbed, progress, command, log, started, own) -> dict:
    answer = {"problem": problem.label(), "target": target, "measure": measure,
              "scored": list(problem.error_components or problem.components),
              "budget_s": budget_s, "candidates": len(cands) + len(ruled_out),
              "ruled_out": [vars(r) for r in ruled_out]}
    try:
        answer["reference"] = certificate.reference_check(problem, target, reference_dir,
                                                          limit=budget_s)
    except certificate.TooFewDigits as exc:
        try:  # the stored one is not good enough: computed tighter, in the advice's folder
            answer["reference"] = certificate.tighter_reference(
                problem, target, own, limit=budget_s * REFERENCE_SHARE, log=log)
        except certificate.NoGoodReference as tighter:
            return {**answer, "status": "none", "why": f"{exc}; {tighter}"}
        reference_dir = own
    except certificate.NoGoodReference as exc:
        return {**answer, "status": "none", "why": str(exc)}
    found = search.search(problem, cands, target, measure, budget_s * SEARCH_SHARE
                          - (time.monotonic() - started), store=store, jobs=jobs, dask=dask,
                          reference_dir=reference_dir, resume=resume, progress=progress,
                          command=command, log=log)
    points_of = search.points_by_line(found.records, measure)
    ranked = certificate.ranking(found, lambda ln: points_of.get(ln.key, search.NO_POINTS))
    answer["lines"] = ranked
    answer["families"] = {f: {"integrator": e["integrator"], "formulation": e["formulation"],
                              "rtol": e["run"]["rtol"], "cpu_s": e["run"]["cpu_s"]}
                          for f, e in certificate.family_bests(ranked).items()}
    by_key = {c.key: c for c in cands}

    out_of_budget = []

    def run(cases):
        left = budget_s - (time.monotonic() - started)
        if left <= search.CASE_TIMEOUT[0]:
            out_of_budget.append(len(cases))
            return run_matrix([], store=None, progress=False)
        return run_matrix(cases, store=store, jobs=jobs, dask=dask, resume=resume,
                          timeout=max(search.CASE_TIMEOUT[0], left / 2), progress=progress,
                          reference_dir=reference_dir, command=command, skip=False,
                          purpose="advise")

    reached = [e for e in ranked if e["run"] is not None]
    robust = certificate.robustness(problem, ranked, by_key, target, measure, perturbed, run) \
        if reached and perturbed else {"perturbed": None, "sets": [], "checked": [],
                                       "holds": None,
                                       "why": "not asked for (--perturbed 0)" if reached
                                       else "no line reached the target"}
    answer["robustness"] = {k: v for k, v in robust.items() if k != "holds"}
    partial = "; ".join(filter(None, [found.partial, out_of_budget and (
        f"the budget of {budget_s:g} s ran out before the robustness check was done")]))
    winner = robust["holds"] or (reached[0] if reached and robust["why"] else None)
    answer["cost"] = {"wall_s": time.monotonic() - started, "search_wall_s": found.wall_s,
                      "search_cpu_s": found.cpu_s, "cases": found.cases, "rounds": found.rounds}
    if winner is None:
        why = "no line reached the target" if not reached else \
            "no line kept its error at or below the target on every perturbed set"
        return {**answer, "status": "partial" if partial else
                "none" if not reached else "unverified",
                "why": "; ".join(filter(None, [partial, why]))}
    def key(e):
        return e["integrator"], e["formulation"]

    # the runner-up: another line that held (at the rtol it held at), or one not checked
    line, checked = key(winner), {key(c) for c in robust["checked"]}
    rest = sorted([e for e in robust.get("holders", []) if key(e) != line]
                  + [e for e in reached if key(e) not in checked and key(e) != line],
                  key=lambda e: e["run"]["cpu_s"])
    answer["winner"] = winner
    answer["runner_up"] = rest[0] if rest else None
    answer["margin"] = certificate.margin(winner, rest[0]) if rest else None
    answer["verified_sets"] = len(robust["sets"]) if robust["holds"] is winner else 0
    if winner.get("retightened_from"):  # re-calibrated on the perturbed sets: in the table too
        answer["lines"] = [winner if key(e) == line else e for e in answer["lines"]]
    answer["reproduce"] = certificate.reproduction(
        problem, by_key[(winner["integrator"], winner["formulation"])], winner["run"]["rtol"])
    answer["status"] = "partial" if partial else "answer"
    answer["why"] = partial or None
    return answer


_UNITS = {"": 1.0, "s": 1.0, "m": 60.0, "min": 60.0, "h": 3600.0}


def parse_duration(text: str) -> float:
    """``300``, ``300s``, ``10m``, ``1.5h`` -> seconds; :class:`BadInput` otherwise
    (not a positive finite duration)."""
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*([a-z]*)\s*", str(text))
    if m is None or m.group(2) not in _UNITS or not float(m.group(1)) > 0 \
            or float(m.group(1)) == float("inf"):
        raise BadInput(f"--budget {text!r} is not a positive duration; valid: seconds, or a "
                       "number with s, m or h (300, 300s, 10m, 1h)")
    return float(m.group(1)) * _UNITS[m.group(2)]


def exit_status(answer: dict) -> int:
    """0 for a complete, verified answer; 1 otherwise (partial, unverified, none)."""
    return 0 if answer["status"] == "answer" else 1

