"""One advice from start to end: candidates, reference, search, certificate.

:func:`advise` returns the answer as typed values (:class:`~.answer.Advice`;
its ``to_dict`` is the ``--json`` object, :mod:`.page` renders it as text and
HTML). Its ``status`` is
``answer`` (a line reached the target and held on the perturbed sets),
``partial`` (the budget ran out first: what was found so far, marked so),
``unverified`` (no line held on every perturbed set) or ``none`` (no line
reached the target, or no reference good enough: ``why`` says which).

One rule names the line, the report's: after the search the contenders (the
lines within twice the cheapest's CPU to the target) are timed again in
alternating rounds (:func:`_contenders`), the lines are ranked by their CPU to
the target as the report's table ranks them
(:func:`~integrator_bench.harness.ranking.reach.target_table`: interpolated
between a line's runs either side of the target), the robustness check takes
the leaders in that order, and the answer is
:func:`~integrator_bench.harness.ranking.reach.cheapest` of the table of the
lines that held (:func:`~.certificate.verdict`): the named line is the report's
and the run's summary's top line on the same records whenever that line holds
on the perturbed sets at its rtol (a line re-tightened there is ranked by its
tighter run). Ranking the lines by the CPU of each one's measured run at or
below the target instead (the advised run's) would name another line than the
report whenever that order and the crossing's differ. A winner is named only
when every contender's margin interval lies above 1; else the answer is a tie,
the named line the cheapest by the medians, the tied lines listed with the
runner-up's margin.
"""

from __future__ import annotations

import contextlib
import dataclasses
import re
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from integrator_bench.harness.ranking.cost import DEFAULT_COST, by_cost, check_cost
from integrator_bench.harness.advise import certificate, search
from integrator_bench.harness.advise.answer import Advice, Asked, Contenders, Cost
from integrator_bench.harness.advise.evidence import Robustness
from integrator_bench.harness.advise.candidates import candidates, stiffness_ruled
from integrator_bench.harness.contend.rounds import Contention, settle
from integrator_bench.harness.errors import BadInput
from integrator_bench.harness.ranking import reach
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.runner import Session, process_cpu, to_dataframe

#: the search's share of the budget the reference leaves; the rest is the robustness check's
SEARCH_SHARE = 0.75
#: the budget of an advice when none is given: a small model in a few minutes on 2 cores
DEFAULT_BUDGET = "5m"
#: the share of the budget a tighter reference may take, when one is needed
REFERENCE_SHARE = 0.25
#: the folder, beside the store, of the references the advice computes tighter
OWN_REFERENCES = "advice-reference"


@dataclass(frozen=True)
class Question:
    """What an advice is asked: the error to reach, how it is measured, the budget,
    the candidates' restriction, the robustness check and what lines are ranked by.

    Attributes
    ----------
    target : float
        The error to reach, in ``measure`` (``max``: over the output times;
        ``final``: at the final time), 0 < target < 1.
    measure : str
        ``--error``.
    budget_s : float
        Wall seconds for the whole advice (references, search and robustness
        check), a hard limit: past it nothing more is run (:func:`budget_warning`
        for one too small to suffice).
    integrators, formulations : list of str, optional
        Restrict the candidates (``-i``, ``-f``).
    perturbed : int
        Perturbed sets of the robustness check (0: none): of the parameters, or
        of the initial states of a model with no parameter to perturb.
    cost : str
        What the lines are ranked by (``--cost``,
        :data:`~integrator_bench.harness.ranking.cost.COSTS`): ``cpu`` or the
        method's ``work`` (a line's ``cpu_s`` figures then hold its
        work, :func:`~integrator_bench.harness.ranking.cost.by_cost`); the answer's
        ``ranked_by`` says which. The search spends its budget by CPU either way.
    """

    target: float
    measure: str = "max"
    budget_s: float = 300.0
    integrators: list | None = None
    formulations: list | None = None
    perturbed: int = certificate.PERTURBED_SETS
    cost: str = DEFAULT_COST


