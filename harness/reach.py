"""CPU to reach a relative position error, the IFToMM benchmarks' measure.

A line is one (integrator, formulation) of one problem over its tolerances or
step sizes. Its error is the relative position error at the final time,
``10**-scd`` (scd as the IVP Test Set defines it). The CPU a line needs to reach
a target error is interpolated, log CPU against log error, between the two
consecutive points (in tolerance order) that bracket the target; a point
already at or below the target counts at its own CPU; the least of these is
the answer. Nothing is extrapolated: a line that never gets there has none
("not reached"). Failed cases are not points and break nothing.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

TARGETS = (1e-3, 1e-6)


def points(rows: pd.DataFrame) -> pd.DataFrame:
    """The ok records with a finite error and CPU: columns ``err`` (10**-scd) and
    ``_tol`` (rtol, else h) added, sorted by integrator, formulation and
    tolerance, loosest first."""
    ok = rows[(rows["status"] == "ok") & np.isfinite(rows["scd"])
              & np.isfinite(rows["cpu_s"]) & (rows["cpu_s"] > 0)]
    ok = ok.assign(err=10.0 ** -ok["scd"], _tol=ok["rtol"].fillna(ok["h"]))
    return ok.sort_values(["integrator", "formulation", "_tol"],
                          ascending=[True, True, False], kind="stable")


def cpu_to_reach(err, cpu, target: float) -> float:
    """CPU seconds at which one line reaches ``target`` error (NaN: not reached).

    Parameters
    ----------
    err, cpu : sequence of float
        The line's errors and CPU seconds, in tolerance order (loosest first).
    target : float
        Relative error to reach.

    Returns
    -------
    float
        The least of: the CPU of every point with ``err <= target``, and the
        log-log interpolation between every two consecutive points whose
        errors bracket ``target``. NaN when no point reaches it.
    """
    err, cpu = np.asarray(err, float), np.asarray(cpu, float)
    found = list(cpu[err <= target])
    for (e0, c0), (e1, c1) in zip(zip(err[:-1], cpu[:-1]), zip(err[1:], cpu[1:])):
        if min(e0, e1) <= target <= max(e0, e1) and e0 != e1:
            w = (math.log(target) - math.log(e0)) / (math.log(e1) - math.log(e0))
            found.append(math.exp(math.log(c0) + w * (math.log(c1) - math.log(c0))))
    return min(found) if found else math.nan


def reach_table(rows: pd.DataFrame) -> pd.DataFrame:
    """One row per line of one problem, ranked by CPU to reach 1e-6, then 1e-3.

    Parameters
    ----------
    rows : pandas.DataFrame
        Cleaned records of one problem and parameter set.

    Returns
    -------
    pandas.DataFrame
        Columns ``integrator``, ``formulation``, ``cpu_1e-03``, ``cpu_1e-06``
        (NaN: not reached), ``best_err`` (least error of the line), ``n_ok``,
        ``n_failed`` (cases neither ok nor unsupported) and ``rank`` (1 = least
        CPU to reach 1e-6; lines that reach neither target are unranked, NaN).
        Lines with no ok point appear with NaN CPU and error.
    """
    pts = points(rows)
    run = rows[rows["status"] != "unsupported"]
    out = []
    for (integrator, formulation), sub in run.groupby(["integrator", "formulation"]):
        line = pts[(pts["integrator"] == integrator) & (pts["formulation"] == formulation)]
        row = {"integrator": integrator, "formulation": formulation}
        for target in TARGETS:
            row[f"cpu_{target:.0e}"] = cpu_to_reach(line["err"], line["cpu_s"], target)
        row["best_err"] = line["err"].min() if len(line) else math.nan
        row["n_ok"] = int((sub["status"] == "ok").sum())
        row["n_failed"] = int((sub["status"] != "ok").sum())
        out.append(row)
    cols = (["integrator", "formulation"] + [f"cpu_{t:.0e}" for t in TARGETS]
            + ["best_err", "n_ok", "n_failed"])
    table = pd.DataFrame(out, columns=cols)
    keys = [f"cpu_{t:.0e}" for t in reversed(TARGETS)]
    table = table.sort_values(keys + ["best_err", "integrator", "formulation"],
                              na_position="last", kind="stable").reset_index(drop=True)
    reached = table[keys].notna().any(axis=1).to_numpy()
    table["rank"] = np.where(reached, np.cumsum(reached), np.nan)
    return table
