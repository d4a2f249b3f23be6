"""Where the in-house HHT spends its CPU on the chain drive.

Runs HHT (and, on request, Newmark and generalized-alpha) on the ``i3`` form of
``chain_drive`` (150 links by default) the way the harness runs a case
(:func:`~integrator_bench.problems.system.convert`, the counting wrappers of
:func:`~integrator_bench.harness.run.execution.counted`, ``solve`` with
``atol = system.atol(rtol)``), once unprofiled for its CPU time and once under
:mod:`cProfile`, and splits the profiled time into three shares:

``model``
    the problem's functions: code in ``integrator_bench/problems/`` (the
    chain's forces, constraints and Jacobians and the formulation's assembly in
    ``mechanical.py`` and ``system.py``);
``linalg``
    linear algebra: ``scipy.sparse`` (matrix construction, format conversion,
    arithmetic, ``scipy.sparse.linalg`` with SuperLU's ``splu``/``solve``),
    ``scipy.linalg`` and ``numpy.linalg`` (LAPACK);
``overhead``
    the integrator and driver: ``integrator_bench/integrators/`` and
    ``integrator_bench/harness/``, and whatever cannot be charged elsewhere.

The rule. Every function's own time (cProfile's ``tottime``) is charged by the
file of the function: a file under ``problems/`` to ``model``; a file under
``scipy/sparse/``, ``scipy/linalg/`` or ``numpy/linalg/``, or a compiled
function of those packages (SuperLU's ``gstrf``/``gssv``, ``SuperLU.solve``,
``_sparsetools``, LAPACK) to ``linalg``; a file under ``integrators/`` or
``harness/`` to ``overhead``. Any other function (numpy's core such as
``np.roll`` or ``einsum``, Python built-ins, the standard library) does work
for whoever calls it: its own time goes to its callers in the proportion
cProfile recorded per caller (its own time per caller at the first level,
cumulative time per caller further up) until it reaches a charged function;
time that reaches none (the profile's root, a cycle of uncharged functions)
goes to ``overhead``. So ``np.concatenate`` in the corrector is integrator
overhead, ``np.einsum`` in the chain's Jacobian is model evaluation. ``linalg``
is also shown split into its compiled part (SuperLU, ``_sparsetools``, LAPACK:
the functions charged by name) and its Python part (``scipy.sparse``'s
constructors, checks and conversions, and the numpy helpers they call), since
the latter is interpreter time too, only not the integrator's.

Beside the shares the script reports, side by side in the same run, IDA's CPU
on the ``ggl`` form (ADAMS's SI2) at the same tolerance, with the counts.
No targets are checked: the aim is that ``model + linalg`` reach 70 % for
HHT at 150 links; the script prints the figure and that target next to it.

    python studies/hht_profile.py                          # 150 links, rtol 1e-4
    python studies/hht_profile.py -i hht -i newmark -i gen-alpha --json out.json
    python studies/hht_profile.py --problem chain_drive:n_links=20,t_end=0.01 --no-ida

Newmark and generalized-alpha run at a fixed step only: ``--h``, by default a
quarter of the mean step of the HHT run (its span over its accepted steps). At
HHT's mean step itself (6.7e-4 s at 150 links, t_end 1) their first step, from
the start at rest, does not converge (``newton_failure``; the step of a
fixed-step run cannot be shortened), at 2e-4 s it does. Exits 2 on bad input (one line naming the bad value).
Not an asv benchmark: asv looks for ``time_``/``track_`` names, this module has none.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import pstats
import sys
import time
from pathlib import Path

# the harness before numpy, as ``ibench`` imports them (one BLAS thread per process)
from integrator_bench.harness.run import isolation  # noqa: F401  isort: skip

import numpy as np  # noqa: E402

import integrator_bench.harness as _harness  # noqa: E402
import integrator_bench.integrators as _integrators  # noqa: E402
import integrator_bench.problems as _problems  # noqa: E402
from integrator_bench.harness.matrix import registry  # noqa: E402
from integrator_bench.harness.matrix.cases import check_positive, parse_problem_spec  # noqa: E402
from integrator_bench.harness.errors import BadInput  # noqa: E402
from integrator_bench.harness.run.execution import counted  # noqa: E402
from integrator_bench.harness.matrix.registry import UnknownName  # noqa: E402
from integrator_bench.problems.system import Unsupported, convert  # noqa: E402

CATEGORIES = ("model", "linalg", "overhead")
#: the finer split the rule works on: linear algebra in compiled code (SuperLU,
#: sparsetools, LAPACK) and in Python (scipy.sparse's construction, checks and
#: format conversions), so that the interpreter's share of ``linalg`` shows
FINE = ("model", "linalg_compiled", "linalg_python", "overhead")
TARGET = 0.70     # the aim: at least 70 % in model evaluation and linear algebra
ALPHA_METHODS = ("hht", "newmark", "gen-alpha")
DEFAULT_PROBLEM = "chain_drive:n_links=150,t_end=1.0"
FIXED_STEP_FRACTION = 0.25   # default h of newmark, gen-alpha: this times HHT's mean step

_DIRS = {"model": Path(_problems.__file__).resolve().parent,
         "overhead_i": Path(_integrators.__file__).resolve().parent,
         "overhead_h": Path(_harness.__file__).resolve().parent}
_LINALG_FILES = ("/scipy/sparse/", "/scipy/linalg/", "/numpy/linalg/")
_LINALG_BUILTINS = ("scipy.sparse", "_superlu", "superlu", "_sparsetools", "scipy.linalg",
                    "lapack", "_flapack", "_umath_linalg", "numpy.linalg", "_fblas")


def category(func) -> str | None:
    """The category a function's own time is charged to by its file, or None
    when it is charged to its callers (see the module docstring)."""
    filename, _, name = func
    if filename == "~":                        # compiled: judge by the qualified name
        low = name.lower()
        return "linalg_compiled" if any(key in low for key in _LINALG_BUILTINS) else None
    path = Path(filename)
    try:
        path = path.resolve()
    except OSError:
        pass
    text = path.as_posix()
    if any(part in text for part in _LINALG_FILES):
        return "linalg_python"
    if path.is_relative_to(_DIRS["model"]):
        return "model"
    if path.is_relative_to(_DIRS["overhead_i"]) or path.is_relative_to(_DIRS["overhead_h"]):
        return "overhead"
    return None


def classify(stats: pstats.Stats) -> dict[str, float]:
    """Seconds of own time per fine category (:data:`FINE`), by the rule of the
    module docstring."""
    table = stats.stats      # func -> (cc, nc, tt, ct, callers{caller: (cc, nc, tt, ct)})
    cats = {f: category(f) for f in table}
    memo: dict = {}

    def upward(func, visiting) -> dict[str, float]:
        """Fractions per category of the time an uncharged ``func`` does for its
        callers, by the callers' cumulative times."""
        if func in memo:
            return memo[func]
        callers = table[func][4] if func in table else {}
        weights = {c: v[3] for c, v in callers.items() if c != func}
        out = _spread(weights, cats, upward, visiting | {func})
        memo[func] = out
        return out

    seconds = dict.fromkeys(FINE, 0.0)
    for func, (_, _, tt, _, callers) in table.items():
        if cats[func] is not None:
            seconds[cats[func]] += tt
            continue
        weights = {c: v[2] for c, v in callers.items() if c != func}
        if sum(weights.values()) <= 0.0:      # no split of own time recorded: cumulative
            weights = {c: v[3] for c, v in callers.items() if c != func}
        for cat, frac in _spread(weights, cats, upward, {func}).items():
            seconds[cat] += tt * frac
    return seconds