def advise(problem, question: Question, context: RunContext | None = None, log=None,
           started: float | None = None) -> Advice:
    """The cheapest line to ``question``'s target on ``problem`` (an instance), with
    its certificate.

    Parameters
    ----------
    problem : Problem
    question : Question
    context : RunContext, optional
        The store, backend, reference directory, resume policy, progress and
        command every run of the advice is made in (its ``skip`` and ``purpose``
        are the advice's own: every case runs, each stored as ``advise``); its
        rounds run in one :class:`~integrator_bench.harness.run.runner.Session`
        (one provenance row, the store read once). A store given as a path is
        opened once the candidates are known, so that bad input writes nothing.
    log : callable, optional
        Progress lines (standard error).
    started : float, optional
        The ``time.monotonic()`` the budget counts from (default: now; the command
        line's start).
    """
    check_cost(question.cost)
    started = time.monotonic() if started is None else started
    cpu0 = process_cpu()
    context = (context or RunContext(progress=False, resume=True)).replace(
        skip=False, purpose="advise")

    # the stiffness bound holds each candidate against the timeout its case will have
    # in the first round, when every candidate runs
    def first_round(n):
        return search.case_timeout(question.budget_s * SEARCH_SHARE, context.parallel, n)
    # the selection and its bad input first; the stiffness bound, which reads the
    # reference, once the reference is had within the budget
    cands, ruled_out = candidates(problem, question.integrators, question.formulations, None,
                                  context.reference_dir)
    warning = budget_warning(question.budget_s, question.perturbed)
    if warning and log:
        log(warning)
    with contextlib.ExitStack() as stack:
        session = stack.enter_context(Session(context))   # opened once the input is good
        # where a tighter reference goes, when one is needed: beside the store, never
        # among the committed references
        own = (Path(session.store.path).resolve().parent if session.store is not None
               else Path(stack.enter_context(tempfile.TemporaryDirectory()))) / OWN_REFERENCES
        clock = Clock(started, question.budget_s, cpu0)
        return _advise(problem, question, clock, (cands, ruled_out, first_round), session,
                       log, own)


def budget_warning(budget_s: float, perturbed: int) -> str | None:
    """One line when ``budget_s`` cannot suffice for a complete advice, with the
    figure it needs and why; None otherwise. A round of the search is started
    only with :data:`~.search.CASE_TIMEOUT`'s least per-case timeout left of the
    search's share (:data:`SEARCH_SHARE`), the robustness check only with as much
    left of the rest."""
    least = search.CASE_TIMEOUT[0]
    need = least / (1 - SEARCH_SHARE) if perturbed else least / SEARCH_SHARE
    if budget_s >= need:
        return None
    why = (f"the robustness check starts only with {least:g} s left of the "
           f"{1 - SEARCH_SHARE:.0%} the search leaves" if perturbed else
           f"a round of the search starts only with {least:g} s left of its "
           f"{SEARCH_SHARE:.0%} of the budget")
    return (f"ibench: advise: a budget of {budget_s:g} s cannot suffice, {need:.3g} s at "
            f"least are needed ({why}): the answer will be partial")


@dataclass
class Clock:
    """The advice's budget: its start (``time.monotonic()``), length and CPU at the start."""

    started: float
    budget_s: float
    cpu0: float

    @property
    def deadline(self) -> float:
        return self.started + self.budget_s

    def spent(self) -> float:
        return time.monotonic() - self.started

    def left(self) -> float:
        return self.deadline - time.monotonic()

    def ran_out(self, what: str, spent: float) -> str:
        """``the budget of B s did not suffice (S s spent): what``."""
        return f"the budget of {self.budget_s:g} s did not suffice ({spent:.3g} s spent): {what}"


