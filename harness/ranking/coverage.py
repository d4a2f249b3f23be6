"""Does a store still answer the question once cases were skipped?

Every problem x formulation family x integrator family should keep at least
one measured (``ok``) point on each side of the default target
(:data:`~integrator_bench.harness.ranking.reach.DEFAULT_TARGET`, in the ranking's
error, by default the largest mixed error over the output times,
:mod:`integrator_bench.harness.ranking.reach`),
where its methods can reach it. :func:`coverage` tells, per group, how many
points lie above and at-or-below the target and how many cases were cut
short by the budget (``timeout``, or ``skipped``: every skip rule stands for a
timeout foreseen); a side with no point is a *gap* when some case of the group
was so cut (a larger budget, a looser ladder or ``--no-skip`` might give it the
point), and ``not reached`` when every case ran to its end: the methods do not
reach that side at the run's tolerances and steps.

Formulation families (:data:`FORMULATION_FAMILIES`): the underlying ODE (``ode``,
``partitioning`` and ``tangent``, ODEs in independent coordinates), the index-reduced
DAEs (``i3``, ``i2``, ``i1``, and ``al3``, the index-3 DAE in augmented
Lagrangian form), the stabilized forms (``ggl``, ``baumgarte``)
and ``projection``. Integrator families: the family
(:func:`~integrator_bench.harness.matrix.line.family`) of the integrator alone, whatever
the formulation: ``explicit`` and ``implicit`` ODE methods (the integrator's
``implicit``), ``dae`` for those that take no ODE (DAE and second-order mechanical
solvers).
"""

from __future__ import annotations

import pandas as pd

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.line import family
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.harness.ranking.reach import DEFAULT_TARGET, line_points

FORMULATION_FAMILIES = {"ode": ("ode", "partitioning", "tangent"),
                        "dae": ("i3", "i2", "i1", "al3"),
                        "stabilized": ("ggl", "baumgarte"), "projection": ("projection",)}
VERDICTS = ("both sides", "gap", "not reached", "only below")


def formulation_family(formulation: str) -> str:
    """The family of ``formulation`` (itself when none lists it: a plugin's)."""
    for name, members in FORMULATION_FAMILIES.items():
        if formulation in members:
            return name
    return formulation


def coverage(df: pd.DataFrame, target: float = DEFAULT_TARGET,
             measure: str | None = None) -> pd.DataFrame:
    """One row per problem x formulation family x integrator family that ran.

    Parameters
    ----------
    df : pandas.DataFrame
        Records with every field (a loaded store, ``Session.run``'s DataFrame,
        :func:`~integrator_bench.harness.ranking.records.clean_records`).
    target : float
        The error whose two sides are checked.
    measure : str, optional
        The error (a key of :data:`~integrator_bench.harness.ranking.reach.ERRORS`;
        default theirs).

    Returns
    -------
    pandas.DataFrame
        ``problem``, ``formulation_family``, ``integrator_family``, ``above``
        and ``below`` (ok points with error above, and at or below, the
        target), ``cut`` (cases ``timeout`` or ``skipped``) and ``verdict``
        (one of :data:`VERDICTS`).
    """
    cols = ["problem", "formulation_family", "integrator_family", "above", "below", "cut",
            "verdict"]
    run = df[df["status"] != CaseStatus.UNSUPPORTED].reset_index(drop=True)  # stores concatenated
    if run.empty:
        return pd.DataFrame(columns=cols)
    run = run.assign(formulation_family=[formulation_family(f) for f in run["formulation"]],
                     integrator_family=[family(registry.integrators().get(i), None)
                                        for i in run["integrator"]])
    points = line_points(run, *([measure] if measure else []))
    out = []
    for key, rows in run.groupby(cols[:3], sort=True):
        err = points.loc[points.index.intersection(rows.index), "err"]
        above, below = int((err > target).sum()), int((err <= target).sum())
        cut = int(rows["status"].isin([CaseStatus.SKIPPED, CaseStatus.TIMEOUT]).sum())
        if above and below:
            verdict = "both sides"
        elif cut:
            verdict = "gap"
        else:
            verdict = "only below" if below else "not reached"
        out.append([*key, above, below, cut, verdict])
    return pd.DataFrame(out, columns=cols)


def gaps(df: pd.DataFrame, target: float = DEFAULT_TARGET,
         measure: str | None = None) -> pd.DataFrame:
    """The rows of :func:`coverage` whose verdict is ``gap``."""
    table = coverage(df, target, measure)
    return table[table["verdict"] == "gap"]


def summary_line(df: pd.DataFrame, target: float = DEFAULT_TARGET, width: int = 100,
                 measure: str | None = None) -> str:
    """One line of at most ``width`` characters: how many groups have points on
    both sides of ``target`` (in ``measure``), and the gaps."""
    table = coverage(df, target, measure)
    counts = table["verdict"].value_counts()
    line = (f"points both sides of {target:.0e}: {counts.get('both sides', 0)} of {len(table)} "
            f"problem/formulation/integrator families; {counts.get('gap', 0)} gaps")
    bad = table[table["verdict"] == "gap"]
    if len(bad):
        line += ": " + ", ".join(f"{r.problem}/{r.formulation_family}/{r.integrator_family}"
                                 for r in bad.itertuples())
    return line if len(line) <= width else line[:width - 1] + "…"
