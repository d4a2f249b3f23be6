"""Which case runs next: lines in order, evidence that skips, the longest line first.

A *line* is the cases of one problem, parameter set, formulation, integrator
(and its settings: every field of the case's identity but ``rtol`` and ``h``,
:class:`~integrator_bench.harness.matrix.line.Line`, the case's ``line``) and step mode. :class:`Schedule` hands the scheduling loop
(:func:`integrator_bench.harness.run.loop.drive`) one case of a line at a time,
from loose to tight (decreasing ``rtol``, or decreasing ``h``: increasing
work), and holds the line's next case until the previous one has its record,
so that what a case shows can decide the cases after it. Lines are taken in
order of predicted remaining cost, the most expensive first
(:class:`CostModel`): the longest-processing-time rule (Graham, SIAM J. Appl.
Math. 17 (1969) 416-429), which makes the workers finish together.

The evidence (:func:`implied`), under :data:`POLICY`:

* a case that timed out: every tighter tolerance, or smaller step, of its line
  takes more work and would time out too (reason ``after_timeout``);
* a fixed-step case that diverged (``failed`` with reason ``diverged`` or
  ``nonfinite_state``: the step is past the method's stability limit): every
  *larger* step of its line is past it too (reason ``after_divergence``).
  A larger step diverging says nothing of smaller ones, and the loose-to-tight
  order runs the larger steps first, so within one run this fires on evidence
  from an earlier run of the same code version in the store (``--resume``);
* a fixed-step case that ended ``ok`` after ``cpu_s`` seconds: a smaller step
  ``h'`` of its line takes ``h / h'`` times the steps, so at least
  ``cpu_s h / (h' STEP_MARGIN)`` seconds (``STEP_MARGIN`` = 2 allows a step at
  ``h'`` to cost down to half a step at ``h``: fewer Newton iterations); over
  the per-case budget (the case's one solve has all of it), it would time out
  (reason ``predicted_timeout``);
* :class:`StiffnessBound`: an explicit method whose stability interval,
  against the spectral radius of the problem's ``ode`` Jacobian, needs more
  steps than the case's budget allows at the least
  measured cost of one right-hand side (reason ``stiffness_budget``).

A skipped case is recorded ``skipped`` (``CaseStatus.SKIPPED``) with the
reason, a message, the id of the case that decided it (``decided_by``) and
the policy (``skip_policy``); ``--no-skip`` (``skip=False``) runs every case.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections import defaultdict, deque

from integrator_bench.harness.run import raced
from integrator_bench.harness.run.execution import base_record, finish, sampled_cpu
from integrator_bench.harness.matrix.line import ProblemSpec
from integrator_bench.harness.matrix.record import CaseStatus

#: the name of the rules above, stored in each skipped record: ``--resume`` treats a
#: skipped case as done only when the run's policy is the same
POLICY = ("skip-4: timeout->tighter, diverged h->larger h, ok h->smaller h over the CPU "
          "budget (margin 2), stiffness over the CPU budget (margin 2)")
AFTER_TIMEOUT = "after_timeout"
AFTER_DIVERGENCE = "after_divergence"
PREDICTED_TIMEOUT = "predicted_timeout"
STIFFNESS_BUDGET = "stiffness_budget"
SKIP_REASONS = (AFTER_TIMEOUT, AFTER_DIVERGENCE, PREDICTED_TIMEOUT, STIFFNESS_BUDGET)
#: a step at h' costs at least 1/STEP_MARGIN of a step at h > h' (predicted_timeout)
STEP_MARGIN = 2.0
#: the failure reasons that say a fixed step is past the stability limit
DIVERGED = ("diverged", "nonfinite_state")


def tolerance(case) -> float:
    """The line's ordering value: ``rtol``, else ``h`` (larger is looser)."""
    return case.rtol if case.rtol is not None else case.h


