"""``ibench stiffness -p PROBLEM``: the spectrum of the problem's Jacobian along its
reference, its stiffness ratio and the stable steps of the explicit methods."""

from __future__ import annotations

import functools
import json
import sys
from pathlib import Path

from integrator_bench.harness.cli.options import (Once, built, finite_float, json_default,
                                                  usable_directory)


def add_parser(sub) -> None:
    from integrator_bench.harness.matrix.store import DEFAULT_STORE

    p = sub.add_parser("stiffness", help="spectrum of a problem's Jacobian along its reference")
    p.add_argument("-p", "--problem", required=True, metavar="PROBLEM", action=Once,
                   help="name or name:key=value,...")
    p.add_argument("--at", nargs="+", action="extend", type=finite_float("--at", positive=False),
                   metavar="T", help="times (repeatable, the values accumulate; default: "
                                     "start, middle and end of the span)")
    p.add_argument("--json", action="store_true", help="print one JSON object per parameter set")
    p.add_argument("--store", type=Path, default=DEFAULT_STORE, action=Once, metavar="PATH",
                   help="store whose fixed-step runs give the achieved steps")
    p.add_argument("--out", type=Path, default=None, action=Once, metavar="DIR",
                   help="directory of the spectrum PNGs (default: <store dir>/stiffness)")
    p.add_argument("--reference-timeout", type=finite_float("--reference-timeout"),
                   default=None, action=Once, metavar="SECONDS",
                   help="seconds of CPU each parameter set's analysis (and its missing "
                        "reference) may take: its model's code runs in a process of its own, "
                        "killed past it (default: no limit)")


def command(args) -> int:
    """Spectrum, stiffness ratio and stable steps per parameter set (see
    :mod:`integrator_bench.harness.measure.stiffness`); every input is checked before
    anything is computed or written. Each analysis runs in a process of its own
    (:mod:`~integrator_bench.harness.run.model_calls`): a parameter set whose model
    raises, crashes or hangs there is one line on standard error, the others go
    on; exit 1 when one failed."""
    from integrator_bench.harness.errors import ModelFault, ReferenceFailure
    from integrator_bench.harness.measure import stiffness
    from integrator_bench.harness.matrix.cases import parse_problem_spec
    from integrator_bench.harness.forking.child import call
    from integrator_bench.harness.run import model_calls
    from integrator_bench.harness.run.streams import stdout_to_stderr
    from integrator_bench.problems.base import ProblemError

    problems, failed = built(parse_problem_spec(args.problem), "stiffness analysis")
    times = [stiffness.parse_times(problem, args.at) for problem in problems]
    stiffness.check_store(args.store)
    out = usable_directory(args.out or Path(args.store).resolve().parent / "stiffness")
    for problem, at in zip(problems, times):
        with stdout_to_stderr():  # the reference's solvers may write from C
            try:   # a missing reference computed, and stored from here
                model_calls.reference(problem, limit=args.reference_timeout)
                result = call(
                    functools.partial(stiffness.analyse, problem, at, args.store),
                    "its stiffness was analysed", args.reference_timeout,
                    expected=(ReferenceFailure, ProblemError))
            except (ReferenceFailure, ProblemError, ModelFault) as exc:
                failed += 1
                print(f"ibench: no stiffness analysis for {problem.label()}: {exc}",
                      file=sys.stderr, flush=True)
                continue
        png = stiffness.plot(result, stiffness.png_path(problem, out))
        if args.json:
            print(json.dumps({**stiffness.to_json(result), "png": str(png)}, default=json_default),
                  file=args.data_out)
        else:
            print(stiffness.text(result) + f"\n\nspectrum: {png}\n", flush=True)
    return 1 if failed else 0


