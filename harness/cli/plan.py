"""``ibench run --plan``: the plan of a run (:mod:`integrator_bench.harness.run.plan`),
printed, nothing run and nothing written."""

from __future__ import annotations

import json
import os

from integrator_bench.harness.cli.options import json_default


def show_plan(cases, context, args) -> int:
    """Print the plan of ``cases`` under ``context`` (its store read, never written;
    ``--json``: one JSON object) and return the exit status."""
    from integrator_bench.harness.matrix.store import Store, StoreError
    from integrator_bench.harness.run.plan import committed_model, fitted_model, make_plan
    from integrator_bench.harness.run.schedule import problem_size

    sizes = {}
    for case in cases:
        if case.spec not in sizes and not case.unsupported:
            sizes[case.spec] = problem_size(case.spec)
    rows = []
    if os.path.isfile(context.store):
        try:
            with Store(context.store, create=False) as store:
                rows = store.measured()
        except StoreError:
            rows = []
    model, used = fitted_model(sizes, rows)
    source = f"fitted on {used} records (ok, failed, timeout) of {context.store}"
    if not used:
        model, source = committed_model(sizes), "the committed model (no record of these " \
            "problems in the store)"
    workers = sorted({context.parallel, *(args.workers or ())})
    plan = make_plan(cases, model, context.limits.budget_s, workers, skip=context.skip,
                     source=source, repeat=context.limits.repeat)
    if args.json:
        print(json.dumps(plan.to_dict(), default=json_default), file=args.data_out)
        return 0
    print(plan_text(plan, context.limits.budget_s, context.race is not None), file=args.data_out)
    return 0


def plan_text(plan, budget_s: float, raced: bool) -> str:
    """The plan in lines."""
    kinds = plan.kinds
    skipped = ", ".join(f"{n} {k.split(': ')[1]}" for k, n in sorted(kinds.items())
                        if k.startswith("skipped"))
    failed = (f"{kinds['build failed']} of problems that failed to build (no process), "
              if kinds["build failed"] else "")
    lines = [f"plan: {kinds['unsupported'] + kinds['build failed'] + kinds['runnable']} cases: "
             f"{kinds['unsupported']} unsupported (no process), {failed}"
             f"{kinds['runnable']} runnable; "
             f"predicted: {kinds['timeout']} timeout (over {budget_s:g} s of CPU), "
             f"{sum(n for k, n in kinds.items() if k.startswith('skipped'))} skipped"
             + (f" ({skipped})" if skipped else ""),
             f"model: {plan.source}",
             "predicted CPU by problem:"]
    lines += [f"  {name:<24} {cpu:10.1f} s" for name, cpu in plan.cpu_by_problem.items()]
    lines.append(f"  {'all':<24} {plan.cpu:10.1f} s  (dearest case {plan.dearest:.3g} s)")
    lines += [f"wall on {n} worker{'s' if n > 1 else ''}: {m:.0f} s "
              f"(lower bound {b:.0f} s: max(CPU / {n}, dearest case); {m / b:.2f} of it)"
              if b else f"wall on {n} workers: 0 s" for n, (m, b) in plan.walls.items()]
    lines.append("not predicted: the stiffness bound's skips" + (
        " and racing's cuts (the plan is of an exhaustive run)" if raced else ""))
    return "\n".join(lines)
