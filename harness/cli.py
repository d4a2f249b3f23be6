"""The ``ibench`` command line (the contract of its names and options: README.md).

    ibench list {problems,integrators,formulations} [--json]
    ibench run [--preset quick|seeds|full] [-p PROBLEM ...] [-f FORMULATION ...]
               [-i INTEGRATOR ...] [--rtol R ...] [--h H ...]
               [--jobs N | --dask tcp://HOST:PORT|local:N] [--timeout SECONDS]
               [--memory MB] [--repeat N] [--store PATH] [--resume] [--no-skip] [--json]
    ibench report [--store PATH] [--out DIR] [--all]
    ibench reference [-p PROBLEM ...] [--check | --recompute] [--json]
    ibench verify [-i INTEGRATOR ...] [--json]
    ibench stiffness -p PROBLEM [--at T ...] [--store PATH] [--out DIR] [--json]
    ibench check-plugin NAME [--timeout SECONDS] [--json]
    ibench advise -p PROBLEM --target E [--error max|final|rms] [-i INTEGRATOR ...]
                  [-f FORMULATION ...] [--budget DURATION] [--perturbed N]
                  [--jobs N | --dask ADDRESS] [--store PATH] [--[no-]resume] [--json] [--out DIR]

The presets are :data:`integrator_bench.harness.cases.PRESETS`. An option that
takes several values (``-p``, ``-f``, ``-i``, ``--rtol``, ``--h``, ``--at``)
accumulates them over repeats (``--rtol 1e-6 --rtol 1e-8`` runs both); an
option of one value given twice is refused. Every option has a help line
(``ibench COMMAND --help``). A bad name or value exits with status 2 and one
line on standard error naming it and the valid choices. Output piped into a
reader that stops early (``| head``) ends quietly with status 0.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
import time
from pathlib import Path

from integrator_bench.harness import registry
from integrator_bench.harness.report.tables import text_table
from integrator_bench.problems.base import format_label

EXIT_BAD_INPUT = 2


# a negative number in any notation: argparse's own pattern misses -1e-3
_NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


class _Parser(argparse.ArgumentParser):
    """Errors in one line with exit status 2; a negative number (``--rtol -1e-3``)
    is read as a value, so its check names it, never as an unknown option."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NEGATIVE_NUMBER

    def error(self, message):  # one line, exit 2
        self.exit(EXIT_BAD_INPUT, f"ibench: error: {message}\n")


def _float(name, positive=True):
    """An argparse type: a finite float, positive unless ``positive`` is False."""
    what = "a positive finite number" if positive else "a finite number"

    def parse(text):
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} {text!r} is not a number") from None
        if not (math.isfinite(value) and (value > 0 or not positive)):
            raise argparse.ArgumentTypeError(f"{name} {text!r} must be {what}")
        return value
    return parse


def _positive_int(text, name="--jobs", least=1):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name} {text!r} is not a whole number") from None
    if value < least:
        raise argparse.ArgumentTypeError(f"{name} {text!r} must be at least {least}")
    return value


def _memory(text):
    if text.lower() in ("none", "unlimited"):
        return None
    return _float("--memory")(text)


class _Once(argparse.Action):
    """Store the option's value; the option given a second time is an error (exit 2)
    rather than a silent choice of the last value."""

    def __call__(self, parser, namespace, values, option_string=None):
        given = namespace.__dict__.setdefault("_given_once", set())
        if self.dest in given:
            parser.error(f"{option_string} given twice ({_shown(getattr(namespace, self.dest))} "
                         f"and {_shown(values)}); give it once")
        given.add(self.dest)
        setattr(namespace, self.dest, values)


