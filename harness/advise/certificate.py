"""The certificate: the evidence an advice is shown with, as typed values
(:mod:`.evidence`).

* **Reference**: the problem's verified reference
  (:mod:`integrator_bench.harness.measure.references`): two independent methods (or the
  exact solution and a tight numerical one) agreeing to at least
  :data:`EXTRA_DIGITS` digits beyond the target. A reference that is not that
  good stops the advice (:class:`NoGoodReference`).
* **Ranking** (:func:`ranking`): each line that reached the target, by its
  CPU to reach it as the report ranks it (the crossing of
  :func:`integrator_bench.harness.ranking.reach.target_table`), with its
  cheapest measured run at or below it (the advised rtol): its error, CPU
  (median and interquartile range of the timed solves), counters and drift.
  The **verdict** (:func:`verdict`): the report's rule,
  :func:`integrator_bench.harness.ranking.reach.cheapest`, on the lines that
  may be named: a winner only when every contender's margin interval lies
  above 1, else a tie with those whose interval reaches 1 or could not be
  measured; the runner-up and its margin (:func:`margin_of`); the best line of
  each family.
* **Robustness** (:func:`robustness`): the leading lines re-run at their
  advised rtol on :data:`PERTURBED_SETS` parameter sets, each continuous
  parameter moved by up to :data:`PERTURBATION` of its value within its range
  (seeded: the same sets every time), each against its own reference. A model
  with no parameter to perturb (an FMU whose only inputs are its states' start
  values) is perturbed in its settable initial states instead
  (:func:`perturbation`). The advice holds only for a line whose error stays at
  or below the target on every set; the verdict is taken over the lines that
  hold, the ones that failed are named.
* **Reproduction** (:func:`reproduction`): what a user must set outside the
  harness to get the same error: rtol, atol and its scale per component, the
  Jacobian's source, the output times, the formulation's variables, every
  setting's value and the library call with every option it passes (the
  integrator's own description of it).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import functools
import math
import time

import numpy as np
import pandas as pd

from integrator_bench.harness.measure import references
from integrator_bench.integrators import library_call

from integrator_bench.harness.advise.answer import FamilyBest, Margin
from integrator_bench.harness.advise.evidence import (CheckRun, Checked, LineEntry,
                                                      OutputTimes, Perturbed, Reference,
                                                      ReferenceMethod, Reproduction,
                                                      Robustness, Run)
from integrator_bench.harness.matrix import builds, registry
from integrator_bench.harness.matrix.stand_in import system_of
from integrator_bench.harness.errors import ModelFault, ReferenceFailure
from integrator_bench.harness.forking.child import call
from integrator_bench.harness.run import model_calls
from integrator_bench.harness.ranking import reach
from integrator_bench.harness.ranking.records import clean_records
from integrator_bench.harness.run.referencing import reference_progress
from integrator_bench.problems.base import ProblemError
from integrator_bench.problems.system import convert

EXTRA_DIGITS = 2        # digits the reference must have beyond the target's
PERTURBATION = 0.03     # the largest relative change of a parameter in a perturbed set
PERTURBED_SETS = 2      # perturbed parameter sets of the robustness check (--perturbed)
SEED = 20261126         # of the perturbations
LEADERS = 3             # lines tried on the perturbed sets, at most, in rank order
COUNTERS = ("nfev", "njev", "nlu", "nsteps", "nreject")
DRIFTS = ("drift_pos", "drift_vel")


class NoGoodReference(Exception):
    """No reference good enough for the target can be had (one line why)."""


class TooFewDigits(NoGoodReference):
    """The reference's two methods agree to fewer digits than the target needs (a
    tighter one may be had: :func:`tighter_reference`)."""


def digits_needed(target: float) -> int:
    """Agreement digits a reference needs for ``target``."""
    return math.ceil(-math.log10(target)) + EXTRA_DIGITS


def reference_check(problem, target: float, reference_dir=None, limit=None,
                    log=None) -> Reference:
    """The reference's facts, or :class:`NoGoodReference`. A reference not stored
    is computed within ``limit`` wall seconds, its progress given to ``log`` as
    ``ibench run`` gives it (:func:`~integrator_bench.harness.run.referencing.reference_progress`).

    Returns
    -------
    Reference
        ``id``, ``methods`` (each with its family: exact, explicit or implicit, and
        its code: the integrator's declared ``event_locator``, whose step, error
        and event machinery it runs on), ``claimed_digits`` (on the scored
        components: :func:`~integrator_bench.harness.measure.references.claimed_digits`),
        ``needed_digits``.
        Two methods are independent when they differ in family or in code: Radau
        IIA in scipy against CVODE's Adams in SUNDIALS (the reference of a problem
        with events, which needs two event locators) as much as Radau against
        DOP853.
    """
    try:
        ref = model_calls.reference(
            problem, reference_dir, limit, what="its reference was checked or computed",
            progress=lambda why: reference_progress(problem, why, limit, log))
    except (ReferenceFailure, ProblemError, ModelFault) as exc:
        raise NoGoodReference(f"no reference for {problem.label()}: {exc}") from None
    methods = []
    for m in ref.meta["methods"]:
        name = m.get("integrator")
        icls = None if name is None else registry.get_integrator(name)
        kind = "exact" if icls is None else "implicit" if icls.implicit else "explicit"
        # the code that runs it: its own step, error and event machinery
        methods.append(ReferenceMethod(m, kind, "exact" if icls is None else icls.event_locator))
    need, claim = digits_needed(target), references.claimed_digits(ref, problem)
    facts = Reference(ref.id, tuple(methods), claim, need)
    if len({(m.family, m.code) for m in methods}) < 2:
        raise NoGoodReference(
            f"the reference of {problem.label()} comes from one method family "
            f"({methods[0].family}) in one code ({methods[0].code}); two "
            "independent ones are needed")
    if claim < need:
        raise TooFewDigits(
            f"the reference of {problem.label()} ({' vs '.join(_method(m) for m in methods)}) "
            f"agrees to {claim} digits; a target of {target:g} needs {need}: the advice would "
            "not be verified")
    return facts


#: how much tighter the reference methods' rtols are taken, in turn, when the stored
#: reference agrees to too few digits
TIGHTER = (1e-2, 1e-4)


def tighter_reference(problem, target: float, directory, limit=None,
                      log=None) -> Reference:
    """A reference good enough for ``target``, computed with the problem's reference
    methods at tighter rtols (:data:`TIGHTER`, never below
    :data:`~integrator_bench.harness.measure.references.TIGHTEST`) and saved in
    ``directory`` (the advice's own, never the committed references), with its facts
    as :func:`reference_check` gives them, all within ``limit`` wall seconds (its
    progress given to ``log``); :class:`NoGoodReference` when the methods
    are at the tightest already or still agree to too few digits."""
    why, started = "", time.monotonic()
    for tighten in TIGHTER:
        if references.methods_of(problem, tighten) is None:
            break
        left = None if limit is None else max(limit - (time.monotonic() - started), 0.0)
        try:   # computed in a process of its own, saved in ``directory`` from here
            model_calls.reference(
                problem, directory, left, recompute=True, tighten=tighten,
                what="its tighter reference was computed",
                progress=lambda _, left=left, tighten=tighten: reference_progress(
                    problem, f"tighter: the methods' rtols x{tighten:g}", left, log))
        except (ReferenceFailure, ProblemError, ModelFault) as exc:
            raise NoGoodReference(f"no tighter reference for {problem.label()}: {exc}") \
                from None
        try:
            return replace(reference_check(problem, target, directory), tightened=tighten)
        except TooFewDigits as exc:
            why = str(exc)
    raise NoGoodReference(why or f"the reference methods of {problem.label()} run at rtol "
                          f"{references.TIGHTEST:g} already: no tighter reference can be had")


def _method(m: ReferenceMethod) -> str:
    return m.name + ("" if m.rtol is None else f" rtol {m.rtol:g}")


def _num(v) -> float | None:
    """A record value as a float for JSON (None when missing or not a number)."""
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return None if math.isnan(f) else f


def run_facts(row) -> Run:
    """One measured run (a record's row): rtol, error, CPU and spread, counters, drift."""
    return Run(float(row["tol"]), float(row["err"]), float(row["cpu_s"]),
               _num(row.get("cpu_s_iqr")), _num(row.get("repeat")), row.get("case_id"),
               **{n: None if pd.isna(row.get(n)) else int(row[n]) for n in COUNTERS},
               **{d: _num(row.get(d)) for d in DRIFTS})


def ranking(result, points_of) -> list[LineEntry]:
    """Every line of the search, best first: those with a run at or below the
    target in the order of the report's table of the search's records
    (``result.records``) at the target, then the others.

    ``points_of(line)`` gives the line's points (:func:`.search.points`). The
    table (:func:`~integrator_bench.harness.ranking.reach.target_table`, of the
    records cleaned as the report's are) is ordered by the CPU to reach the target
    (interpolated between a line's runs either side of it, or its first run's
    CPU as an upper bound when that run reached it already): the order
    :func:`~integrator_bench.harness.ranking.reach.cheapest` ranks by, so that
    the ranks, the robustness check's order and the verdict (:func:`verdict`)
    agree with the report and the run's summary on the same records. Each
    line's ``run`` is its cheapest measured run at or below the target (the
    advised rtol): the crossing's own run when the CPU is an upper bound, the
    one below the crossing otherwise."""
    table = reach.target_table(clean_records(result.records), (result.target,),
                               result.measure) if len(result.records) else pd.DataFrame()
    name = reach.tag(result.target)
    crossing = {}
    for row in table.to_dict("records") if len(table) else ():
        if row[f"how_{name}"] != "not reached":
            crossing[(row["label"], row["formulation"])] = (len(crossing), row[f"cpu_{name}"],
                                                            row[f"how_{name}"])
    reached, rest = [], []
    for line in result.lines:
        pts = points_of(line)
        c = line.candidate
        entry = LineEntry(c.label, c.formulation, c.family, int(len(pts)), line.calibrated,
                          line.out, tuple((float(t), float(e), float(u)) for t, e, u in zip(
                              pts.get("tol", []), pts.get("err", []), pts.get("cpu_s", []))))
        below = pts[pts["err"] <= result.target] if len(pts) else pts
        if len(below) and entry.key in crossing:
            _, cpu, how = crossing[entry.key]
            reached.append(replace(entry, run=run_facts(below.loc[below["cpu_s"].idxmin()]),
                                   to_target=float(cpu), how=how))
        else:
            rest.append(replace(entry, best_error=float(pts["err"].min()) if len(pts)
                                else None))
    reached.sort(key=lambda e: crossing[e.key][0])
    return [replace(e, rank=rank) for rank, e in enumerate(reached, 1)] + rest


def verdict(records: pd.DataFrame, pool, target: float, measure: str) -> dict | None:
    """The advice's answer among the lines of ``pool`` (entries that reached the
    target; those that can be named: :mod:`.advice`): the report's rule
    (:func:`~integrator_bench.harness.ranking.reach.cheapest` of
    :func:`~integrator_bench.harness.ranking.reach.target_table`) on ``records``
    (the search's, its contenders timed again) of those lines only, so that one
    function decides the advice, the report and the run's summary alike.

    A line re-tightened on the perturbed sets (``retightened_from``) counts from
    its tighter run on: its looser records, one of which missed the target on a
    perturbed set, are left out, and its tighter run (``run.case_id``, among
    ``records``) is its first point below the target, so its CPU to the target
    is that run's, an upper bound. The records are cleaned as the report's are
    (:func:`~integrator_bench.harness.ranking.records.clean_records`: the newest
    of each case).

    Returns
    -------
    dict or None
        :func:`~integrator_bench.harness.ranking.reach.cheapest`'s answer (its
        ``label`` and ``formulation`` the named line, ``verdict``, ``tied``,
        ``same_code``, ``runner_up`` with its ``margin``), and ``table``, the
        table it was taken from; None when no line of ``pool`` reaches the
        target in ``records``.
    """
    if not len(records) or not pool:
        return None
    label, form = records["label"].astype(str), records["formulation"].astype(str)
    rtol = pd.to_numeric(records["rtol"], errors="coerce")
    keep = pd.Series(False, index=records.index)
    for e in pool:
        mine = (label == e.label) & (form == e.formulation)
        if e.retightened_from is not None:
            mine &= (rtol <= e.run.rtol) | (records["case_id"] == e.run.case_id)
        keep |= mine
    table = reach.target_table(clean_records(records[keep]), (target,), measure)
    top = reach.cheapest(table, target)
    return None if top is None else {**top, "table": table}


def margin_of(top: dict) -> Margin | None:
    """The runner-up's margin of :func:`verdict`'s answer ``top`` as the advice
    gives it (None: no runner-up); the margin the report shows beside its answer
    (:func:`~integrator_bench.harness.ranking.reach.answer_parts`)."""
    up = top["runner_up"]
    if up is None:
        return None
    m = up["margin"]
    if m is None:       # out of contention: beyond the band, timed no more
        ratio = up["ratio"]
        return Margin(None if math.isnan(ratio) else float(ratio), False, line=up["line"])
    return Margin(None if math.isnan(m.ratio) else float(m.ratio), not m.clear,
                  m.low if m.measured else None, m.high if m.measured else None, m.n,
                  up["line"])


def family_bests(ranked: list[LineEntry]) -> dict:
    """The best line of each family that reached the target (family ->
    :class:`~.answer.FamilyBest`)."""
    out = {}
    for e in ranked:
        if e.run is not None and e.family not in out:
            out[e.family] = FamilyBest(e.label, e.formulation, e.run.rtol, e.run.cpu_s)
    return out


#: what :func:`perturbation` moves: the parameters, or (when none can be) the initial states
PARAMETERS, STARTS = "parameters", "initial states"
#: the rule of a perturbed initial state, as the certificate states it
START_RULE = (f"each start times 1 + u {PERTURBATION:g}, u uniform in [-1, 1]; a start at 0 "
              f"plus u {PERTURBATION:g} times its atol scale")


@dataclass(frozen=True)
class Perturbation:
    """What :func:`perturbation` moves: ``what`` (:data:`PARAMETERS`,
    :data:`STARTS`, or None when nothing can be perturbed), ``names`` (the options
    moved), ``sets`` (each a full option dict of the problem)."""

    what: str | None
    names: tuple
    sets: tuple


def perturbation(problem, n: int, seed: int = SEED) -> Perturbation:
    """``n`` perturbed variants of ``problem``, as option sets, and what was moved.

    The continuous parameters (one the problem accepts at a non-integral value; a
    zero stays zero): each times ``1 + u PERTURBATION``, ``u`` uniform in [-1, 1],
    clipped to its range. A parameter is perturbed only when the problem still
    starts at both ends of that range (``1 -+ PERTURBATION``, the others at their
    values): a mechanism's link length moves its joints off the given start, which
    then is no longer consistent; and only when the problem's time span
    (``t_span``) and output times (``t_eval``) stay as they are at both ends: a
    parameter that moves them (an end time, ``t_end``) is the question asked, not
    the model.

    When no parameter can be perturbed, the initial states the problem lets its
    user set (:meth:`~integrator_bench.problems.base.Problem.settable_starts`, an
    FMU's ``start.NAME``): each start times ``1 + u PERTURBATION``; a start at 0,
    which a relative change would leave at 0, becomes ``u PERTURBATION`` times the
    state's absolute scale (the problem's ``atol_scale``); clipped to its range.
    A mechanism's start is never one of them (it must stay consistent).

    A set that still cannot start is left out, so fewer than ``n`` may come back.

    Returns
    -------
    Perturbation
    """
    cls = builds.class_of(problem)
    base = dict(problem.params)
    free = []
    for p in getattr(problem, "parameters", ()):
        value = base.get(p.name)
        if not isinstance(value, (int, float)) or value == 0:
            continue
        ends = [_clip(value * (1 + s * PERTURBATION) + s * 1e-9 * abs(value), p)
                for s in (-1, 1)]
        if all(_same_times(problem, _built(cls, {**base, p.name: end})) for end in ends):
            free.append(p)
    what = PARAMETERS if free else STARTS
    if not free:
        free = [s for s in problem.settable_starts() if s.default != 0 or s.scale > 0]
    if not free:
        return Perturbation(None, (), ())
    rng = np.random.default_rng(seed)
    sets = []
    for _ in range(n):
        u = rng.uniform(-1, 1, len(free))
        sets.append({**base, **{p.name: _moved(p, base.get(p.name, p.default), ui, what)
                                for p, ui in zip(free, u)}})
    return Perturbation(what, tuple(p.name for p in free),
                        tuple(s for s in sets if _starts(cls, s)))


def _moved(p, value: float, u: float, what: str) -> float:
    """``value`` of parameter or start ``p`` moved by ``u`` (in [-1, 1]) as
    :func:`perturbation` says, clipped to ``p``'s range."""
    if what == STARTS and value == 0:
        return _clip(u * PERTURBATION * p.scale, p)
    return _clip(value * (1 + PERTURBATION * u), p)


def _clip(value: float, p) -> float:
    return float(min(max(value, p.low), p.high))


def perturbed_sets(problem, n: int, seed: int = SEED) -> list[dict]:
    """The option sets of :func:`perturbation`."""
    return list(perturbation(problem, n, seed).sets)


def _built(cls, params: dict):
    """Problem class ``cls`` at ``params`` when it builds and has a start in its
    first formulation (a mechanism's consistent start is found there); else None (one
    from outside the project that raised, crashed or hung in its trial build too:
    :func:`~integrator_bench.harness.matrix.builds.build`)."""
    try:
        inst = builds.build(cls, params)
        system_of(inst, inst.formulations[0])
    except (ProblemError, ModelFault, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return None
    return inst


def _starts(cls, params: dict) -> bool:
    """Whether problem class ``cls`` builds and starts at ``params`` (:func:`_built`)."""
    return _built(cls, params) is not None


def _same_times(problem, other) -> bool:
    """Whether ``other`` (a variant of ``problem``, or None) starts and has the same
    time span and output times: a parameter that moves them (an end time) changes
    the question, not the model, and is never perturbed."""
    return (other is not None and tuple(other.t_span) == tuple(problem.t_span)
            and np.array_equal(other.t_eval, problem.t_eval))


def robustness(problem, ranked: list[LineEntry], cands: dict, target: float, measure: str,
               n_sets: int, run) -> Robustness:
    """Re-run the leading lines (at most :data:`LEADERS`, in rank order, until two
    hold: the winner and the runner-up are checked alike) on ``n_sets`` perturbed
    parameter sets.

    A rtol calibrated on the model itself leaves the error just under the target,
    so a perturbed set may put it just over. A line that misses (every run ``ok``,
    an error over the target) is tried once more before it is dropped, on the
    model and on every set, at its rtol divided by :data:`TIGHTER_BY` (a decade),
    or by more when its worst error calls for it (its rtol times ``target / worst
    error`` times :data:`RETIGHTEN`); when it then holds, its run on the model at
    the tighter rtol is its measured run. The holders stay in rank order; the
    advice's verdict is taken over them (:func:`verdict`).

    ``run(cases)`` runs cases and returns their records (a DataFrame; a case it
    did not run, the budget spent, has no record); ``cands`` maps an entry's
    :attr:`~.evidence.LineEntry.key` to its Candidate.

    Returns
    -------
    Robustness
        What was perturbed and by how much (:func:`perturbed_facts`), the options
        each set changed, the checks per line and rtol (its errors on each set and
        whether it holds: True, False, or None when a run is missing), the lines
        that hold, in rank order (a re-tightened one with its new run and
        ``retightened_from``), and why there was no check.
    """
    moved = perturbation(problem, n_sets)
    leaders = [e for e in ranked if e.run is not None][:LEADERS]
    if not moved.sets or not leaders:
        return Robustness(perturbed_facts(problem, moved),
                          why="the model has neither a continuous parameter nor a settable "
                          "initial state to perturb" if not moved.sets
                          else "no line reached the target")
    cls = builds.class_of(problem)
    variants = [builds.build(cls, s) for s in moved.sets]   # each built once (_built)
    check = _Check(problem, variants, cands, target, measure, run)
    checked, holders = [], []
    for entry in leaders:
        if len(holders) >= 2:
            break
        got, _ = _check(entry, entry.run.rtol, check)
        ok = _holds(got, target)
        checked.append(Checked(entry.label, entry.formulation, entry.run.rtol, ok, got))
        if ok:
            holders.append(entry)
        elif ok is False and all(g.status == "ok" and g.error is not None for g in got):
            held = _retightened(entry, max(g.error for g in got), check, checked)
            holders += [held] if held else []
    return Robustness(perturbed_facts(problem, moved),
                      tuple(_changed(problem.params, v.params) for v in variants),
                      tuple(checked), tuple(holders))


def perturbed_facts(problem, moved: Perturbation) -> Perturbed:
    """What :func:`perturbation` (``moved``) perturbed and by how much: ``what``,
    ``names``, ``relative`` (:data:`PERTURBATION`), ``seed``, and for initial
    states the ``rule`` and each one's ``start`` and absolute ``scale``."""
    if moved.what != STARTS:
        return Perturbed(moved.what, moved.names, PERTURBATION, SEED)
    return Perturbed(moved.what, moved.names, PERTURBATION, SEED, START_RULE,
                     {s.name: {"start": s.default, "scale": s.scale}
                      for s in problem.settable_starts() if s.name in moved.names})


#: a line that missed the target on a perturbed set is tried again at its rtol divided by
#: TIGHTER_BY, or at its rtol times ``target / worst error`` times RETIGHTEN when that is
#: tighter still
TIGHTER_BY = 10.0
RETIGHTEN = 0.5


@dataclass(frozen=True)
class _Check:
    """What every try of :func:`robustness` is made against: the model, its
    perturbed ``variants``, the candidates by ``(integrator, formulation)``, the
    target and its measure, and ``run(cases)``."""

    problem: object
    variants: list
    cands: dict
    target: float
    measure: str
    run: object


def _check(entry: LineEntry, rtol, check: _Check, nominal=False):
    """The line of ``entry`` at ``rtol`` on every perturbed set: the status and
    error of each run (status ``not run`` for a case ``run`` gave no record of);
    with ``nominal``, on the model itself first, whose records come second (else
    None)."""
    problem = check.problem
    cand = check.cands[entry.key]
    models = ([problem] if nominal else []) + check.variants
    cases = [cand.case(m, rtol) for m in models]
    df = check.run(cases)
    errs = reach.error_values(df, check.measure) if len(df) else pd.Series([], dtype=float)
    by_id = dict(zip(df["case_id"], errs)) if len(df) else {}
    status = dict(zip(df["case_id"], df["status"])) if len(df) else {}
    got = tuple(CheckRun(_changed(problem.params, m.params), _num(by_id.get(c.case_id)),
                         status.get(c.case_id, NOT_RUN)) for c, m in zip(cases, models))
    own = cases[0].case_id
    return got, (df[df["case_id"] == own] if nominal and own in by_id else None)


#: the status of a robustness run that was not run (the budget spent)
NOT_RUN = "not run"


def _holds(got: tuple[CheckRun, ...], target: float) -> bool | None:
    """Whether every run of ``got`` is ``ok`` at or below the target; None when
    none failed so but one was not run (the check is unfinished)."""
    if any(g.status not in ("ok", NOT_RUN) or (g.status == "ok" and (
            g.error is None or g.error > target)) for g in got):
        return False
    return None if any(g.status == NOT_RUN for g in got) else True


def _retightened(entry: LineEntry, worst, check: _Check, checked) -> LineEntry | None:
    """``entry``'s line (whose worst error on the sets was ``worst``) tried tighter
    (:func:`robustness`) on the model and every set: the entry with its new run
    and ``retightened_from`` when it holds, else None. The attempt is added to
    ``checked``."""
    from integrator_bench.harness.advise.search import round_rtol

    rtol = entry.run.rtol
    tighter = round_rtol(rtol * min(1 / TIGHTER_BY, check.target / worst * RETIGHTEN))
    got, own = _check(entry, tighter, check, nominal=True)
    ok = _holds(got, check.target)
    checked.append(Checked(entry.label, entry.formulation, tighter, ok, got[1:]))
    pts = reach.line_points(own, check.measure) if ok else None
    if not ok or not len(pts):
        return None
    return replace(entry, run=run_facts(pts.iloc[0]), retightened_from=rtol)


def _changed(base: dict, params: dict) -> dict:
    return {k: v for k, v in params.items() if base.get(k) != v}


def reproduction(problem, candidate, rtol: float) -> Reproduction | None:
    """:func:`described_reproduction`, in a process of its own (it formulates the
    problem: a plugin's or an FMU's code,
    :func:`~integrator_bench.harness.forking.child.call`); None when the model
    raised, crashed or hung there."""
    try:
        return call(functools.partial(described_reproduction, problem, candidate, rtol),
                    "its reproduction was described")
    except ModelFault:
        return None


def described_reproduction(problem, candidate, rtol: float) -> Reproduction:
    """What a user needs to get the same error outside the harness: the integrator
    and its settings, the formulation (its kind, states, variables and the scored
    ones), rtol and atol's scale per state, the output times, the loop the timed
    solve runs (:meth:`~integrator_bench.integrators.base.Integrator.timing_loop`)
    and, for a library code, the call it makes with every option
    (``library_call``:
    :meth:`~integrator_bench.integrators.base.Integrator.library_call`, the
    integrator's own description, made from the configuration both its solves use;
    None for an integrator implemented in this project). The Jacobian's source is
    the call's (the FMU's directional derivatives where the analytic one is an
    FMU's); without a call, the system's."""
    icls = registry.get_integrator(candidate.integrator)
    integrator = icls(**dict(candidate.settings))
    system = convert(problem.formulate(candidate.formulation), icls)
    call = integrator.library_call(system, rtol, system.atol(rtol))
    if call is not None:
        source = call["jacobian"]
        handed = source == library_call.ANALYTIC
    else:
        handed = icls.uses_jacobian and getattr(system, "jac", None) is not None
        source = library_call.jacobian_source(icls.uses_jacobian, handed)
    if handed and getattr(problem, "fmu", None) is not None:
        source = "the FMU's directional derivatives, handed to the code"
    scale = np.asarray(system.atol_scale, float)
    t = np.asarray(system.t_eval, float)
    return Reproduction(
        candidate.integrator, integrator.setting_values, candidate.formulation, system.kind,
        int(system.n), rtol, "rtol * scale per state", float(scale.min()), float(scale.max()),
        tuple(scale.tolist()), source, integrator.timing_loop(system), call,
        OutputTimes(float(t[0]), float(t[-1]), int(t.size),
                    "uniform" if np.allclose(np.diff(t), t[1] - t[0]) else "given"),
        tuple(problem.components), tuple(problem.error_components or problem.components))