def _advise(problem, question, clock, selected, session, log, own) -> Advice:
    budget_s, target, measure = clock.budget_s, question.target, question.measure
    ranked_by, perturbed = question.cost, question.perturbed
    cands, ruled_out, first_round = selected
    asked = Asked(problem.label(), target, measure, ranked_by,
                  tuple(problem.error_components or problem.components), budget_s)
    ruled_out = list(ruled_out)
    candidates_n = len(cands) + len(ruled_out)
    robustness_cases = 0

    def cost(found=None) -> Cost:
        search_cases = found.cases if found else 0
        return Cost(clock.spent(), process_cpu() - clock.cpu0,
                    search_cases + robustness_cases, search_cases, robustness_cases,
                    found.rounds if found else 0, found.wall_s if found else 0.0,
                    found.cpu_s if found else 0.0)

    def no_reference(why) -> Advice:
        spent = cost()
        out_of_time = spent.wall_s >= budget_s
        return Advice(asked, candidates_n, tuple(ruled_out),
                      "partial" if out_of_time else "none", spent,
                      clock.ran_out(why, spent.wall_s) if out_of_time else why)

    try:
        reference = certificate.reference_check(
            problem, target, session.context.reference_dir, limit=max(clock.left(), 0.0),
            log=log)
    except certificate.TooFewDigits as exc:
        try:  # the stored one is not good enough: computed tighter, in the advice's folder
            reference = certificate.tighter_reference(
                problem, target, own, limit=max(min(budget_s * REFERENCE_SHARE, clock.left()),
                                                0.0), log=log)
        except certificate.NoGoodReference as tighter:
            return no_reference(f"{exc}; {tighter}")
        session.context = session.context.replace(reference_dir=own)
    except certificate.NoGoodReference as exc:
        return no_reference(str(exc))
    cands, stiff = stiffness_ruled(problem, cands, first_round, session.context.reference_dir)
    ruled_out += stiff
    # the search's share of what the reference (and the stiffness bound) left
    found = search.search(problem, cands, target, measure, clock.left() * SEARCH_SHARE,
                          session, log=log)
    contenders = _contenders(found, question, session, clock, log)
    found.records = by_cost(found.records, ranked_by)
    points_of = search.points_by_line(found.records, measure)
    ranked = certificate.ranking(found, lambda ln: points_of.get(ln.key, search.NO_POINTS))
    families = certificate.family_bests(ranked)
    by_key = {c.key: c for c in cands}

    out_of_budget, robust_records = [], []

    def run(cases):
        nonlocal robustness_cases
        left = clock.left()
        if left <= search.CASE_TIMEOUT[0]:
            out_of_budget.append(len(cases))
            return to_dataframe([])
        robustness_cases += len(cases)
        df = session.run(cases, budget_s=min(max(search.CASE_TIMEOUT[0], left / 2), left),
                         deadline=clock.deadline)
        if len(df) < len(cases) and clock.left() <= 0:   # cut at the budget's end
            out_of_budget.append(len(cases) - len(df))
        df = by_cost(df, ranked_by)
        robust_records.append(df)
        return df

    any_reached = any(e.run is not None for e in ranked)
    robust = certificate.robustness(problem, ranked, by_key, target, measure, perturbed, run) \
        if any_reached and perturbed else Robustness(
            None, why="not asked for (--perturbed 0)" if any_reached
            else "no line reached the target")
    # every line and every holder with its verdict
    verdicts = robust.verdicts()
    ranked = [dataclasses.replace(e, robustness=verdicts.get(e.key)) for e in ranked]
    if robust.holders is not None:
        robust = dataclasses.replace(robust, holders=tuple(
            dataclasses.replace(e, robustness=verdicts.get(e.key)) for e in robust.holders))
    reached = [e for e in ranked if e.run is not None]
    partial = "; ".join(filter(None, [found.partial, out_of_budget and (
        "the robustness check was not finished")]))
    # the lines that may be named: those that held; without one, the search's lines
    # when the check was not asked for or could not be made, or (the budget spent)
    # those that did not fail it
    pool = list(robust.holders or ()) or [
        e for e in reached if robust.why or partial and verdicts.get(e.key) != "failed"]
    top = certificate.verdict(_on_the_model(found.records, robust_records), pool, target,
                              measure)
    spent = cost(found)
    if partial:
        partial = clock.ran_out(partial, spent.wall_s)
    answer = Advice(asked, candidates_n, tuple(ruled_out), "answer", spent,
                    reference=reference, lines=tuple(ranked), families=families,
                    robustness=robust, contenders=contenders)
    if top is None:
        why = "no line reached the target" if not reached else \
            "no line kept its error at or below the target on every perturbed set"
        return dataclasses.replace(
            answer, status="partial" if partial else "none" if not reached else "unverified",
            why="; ".join(filter(None, [partial, why])))

    # the pool's lines at their CPU to the target in the verdict's table (a line
    # re-tightened on the perturbed sets: at the rtol it held at, in the table too)
    named = {e.name: e for e in pool}
    tag = reach.tag(target)
    for row in top["table"].to_dict("records"):
        e = named.get(reach.line_name(row))
        if e is not None and row[f"how_{tag}"] != "not reached":
            named[reach.line_name(row)] = dataclasses.replace(
                e, to_target=float(row[f"cpu_{tag}"]), how=row[f"how_{tag}"])
    winner = named[reach.line_name(top)]
    up = top["runner_up"]
    in_pool = {e.key: named[e.name] for e in pool}
    return dataclasses.replace(
        answer, status="partial" if partial else "answer", why=partial or None,
        lines=tuple(in_pool.get(e.key, e) for e in ranked),
        winner=winner, runner_up=named[up["line"]] if up else None,
        margin=certificate.margin_of(top), verdict=top["verdict"], tied=tuple(top["tied"]),
        same_code=top["same_code"],
        verified_sets=len(robust.sets) if winner.robustness == "holds" else 0,
        reproduce=certificate.reproduction(problem, by_key[winner.key], winner.run.rtol))