def _shown(value) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def build_parser() -> argparse.ArgumentParser:
    from integrator_bench.harness.cases import PRESETS
    from integrator_bench.harness.execution import MAX_SAMPLES, MIN_CPU_S
    from integrator_bench.harness.isolation import DEFAULT_MEMORY_MB, DEFAULT_TIMEOUT
    from integrator_bench.harness.report.targets import DEFAULT_ERROR, ERRORS
    from integrator_bench.harness.references import REFERENCE_TIMEOUT
    from integrator_bench.harness.store import DEFAULT_STORE

    parser = _Parser(prog="ibench", description="Benchmark ODE/DAE integrators on mechanical systems.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    json_help = "print JSON instead of a table"
    error_option = dict(
        choices=sorted(ERRORS), default=DEFAULT_ERROR, action=_Once,
        help="the error lines are ranked by: the largest mixed error |y - r| / (floor + |r|) "
             "of the error components at the final time (final), over the output times (max), "
             "or its root-mean-square over them (rms); floor: the problem's absolute scale "
             f"(default: {DEFAULT_ERROR})")
    store_help = f"the SQLite store of the records (default: {DEFAULT_STORE})"

    p = sub.add_parser("list", help="list problems, integrators or formulations")
    p.add_argument("what", choices=["problems", "integrators", "formulations"],
                   help="what to list")
    p.add_argument("--json", action="store_true", help=f"{json_help}: one JSON array")

    p = sub.add_parser("run", help="run the benchmark matrix")
    p.add_argument("--preset", default="quick", choices=sorted(PRESETS), action=_Once,
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
    p.add_argument("--rtol", nargs="+", action="extend", type=_float("--rtol"), metavar="R",
                   help="relative tolerances, given to every selected integrator "
                        "(repeatable, the values accumulate; default: the preset's)")
    p.add_argument("--h", nargs="+", action="extend", type=_float("--h"), metavar="H",
                   help="fixed step sizes, given to every selected integrator "
                        "(repeatable, the values accumulate; default: the preset's steps "
                        "per time span)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--jobs", type=_positive_int, default=None, action=_Once, metavar="N",
                       help="local worker processes at once (default: the number of cores)")
    where.add_argument("--dask", metavar="ADDRESS", action=_Once,
                       help="run on Dask: tcp://HOST:PORT of a running scheduler, or local:N "
                            "to start a LocalCluster of N workers")
    p.add_argument("--timeout", type=_float("--timeout"), default=None, action=_Once,
                   metavar="SECONDS",
                   help=f"seconds a case may take before its worker is killed (default: "
                        f"{DEFAULT_TIMEOUT:g}; the preset's per-case budget, quick's "
                        f"{PRESETS['quick'].budget_s:g}, full's {PRESETS['full'].budget_s:g}, "
                        f"when no -i, --rtol or --h is given)")
    p.add_argument("--memory", type=_memory, default=DEFAULT_MEMORY_MB, metavar="MB",
                   action=_Once,
                   help="address space a case may allocate, in MiB (RLIMIT_AS; 'none': no "
                        f"limit; default: {DEFAULT_MEMORY_MB:g})")
    p.add_argument("--repeat", type=lambda t: _positive_int(t, "--repeat"), default=None,
                   metavar="N", action=_Once,
                   help=f"time each case at most N times, fewer once the samples add up to "
                        f"{MIN_CPU_S:g} s CPU (default: the preset's, {PRESETS['quick'].samples} "
                        f"for quick whatever the other options, {MAX_SAMPLES} for seeds and "
                        "full; ties need 4 or more): "
                        "cpu_s is the median, cpu_s_min the least, cpu_s_iqr the spread")
    p.add_argument("--store", type=Path, default=DEFAULT_STORE, action=_Once, metavar="PATH",
                   help=store_help)
    p.add_argument("--resume", action="store_true",
                   help="skip the cases the store already holds for this code version (a "
                        "skipped one only when skipped under the same policy)")
    p.add_argument("--no-skip", action="store_true",
                   help="run every case: record none skipped after a timeout at a looser "
                        "tolerance or a divergence at a smaller step")
    p.add_argument("--json", action="store_true",
                   help="print one JSON record per case, one line each, instead of the summary")
    p.add_argument("--error", **error_option)
    p.add_argument("--reference-timeout", type=_float("--reference-timeout"),
                   default=REFERENCE_TIMEOUT, action=_Once, metavar="SECONDS",
                   help="seconds a missing reference may take to compute (default: "
                        f"{REFERENCE_TIMEOUT:g}); past it the problem's cases are recorded "
                        "error, reason no_reference, and not run")

    p = sub.add_parser("report", help="work-precision diagrams and tables from a store")
    p.add_argument("--store", type=Path, default=DEFAULT_STORE, action=_Once, metavar="PATH",
                   help=store_help)
    p.add_argument("--out", type=Path, default=None, action=_Once, metavar="DIR",
                   help="directory of index.html and its figures (default: report/ beside "
                        "the store)")
    p.add_argument("--all", action="store_true",
                   help="keep unsupported combinations in the Markdown tables")
    p.add_argument("--error", **error_option)

    p = sub.add_parser("check-plugin", help="conformance check of a registered integrator")
    p.add_argument("name", help="integrator registry name")
    p.add_argument("--timeout", type=_float("--timeout"), default=60.0, action=_Once,
                   metavar="SECONDS", help="seconds each run of the check may take "
                                           "(default: 60)")
    p.add_argument("--json", action="store_true", help=f"{json_help}: one object per check")

    p = sub.add_parser("reference", help="compute, show or check reference solutions")
    p.add_argument("-p", "--problem", action="append", metavar="PROBLEM",
                   help="name or name:key=value,...; a bare name stands for every benchmark "
                        "parameter set (repeatable; default: every problem)")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--check", action="store_true", help="recompute and compare with the claim")
    group.add_argument("--recompute", action="store_true",
                       help="compute the references again and store them")
    p.add_argument("--json", action="store_true",
                   help=f"{json_help}: the metadata of each reference, one line each")

    p = sub.add_parser("stiffness", help="spectrum of a problem's Jacobian along its reference")
    p.add_argument("-p", "--problem", required=True, metavar="PROBLEM", action=_Once,
                   help="name or name:key=value,...")
    p.add_argument("--at", nargs="+", action="extend", type=_float("--at", positive=False),
                   metavar="T", help="times (repeatable, the values accumulate; default: "
                                     "start, middle and end of the span)")
    p.add_argument("--json", action="store_true", help="print one JSON object per parameter set")
    p.add_argument("--store", type=Path, default=DEFAULT_STORE, action=_Once, metavar="PATH",
                   help="store whose fixed-step runs give the achieved steps")
    p.add_argument("--out", type=Path, default=None, action=_Once, metavar="DIR",
                   help="directory of the spectrum PNGs (default: <store dir>/stiffness)")

    _add_advise(sub, error_option, store_help)

    p = sub.add_parser("verify", help="observed order and stability of integrators")
    p.add_argument("-i", "--integrator", action="append", metavar="INTEGRATOR",
                   help="registry name (repeatable; default: every registered integrator)")
    p.add_argument("--json", action="store_true", help="print one JSON object per integrator")
    return parser


def main(argv=None) -> int:
    from integrator_bench.harness.errors import BadInput, StoreError

    args = build_parser().parse_args(argv)
    args.argv = ["ibench", *(sys.argv[1:] if argv is None else argv)]
    try:
        status = {"list": cmd_list, "run": cmd_run, "report": cmd_report, "verify": cmd_verify,
                  "reference": cmd_reference, "check-plugin": cmd_check_plugin,
                  "stiffness": cmd_stiffness, "advise": cmd_advise}[args.command](args)
        sys.stdout.flush()  # a reader that went away shows here, not at exit
        return status
    except (BadInput, registry.UnknownName, StoreError) as exc:
        print(f"ibench: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except BrokenPipeError:  # `ibench ... | head`: the reader has what it wanted
        _discard_stdout()
        return 0


def _discard_stdout() -> None:
    """Point standard output at /dev/null, so the interpreter's last flush of
    what is still buffered for a closed pipe raises nothing."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)


def cmd_list(args) -> int:
    """The registered problems, integrators or formulations: a table, or JSON.

    Problems come with a second table: each parameter, its default and its
    valid range.
    """
    extra = ""
    if args.what == "problems":
        items = [cls(**{}).describe() for cls in registry.problems().values()]
        rows = [(d["name"], d["dimension"], ",".join(d["formulations"]), d["description"])
                for d in items]
        header = ("name", "dim", "formulations", "description")
        extra = "\n\nparameters:\n" + parameter_table(items) + "\n\nnamed with their parameters:\n" \
            + "\n".join(f"  {name}: {cls.description}" for name, cls in registry.FAMILIES.items())
    elif args.what == "integrators":
        items = [{"name": name, "origin": cls.origin, "description": cls.description,
                  "reference": cls.reference, **cls.capabilities()}
                 for name, cls in registry.integrators().items()]
        rows = [(d["name"], d["origin"],
                 "/".join(d["accepts"]) + (f"<=i{d['max_index']}" if d["max_index"] else ""),
                 d["order"] if d["order"] is not None else "var", _step_kind(d),
                 "yes" if d["events"] else "no", d["description"]) for d in items]
        header = ("name", "origin", "accepts", "order", "step", "events", "description")
        extra = ("\n\nsettings (-i NAME:setting=value,...; value|value|... sweeps one):\n"
                 + settings_table(items))
    else:
        items = [{"name": f, "problems": [n for n, c in registry.problems().items()
                                          if f in c.formulations]}
                 for f in registry.formulations()]
        rows = [(d["name"], ", ".join(d["problems"])) for d in items]
        header = ("name", "problems")
    if args.json:
        print(json.dumps(items, indent=1))
    else:
        print(text_table(header, rows) + extra)
    return 0


def settings_table(items: list[dict]) -> str:
    """Each integrator's settings: default, valid values, the seed's control
    it corresponds to, and meaning."""
    rows = [(d["name"], s["name"], "code's own" if s["default"] is None else s["default"],
             s["valid"], s["control"] or "", s["meaning"])
            for d in items for s in d["settings"]]
    return text_table(("integrator", "setting", "default", "valid", "control", "meaning"), rows)


def _step_kind(capabilities: dict) -> str:
    """``both``, ``adaptive`` or ``fixed``: how an integrator can be driven."""
    if capabilities["adaptive"]:
        return "both" if capabilities["fixed_step"] else "adaptive"
    return "fixed"


def parameter_table(problems: list[dict]) -> str:
    """One row per parameter of each described problem: default and valid range.

    Parameters
    ----------
    problems : list of dict
        :meth:`~integrator_bench.problems.base.Problem.describe` of each problem.
    """
    def bound(value, infinite):
        return infinite if value is None else f"{value:g}"

    rows = [(d["name"], p["name"], f"{p['default']:g}",
             f"[{bound(p['low'], '-inf')}, {bound(p['high'], 'inf')}]", p["description"])
            for d in problems for p in d["parameters"]]
    return text_table(("problem", "parameter", "default", "range", "description"), rows)


def cmd_run(args) -> int:
    from integrator_bench.harness.cases import PRESETS, budget, expand, left_out
    from integrator_bench.harness.isolation import DEFAULT_TIMEOUT
    from integrator_bench.harness.runner import run_matrix
    from integrator_bench.harness.store import DEFAULT_STORE, Store

    cases = expand(problems=args.problem, formulations=args.formulation,
                   integrators=args.integrator, rtols=args.rtol, hs=args.h, preset=args.preset)
    skipped = [] if args.problem else left_out(args.preset)
    if skipped:
        print(f"ibench: the {args.preset} preset leaves out problems of more than "
              f"{PRESETS[args.preset].max_dimension} states: {', '.join(skipped)} "
              f"(name one with -p to run it)", file=sys.stderr)
    if not cases:
        print("ibench: error: the selection gives no cases", file=sys.stderr)
        return EXIT_BAD_INPUT
    import contextlib
    import shlex

    from integrator_bench.harness import dask_backend
    from integrator_bench.harness.errors import BackendLost

    on_record = (lambda r: print(json.dumps(r, default=_json_default), flush=True)) if args.json else None
    with contextlib.ExitStack() as stack:
        # every check that can fail on bad input comes before the store is opened
        client = stack.enter_context(dask_backend.connect(args.dask)) if args.dask else None
        if args.store == DEFAULT_STORE:  # the data directory (harness.paths) may not exist yet
            DEFAULT_STORE.parent.mkdir(parents=True, exist_ok=True)
        store = stack.enter_context(Store(args.store))
        started, cpu0 = time.monotonic(), _process_cpu()
        try:
            timeout = args.timeout or budget(args.preset, args.integrator, args.rtol, args.h,
                                             args.problem, args.formulation) or DEFAULT_TIMEOUT
            df = run_matrix(cases, store=store, jobs=args.jobs, timeout=timeout,
                            resume=args.resume, progress=sys.stderr.isatty() or not args.json,
                            on_record=on_record, memory_mb=args.memory,
                            repeat=args.repeat or PRESETS[args.preset].samples,
                            dask=client, command=shlex.join(args.argv), skip=not args.no_skip,
                            reference_timeout=args.reference_timeout)
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
                      cpu_s=_process_cpu() - cpu0, error=args.error))
    return 0


SUMMARY_COLUMNS = 100  # the widest line of the end-of-run summary
SUMMARY_TARGET = 1e-5  # the error whose cheapest line the summary names
_LABEL_COLUMNS = 26    # the summary's problem column


def summary(df, store: Path | None = None, wall_s: float | None = None,
            cpu_s: float | None = None, error: str | None = None) -> str:
    """The end of ``ibench run``: a line per problem and parameter set, at most
    :data:`SUMMARY_COLUMNS` wide.

    Each line gives the problem (with the parameters that differ from their
    defaults), the counts of ``ok``, ``failed`` and ``timeout`` cases (and of
    ``untimed``, ``error``, ``crashed`` and ``skipped`` ones when there are
    any) and the line (integrator/formulation) that reached an error of
    :data:`SUMMARY_TARGET` (in ``error``, a key of
    :data:`~integrator_bench.harness.report.targets.ERRORS`, default theirs) on
    the least CPU: the report's answer line, from the same table
    (:func:`~integrator_bench.harness.report.targets.cheapest` of
    :func:`~integrator_bench.harness.report.targets.target_table`), ``≤`` marking
    an upper bound as the table does, and the tolerance at the crossing. Then a
    line for each adaptive line whose ok records are the same at every tolerance
    (:func:`integrator_bench.harness.report.records.unresponsive`: "does not
    respond to rtol"), the run's totals (:func:`totals`; with ``wall_s`` and ``cpu_s``, the run's
    wall time and its processes' CPU) and
    the coverage line (:func:`integrator_bench.harness.coverage.summary_line`).
    With ``store``, the last lines name the store, the command that makes the
    report and where it goes (the only lines that may be longer: by their paths).
    """
    from integrator_bench.harness.coverage import summary_line
    from integrator_bench.harness.store import DEFAULT_STORE
    from integrator_bench.harness.report import targets
    from integrator_bench.harness.report.records import clean_records, unresponsive

    error = error or targets.DEFAULT_ERROR
    lines = [f"{'problem':<{_LABEL_COLUMNS}} cases by status; cheapest integrator/formulation "
             f"to {SUMMARY_TARGET:.0e} ({error}), CPU s".replace("e-0", "e-")]
    df = clean_records(df)
    for (name, params), rows in df.groupby(["problem", "params"], sort=True):
        counts = rows["status"].value_counts()
        tally = " ".join(f"{counts.get(s, 0):>3} {s}" for s in ("ok", "failed", "timeout"))
        tally += "".join(f" {counts[s]} {s}" for s in ("untimed", "error", "crashed", "skipped")
                         if counts.get(s))
        top = targets.cheapest(targets.target_table(rows, (SUMMARY_TARGET,), error),
                               SUMMARY_TARGET)
        best, at = "not reached", ""
        if top is not None:
            best = (f"{top['integrator']}/{top['formulation']} "
                    f"{targets.cpu_cell(top['cpu_s'], top['how'])}")
            at = " " + targets.tol_cell(top["tol"], top["mode"]).replace(" ", "=")
        label = _fit(_short_label(name, json.loads(params)), _LABEL_COLUMNS, len(name))
        line = f"{label:<{_LABEL_COLUMNS}} {tally}  {best}"
        # the tolerance at the crossing where it fits, never cut in the middle
        lines.append((line + at if len(line + at) <= SUMMARY_COLUMNS else line)
                     [:SUMMARY_COLUMNS])
    lines += [f"{_short_label(line['problem'], json.loads(line['params']))}: "
              f"{line['integrator']}/{line['formulation']} does not respond to rtol (the same "
              f"counts and errors at {', '.join(f'{r:g}' for r in line['rtols'])})"
              [:SUMMARY_COLUMNS] for line in unresponsive(df)]
    lines += [*totals(df, wall_s, cpu_s), summary_line(df, measure=error)]
    if store is not None:
        command = "ibench report" + ("" if store == DEFAULT_STORE else f" --store {store}")
        unsupported = int((df["status"] == "unsupported").sum())
        lines += [f"{len(df)} cases stored in {store}"
                  + (f" ({unsupported} unsupported, not counted above)" if unsupported else ""),
                  f"the report: {command}",
                  f"  (writes {Path(store).resolve().parent / 'report' / 'index.html'})"]
    return "\n".join(lines)


def _fit(label: str, width: int, keep: int = 0) -> str:
    """``label`` in at most ``width`` characters: a longer one keeps its start (at
    least ``keep`` characters, the problem's name, as room allows) and its end,
    where parameter sets and files differ (``fmu:path…BouncingBall3.fmu``), around
    an ellipsis."""
    if len(label) <= width:
        return label
    head = min(max((width - 1) // 3, keep), width - 9)
    return label[:head] + "…" + label[len(label) - (width - 1 - head):]


def _process_cpu() -> float:
    """CPU seconds of this process and its reaped children (the local workers)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def totals(df, wall_s: float | None = None, cpu_s: float | None = None) -> list[str]:
    """Two lines: wall time, CPU (the processes' with ``cpu_s``, and the solves'
    own, the sum of ``cpu_s``) and the skipped cases' share of those that could
    run (all but ``unsupported``); the counts by status."""
    import pandas as pd

    from integrator_bench.harness.record import STATUSES

    counts = df["status"].value_counts()
    runnable = len(df) - int(counts.get("unsupported", 0))
    skipped = int(counts.get("skipped", 0))
    solves = pd.to_numeric(df["cpu_s"], errors="coerce").sum()
    parts = ([f"wall {wall_s:.0f} s"] if wall_s is not None else [])
    parts.append(f"CPU {cpu_s:.0f} s (solves {solves:.0f} s)" if cpu_s is not None
                 else f"CPU of the solves {solves:.0f} s")
    parts.append(f"skipped {100 * skipped / runnable:.0f} % of {runnable} runnable"
                 if runnable else "nothing runnable")
    return ["; ".join(parts),
            "cases: " + ", ".join(f"{counts[s]} {s}" for s in STATUSES if counts.get(s))]


def _short_label(name: str, params: dict) -> str:
    """``name:key=value,...`` with the parameters that differ from the problem's
    defaults (all of them for a problem the registry does not list)."""
    cls = registry.problems().get(name)
    defaults = {p.name: p.default for p in getattr(cls, "parameters", ())}
    return format_label(name, {k: v for k, v in params.items()
                               if k not in defaults or v != defaults[k]})


def _json_default(value):
    if hasattr(value, "item"):
        return value.item()
    raise TypeError(type(value))


def cmd_report(args) -> int:
    from integrator_bench.harness.report import write_report
    from integrator_bench.harness.store import load, load_runs

    df = load(args.store)
    out = args.out or Path(args.store).resolve().parent / "report"
    files = write_report(df, out, runs=load_runs(args.store), include_unsupported=args.all,
                         scaling_dir=Path(args.store).resolve().parent / "scaling",
                         error=args.error)
    print(f"wrote {len(files)} files to {out}; open {Path(out) / 'index.html'}")
    return 0


def cmd_check_plugin(args) -> int:
    """One line per check; exit 1 when one fails."""
    from integrator_bench.harness.conformance import check_plugin
    from integrator_bench.harness.streams import stdout_to_stderr

    registry.get_integrator(args.name)  # a bad name exits 2 before anything runs
    with stdout_to_stderr():  # what runs here (not in a worker) never mixes with the lines
        checks = check_plugin(args.name, timeout=args.timeout)
    for check in checks:
        print(json.dumps(check.to_dict()) if args.json else check.line(), flush=True)
    return 1 if any(c.passed is False for c in checks) else 0


def cmd_verify(args) -> int:
    """Observed vs declared order and stability per integrator; exit 1 when a check fails."""
    from integrator_bench.harness.streams import stdout_to_stderr
    from integrator_bench.harness.verify import verify

    names = args.integrator or list(registry.integrators())
    for name in names:
        registry.get_integrator(name)  # a bad name exits 2 before anything runs
    failed = 0
    if not args.json:
        print(f"{'integrator':16} {'declared':>8} {'observed':>8}  order  stability  interval  "
              "verdict")
    for name in names:
        with stdout_to_stderr():  # a C solver's messages never among the JSON lines
            v = verify(name)
        failed += v.passed is False
        if args.json:
            print(json.dumps(v.to_dict(), default=_json_default), flush=True)
            continue
        obs = f"{v.observed_order:.2f}" if v.observed_order is not None else "-"
        decl = "var" if v.declared_order is None else v.declared_order
        stab = "-" if v.stability is None else \
            f"{v.stability.declared}:{'ok' if v.stability.passed else 'FAIL'}"
        verdict = {True: "pass", False: "FAIL", None: "no verdict"}[v.passed]
        interval = "-" if v.interval is None else _mark(v.interval.passed)
        print(f"{name:16} {decl!s:>8} {obs:>8}  {_mark(v.order_passed):5}  {stab:9}  "
              f"{interval:8}  {verdict}"
              f"{'  (' + v.note + ')' if v.note else ''}", flush=True)
    return 1 if failed else 0


def _mark(passed) -> str:
    return {True: "ok", False: "FAIL", None: "-"}[passed]


def cmd_reference(args) -> int:
    from integrator_bench.harness import references
    from integrator_bench.harness.cases import parse_problem_spec
    from integrator_bench.harness.streams import stdout_to_stderr

    specs = args.problem or list(registry.problems())
    problems = [registry.get_problem_class(s.partition(":")[0])(**params)
                for s in specs for params in parse_problem_spec(s)]
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
                  f"{'ok  ' if ok else 'FAIL'} {problem.label()}: {detail}")
            continue
        meta = ref.meta
        if args.json:
            print(json.dumps(meta))
        else:
            digits = ", ".join(f"{k} {v:.1f}" for k, v in meta["agreement_digits"].items())
            methods = " vs ".join(m.get("integrator", m.get("method")) for m in meta["methods"])
            print(f"{problem.label()}: {methods}; claimed {meta['claimed_digits']} digits ({digits})")
    return 1 if failed else 0


def cmd_stiffness(args) -> int:
    """Spectrum, stiffness ratio and stable steps per parameter set (see
    :mod:`integrator_bench.harness.stiffness`); every input is checked before
    anything is computed or written."""
    from integrator_bench.harness import stiffness
    from integrator_bench.harness.cases import parse_problem_spec
    from integrator_bench.harness.streams import stdout_to_stderr

    cls = registry.get_problem_class(args.problem.partition(":")[0])
    problems = [cls(**params) for params in parse_problem_spec(args.problem)]
    times = [stiffness.parse_times(problem, args.at) for problem in problems]
    stiffness.check_store(args.store)
    out = args.out or Path(args.store).resolve().parent / "stiffness"
    for problem, at in zip(problems, times):
        with stdout_to_stderr():  # the reference's solvers may write from C
            result = stiffness.analyse(problem, at, args.store)
        png = stiffness.plot(result, stiffness.png_path(problem, out))
        if args.json:
            print(json.dumps({**stiffness.to_json(result), "png": str(png)}, default=_json_default))
        else:
            print(stiffness.text(result) + f"\n\nspectrum: {png}\n", flush=True)
    return 0


def _add_advise(sub, error_option, store_help) -> None:
    """The parser of ``ibench advise``."""
    from integrator_bench.harness.advise.advice import DEFAULT_BUDGET
    from integrator_bench.harness.advise.certificate import PERTURBED_SETS

    p = sub.add_parser("advise", help="the cheapest integrator, settings, formulation and rtol "
                                      "to a target error on your model, with its evidence")
    p.add_argument("-p", "--problem", required=True, metavar="PROBLEM", action=_Once,
                   help="name or name:key=value,... (a bare name: its first benchmark "
                        "parameter set), a plugin, or fmu:path=MODEL.fmu[,score=a+b]")
    p.add_argument("--target", required=True, type=_float("--target", positive=False),
                   action=_Once, metavar="E",
                   help="the error to reach, in (0, 1)")
    p.add_argument("--error", **{**error_option, "help": "the error the target bounds: max "
                                 "(default), the largest mixed error over the output times; "
                                 "final, at the final time; rms, over the output times"})
    p.add_argument("-i", "--integrator", action="append", metavar="INTEGRATOR",
                   help="restrict the candidates (repeatable; name or name:setting=value; a "
                        "bare name brings the seeds' setting variants along)")
    p.add_argument("-f", "--formulation", action="append", metavar="FORMULATION",
                   help="restrict the formulations (repeatable; default: every one)")
    p.add_argument("--budget", default=DEFAULT_BUDGET, action=_Once, metavar="DURATION",
                   help=f"wall time of the whole advice: 300, 300s, 10m, 1h (default: "
                        f"{DEFAULT_BUDGET})")
    p.add_argument("--perturbed", type=lambda t: _positive_int(t, "--perturbed", 0),
                   default=PERTURBED_SETS, action=_Once, metavar="N",
                   help="perturbed parameter sets the leading lines must hold on (0: none; "
                        f"default: {PERTURBED_SETS})")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--jobs", type=_positive_int, default=None, action=_Once, metavar="N",
                       help="local worker processes at once (default: the number of cores)")
    where.add_argument("--dask", metavar="ADDRESS", action=_Once,
                       help="run on Dask: tcp://HOST:PORT or local:N")
    from integrator_bench.harness.store import DEFAULT_STORE
    p.add_argument("--store", type=Path, default=DEFAULT_STORE, action=_Once, metavar="PATH",
                   help=store_help)
    p.add_argument("--resume", action=argparse.BooleanOptionalAction, default=True,
                   help="reuse the store's records of the same cases and code version "
                        "(default); --no-resume runs every case again")
    p.add_argument("--json", action="store_true",
                   help="print the advice as one JSON object, nothing else")
    p.add_argument("--out", type=Path, default=None, action=_Once, metavar="DIR",
                   help="directory of the page index.html and advice.json (default: "
                        "advice/ beside the store)")


def cmd_advise(args) -> int:
    """The advice and its certificate (:mod:`integrator_bench.harness.advise`);
    exit 1 when it is partial, unverified or missing."""
    import contextlib
    import shlex

    from integrator_bench.harness import dask_backend
    from integrator_bench.harness.advise import advice, page
    from integrator_bench.harness.cases import parse_problem_spec
    from integrator_bench.harness.store import DEFAULT_STORE
    from integrator_bench.harness.streams import stdout_to_stderr

    from integrator_bench.harness.errors import BadInput

    if not 0 < args.target < 1:
        raise BadInput(f"--target {args.target:g} must lie in (0, 1)")
    budget_s = advice.parse_duration(args.budget)
    cls = registry.get_problem_class(args.problem.partition(":")[0])
    problem = cls(**parse_problem_spec(args.problem)[0])
    log = lambda line: print(line, file=sys.stderr, flush=True)  # noqa: E731
    with contextlib.ExitStack() as stack:
        client = stack.enter_context(dask_backend.connect(args.dask)) if args.dask else None
        if args.store == DEFAULT_STORE:
            DEFAULT_STORE.parent.mkdir(parents=True, exist_ok=True)
        stack.enter_context(stdout_to_stderr())   # the solvers' messages never on stdout
        try:
            answer = advice.advise(problem, args.target, args.error, budget_s, args.integrator,
                                   args.formulation, store=args.store, jobs=args.jobs,
                                   dask=client, resume=args.resume, perturbed=args.perturbed,
                                   progress=sys.stderr.isatty(), command=shlex.join(args.argv),
                                   log=log)
        except KeyboardInterrupt:
            log(f"ibench: interrupted; every finished case is in {args.store} "
                "(rerun to go on)")
            return 130
    out = args.out or Path(args.store).resolve().parent / "advice"
    answer["page"] = str(page.write_page(answer, out))
    print(json.dumps(answer, default=_json_default) if args.json else page.text(answer),
          flush=True)
    if not args.json:
        log(f"page: {answer['page']}")
    return advice.exit_status(answer)


if __name__ == "__main__":
    sys.exit(main())
