"""The plan of a run before it starts: what it will cost, from a cost model alone.

:func:`make_plan` sorts the cases by kind (``unsupported``, runnable, predicted
to be skipped and by which rule), predicts each runnable case's CPU with a
:class:`~integrator_bench.harness.run.schedule.CostModel` (one solve's, as
often as the case's timing samples take it, :func:`~.execution.sampled_cpu`; at
most the case's budget: a case predicted over it is a predicted ``timeout``, and the tighter
cases of its line are predicted skipped, as :func:`~.schedule.implied` would
skip them), and the wall time on ``N`` workers: the makespan of the scheduler's
rule (:class:`~.schedule.Schedule`: the line with the most predicted CPU left
first, a line's next case once its previous one ended) over those costs, beside
the lower bound ``max(total CPU / N, the dearest case)``. Nothing runs and
nothing is written; the stiffness bound (which measures the model) and racing
(which needs errors) are not predicted, so the plan is of an exhaustive run.

The model is fitted on the store's measured records (:meth:`Store.measured`)
where the store has any for the run's problems, else it is the one committed
with the project, :data:`MODEL_FILE`, refitted from a store by ``python -m
integrator_bench.harness.run.plan STORE`` (docs/full-run.md, "The plan").
"""

from __future__ import annotations

import dataclasses
import heapq
import json
import sys
from collections import Counter, defaultdict, deque
from pathlib import Path

from integrator_bench.harness.run.schedule import (CostModel, predicted_line, problem_size,
                                                  tolerance)

#: the committed model: the medians of CPU per unit of work (:func:`~.schedule.prior_work`)
#: by problem and integrator, problem, integrator and over all, and the problems' sizes
MODEL_FILE = Path(__file__).with_name("cost_model.json")


@dataclasses.dataclass
class Plan:
    """What :func:`make_plan` predicts (seconds of CPU and wall).

    Attributes
    ----------
    kinds : Counter
        ``unsupported``, ``runnable``, ``timeout`` (predicted over its budget)
        and ``skipped: REASON`` -> cases.
    cpu_by_problem : dict
        Problem name -> predicted CPU of its cases.
    dearest : float
        The dearest case's predicted CPU.
    walls : dict
        Workers -> ``(makespan, lower bound)``.
    source : str
        Where the model came from, in words.
    """

    kinds: Counter
    cpu_by_problem: dict
    dearest: float
    walls: dict
    source: str

    @property
    def cpu(self) -> float:
        return sum(self.cpu_by_problem.values())

    def to_dict(self) -> dict:
        return {"cases": dict(self.kinds), "cpu_s": self.cpu,
                "cpu_s_by_problem": self.cpu_by_problem, "dearest_case_s": self.dearest,
                "wall_s": {str(n): {"makespan": m, "lower_bound": b}
                           for n, (m, b) in self.walls.items()},
                "model": self.source}


class _Frozen(CostModel):
    """A :class:`CostModel` that learns nothing more (the plan's predictions)."""

    def learn(self, case, cpu_s) -> None:
        return None


def committed_model(sizes: dict, frozen: bool = True) -> CostModel:
    """The model of :data:`MODEL_FILE` over ``sizes``; not ``frozen``, it learns on (a
    run's model, :class:`~integrator_bench.harness.run.runner.Session`: each
    committed rate one value among the measured ones of its key)."""
    model = _Frozen(sizes) if frozen else CostModel(sizes)
    data = json.loads(MODEL_FILE.read_text(encoding="utf-8"))
    for key, rate in data["rates"].items():
        model.rates[tuple(key.split("|")) if key else ()].append(rate)
    return model


def fitted_model(sizes: dict, rows) -> tuple[CostModel, int]:
    """The model fitted on the store's measured ``rows`` (:meth:`Store.measured`) of
    the problems of ``sizes``, and how many it took."""
    fit = CostModel(sizes)
    for row in rows:
        fit.learn_row(row)
    model = _Frozen(sizes)
    model.rates.update(fit.rates)
    return model, len(fit.rates.get((), ()))


