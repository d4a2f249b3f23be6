"""Orlov's DUMKA3 grid on ``cvt_chain``: his polynomials at his steps, beside RK4.

Orlov, Kuzin and Shabrov (Russian Supercomputing Days 2017, slides
deadmorous/rsd-2017 ``docs/speedup.html``; the paper is seed 004) ran DUMKA3 with
one fixed stability polynomial, labelled from P0 (degree 3) to P13 (degree 324),
at steps 2e-6 to 5e-6 s on their CVT chain, and marked each tested cell good,
bad (inaccurate) or failed (:data:`ORLOV_GRID`); their speed-ups over RK4 at 5e-8
s were 5.9 (P5 at 2e-6), 4.7 (P7 at 3e-6) and 4.4 (P8 at 4e-6)
(:data:`ORLOV_SPEEDUP`). This script runs every tested cell of P4 ... P9 (and
P10) on ``cvt_chain`` (:func:`~integrator_bench.integrators.dumka.with_polynomial`,
registered for the run as ``dumka3-P4`` ...), RK4 at Orlov's 5e-8 s and at 0.95
of its own largest stable step, and the adaptive stabilized methods (DUMKA3,
RKC, ROCK2, SERK2v2) over ``--rtol``, each case through the harness
(:class:`~integrator_bench.harness.run.runner.Session`: a forked worker per case,
CPU of the solve alone, errors against the committed reference).

Per cell it gives our pin-force error E (Orlov's measure, unacceptable above
0.05), our verdict (good: E <= 0.05; bad: finished with E > 0.05; failed: did
not finish), Orlov's verdict, and the speed-up over RK4 at matched accuracy:
RK4's CPU and f-evaluations over the cell's when both reach E <= 0.05 (the
f-evaluation ratio carries across machines; the CPU ratio adds the per-step
overhead). Where a cell behaves otherwise than Orlov's, the spectrum says
why: at the start, middle and end of the reference the eigenvalues of the
``ode`` Jacobian (:func:`integrator_bench.harness.measure.stiffness.analyse`, as ``ibench
stiffness``) are multiplied by ``h`` and put into the polynomial's stability
function; ``|R|`` over the real eigenvalues alone and over the complex ones
says whether the real extent or the imaginary one is exceeded, and each
polynomial's largest stable step along the whole spectrum (bisection on ``h``)
stands beside its real-axis limit ``beta / rho``.

Usage::

    .venv/bin/python studies/orlov_grid.py --jobs 2            # Markdown, smooth law
    .venv/bin/python studies/orlov_grid.py --friction 0 --json
    .venv/bin/python studies/orlov_grid.py --records grid.sqlite   # an earlier --store

Bad input: one line on standard error, exit 2.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from integrator_bench.harness.matrix import registry

from integrator_bench.harness.measure import stiffness
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits
from integrator_bench.harness.run.runner import Session
from integrator_bench.harness.matrix.store import Store, load
from integrator_bench.harness.sources.numbers import ORLOV_SPEEDUPS
from integrator_bench.integrators.dumka import N_DEG, PUBLISHED_BETA, stability_function

sys.path.insert(0, str(Path(__file__).resolve().parent))
from chain_headline import _num  # noqa: E402
from cvt_headline import cvt_spec, prepare  # noqa: E402

#: Orlov's tested cells: (polynomial, h) -> "good", "bad" or "failed" (slides, DUMKA3 table)
ORLOV_GRID = {
    **{(k, 2e-6): "bad" for k in (0, 1, 2, 3, 4, 9, 10)},
    **{(k, 2e-6): "good" for k in (5, 6, 7, 8)},
    (5, 3e-6): "bad", (6, 3e-6): "bad", (7, 3e-6): "good", (8, 3e-6): "good",
    (9, 3e-6): "bad", (10, 3e-6): "bad",
    (7, 4e-6): "bad", (8, 4e-6): "good", (9, 4e-6): "failed", (10, 4e-6): "failed",
    **{(k, 5e-6): "failed" for k in (7, 8, 9, 10)},
}
#: Orlov's speed-ups over RK4 at 5e-8 s, by cell (the slides, transcribed once in the
#: harness: :data:`~integrator_bench.harness.sources.numbers.ORLOV_SPEEDUPS`)
ORLOV_SPEEDUP = {(k, h): speedup for k, h, speedup in ORLOV_SPEEDUPS}
ORLOV_RK4_H = 5e-8
POLYNOMIALS = (4, 5, 6, 7, 8, 9, 10)
RTOLS = (1e-3, 1e-4)
ADAPTIVE = ("dumka3", "rkc", "rock2", "serk2v2")
ACCEPTABLE = 0.05
RK4_FRACTION = 0.95


def cells() -> list[tuple[int, float]]:
    """Orlov's tested cells of :data:`POLYNOMIALS`, by polynomial then step."""
    return sorted(c for c in ORLOV_GRID if c[0] in POLYNOMIALS)