def _spread(weights, cats, upward, visiting) -> dict[str, float]:
    total = sum(w for w in weights.values() if w > 0)
    if total <= 0.0:
        return {"overhead": 1.0}
    out = dict.fromkeys(FINE, 0.0)
    for caller, w in weights.items():
        if w <= 0:
            continue
        share = w / total
        if cats.get(caller) is not None:
            out[cats[caller]] += share
        elif caller in visiting:
            out["overhead"] += share
        else:
            for cat, frac in upward(caller, visiting).items():
                out[cat] += share * frac
    return out


def top_functions(stats: pstats.Stats, k: int = 12) -> list[dict]:
    """The ``k`` functions with the most own time, with their category."""
    rows = sorted(stats.stats.items(), key=lambda kv: -kv[1][2])[:k]
    return [{"function": f"{Path(f[0]).name}:{f[1]}({f[2]})", "ncalls": v[1],
             "tottime_s": round(v[2], 4), "category": category(f) or "callers"}
            for f, v in rows]


def prepare(problem, formulation, name):
    icls = registry.get_integrator(name)
    try:
        system = convert(problem.formulate(formulation), icls)
    except Unsupported as exc:
        raise BadInput(f"{name} cannot take {formulation}: {exc}") from None
    return icls, system


def solve(icls, problem, formulation, rtol, h, profile: bool):
    """One run as the harness makes it; returns the solution, CPU seconds and the profile."""
    _, system = prepare(problem, formulation, icls.name)
    system, counters = counted(system)
    atol = system.atol(rtol) if h is None else None
    integrator = icls()
    prof = cProfile.Profile() if profile else None
    cpu0 = time.process_time()
    if prof is not None:
        prof.enable()
    sol = integrator.solve(system, rtol=None if h is not None else rtol, atol=atol, h=h)
    if prof is not None:
        prof.disable()
    cpu = time.process_time() - cpu0
    counts = {k: int(v) for k, v in sol.counts.items()}
    for key, counter in counters.items():
        if counter is not None:
            counts[key] = counter.n
    return sol, cpu, counts, prof


