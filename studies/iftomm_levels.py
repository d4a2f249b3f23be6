"""Which formulation/integrator pairs reach the IFToMM precision levels, and at what CPU.

The IFToMM multibody benchmark library (specifications A01-A05 of the University of A
Coruna, ``mbsbenchmark/dist/A0x/A0x_specification.xml``) judges a simulation by the
largest error of its reference variables over the output steps against two levels:
A01 and A02 give 1e-1 (low precision) and 1e-3 (high precision). After ::

    .venv/bin/ibench run --preset iftomm --jobs 2 --store results/iftomm.sqlite
    .venv/bin/python studies/iftomm_levels.py results/iftomm.sqlite

this prints, per problem, a Markdown table with one row per formulation/integrator
pair: for each level the least CPU of an ok run whose largest error over the output
times (the record's ``err_max``: mixed error ``|e| / (1 + |ref|)`` of the problem's
error components, B0's position for ``n_four_bar``, at its ``position_scale`` of 1 m)
is within the level (with its rtol or h), or why none is: ``not reached`` (ran, too
inaccurate), ``failed``/``timeout`` (the statuses of its runs, with the first
message), ``unsupported``. The velocity error of that run (``err_vel``) is shown beside
it, since A02 scores B0's velocity too, and for a mechanism that conserves its energy
(A01, A02, A04) the run's energy variation (``energy_var``, J), IFToMM's accuracy measure
for those. A problem declaring ``precision_levels`` uses its own; the others take
A01/A02's (1e-1, 1e-3), and the table says so (the A04 and A05 levels were not found in
the sources accessible to the project: docs/problems.md). Each row names the pair's
family (``explicit``, ``implicit``, ``dae``: the record's ``family``). Under each table,
per level, the pairs that reach it by family, and the explicit pairs that do not with
what their runs ended in (the stiff A05 is where they are ruled out); then the
unsupported cases with their reasons (the forms that need a Jacobian of full row rank on
Bricard's redundant mechanism, say). Bad input: one line on standard error, exit 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.record import CaseStatus

#: A01's and A02's levels: low and high precision
LEVELS = {"low": 1e-1, "high": 1e-3}


def levels_of(problem: str) -> tuple[dict, bool]:
    """The problem's precision levels, and whether it declares them itself."""
    cls = registry.problems().get(problem)
    own = getattr(cls, "precision_levels", None)
    return (dict(own), True) if own else (dict(LEVELS), False)


def cell(runs: pd.DataFrame, level: float) -> str:
    """The cheapest ok run within ``level``, or why there is none."""
    ok = runs[runs.status == CaseStatus.OK]
    within = ok[ok.err_max <= level].sort_values("cpu_s")
    if len(within):
        best = within.iloc[0]
        tol = f"rtol {best.rtol:g}" if pd.notna(best.rtol) else f"h {best.h:g}"
        vel = f", vel {best.err_vel:.1e}" if pd.notna(best.err_vel) else ""
        energy = (f", dE {best.energy_var:.1e} J"
                  if pd.notna(getattr(best, "energy_var", None)) else "")
        return f"{best.cpu_s:.2f} s ({tol}, err {best.err_max:.1e}{vel}{energy})"
    if len(ok):
        return f"not reached (best err {ok.err_max.min():.1e})"
    statuses = runs.status.value_counts()
    first = runs[runs.status != CaseStatus.OK].iloc[0]
    message = str(first.message or "")[:60]
    return f"{'/'.join(statuses.index)}: {message}"


def tables(df: pd.DataFrame) -> str:
    """The Markdown tables of every problem in the records ``df``."""
    out = []
    for (problem, params), rows in df.groupby(["problem", "params"], sort=True):
        levels, own = levels_of(problem)
        note = "" if own else " (A01/A02's levels; the problem declares none)"
        out += [f"## {problem} {params}{note}", "",
                "| formulation | integrator | family | " + " | ".join(
                    f"{name} ({value:g})" for name, value in levels.items()) + " |",
                "|---|---|---|" + "---|" * len(levels)]
        run = rows[rows.status != CaseStatus.UNSUPPORTED]
        pairs = list(run.groupby(["formulation", "label"], sort=True))
        for (form, integ), runs in pairs:
            out.append(f"| {form} | {integ} | {family_of(runs)} | " + " | ".join(
                cell(runs, value) for value in levels.values()) + " |")
        out += [""] + [who_reaches(pairs, name, value) for name, value in levels.items()]
        out += ["", *unsupported_lines(rows[rows.status == CaseStatus.UNSUPPORTED]), ""]
    return "\n".join(out)


def family_of(runs: pd.DataFrame) -> str:
    """The pair's family as its records say (``explicit``, ``implicit``, ``dae``)."""
    families = runs["family"].dropna() if "family" in runs.columns else pd.Series([], dtype=str)
    return str(families.iloc[0]) if len(families) else "?"


def reaches(runs: pd.DataFrame, level: float) -> bool:
    ok = runs[runs.status == CaseStatus.OK]
    return bool((ok.err_max <= level).any())


def who_reaches(pairs, name: str, level: float) -> str:
    """One line: the pairs within ``level`` by family, and the explicit pairs that
    are not, with the statuses their runs ended in."""
    by_family: dict = {}
    explicit_not = []
    for (form, integ), runs in pairs:
        family = family_of(runs)
        if reaches(runs, level):
            by_family.setdefault(family, []).append(f"{form}/{integ}")
        elif family == "explicit":
            statuses = "/".join(sorted(runs.status.astype(str).unique()))
            explicit_not.append(f"{form}/{integ} ({statuses})")
    reached = "; ".join(f"{family}: {', '.join(names)}" for family, names in
                        sorted(by_family.items())) or "none"
    line = f"- {name} ({level:g}) reached by {reached}."
    if explicit_not:
        line += f" Explicit pairs that did not: {', '.join(explicit_not)}."
    return line


def unsupported_lines(rows: pd.DataFrame) -> list[str]:
    """How many cases were unsupported, and the reason of each formulation that no
    integrator could take (one reason for all, the problem's: Bricard's forms that
    need a full-rank Jacobian); the other refusals are an integrator's kind."""
    if rows.empty:
        return ["0 unsupported cases."]
    lines = []
    for form, cases in rows.groupby("formulation", sort=True):
        reasons = cases["message"].fillna("").unique()
        if len(reasons) == 1 and cases["label"].nunique() > 1:
            lines.append(f"- {form}, every integrator: {reasons[0]}")
    rest = len(rows) - sum(len(c) for f, c in rows.groupby("formulation")
                           if any(line.startswith(f"- {f}, ") for line in lines))
    return ([f"{len(rows)} unsupported cases left out"
             f"{':' if lines else '.'}"] + lines +
            ([f"- {rest} where the integrator takes another kind of system"] if rest and lines
             else []))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("store", type=Path, help="SQLite store of an `ibench run`")
    args = parser.parse_args(argv)
    if not args.store.is_file():
        print(f"store {str(args.store)!r} does not exist", file=sys.stderr)
        return 2
    from integrator_bench.harness.matrix.store import load
    df = load(args.store)
    df = df.sort_values("created").drop_duplicates("case_id", keep="last")
    print(tables(df))
    return 0


if __name__ == "__main__":
    sys.exit(main())