def make_cases(spec: str, rho: float, rtols) -> list:
    """RK4 at Orlov's step and at 0.95 of its own limit, every cell, the adaptive lines."""
    rk4 = [ORLOV_RK4_H, RK4_FRACTION * registry.get_integrator("rk4").stability_intervals[""]
           / rho]
    cases = expand(problems=[spec], integrators=["rk4"], hs=rk4)
    for k, h in cells():
        cases += expand(problems=[spec], integrators=[f"dumka3-P{k}"], hs=[h])
    cases += expand(problems=[spec], integrators=list(ADAPTIVE), rtols=list(rtols))
    return [c for c in cases if not c.unsupported]


def decaying(eigs: np.ndarray) -> np.ndarray:
    """The eigenvalues of negative real part: those a stable step must keep inside
    ``|R| <= 1`` (one of positive real part grows in the exact solution too)."""
    return eigs[eigs.real < 0]


def spectrum_check(eigs: np.ndarray, k: int, h: float) -> dict:
    """``max |R_k(h lambda)|`` over the decaying real eigenvalues and over the complex
    ones."""
    eigs = decaying(eigs)
    real = np.abs(eigs.imag) <= stiffness.REAL_TOL * np.maximum(np.abs(eigs), 1e-300)
    growth = np.abs(stability_function(k, h * eigs))
    worst = int(np.argmax(growth))
    return {"real": float(growth[real].max(initial=0.0)),
            "complex": float(growth[~real].max(initial=0.0)),
            "worst": [float(eigs[worst].real), float(eigs[worst].imag)]}


def spectrum_step(eigs: np.ndarray, k: int, h_hi: float) -> float:
    """The largest ``h <= h_hi`` with ``|R_k(h lambda)| <= 1`` for every eigenvalue
    (bisection from a step that is stable; the region may have holes, so this is the
    first boundary above 0)."""
    eigs = decaying(eigs)

    def stable(h):
        return np.abs(stability_function(k, h * eigs)).max() <= 1.0 + 1e-9

    grid = np.linspace(0.0, h_hi, 401)[1:]
    bad = next((h for h in grid if not stable(h)), None)
    if bad is None:
        return h_hi
    lo, hi = bad - grid[0], bad
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo


def verdict(row) -> str:
    """good (E <= 0.05), bad (finished, E > 0.05) or failed (did not finish)."""
    if row is None or str(row["status"]) != CaseStatus.OK:
        return "failed"
    e = _num(row["monitor_err"])
    return "good" if e is not None and e <= ACCEPTABLE else "bad"


def _row(df, name, h=None, rtol=None):
    g = df[df["integrator"] == name]
    if h is not None:
        g = g[np.isclose(pd.to_numeric(g["h"], errors="coerce").astype(float), h, rtol=1e-9)]
    if rtol is not None:
        g = g[np.isclose(pd.to_numeric(g["rtol"], errors="coerce").astype(float), rtol)]
    return None if g.empty else g.iloc[0]


