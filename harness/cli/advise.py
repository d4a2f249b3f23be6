"""``ibench advise -p PROBLEM --target E``: the cheapest integrator, settings,
formulation and rtol to a target error on the user's model, found within a budget
and shown with its certificate (:mod:`integrator_bench.harness.advise`)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from integrator_bench.harness.cli.options import (Once, built, cost_option, error_option,
                                                  finite_float, json_default, positive_int,
                                                  store_help, usable_directory)


def add_parser(sub) -> None:
    from integrator_bench.harness.advise.advice import DEFAULT_BUDGET
    from integrator_bench.harness.advise.certificate import PERTURBED_SETS
    from integrator_bench.harness.matrix.store import DEFAULT_STORE

    p = sub.add_parser("advise", help="the cheapest integrator, settings, formulation and rtol "
                                      "to a target error on your model, with its evidence")
    p.add_argument("-p", "--problem", required=True, metavar="PROBLEM", action=Once,
                   help="name or name:key=value,... (a bare name: its first benchmark "
                        "parameter set), a plugin, or fmu:path=MODEL.fmu[,score=a+b]")
    p.add_argument("--target", required=True, type=finite_float("--target", positive=False),
                   action=Once, metavar="E",
                   help="the error to reach, in (0, 1)")
    p.add_argument("--error", **{**error_option(), "help": "the error the target bounds: max "
                                 "(default), the largest mixed error over the output times; "
                                 "final, at the final time; rms, over the output times"})
    p.add_argument("--cost", **cost_option())
    p.add_argument("-i", "--integrator", action="append", metavar="INTEGRATOR",
                   help="restrict the candidates (repeatable; name or name:setting=value; a "
                        "bare name brings the seeds' setting variants along)")
    p.add_argument("-f", "--formulation", action="append", metavar="FORMULATION",
                   help="restrict the formulations (repeatable; default: every one)")
    p.add_argument("--budget", default=DEFAULT_BUDGET, action=Once, metavar="DURATION",
                   help=f"wall time of the whole advice, references included, a hard "
                        f"limit: 300, 300s, 10m, 1h (default: {DEFAULT_BUDGET})")
    p.add_argument("--perturbed", type=lambda t: positive_int(t, "--perturbed", 0),
                   default=PERTURBED_SETS, action=Once, metavar="N",
                   help="perturbed parameter sets (initial-state sets for a model with no "
                        "parameter to perturb) the leading lines must hold on (0: none; "
                        f"default: {PERTURBED_SETS})")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--jobs", type=positive_int, default=None, action=Once, metavar="N",
                       help="local worker processes at once (default: the number of cores)")
    where.add_argument("--dask", metavar="ADDRESS", action=Once,
                       help="run on Dask: tcp://HOST:PORT or local:N")
    p.add_argument("--store", type=Path, default=DEFAULT_STORE, action=Once, metavar="PATH",
                   help=store_help())
    p.add_argument("--resume", action=argparse.BooleanOptionalAction, default=True,
                   help="reuse the store's records of the same cases and code version "
                        "(default); --no-resume runs every case again")
    p.add_argument("--json", action="store_true",
                   help="print the advice as one JSON object, nothing else")
    p.add_argument("--out", type=Path, default=None, action=Once, metavar="DIR",
                   help="directory of the page index.html and advice.json (default: one "
                        "per problem, parameters, target, error and -i/-f choice in advice/ "
                        "beside the store)")


def command(args) -> int:
    """The advice and its certificate; exit 1 when it is partial, unverified or
    missing."""
    import shlex
    import time

    from integrator_bench.harness.advise import advice, page
    from integrator_bench.harness.errors import BackendLost, BadInput
    from integrator_bench.harness.matrix.cases import parse_problem_spec
    from integrator_bench.harness.run.context import RunContext
    from integrator_bench.harness.run.streams import stdout_to_stderr

    started = time.monotonic()   # the budget counts from here
    if not 0 < args.target < 1:
        raise BadInput(f"--target {args.target:g} must lie in (0, 1)")
    budget_s = advice.parse_duration(args.budget)
    problems, _ = built(parse_problem_spec(args.problem)[:1], "advice")
    if not problems:   # its build failed: said in one line
        return 1
    problem = problems[0]
    out = usable_directory(args.out or page.default_dir(args.store, problem, args.target,
                                                        args.error, args.integrator,
                                                        args.formulation))
    log = lambda line: print(line, file=sys.stderr, flush=True)  # noqa: E731
    question = advice.Question(args.target, args.error, budget_s, args.integrator,
                               args.formulation, args.perturbed, args.cost)
    context = RunContext(store=args.store, jobs=args.jobs, dask=args.dask, resume=args.resume,
                         progress=sys.stderr.isatty() or not args.json,
                         command=shlex.join(args.argv))
    with stdout_to_stderr():   # the solvers' messages never on stdout
        try:
            answer = advice.advise(problem, question, context, log=log, started=started)
        except KeyboardInterrupt:
            log(f"ibench: interrupted; every finished case is in {args.store} "
                "(rerun to go on)")
            return 130
        except BackendLost as exc:
            log(f"ibench: {exc}; every finished case is in {args.store} (rerun to go on)")
            return 1
    written = str(page.write_page(answer, out))
    print(json.dumps({**answer.to_dict(), "page": written}, default=json_default) if args.json
          else page.text(answer), file=args.data_out, flush=True)
    if not args.json:
        log(f"page: {written}")
    return advice.exit_status(answer)