def implied(record: dict, case, budget_s: float | None = None) -> tuple[str, str] | None:
    """The reason and message for which ``record`` (a case of ``case``'s line)
    makes ``case`` hopeless, or None; ``budget_s`` is the per-case budget
    (None: no ``predicted_timeout``)."""
    tol = record.get("rtol") if case.rtol is not None else record.get("h")
    if tol is None or tol != tol or record.get("case_id") == case.case_id:
        return None
    what = "rtol" if case.rtol is not None else "h"
    if record.get("status") == CaseStatus.TIMEOUT and tolerance(case) < tol:
        return AFTER_TIMEOUT, (f"skipped: {what}={tol:g} of this line timed out; a tighter "
                               f"{what} takes more work")
    if (case.h is not None and record.get("status") == CaseStatus.FAILED
            and record.get("reason") in DIVERGED and tolerance(case) > tol):
        return AFTER_DIVERGENCE, (f"skipped: h={tol:g} of this line diverged "
                                  f"({record.get('reason')}); a larger step is further past "
                                  f"the stability limit")
    cpu = record.get("cpu_s")
    if (case.h is not None and budget_s and record.get("status") == CaseStatus.OK
            and cpu is not None and cpu == cpu and tolerance(case) < tol):
        least = cpu * tol / (case.h * STEP_MARGIN)
        if least > budget_s:
            return PREDICTED_TIMEOUT, (f"skipped: h={tol:g} of this line took {cpu:.3g} s; "
                                       f"{tol / case.h:.3g} times the steps take at least "
                                       f"{least:.3g} s (margin {STEP_MARGIN:g}), over the "
                                       f"case's budget of {budget_s:g} s of CPU")
    return None


def predicted_line(cases, predict, budget_s: float, cap: float = math.inf,
                   skip: bool = True, repeat: int = 1) -> tuple[list[float], int, list[str]]:
    """What a line's ``cases`` (loosest first) are predicted to cost: each case's
    CPU (``predict``: one solve's, taken as often as a case with at most ``repeat``
    timing samples takes it, :func:`~.execution.sampled_cpu`) at most the budget
    ``timeout`` and ``cap`` (a race bound), a case whose one solve is predicted
    at the budget a timeout, and, with ``skip``, the tighter cases its predicted
    record makes hopeless (:func:`implied`) left out. Returns ``(the CPU of each
    case kept, the timeouts, the reasons of the cases left out)``: the plan's
    count (:func:`~integrator_bench.harness.run.plan.make_plan`) and the progress
    bar's (:meth:`Schedule.predicted_left`)."""
    ordered, kept, timeouts, reasons = list(cases), [], 0, []
    i = 0
    while i < len(ordered):
        case = ordered[i]
        cpu = predict(case)
        over = cpu >= budget_s
        kept.append(min(sampled_cpu(cpu, repeat), budget_s, cap))
        timeouts += over
        if skip:
            record = {"case_id": case.case_id, "rtol": case.rtol, "h": case.h,
                      "status": CaseStatus.TIMEOUT if over else CaseStatus.OK,
                      "cpu_s": None if over else cpu}
            later = [implied(record, c, budget_s) for c in ordered[i + 1:]]
            reasons += [why[0] for why in later if why]
            ordered[i + 1:] = [c for c, why in zip(ordered[i + 1:], later) if not why]
        i += 1
    return kept, timeouts, reasons


def skipped_record(case, reason: str, message: str, decided_by: str | None,
                   policy: str | None = POLICY) -> dict:
    """The ``skipped`` record of ``case`` (``policy``: the run's, :func:`~.raced.policy_of`)."""
    record = finish(base_record(case), CaseStatus.SKIPPED, message, reason)
    record.update(decided_by=decided_by, skip_policy=policy)
    return record


def prior_work(case, dimension: int, span: float) -> float:
    """A case's work before any measurement: states times steps over the span
    (``span / h`` for a fixed step; ``10 rtol**(-1/4)``, the steps of a
    fourth-order method, for an adaptive one)."""
    steps = span / case.h if case.h is not None else 10.0 * case.rtol ** -0.25
    return max(dimension, 1) * max(steps, 1.0)


def problem_size(spec, build=ProblemSpec.build) -> tuple:
    """``(dimension, span)`` of a problem spec, for the cost model (``(1, 1.0)`` for
    one that fails to build: it fails in its worker); ``build(spec)`` gives the
    problem (default: built here; a session's, built once)."""
    try:
        problem = build(spec)
        return problem.dimension, problem.t_span[1] - problem.t_span[0]
    except Exception:  # noqa: BLE001  a problem that fails to build fails in its worker
        return 1, 1.0


@dataclasses.dataclass(frozen=True)
class _Key:
    """What the cost model reads of a case, for a stored record."""

    problem: str
    params: tuple
    integrator: str
    rtol: float | None
    h: float | None
    formulation: str | None = None

    @property
    def spec(self) -> ProblemSpec:
        return ProblemSpec(self.problem, self.params)