def summarize(df: pd.DataFrame, rho: float, eigs: np.ndarray, rtols) -> dict:
    """The grid, the RK4 lines, the adaptive lines and each polynomial's steps."""
    rk4_h = RK4_FRACTION * registry.get_integrator("rk4").stability_intervals[""] / rho
    rk4 = [{"h": h, "verdict": verdict(r), "E": _num(r["monitor_err"]) if r is not None else None,
            "cpu_s": _num(r["cpu_s"]) if r is not None else None,
            "nfev": _num(r["nfev"]) if r is not None else None}
           for h in (ORLOV_RK4_H, rk4_h) for r in [_row(df, "rk4", h=h)]]
    base = next((r for r in reversed(rk4) if r["verdict"] == "good"), None)
    grid = []
    for k, h in cells():
        r = _row(df, f"dumka3-P{k}", h=h)
        ours = verdict(r)
        e, cpu, nfev = ((_num(r["monitor_err"]), _num(r["cpu_s"]), _num(r["nfev"]))
                        if r is not None else (None, None, None))
        fast = base is not None and ours == "good"
        grid.append({"polynomial": k, "degree": N_DEG[k], "h": h, "orlov": ORLOV_GRID[(k, h)],
                     "ours": ours, "E": e, "cpu_s": cpu, "nfev": nfev,
                     "rk4_over_cpu": base["cpu_s"] / cpu if fast and cpu else None,
                     "rk4_over_nfev": base["nfev"] / nfev if fast and nfev else None,
                     "orlov_speedup": ORLOV_SPEEDUP.get((k, h)),
                     "h_rho_over_beta": h * rho / PUBLISHED_BETA[k],
                     "spectrum": spectrum_check(eigs, k, h)})
    steps = [{"polynomial": k, "degree": N_DEG[k], "beta_over_rho": PUBLISHED_BETA[k] / rho,
              "spectrum_step": spectrum_step(eigs, k, 2.0 * PUBLISHED_BETA[k] / rho)}
             for k in POLYNOMIALS]
    adaptive = []
    for name in ADAPTIVE:
        for rtol in rtols:
            r = _row(df, name, rtol=rtol)
            if r is None:
                continue
            adaptive.append({"integrator": name, "rtol": rtol, "verdict": verdict(r),
                             "E": _num(r["monitor_err"]), "cpu_s": _num(r["cpu_s"]),
                             "nsteps": _num(r["nsteps"]), "nfev": _num(r["nfev"])})
    return {"rk4": rk4, "grid": grid, "steps": steps, "adaptive": adaptive}


def _g(x, fmt=".3g") -> str:
    return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, fmt)


def markdown(results: list[dict], meta: dict) -> str:
    from integrator_bench.harness.tables import markdown_lines

    lines = []
    for res in results:
        lines += [f"### cvt_chain, friction {res['friction']}: rho = {res['rho']:.3g} 1/s, "
                  f"max |Im lambda| = {res['max_imag']:.3g} 1/s", ""]
        lines += ["RK4: " + "; ".join(
            f"h {_g(r['h'])}: {r['verdict']}, E {_g(r['E'], '.1e')}, CPU {_g(r['cpu_s'])} s, "
            f"nfev {_g(r['nfev'], '.0f')}" for r in res["rk4"]) + ".", ""]
        rows = [(f"P{c['polynomial']} ({c['degree']})", _g(c["h"]), f"{c['h_rho_over_beta']:.2f}",
                 c["orlov"], c["ours"], _g(c["E"], ".1e"),
                 f"{c['spectrum']['real']:.3g} / {c['spectrum']['complex']:.3g}",
                 _g(c["rk4_over_nfev"], ".1f"), _g(c["rk4_over_cpu"], ".1f"),
                 _g(c["orlov_speedup"], ".1f"))
                for c in res["grid"]]
        lines += markdown_lines(("polynomial (degree)", "h [s]", "h rho / beta", "Orlov",
                                 "ours", "E", "max |R| real / complex", "RK4 / line nfev",
                                 "RK4 / line CPU", "Orlov RK4 / line"), rows,
                                [1, 2, 5, 6, 7, 8, 9])
        lines += ["", "Each polynomial's largest stable step: on the real axis (beta / rho) "
                  "and along the whole spectrum (all eigenvalues inside |R| <= 1):", ""]
        lines += markdown_lines(("polynomial (degree)", "beta / rho [s]", "spectrum [s]"),
                                [(f"P{s['polynomial']} ({s['degree']})",
                                  _g(s["beta_over_rho"]), _g(s["spectrum_step"]))
                                 for s in res["steps"]], [1, 2])
        lines += ["", "Adaptive stabilized methods:", ""]
        lines += markdown_lines(("line", "rtol", "verdict", "E", "nsteps", "nfev", "CPU [s]"),
                                [(a["integrator"], _g(a["rtol"]), a["verdict"],
                                  _g(a["E"], ".1e"), _g(a["nsteps"], ".0f"),
                                  _g(a["nfev"], ".0f"), _g(a["cpu_s"]))
                                 for a in res["adaptive"]], [1, 3, 4, 5, 6])
        lines.append("")
    ran = (f"summarized from {meta['records']}" if meta.get("records") else
           f"wall time {meta['wall_s']:.0f} s ({meta['jobs']} "
           f"worker{'s' if meta['jobs'] > 1 else ''})")
    lines.append(f"{meta['cases']} cases; {ran}; code {meta['code_version']}.")
    return "\n".join(lines) + "\n"