#: the share of the advice's CPU so far (its references and search) that timing the
#: contenders again may take (:func:`_contenders`), as ``ibench run`` gives them a
#: tenth of the matrix's (:data:`~integrator_bench.harness.contend.rounds.CPU_SHARE`)
CONTENDERS_SHARE = 0.10


def _contenders(found, question, session, clock, log) -> Contenders:
    """The search's contenders timed again before the advice ranks them
    (:func:`~integrator_bench.harness.contend.rounds.settle` at the advice's
    target and error): the lines within
    :data:`~integrator_bench.harness.ranking.margin.BAND` of the cheapest, in
    alternating rounds, until their margins' intervals are decided, within
    :data:`CONTENDERS_SHARE` of the advice's CPU so far and its deadline, on the
    context's parallel processes. Each record timed again is stored, superseding
    (:meth:`~integrator_bench.harness.run.runner.Session.supersede`), and replaces
    its earlier self in ``found.records``. Under ``--cost work`` nothing is timed:
    the work is counted, not timed, and has no noise."""
    if question.cost != "cpu":
        return Contenders(why=f"not timed again: ranked by {question.cost}, which is "
                              "counted, not timed")
    if not len(found.records):
        return Contenders(why="no record to time again")
    cap = CONTENDERS_SHARE * (process_cpu() - clock.cpu0)
    how = Contention(targets=(question.target,), measure=question.measure, cpu_cap_s=cap,
                     jobs=session.context.parallel, limits=session.context.limits,
                     deadline=clock.deadline)
    settled = settle(found.records, found.ran, session.supersede, how, log=log)
    found.records = settled.records
    return Contenders(settled.contests, settled.retimed, settled.blocks, settled.cpu_s, cap,
                      settled.stopped if settled.contests else None, settled.left_open)


def _on_the_model(records: pd.DataFrame, robust: list) -> pd.DataFrame:
    """The search's ``records`` with the robustness check's runs on the model itself
    (a line re-tightened: its tighter run), not those on the perturbed sets."""
    if not len(records):
        return records
    own = [df[df["params"].isin(set(records["params"]))] for df in robust if len(df)]
    own = [df for df in own if len(df)]
    return pd.concat([records, *own], ignore_index=True) if own else records


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


def exit_status(answer: Advice) -> int:
    """0 for a complete, verified answer; 1 otherwise (partial, unverified, none)."""
    return 0 if answer.status == "answer" else 1