def levels(case) -> tuple:
    """The keys of ``case``'s rates in a :class:`CostModel`, the narrowest first: its
    problem, formulation, integrator and tolerance (rtol, else h); problem,
    formulation and integrator; problem and integrator; problem; integrator; all."""
    line = (case.problem, case.formulation, case.integrator)
    return ((*line, tolerance(case)), line, (case.problem, case.integrator), (case.problem,),
            (case.integrator,), ())


class CostModel:
    """Predicted CPU seconds of a case: its :func:`prior_work` times a CPU per
    unit of work fitted on measured records.

    The factor is the median of ``cpu_s / prior_work`` over the records of the
    same case (problem, formulation, integrator and tolerance: a store's own), else
    of the same problem, formulation and integrator, else of the same problem and
    integrator, else of the same problem, else of the same integrator, else of all
    records (1e-6 s without any; :func:`levels`). A timed-out record
    counts with the timeout as its CPU. Records come from the store (earlier
    runs) and from the run so far (:meth:`learn`).

    Parameters
    ----------
    sizes : dict
        ``ProblemSpec -> (dimension, span)`` of every problem of the run.
    """

    DEFAULT = 1e-6

    def __init__(self, sizes: dict):
        self.sizes = sizes
        self.rates: dict = defaultdict(list)
        self._median: dict = {}

    def work(self, case) -> float:
        dimension, span = self.sizes.get(case.spec, (1, 1.0))
        return prior_work(case, dimension, span)

    def learn(self, case, cpu_s) -> None:
        """Take one measured (or timed-out) case into the fit."""
        if cpu_s is None or not math.isfinite(cpu_s) or cpu_s <= 0:
            return
        rate = cpu_s / self.work(case)
        for key in levels(case):
            self.rates[key].append(rate)
            self._median.pop(key, None)

    def learn_row(self, row: dict, among=None) -> None:
        """Take one stored record (``Store.measured``) into the fit, when its
        problem and parameter set are among the model's (or among ``among``'s keys)."""
        try:
            params = tuple(sorted(json.loads(row["params"]).items()))
        except (TypeError, ValueError, AttributeError):
            return
        case = _Key(row["problem"], params, row["integrator"], row["rtol"], row["h"],
                    row.get("formulation"))
        if case.spec in (self.sizes if among is None else among):
            self.learn(case, row["cpu_s"])

    def rate(self, case) -> float:
        for key in levels(case):
            if self.rates.get(key):
                if key not in self._median:
                    values = sorted(self.rates[key])
                    self._median[key] = values[len(values) // 2]
                return self._median[key]
        return self.DEFAULT

    def predict(self, case) -> float:
        return self.work(case) * self.rate(case)


class Schedule:
    """The pending cases of a run, as lines, for :func:`~integrator_bench.harness.run.loop.drive`.

    Parameters
    ----------
    cases : iterable of Case
        The cases to run (``unsupported`` ones, and those whose problem failed to
        build, are handed out first: they cost nothing).
    skip : bool
        Apply :func:`implied` and ``bound`` (False: ``--no-skip``, every case runs).
    model : CostModel, optional
        Orders the lines, most expensive remaining first (None: as given).
    evidence : iterable of (Case, dict), optional
        Records already stored for cases of these lines (a resumed run): they
        skip what they imply before anything runs.
    bound : callable, optional
        ``case -> (message) or None``: why the stiffness analysis rules the case
        out (:class:`StiffnessBound`).
    budget_s : float, optional
        The per-case budget: what a timed-out case is taken to have cost, for
        the model, and the bound of ``predicted_timeout`` (None: no such skip).
    repeat : int, optional
        The most timing samples a case takes (``--repeat``, the preset's): a
        case's predicted CPU counts them (:func:`predicted_line`).
    race : Race, optional
        The run's race (:class:`~integrator_bench.harness.ranking.racing.Race`;
        None: ``--exhaustive``): it learns every record (a resumed run's
        stored ones before, from the caller); a case is handed out with the race
        bound of its problem as its budget (:func:`~.raced.under_bound`), a
        record past it becomes ``dominated`` and so do the tighter cases of its
        line (:mod:`~integrator_bench.harness.run.raced`); while a problem has no
        lead its predicted cheapest lines (:func:`~.raced.scouts`) go first.
    """

    def __init__(self, cases, skip: bool = True, model: CostModel | None = None,
                 evidence=(), bound=None, budget_s: float | None = None, race=None,
                 repeat: int = 1):
        self.skip, self.model, self.bound, self.budget_s = skip, model, bound, budget_s
        self.repeat = repeat   # the most timing samples a case takes
        self.race, self.raced = race, {}   # case_id -> the race fields it runs under
        self.policy = raced.policy_of(POLICY if skip else None, race)
        self.free: deque = deque()
        lines: dict = defaultdict(list)
        for case in cases:
            if case.settled:
                self.free.append(case)
            else:
                lines[case.line].append(case)
        self.lines = {k: deque(sorted(v, key=tolerance, reverse=True)) for k, v in lines.items()}
        self.busy: set = set()
        self.flying: dict = {}
        self._cost: dict = {}      # line -> predicted remaining CPU, refitted every REFIT
        self._learned = 0
        self.ready_skips: list = []
        self.scouts = raced.scouts(self.lines, self._remaining) if race and model else set()
        for case, record in evidence:
            self._apply(case.line, record)
            self._learn(case, record)

    def __bool__(self) -> bool:
        return bool(self.free or any(self.lines.values()) or self.ready_skips)

    def __len__(self) -> int:
        return len(self.free) + sum(map(len, self.lines.values()))

    def skips(self) -> list[dict]:
        """The skipped records decided since the last call."""
        out, self.ready_skips = self.ready_skips, []
        return out

    def next(self):
        """The next case to hand out, or None while every line with cases left
        waits for its running case."""
        if self.free:
            return self.free.popleft()
        while True:
            ready = [k for k, q in self.lines.items() if q and k not in self.busy]
            if not ready:
                return None
            scouting = [k for k in ready if k in self.scouts
                        and not self.race.raced(k.problem.name, k.problem.params_json)]
            key = max(scouting or ready, key=self._remaining) if self.model else ready[0]
            case = self.lines[key].popleft()
            self._cost.pop(key, None)
            why = self.bound(case) if (self.skip and self.bound) else None
            if why:
                self.ready_skips.append(skipped_record(case, STIFFNESS_BUDGET, why, None,
                                                       self.policy))
                continue
            self.busy.add(key)
            self.flying[case.case_id] = case
            case, fields = raced.under_bound(case, self.race, self.budget_s)
            if fields:
                self.raced[case.case_id] = fields
            return case

    def done(self, record: dict) -> None:
        """Take the record of a handed-out case: free its line, learn, skip what
        it implies."""
        case = self.flying.pop(record.get("case_id"), None)
        if case is None:
            return
        key = case.line
        self.busy.discard(key)
        fields = self.raced.pop(case.case_id, None)
        if fields:
            raced.settle(record, fields, self.budget_s, self.policy)
        if self.race is not None:
            self.race.learn(record)
        self._apply(key, record)
        self._learn(case, record)

    def _apply(self, key, record) -> None:
        if key not in self.lines:
            return
        keep = deque()
        for case in self.lines[key]:
            if record.get("status") == CaseStatus.DOMINATED and tolerance(case) < (
                    record.get("rtol") if case.rtol is not None else record.get("h")):
                self.ready_skips.append(raced.dominated_record(case, record, self.policy))
                continue
            why = implied(record, case, self.budget_s) if self.skip else None
            if why:
                self.ready_skips.append(skipped_record(case, *why, record.get("case_id"),
                                                       self.policy))
            else:
                keep.append(case)
        self.lines[key] = keep
        self._cost.pop(key, None)

    def _learn(self, case, record) -> None:
        if self.model is None:
            return
        cpu = record.get("cpu_s")
        if record.get("status") == CaseStatus.TIMEOUT:
            cpu = self.budget_s
        self.model.learn(case, cpu)
        self._learned += 1
        if self._learned % self.REFIT == 0:
            self._cost.clear()

    REFIT = 64  # records learned between two refits of every line's predicted cost

    def _remaining(self, key) -> float:
        """The line's predicted CPU still to run, as the plan counts it
        (:func:`predicted_line`: each case at most the budget and its race bound,
        with skipping the cases a predicted timeout makes hopeless left out)."""
        if key not in self._cost:
            cases = self.lines[key]
            fields = self.race.bound(cases[0]) if cases and self.race is not None else None
            cap = fields["race_bound_s"] if fields else math.inf
            budget_s = self.budget_s if self.budget_s is not None else math.inf
            self._cost[key] = sum(predicted_line(cases, self.model.predict, budget_s, cap,
                                                 self.skip, self.repeat)[0])
        return self._cost[key]

    def predicted_left(self) -> float:
        """Predicted CPU seconds of the cases not yet handed out (0 without a model):
        the progress bar's time left."""
        return sum(self._remaining(k) for k, q in self.lines.items() if q) if self.model else 0.0


class StiffnessBound:
    """Why an explicit method cannot finish within the budget: ``case -> message``
    (None when nothing is proven).

    For an adaptive case of the ``ode`` formulation and an explicit integrator
    with one real stability interval ``[-beta, 0]`` (a fixed number of stages:
    the stabilized methods, whose interval grows with their stages, are left
    alone), stability alone needs steps ``h <= MARGIN beta / rho``; ``rho`` is
    the least spectral radius of the ``ode`` Jacobian at the start, middle and
    end of the reference (:func:`integrator_bench.harness.measure.stiffness.spectrum`),
    taken as holding over the whole span. ``MARGIN`` covers complex spectra, on
    which the stable step may exceed ``beta / rho`` a little (RK4: 2.83 against
    2.79 on the imaginary axis). So the run takes at least
    ``span rho / (MARGIN beta)`` steps, each of at least one right-hand side
    evaluation; when that many evaluations, at the least of ``REPEAT`` timed
    evaluations here, take longer than ``budget_s`` (the case's budget of CPU,
    all of it its one solve's, :func:`integrator_bench.harness.run.execution.execute`),
    the case is ruled out.

    Parameters
    ----------
    budget_s : float
        The per-case budget in CPU seconds.
    reference_dir : path, optional
        Where the run's references are (its ``reference_dir``; None: the default).
    stop : callable, optional
        Polled while the facts are measured: True (the run was interrupted) stops
        them, and the case runs.

    The analysis and the timed evaluations call the model's code: they run in a
    process of their own (:mod:`~integrator_bench.harness.run.model_calls`), within
    the case's budget; a model that fails there proves nothing (the case runs,
    and fails in its worker).
    """

    MARGIN = 2.0
    REPEAT = 20

    def __init__(self, budget_s: float, reference_dir=None, stop=None):
        self.budget_s, self.reference_dir, self.stop = budget_s, reference_dir, stop
        self.facts: dict = {}

    def __call__(self, case) -> str | None:
        from integrator_bench.harness.matrix import registry

        icls = registry.integrators().get(case.integrator)
        if (case.rtol is None or case.formulation != "ode" or icls is None or icls.implicit
                or len(icls.stability_intervals) != 1):
            return None
        facts = self._facts(case)
        if facts is None:
            return None
        rho, t_rhs, span = facts
        beta = next(iter(icls.stability_intervals.values()))
        steps = span * rho / (self.MARGIN * beta)
        if steps * t_rhs <= self.budget_s:
            return None
        return (f"skipped: spectral radius {rho:.3g} of the ode Jacobian; stability alone "
                f"needs at least {steps:.3g} steps (beta {beta:.3g}, margin {self.MARGIN:g}), "
                f"at least {steps * t_rhs:.3g} s at {t_rhs:.2g} s per right-hand side, "
                f"over the case's budget of {self.budget_s:g} s of CPU")

    def _facts(self, case):
        if case.spec not in self.facts:
            self.facts[case.spec] = self._measured(case)
        return self.facts[case.spec]

    def _measured(self, case):
        """:func:`_spectral_facts` of ``case`` in a process of its own; None when its
        model fails there or the run is stopped meanwhile."""
        import functools

        from integrator_bench.harness.forking.child import calls

        [facts] = calls(
            [functools.partial(_spectral_facts, case, self.REPEAT, self.reference_dir)],
            "its stiffness bound was measured", self.budget_s, stop=self.stop)
        return None if isinstance(facts, Exception) else facts


def _spectral_facts(case, repeat: int, reference_dir=None):
    """``(least rho at start, middle, end; least seconds of one right-hand side;
    span)`` of the case's problem, or None when the analysis fails."""
    import time

    from integrator_bench.harness.measure import stiffness
    from integrator_bench.harness.run.streams import stdout_to_stderr

    try:
        problem = case.spec.build()
        with stdout_to_stderr():
            times = stiffness.spectrum(problem, stiffness.parse_times(problem, None),
                                       reference_dir)
        rho = min(t["rho"] for t in times)
        system = problem.formulate("ode")
        best = math.inf
        for _ in range(repeat):
            start = time.process_time()
            system.fun(system.t0, system.y0)
            best = min(best, time.process_time() - start)
    except Exception:  # no evidence: the case runs
        return None
    return rho, best, problem.t_span[1] - problem.t_span[0]
