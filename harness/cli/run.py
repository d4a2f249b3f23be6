"""``ibench run``: the benchmark matrix, a record per case in the store, and the
summary at its end (:mod:`.summary`)."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from integrator_bench.harness.cli.options import (EXIT_BAD_INPUT, Once, error_option,
                                                  json_default, memory, finite_float,
                                                  positive_int, store_help)
from integrator_bench.harness.cli.summary import summary


def add_parser(sub) -> None:
    from integrator_bench.harness.measure.references import REFERENCE_TIMEOUT
    from integrator_bench.harness.matrix.cases import PRESETS
    from integrator_bench.harness.matrix.store import DEFAULT_STORE
    from integrator_bench.harness.run.execution import MAX_SAMPLES, MIN_CPU_S
    from integrator_bench.harness.ranking.racing import TAU
    from integrator_bench.harness.ranking.reach import DEFAULT_TARGET
    from integrator_bench.harness.run.limits import DEFAULT_BUDGET_S, DEFAULT_MEMORY_MB

    p = sub.add_parser("run", help="run the benchmark matrix")
    p.add_argument("--preset", default="quick", choices=sorted(PRESETS), action=Once,
                   help="the matrix run by default: its tolerances, step counts, formulations "
                        "and per-case budget (default: quick)")
    p.add_argument("-p", "--problem", action="append", metavar="PROBLEM",
                   help="name or name:key=value,...; a bare name runs every benchmark "
                        "parameter set of the problem (repeatable; default: every problem; "
                        "the quick preset takes each one's first set and leaves out those "
                        f"of more than {PRESETS['quick'].max_dimension} states)")
    p.add_argument("-f", "--formulation", action="append", metavar="FORMULATION",
                   help="formulation to run, e.g. ode, i3, ggl (repeatable; default: the "
                        "preset's)")
    p.add_argument("-i", "--integrator", action="append", metavar="INTEGRATOR",
                   help="integrator registry name (repeatable; default: every registered one)")
    p.add_argument("--rtol", nargs="+", action="extend", type=finite_float("--rtol", below=1),
                   metavar="R",
                   help="relative tolerances in (0, 1), given to every selected integrator "
                        "(repeatable, the values accumulate; default: the preset's)")
    p.add_argument("--h", nargs="+", action="extend", type=finite_float("--h"), metavar="H",
                   help="fixed step sizes, given to every selected integrator "
                        "(repeatable, the values accumulate; default: the preset's steps "
                        "per time span)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--jobs", type=positive_int, default=None, action=Once, metavar="N",
                       help="local worker processes at once (default: the number of cores)")
    where.add_argument("--dask", metavar="ADDRESS", action=Once,
                       help="run on Dask: tcp://HOST:PORT of a running scheduler, or local:N "
                            "to start a LocalCluster of N workers")
    p.add_argument("--timeout", type=finite_float("--timeout"), default=None, action=Once,
                   metavar="SECONDS", dest="budget_s",
                   help=f"seconds a case may take before its worker is killed (default: "
                        f"{DEFAULT_BUDGET_S:g}; the preset's per-case budget, quick's "
                        f"{PRESETS['quick'].budget_s:g}, full's {PRESETS['full'].budget_s:g}, "
                        f"when no -i, --rtol or --h is given)")
    p.add_argument("--memory", type=memory, default=DEFAULT_MEMORY_MB, metavar="MB",
                   action=Once,
                   help="address space a case may allocate, in MiB (RLIMIT_AS; 'none': no "
                        f"limit; default: {DEFAULT_MEMORY_MB:g})")
    p.add_argument("--repeat", type=lambda t: positive_int(t, "--repeat"), default=None,
                   metavar="N", action=Once,
                   help=f"time each case at most N times, fewer once the samples add up to "
                        f"{MIN_CPU_S:g} s CPU (default: the preset's, {PRESETS['quick'].samples} "
                        f"for quick whatever the other options, {MAX_SAMPLES} for seeds and "
                        "full; the contenders of each answer get more afterwards): "
                        "cpu_s is the median, cpu_s_min the least, cpu_s_iqr the spread")
    p.add_argument("--store", type=Path, default=DEFAULT_STORE, action=Once, metavar="PATH",
                   help=store_help())
    p.add_argument("--resume", action="store_true",
                   help="skip the cases the store already holds for this code version (a "
                        "skipped one only when skipped under the same policy)")
    p.add_argument("--no-skip", action="store_true",
                   help="run every case: record none skipped after a timeout at a looser "
                        "tolerance or a divergence at a smaller step")
    race = p.add_mutually_exclusive_group()
    race.add_argument("--race-target", type=finite_float("--race-target", below=1), default=None,
                      action=Once, metavar="E",
                      help="race the run at target error E (in --error): once a line of a "
                           "problem and parameter set reaches E, its other cases get at most "
                           f"tau = {TAU:g} times the least CPU a line needed, and a case "
                           "stopped there is recorded dominated (default: the full and iftomm "
                           f"presets race at {DEFAULT_TARGET:g}, the others do not)")
    race.add_argument("--exhaustive", action="store_true",
                      help="race nothing: every case runs to its budget")
    p.add_argument("--plan", action="store_true",
                   help="print the plan of the run and run nothing, write nothing: the cases "
                        "by kind, the predicted CPU per problem and in all, and the predicted "
                        "wall time on this machine's cores and on --workers N")
    p.add_argument("--workers", type=lambda t: positive_int(t, "--workers"), action="append",
                   metavar="N", help="with --plan: the wall time predicted on N workers too "
                                     "(repeatable)")
    p.add_argument("--no-contenders", action="store_true",
                   help="time no contender again: every answer rests on the matrix's own "
                        "samples (by default the lines within 2x of each answer's cheapest "
                        "are timed again, alternating, until their margin is known, within "
                        "10 %% of the run's CPU)")
    p.add_argument("--json", action="store_true",
                   help="print one JSON record per case, one line each, instead of the summary "
                        "(the contenders' records timed again are stored, superseding, not "
                        "printed)")
    p.add_argument("--error", **error_option())
    p.add_argument("--reference-timeout", type=finite_float("--reference-timeout"),
                   default=REFERENCE_TIMEOUT, action=Once, metavar="SECONDS",
                   help="seconds a missing reference may take to compute (default: "
                        f"{REFERENCE_TIMEOUT:g}); past it the problem's cases are recorded "
                        "error, reason no_reference, and not run")


def command(args) -> int:
    from integrator_bench.harness.matrix.cases import PRESETS, budget, expand, left_out
    from integrator_bench.harness.sources.numbers import listed_cases

    if args.workers and not args.plan:
        print("ibench: error: --workers is for --plan (the run's own workers: --jobs or "
              "--dask)", file=sys.stderr)
        return EXIT_BAD_INPUT
    cases = expand(problems=args.problem, formulations=args.formulation,
                   integrators=args.integrator, rtols=args.rtol, hs=args.h, preset=args.preset,
                   listed=listed_cases(args.preset))
    skipped = [] if args.problem else left_out(args.preset)
    if skipped:
        print(f"ibench: the {args.preset} preset leaves out problems of more than "
              f"{PRESETS[args.preset].max_dimension} states: {', '.join(skipped)} "
              f"(name one with -p to run it)", file=sys.stderr)
    if not cases:
        print("ibench: error: the selection gives no cases", file=sys.stderr)
        return EXIT_BAD_INPUT
    import shlex

    from integrator_bench.harness.errors import BackendLost
    from integrator_bench.harness.run.context import RunContext
    from integrator_bench.harness.run.limits import Limits
    from integrator_bench.harness.run.runner import Session, process_cpu

    on_record = (lambda r: print(json.dumps(dict(r), default=json_default), file=args.data_out,
                                  flush=True)) if args.json else None
    limits = Limits(budget_s=args.budget_s or budget(args.preset, args.integrator, args.rtol,
                                                      args.h, args.problem, args.formulation),
                    repeat=args.repeat or PRESETS[args.preset].samples,
                    memory_mb=args.memory, reference_timeout=args.reference_timeout)
    context = RunContext(store=args.store, jobs=args.jobs, dask=args.dask, resume=args.resume,
                         skip=not args.no_skip, progress=sys.stderr.isatty() or not args.json,
                         command=shlex.join(args.argv), limits=limits, race=_race(args))
    if args.plan:
        from integrator_bench.harness.cli.plan import show_plan

        return show_plan(cases, context, args)
    # every check that can fail on bad input (--dask) comes before the store is opened
    with Session(context) as session:
        started, cpu0 = time.monotonic(), process_cpu()
        try:
            df = session.run(cases, on_record=on_record)
            settled = None if args.no_contenders else _settle(
                session, df, cases, args.error, process_cpu() - cpu0)
            if settled is not None:
                df = settled.records
        except KeyboardInterrupt:
            print(f"ibench: interrupted; every finished case is in {args.store} "
                  f"(rerun with --resume)", file=sys.stderr)
            return 130
        except BackendLost as exc:
            print(f"ibench: {exc}; every finished case is in {args.store} "
                  f"(rerun with --resume)", file=sys.stderr)
            return 1
    if not args.json:
        print(summary(df, args.store, wall_s=time.monotonic() - started,
                      cpu_s=process_cpu() - cpu0, error=args.error,
                      contenders=settled.line() if settled is not None else None))
    return 0


def _race(args):
    """The run's :class:`~integrator_bench.harness.ranking.racing.Race`, or None: on
    with ``--race-target``, off with ``--exhaustive``, else as the preset says."""
    from integrator_bench.harness.matrix.cases import PRESETS
    from integrator_bench.harness.ranking.racing import Race
    from integrator_bench.harness.ranking.reach import DEFAULT_TARGET

    if args.exhaustive or not (args.race_target or PRESETS[args.preset].race):
        return None
    return Race(args.race_target or DEFAULT_TARGET, measure=args.error)


def _settle(session, df, cases, error, run_cpu_s):
    """The contenders of the run's answers (at the default target, in ``error``)
    timed again (:func:`~integrator_bench.harness.contend.rounds.settle`), within
    :data:`~integrator_bench.harness.contend.rounds.CPU_SHARE` of the run's CPU so
    far, each record timed again stored anew in the run."""
    from integrator_bench.harness.contend.rounds import CPU_SHARE, Contention, settle
    from integrator_bench.harness.ranking.reach import DEFAULT_ERROR, DEFAULT_TARGET

    log = (lambda m: print(m, file=sys.stderr)) if session.context.progress else None
    how = Contention(targets=(DEFAULT_TARGET,), measure=error or DEFAULT_ERROR,
                     cpu_cap_s=CPU_SHARE * run_cpu_s, jobs=session.context.parallel,
                     limits=session.context.limits)
    return settle(df, cases, session.supersede, how, log=log)