def _fail(message: str) -> int:
    print(f"orlov_grid: error: {message}", file=sys.stderr)
    return 2


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--friction", type=int, nargs="+", default=[1],
                    help="friction laws: 1 smooth (default), 0 linear")
    ap.add_argument("--rtol", type=float, nargs="+", default=list(RTOLS))
    ap.add_argument("--t-end", type=float, help="a shorter span than the benchmark's 5 ms")
    ap.add_argument("--compute-reference", action="store_true",
                    help="compute a missing reference first (for --t-end)")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds a case may take")
    ap.add_argument("--store", type=Path, help="store to keep the records (default: temporary)")
    ap.add_argument("--json", action="store_true", help="print JSON instead of Markdown")
    ap.add_argument("--records", type=Path, help="summarize this store's records of an "
                    "earlier run instead of running the cases")
    args = ap.parse_args(argv)
    if args.records is not None and not args.records.is_file():
        return _fail(f"--records {args.records}: no such store")
    if any(not (v > 0) for v in args.rtol):
        return _fail(f"--rtol takes positive numbers, got {args.rtol}")
    try:
        problems = prepare(args, POLYNOMIALS, "studies/orlov_grid.py")
    except ValueError as exc:
        return _fail(str(exc))
    start = time.perf_counter()
    plan = []
    for problem in problems:
        t0, t1 = problem.t_span
        spectrum = stiffness.analyse(problem, [t0, 0.5 * (t0 + t1), t1], store=None)
        eigs = np.concatenate([f["eigenvalues"] for f in spectrum["times"]])
        spec = cvt_spec(problem, args.t_end)
        plan.append((problem, spectrum, eigs, make_cases(spec, spectrum["rho"], args.rtol)))
    cases = [c for *_, cs in plan for c in cs]
    if args.records is not None:
        df = load(args.records)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            with Store(args.store or Path(tmp) / "orlov_grid.sqlite") as store, \
                    Session(RunContext(store=store, jobs=args.jobs, progress=False,
                                       command=" ".join(sys.argv),
                                       limits=Limits(budget_s=args.timeout, repeat=1))) as session:
                df = session.run(cases)
    wall = time.perf_counter() - start
    results = []
    for problem, spectrum, eigs, _ in plan:
        rows = df[np.array([json.loads(p) == problem.params for p in df["params"]], bool)]
        results.append({"friction": int(problem.params["friction"]), "rho": spectrum["rho"],
                        "max_imag": max(f["max_imag"] for f in spectrum["times"]),
                        **summarize(rows, spectrum["rho"], eigs, args.rtol)})
    meta = {"problem": "cvt_chain", "cases": len(df), "wall_s": wall, "jobs": args.jobs,
            "records": str(args.records) if args.records else None,
            "code_version": str(df["code_version"].iloc[0]) if len(df) else None}
    if args.json:
        print(json.dumps({**meta, "orlov_grid": [[k, h, v] for (k, h), v in ORLOV_GRID.items()],
                          "results": results}, indent=1, default=_num))
    else:
        print(markdown(results, meta), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
