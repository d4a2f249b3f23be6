"""``ibench reference``: compute, show or check the problems' reference solutions."""

from __future__ import annotations

import functools
import json
import sys

from integrator_bench.harness.cli.options import JSON_HELP, Once, built, finite_float
from integrator_bench.harness.errors import ReferenceFailure
from integrator_bench.harness.matrix import registry
from integrator_bench.problems.base import ProblemError


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
    p.add_argument("--reference-timeout", type=finite_float("--reference-timeout"),
                   default=None, action=Once, metavar="SECONDS",
                   help="seconds of CPU each problem's work may take (its model's code runs "
                        "in a process of its own, killed past it; default: no limit)")


def command(args) -> int:
    """Each problem's reference shown, computed or checked, in a process of its own
    (:mod:`~integrator_bench.harness.run.model_calls`): a problem whose model
    raises, crashes or hangs there (past ``--reference-timeout``) is one line on
    standard error (a ``FAIL`` line with ``--check``), the others go on; exit 1
    when one failed."""
    from integrator_bench.harness.errors import ModelFault
    from integrator_bench.harness.matrix.cases import parse_problem_spec
    from integrator_bench.harness.run.streams import stdout_to_stderr

    specs = args.problem or list(registry.problems())
    mode = "unit_costs" if args.unit_costs else "check" if args.check else \
        "recompute" if args.recompute else "load"
    problems, failed = built([pspec for s in specs for pspec in parse_problem_spec(s)],
                             "unit costs" if mode == "unit_costs" else "reference")
    for problem in problems:
        with stdout_to_stderr():  # the solvers' own messages never among the results
            try:
                out = _work(problem, mode, args.reference_timeout)
            except (ReferenceFailure, ProblemError, ModelFault) as exc:
                out = exc
        if isinstance(out, Exception) and mode != "check":
            failed += 1
            what = "unit costs" if mode == "unit_costs" else "reference"
            print(f"ibench: no {what} for {problem.label()}: {out}", file=sys.stderr, flush=True)
            continue
        for line in _lines(problem, mode, out, args.json):
            print(line, file=args.data_out, flush=True)
        failed += mode == "check" and (isinstance(out, Exception) or not out[0])
    return 1 if failed else 0


def _work(problem, mode: str, limit):
    """One problem's work, its model's code in a process of its own
    (:mod:`~integrator_bench.harness.run.model_calls`, ``limit`` its CPU budget): its
    unit cost lines, ``(ok, detail)`` of its check, or its reference's metadata (a
    computed reference stored from here)."""
    from integrator_bench.harness.measure import references
    from integrator_bench.harness.forking.child import call
    from integrator_bench.harness.run import model_calls

    if mode == "unit_costs":
        return call(functools.partial(unit_cost_lines, problem), "its unit costs were measured",
                    limit)
    if mode == "check":
        return call(functools.partial(references.check, problem), "its reference was checked",
                    limit, expected=(ReferenceFailure, ProblemError))
    return model_calls.reference(problem, limit=limit, recompute=mode == "recompute").meta


def _lines(problem, mode: str, out, as_json: bool) -> list[str]:
    """The output lines of one problem's work ``out`` (for a check, an exception
    is its failed check)."""
    if mode == "unit_costs":
        return [json.dumps(line) if as_json else _cost_text(line) for line in out]
    if mode == "check":
        ok, detail = (False, str(out)) if isinstance(out, Exception) else out
        line = {"label": problem.label(), "ok": ok, "detail": detail}
        return [json.dumps(line) if as_json else
                f"{'ok  ' if ok else 'FAIL'} {problem.label()}: {detail}"]
    if as_json:
        return [json.dumps(out)]
    digits = ", ".join(f"{k} {v:.1f}" for k, v in out["agreement_digits"].items())
    methods = " vs ".join(m.get("integrator", m.get("method")) for m in out["methods"])
    return [f"{problem.label()}: {methods}; claimed {out['claimed_digits']} digits ({digits})"]


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
