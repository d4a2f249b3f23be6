"""Every integrator across every problem: performance and data profiles.

A *problem* here is a problem and parameter set of the store. An integrator
with its settings (one curve, named by its lines' label: ``cvode-bdf
(max_order=2)``) *solves* a problem to a target when
one of its lines (any formulation, adaptive or fixed step) reaches the target
error, in the report's measure (:mod:`~integrator_bench.harness.ranking.reach`,
``ibench report --error``); its cost there is the least CPU over those lines to reach it
(:func:`~integrator_bench.harness.ranking.reach.cpu_to_reach`: interpolated,
or the loosest point's CPU as an upper bound when the line starts below the
target), its evaluations the ``nfev`` of that same crossing, least over the lines.
A problem it did not solve (failed, timed out, skipped, dominated by a race,
not reached, or unsupported in every formulation) costs infinity: a ``dominated``
case (:mod:`~integrator_bench.harness.ranking.racing`) is no point of its line, so
it counts beyond tau in the performance profile.

Performance profile (E. D. Dolan and J. J. Moré, "Benchmarking optimization
software with performance profiles", Math. Program. 91 (2002) 201-213): with
``t[p, s]`` the cost of integrator ``s`` on problem ``p`` and the ratio
``r[p, s] = t[p, s] / min_s t[p, s]``, ``rho_s(tau) = |{p : r[p, s] <= tau}| / |P|``,
drawn against ``log2 tau``. The problems no integrator solves have no ratio:
they are left out of ``P`` and counted on the page.

Data profile (J. J. Moré and S. M. Wild, "Benchmarking derivative-free
optimization algorithms", SIAM J. Optim. 20 (2009) 172-191, eq. 2.9):
``d_s(alpha) = |{p : t[p, s] / (n_p + 1) <= alpha}| / |P|`` with ``t`` the
function evaluations (``nfev``) to reach the target and ``n_p`` the problem's
state count: they normalize by ``n_p + 1``, the evaluations of one simplex
gradient; for an ODE integrator ``n_p + 1`` is one right-hand side plus one
forward-difference Jacobian. ``alpha`` is thus a budget in such units.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd

from integrator_bench.harness.ranking.reach import DEFAULT_ERROR, TARGETS, cpu_to_reach_each

#: the factors of the best CPU the share table gives
FACTORS = (2.0, 10.0)


def costs(records: pd.DataFrame, target: float,
          measure: str = DEFAULT_ERROR) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The cost matrices at ``target``: CPU and ``nfev``, problems x integrators.

    Parameters
    ----------
    records : pandas.DataFrame
        Result records of any number of problems.
    target : float
        Error to reach, in ``measure``.
    measure : str
        The error (:func:`~integrator_bench.harness.ranking.reach.error_values`).

    Returns
    -------
    (cpu, nfev) : pandas.DataFrame
        Indexed by ``(problem, params)``, one column per integrator with its
        settings (its lines' ``label``) that ran (a case not ``unsupported``) on
        some problem; ``inf`` where it did not
        reach the target (``nfev`` also where it reached it without a count).
    """
    return costs_each(records, (target,), measure)[target]


def costs_each(records: pd.DataFrame, targets,
               measure: str = DEFAULT_ERROR) -> dict[float, tuple[pd.DataFrame, pd.DataFrame]]:
    """:func:`costs` at each of ``targets``, the lines' crossings found once
    (:func:`~integrator_bench.harness.ranking.reach.cpu_to_reach_each`).

    Parameters
    ----------
    records : pandas.DataFrame
        Result records of any number of problems.
    targets : sequence of float
        Errors to reach, in ``measure``.
    measure : str
        The error (:func:`~integrator_bench.harness.ranking.reach.error_values`).

    Returns
    -------
    dict
        Target -> ``(cpu, nfev)`` as :func:`costs` gives them.
    """
    run = records[records["status"] != "unsupported"].reset_index(drop=True)
    solvers = sorted(set(run["label"]))
    problems = sorted(set(zip(records["problem"], records["params"])))
    index = pd.MultiIndex.from_tuples(problems, names=["problem", "params"])
    none = pd.DataFrame(math.inf, index=index, columns=solvers)
    if run.empty:
        return {t: (none.copy(), none.copy()) for t in targets}
    out = {}
    for t, reach in cpu_to_reach_each(run, targets, measure).items():
        reach = reach[reach["how"] != "not reached"]
        out[t] = _least(none, reach, "cpu_s"), _least(none, reach, "nfev")
    return out