def profile_run(name, problem, rtol, h) -> dict:
    icls = registry.get_integrator(name)
    sol, cpu, counts, _ = solve(icls, problem, "i3", rtol, h, profile=False)
    _, cpu_prof, _, prof = solve(icls, problem, "i3", rtol, h, profile=True)
    stats = pstats.Stats(prof)
    fine = classify(stats)
    seconds = {"model": fine["model"], "overhead": fine["overhead"],
               "linalg": fine["linalg_compiled"] + fine["linalg_python"]}
    total = sum(seconds.values())
    shares = {k: (v / total if total > 0 else 0.0) for k, v in seconds.items()}
    fine_shares = {k: (v / total if total > 0 else 0.0) for k, v in fine.items()}
    return {"integrator": name, "formulation": "i3",
            "rtol": None if h is not None else rtol, "h": h,
            "status": sol.status.value, "cpu_s": cpu, "cpu_profiled_s": cpu_prof,
            "counts": counts, "profiled_s": seconds, "shares": shares,
            "fine_shares": fine_shares,
            "model_plus_linalg": shares["model"] + shares["linalg"],
            "top": top_functions(stats)}


def ida_run(problem, rtol) -> dict:
    icls = registry.get_integrator("ida")
    sol, cpu, counts, _ = solve(icls, problem, "ggl", rtol, None, profile=False)
    return {"integrator": "ida", "formulation": "ggl", "rtol": rtol, "status": sol.status.value,
            "cpu_s": cpu, "counts": counts}


def parse(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problem", default=DEFAULT_PROBLEM,
                    help=f"chain_drive:key=value,... (default {DEFAULT_PROBLEM})")
    ap.add_argument("-i", "--integrator", action="append", dest="integrators",
                    help="hht (default), newmark, gen-alpha; repeatable")
    ap.add_argument("--rtol", type=float, default=1e-4)
    ap.add_argument("--h", type=float, default=None,
                    help="fixed step of newmark and gen-alpha (default: a quarter of HHT's mean step)")
    ap.add_argument("--no-ida", action="store_true", help="skip the IDA (ggl) comparison")
    ap.add_argument("--json", metavar="PATH", help="write the figures as JSON to PATH")
    return ap.parse_args(argv)


def main(argv=None) -> int:
    args = parse(argv)
    try:
        names = args.integrators or ["hht"]
        for name in names:
            if name not in ALPHA_METHODS:
                raise BadInput(f"integrator {name!r} is not profiled here; valid: "
                               f"{', '.join(ALPHA_METHODS)}")
        check_positive("rtol", [args.rtol])
        if args.h is not None:
            check_positive("h", [args.h])
        pspec = parse_problem_spec(args.problem)[0]
        if pspec.name != "chain_drive":
            raise BadInput(f"problem {pspec.name!r} is not profiled here; valid: chain_drive")
        problem = pspec.build()
    except (BadInput, UnknownName) as exc:
        print(f"hht_profile: error: {exc}", file=sys.stderr)
        return 2
    names = sorted(set(names), key=ALPHA_METHODS.index)
    if any(n != "hht" for n in names) and args.h is None and "hht" not in names:
        names.insert(0, "hht")             # the default h comes from HHT's steps
    runs, h_fixed = [], args.h
    span = problem.t_span[1] - problem.t_span[0]
    for name in names:
        h = None if name == "hht" else h_fixed
        run = profile_run(name, problem, args.rtol, h)
        runs.append(run)
        if name == "hht" and h_fixed is None:
            h_fixed = FIXED_STEP_FRACTION * span / max(run["counts"].get("nsteps", 1), 1)
        _print_run(run)
    ida = None if args.no_ida else ida_run(problem, args.rtol)
    if ida is not None:
        print(f"ida on ggl, rtol {args.rtol:g}: CPU {ida['cpu_s']:.3f} s, status "
              f"{ida['status']}, counts {ida['counts']}")
        for run in runs:
            if run["cpu_s"] > 0:
                print(f"  CPU ratio ida / {run['integrator']}: {ida['cpu_s'] / run['cpu_s']:.2f}")
    out = {"problem": pspec.name, "params": {k: _plain(v) for k, v in pspec.params},
           "rtol": args.rtol, "target_model_plus_linalg": TARGET, "runs": runs, "ida": ida}
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


def _plain(v):
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    return v


def _print_run(run):
    s = run["shares"]
    mode = f"h {run['h']:.4g}" if run["h"] is not None else f"rtol {run['rtol']:g}"
    print(f"{run['integrator']} on i3, {mode}: CPU {run['cpu_s']:.3f} s "
          f"({run['cpu_profiled_s']:.3f} s profiled), status {run['status']}, "
          f"counts {run['counts']}")
    print(f"  shares of the profiled time: model {s['model']:.1%}, linalg {s['linalg']:.1%}, "
          f"overhead {s['overhead']:.1%}; model + linalg {run['model_plus_linalg']:.1%} "
          f"(target >= {TARGET:.0%})")
    f = run["fine_shares"]
    print(f"  linalg split: compiled (SuperLU, sparsetools, LAPACK) {f['linalg_compiled']:.1%}, "
          f"Python (scipy.sparse construction and checks) {f['linalg_python']:.1%}")
    for row in run["top"][:8]:
        print(f"    {row['tottime_s']:8.3f} s  {row['ncalls']:>7}  {row['category']:<8} "
              f"{row['function']}")


if __name__ == "__main__":
    sys.exit(main())
