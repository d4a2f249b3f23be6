"""``ibench report``: the work-precision diagrams, tables and pages of a store."""

from __future__ import annotations

from pathlib import Path

from integrator_bench.harness.cli.options import (Once, cost_option, error_option, finite_float,
                                                  store_help, usable_directory)


def add_parser(sub) -> None:
    from integrator_bench.harness.matrix.store import DEFAULT_STORE

    p = sub.add_parser("report", help="work-precision diagrams and tables from a store")
    p.add_argument("--store", type=Path, default=DEFAULT_STORE, action=Once, metavar="PATH",
                   help=store_help())
    p.add_argument("--out", type=Path, default=None, action=Once, metavar="DIR",
                   help="directory of index.html and its figures (default: report/ beside "
                        "the store)")
    p.add_argument("--all", action="store_true",
                   help="keep unsupported combinations in the Markdown tables")
    p.add_argument("--error", **error_option())
    p.add_argument("--target", type=finite_float("--target"), default=None, action=Once,
                   metavar="E",
                   help="the target error of the tables, answers and profiles, any positive "
                        "number (default: 1e-3 and 1e-5, the answers at 1e-5)")
    p.add_argument("--cost", **cost_option())


def command(args) -> int:
    from integrator_bench.harness.report import write_report
    from integrator_bench.harness.sources.page import appendix
    from integrator_bench.harness.matrix.store import load, load_runs

    df = load(args.store)   # the store and --out are checked before anything is written
    out = usable_directory(args.out or Path(args.store).resolve().parent / "report")
    files = write_report(df, out, runs=load_runs(args.store), include_unsupported=args.all,
                         scaling_dir=Path(args.store).resolve().parent / "scaling",
                         error=args.error, target=args.target, cost=args.cost,
                         appendix=appendix)
    print(f"wrote {len(files)} files to {out}; open {Path(out) / 'index.html'}")
    return 0