def _least(none: pd.DataFrame, reach: pd.DataFrame, column: str) -> pd.DataFrame:
    """``none`` (problems x integrators, ``inf``) with, where some line of
    ``reach`` has a value of ``column`` (nulls skipped), the least of them
    per problem and integrator."""
    least = reach.dropna(subset=[column]).groupby(["problem", "params", "label"])[column].min()
    out = none.to_numpy(copy=True)
    rows = none.index.get_indexer(least.index.droplevel("label"))
    cols = none.columns.get_indexer(least.index.get_level_values("label"))
    out[rows, cols] = least.to_numpy(float)
    return pd.DataFrame(out, index=none.index, columns=none.columns)


def ratios(cost: pd.DataFrame) -> pd.DataFrame:
    """Dolan and Moré's performance ratios ``t / min_s t`` of the problems some
    integrator solved (``inf`` for a failure)."""
    best = cost.min(axis=1)
    solved = cost[np.isfinite(best)]
    return solved.div(best[np.isfinite(best)], axis=0)


def performance_profile(cost: pd.DataFrame, taus) -> pd.DataFrame:
    """``rho_s(tau)``: per integrator (column), the share of the problems some
    integrator solved on which it is within ``tau`` of the best (row per tau)."""
    r = ratios(cost)
    taus = np.asarray(taus, float)
    if r.empty:
        return pd.DataFrame(0.0, index=taus, columns=cost.columns)
    return _shares(r, taus)


def tau_grid(ratios_: pd.DataFrame, points: int) -> np.ndarray:
    """``points`` values of tau from 1 to a little past the largest finite ratio of
    ``ratios_`` (at least 2), evenly spaced in log2 tau: a profile's x axis."""
    finite = ratios_.to_numpy()[np.isfinite(ratios_.to_numpy())]
    top = max(1.0, float(np.log2(finite.max())) if finite.size else 1.0) * 1.05
    return 2.0 ** np.linspace(0.0, top, points)


def _shares(values: pd.DataFrame, bounds) -> pd.DataFrame:
    """Per column of ``values`` (problems x integrators), the share of rows at or
    below each of ``bounds`` (one row per bound)."""
    v = values.to_numpy(float)
    within = (v[None, :, :] <= np.asarray(bounds, float)[:, None, None]).mean(axis=1)
    return pd.DataFrame(within, index=bounds, columns=values.columns)


def data_profile(nfev: pd.DataFrame, dimension: pd.Series, alphas,
                 problems=None) -> pd.DataFrame:
    """``d_s(alpha)``: per integrator, the share of ``problems`` (default: all
    rows) it solved within ``alpha (n_p + 1)`` evaluations; ``dimension`` is
    ``n_p`` per row of ``nfev``."""
    rows = nfev if problems is None else nfev.loc[problems]
    units = rows.div(dimension.loc[rows.index] + 1, axis=0)
    alphas = np.asarray(alphas, float)
    if units.empty:
        return pd.DataFrame(0.0, index=alphas, columns=nfev.columns)
    return _shares(units, alphas)


def dimensions(index) -> pd.Series:
    """The state count of each ``(problem, params)`` (NaN where it cannot be built)."""
    from integrator_bench.harness.matrix import builds, registry

    out = []
    for problem, params in index:
        try:   # a plugin's problem tried in a process of its own first
            cls = registry.get_problem_class(problem)
            out.append(float(builds.build(cls, json.loads(params)).dimension))
        except Exception:  # a problem no longer registered, or a file gone
            out.append(math.nan)
    return pd.Series(out, index=index)


def share_table(cost: pd.DataFrame, factors=FACTORS) -> pd.DataFrame:
    """Per integrator: problems solved, and the share of the problems some
    integrator solved that it solved within each factor of the best."""
    r = ratios(cost)
    out = pd.DataFrame(index=cost.columns)
    out["solved"] = np.isfinite(cost).sum(axis=0).astype(int)
    for f in factors:
        out[f"within {f:g}x"] = (r <= f).mean() if len(r) else 0.0
    return out


def profile_data(records: pd.DataFrame, targets=TARGETS, measure: str = DEFAULT_ERROR) -> dict:
    """Everything the summary page shows, per target: ``cpu``, ``nfev``,
    ``ratios``, ``shares`` and the counts of problems held and solved; and
    ``dimension`` (``measure``: the error, as the tables')."""
    out = {}
    dim = None
    every = costs_each(records, targets, measure)
    for t in targets:
        cpu, nfev = every[t]
        if dim is None:
            dim = dimensions(cpu.index)
        out[t] = {"cpu": cpu, "nfev": nfev, "ratios": ratios(cpu), "shares": share_table(cpu),
                  "problems": len(cpu), "solved": int(np.isfinite(cpu.min(axis=1)).sum())}
    out["dimension"] = dim
    return out
