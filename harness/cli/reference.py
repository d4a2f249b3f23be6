"""``ibench reference``: compute, show or check the problems' reference solutions."""

from __future__ import annotations

import json

from integrator_bench.harness.cli.options import JSON_HELP
from integrator_bench.harness.matrix import registry


def add_parser(sub) -> None:
    p = sub.add_parser("reference", help="compute, show or check reference solutions")
    p.add_argument("-p", "--problem", action="append", metavar="PROBLEM",
                   help="name or name:key=value,...; a bare name stands for every benchmark "
                        "parameter set (repeatable; default: every problem)")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--check", action="store_true", help="recompute and compare with the claim")
    group.add_argument("--recompute", action="store_true",
                       help="compute the references again and store them")
    group.add_argument("--unit-costs", action="store_true",
                       help="measure each formulation's unit costs on this machine (one "
                            "right-hand side, analytic Jacobian, factorization and solve of "
                            "the iteration matrix: what a case's work is taken at)")
    p.add_argument("--json", action="store_true",
                   help=f"{JSON_HELP}: the metadata of each reference, one line each")


def command(args) -> int:
    from integrator_bench.harness.measure import references
    from integrator_bench.harness.matrix.cases import parse_problem_spec
    from integrator_bench.harness.run.streams import stdout_to_stderr

    specs = args.problem or list(registry.problems())
    problems = [pspec.build() for s in specs for pspec in parse_problem_spec(s)]
    if args.unit_costs:
        for problem in problems:
            for line in unit_cost_lines(problem):
                print(json.dumps(line) if args.json else _cost_text(line), file=args.data_out)
        return 0
    failed = 0
    for problem in problems:
        with stdout_to_stderr():  # the solvers' own messages never among the results
            if args.check:
                ok, detail = references.check(problem)
            elif args.recompute:
                ref = references.compute(problem)
                references.save(ref, problem)
            else:
                ref = references.load(problem)
        if args.check:
            failed += not ok
            line = {"label": problem.label(), "ok": ok, "detail": detail}
            print(json.dumps(line) if args.json else
                  f"{'ok  ' if ok else 'FAIL'} {problem.label()}: {detail}", file=args.data_out)
            continue
        meta = ref.meta
        if args.json:
            print(json.dumps(meta), file=args.data_out)
        else:
            digits = ", ".join(f"{k} {v:.1f}" for k, v in meta["agreement_digits"].items())
            methods = " vs ".join(m.get("integrator", m.get("method")) for m in meta["methods"])
            print(f"{problem.label()}: {methods}; claimed {meta['claimed_digits']} digits ({digits})")
    return 1 if failed else 0




def unit_cost_lines(problem) -> list[dict]:
    """The unit costs of each formulation of ``problem`` in each form it is handed
    to integrators (its own kind; an ODE's index-0 DAE form; a second-order
    form it carries), measured here
    (:func:`~integrator_bench.harness.measure.unit_costs.measure`), one dict each:
    ``label``, ``formulation``, ``kind`` and the costs in seconds."""
    import dataclasses

    from integrator_bench.harness.measure import unit_costs

    out = []
    for formulation in problem.formulations:
        system = problem.formulate(formulation)
        forms = [system]
        if system.kind == "ode" and getattr(system, "project", None) is None:
            forms.append(system.as_dae())
        if getattr(system, "mechanical", None) is not None:
            forms.append(system.mechanical)
        for form in forms:
            costs = unit_costs.measure(form)
            if costs is not None:
                out.append({"label": problem.label(), "formulation": formulation,
                            "kind": form.kind, **dataclasses.asdict(costs)})
    return out


def _cost_text(line: dict) -> str:
    us = {k: "-" if line[k] is None else f"{line[k] * 1e6:.3g} us"
          for k in ("rhs", "jac", "lu", "solve")}
    return (f"{line['label']} {line['formulation']} ({line['kind']}): right-hand side "
            f"{us['rhs']}, Jacobian {us['jac']}, LU {us['lu']}, solve {us['solve']} "
            f"(n {line['n']}, {'sparse, ' + str(line['nnz']) + ' non-zeros' if line['sparse'] else 'dense'})")