def fit_rates(rows, sizes: dict) -> dict:
    """The medians of a :class:`CostModel` fitted on ``rows`` at its broad levels, as
    :data:`MODEL_FILE` keeps them: ``"problem|integrator"``, ``"problem"``,
    ``"integrator"``, ``""`` (over all); the narrower ones (a formulation, a
    tolerance) are a store's own."""
    fit = CostModel(sizes)
    for row in rows:
        fit.learn_row(row)
    return {"|".join(key): float(f"{sorted(v)[len(v) // 2]:.3g}")
            for key, v in sorted(fit.rates.items()) if len(key) <= 2}


def problem_sizes(rows) -> dict:
    """``ProblemSpec -> (dimension, span)`` of every problem and parameter set of
    ``rows`` (stored records: ``params`` as JSON)."""
    from integrator_bench.harness.matrix.line import ProblemSpec

    sizes = {}
    for row in rows:
        try:
            params = tuple(sorted(json.loads(row["params"]).items()))
        except (TypeError, ValueError, AttributeError):
            continue
        spec = ProblemSpec(row["problem"], params)
        if spec not in sizes:
            sizes[spec] = problem_size(spec)
    return sizes


def make_plan(cases, model: CostModel, budget_s: float, workers, skip: bool = True,
              source: str = "", repeat: int = 1) -> Plan:
    """The :class:`Plan` of ``cases`` under ``model`` with a budget of ``budget_s`` CPU
    seconds a case and at most ``repeat`` timing samples (``--repeat``, the preset's),
    its wall time on each of ``workers`` (numbers of workers)."""
    kinds = Counter()
    lines: dict = defaultdict(list)
    for case in cases:
        if case.unsupported:
            kinds["unsupported"] += 1
        elif case.fault:   # its problem failed to build in its trial: recorded, not run
            kinds["build failed"] += 1
        else:
            kinds["runnable"] += 1
            lines[case.line].append(case)
    costs, by_problem = {}, defaultdict(float)
    for key, line in lines.items():
        kept, timeouts, reasons = predicted_line(sorted(line, key=tolerance, reverse=True),
                                                 model.predict, budget_s, skip=skip,
                                                 repeat=repeat)
        kinds["timeout"] += timeouts
        kinds.update(f"skipped: {why}" for why in reasons)
        by_problem[line[0].problem] += sum(kept)
        costs[key] = kept
    dearest = max((c for line in costs.values() for c in line), default=0.0)
    total = sum(by_problem.values())
    walls = {n: (makespan(costs, n), max(total / n, dearest)) for n in sorted(set(workers))}
    return Plan(kinds, dict(sorted(by_problem.items(), key=lambda kv: -kv[1])), dearest,
                walls, source)


def makespan(costs: dict, workers: int) -> float:
    """When the last of ``costs`` (line -> its cases' CPU, in order) ends on
    ``workers`` workers under the scheduler's rule: the idle worker takes the first
    case of the ready line with the most CPU left; a line is ready again once its
    case ended."""
    ready = [(-sum(c), i, deque(c)) for i, c in enumerate(costs.values()) if c]
    heapq.heapify(ready)
    running: list = []   # (end, line index, its cases left)
    now, idle = 0.0, workers
    while ready or running:
        while idle and ready:
            _, i, left = heapq.heappop(ready)
            heapq.heappush(running, (now + left.popleft(), i, left))
            idle -= 1
        now, i, left = heapq.heappop(running)
        idle += 1
        if left:
            heapq.heappush(ready, (-sum(left), i, left))
    return now


def main(argv=None) -> int:
    """``python -m integrator_bench.harness.run.plan STORE``: refit :data:`MODEL_FILE`
    from the measured records of STORE."""
    from integrator_bench.harness.matrix.store import Store

    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print("usage: python -m integrator_bench.harness.run.plan STORE", file=sys.stderr)
        return 2
    with Store(argv[0], create=False) as store:
        rows = store.measured()
    sizes = problem_sizes(rows)
    MODEL_FILE.write_text(json.dumps({"fitted_on": f"{len(rows)} records (ok, failed, timeout)",
                                      "rates": fit_rates(rows, sizes)}, indent=0) + "\n",
                          encoding="utf-8")
    print(f"{MODEL_FILE}: fitted on {len(rows)} records of {len(sizes)} problems")
    return 0


if __name__ == "__main__":
    sys.exit(main())
