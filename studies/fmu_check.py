"""FMUs against their native problems, and fmpy's CVODE against the harness's.

The FMI 2.0 model-exchange FMUs of ``spring_pendulum``, ``two_mass`` and
``bouncing_ball`` (:func:`integrator_bench.problems.fmu_build.build_fmu`, from the
C sources in ``problems/fmu_sources``) are built into a work directory and run as
``fmu:path=FILE.fmu`` problems (:class:`~integrator_bench.problems.fmu.FmuProblem`)
beside the native problems. Three parts, one Markdown table each:

1. **Cross-check of the references.** The FMU problem's reference (computed here,
   keyed by the FMU's checksum, into the work directory: two tight methods as
   :mod:`integrator_bench.harness.measure.references` prescribes) against the native
   problem's (the committed one, or computed into the work directory when none is
   committed): per component
   :func:`~integrator_bench.harness.measure.metrics.agreement_digits` over the whole run
   (the native problem's ``atol_scale`` as floor), and for ``bouncing_ball`` the
   event times, matched by order (the FMU's events are ``state_event``, the
   native's ``impact``), as ``-log10(max |dt| / span)``.
2. **Same integrator, both problems.** Each of :data:`INTEGRATORS` at rtol
   :data:`SAME_RTOL` (fixed-step ones at ``h = span / 1000``) on the FMU problem and
   on the native one: scd (significant correct digits at the final time, IVP Test
   Set; each against its own reference), their difference, nfev of both. The FMU
   problem scores the native problem's error components (``score=x+y``).
3. **Work-precision.** ``fmpy-cvode`` (fmpy's CVODE on the FMU itself, dense
   finite-difference Jacobian) and ``cvode-bdf`` (the harness's CVODE on the FMU
   problem, the FMU's directional derivatives as Jacobian where it provides them)
   over ``--rtols``: scd, nfev, njev, nsteps and the median CPU of ``--repeat``
   solves, fmpy-cvode's CPU over cvode-bdf's at equal rtol, and the CPU each needs
   to reach scd >= 4, 6, 8 (:func:`integrator_bench.harness.ranking.reach.target_table`
   with the measure ``scd``: interpolated log-log between the tolerances that
   bracket the target, never extrapolated; ``≤`` an upper bound).

Every case runs in this process through
:func:`integrator_bench.harness.run.execution.execute` (counters, CPU of the solve
alone, errors against the reference); nothing is stored.

Usage::

    .venv/bin/python studies/fmu_check.py                      # Markdown
    .venv/bin/python studies/fmu_check.py --models spring_pendulum --rtols 1e-4 1e-6 --json

``two_mass`` runs at its defaults (k2 = 1e4: the FMU reference takes about a
minute, DOP853 at rtol 1e-13 crossing some 225 periods of the 141 rad/s mode) and
at k2 = 100 (:data:`VARIANTS`); ``--quick`` leaves the default set out. Bad input:
one line on standard error, exit 2.

References: Modelica Association, "Functional Mock-up Interface for Model
Exchange and Co-Simulation", version 2.0.4 (2022); F. Mazzia and C. Magherini,
"Test Set for Initial Value Problem Solvers", release 2.4 (2008), sect. II (scd).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from integrator_bench.harness.measure import references

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import Case
from integrator_bench.harness.run.execution import execute
from integrator_bench.harness.measure.metrics import agreement_digits, digits
from integrator_bench.harness.paths import CHECKOUT, REFERENCE_DIR, SHIPPED_REFERENCE_DIR
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.harness.ranking import reach
from integrator_bench.problems.base import SCORE_SEPARATOR
from integrator_bench.problems.fmu import FmuProblem
from integrator_bench.problems.fmu_build import MODELS, build_fmu

#: parameter sets per model (beside the FMU's defaults); two_mass also at a soft
#: coupling, whose FMU reference takes seconds instead of a minute
VARIANTS = {"spring_pendulum": ({},), "two_mass": ({}, {"k2": 100.0}),
            "bouncing_ball": ({},)}
#: the sets ``--quick`` runs
QUICK_VARIANTS = {"spring_pendulum": ({},), "two_mass": ({"k2": 100.0},),
                  "bouncing_ball": ({},)}
#: part 2: adaptive ones at SAME_RTOL, fixed-step ones (FIXED) at span / SAME_STEPS
INTEGRATORS = ("scipy-RK45", "scipy-DOP853", "scipy-Radau", "scipy-BDF", "cvode-bdf",
               "cvode-adams", "ida", "bdf3", "rk4", "sdirk3", "gbs", "dumka3")
SAME_RTOL = 1e-6
SAME_STEPS = 1000
#: part 3
WP_INTEGRATORS = ("fmpy-cvode", "cvode-bdf")
RTOLS = tuple(10.0 ** -e for e in range(3, 11))
SCD_TARGETS = (4, 6, 8)


def committed_reference_dir() -> Path:
    """Where the project's own references are: the checkout's ``results/reference``,
    or the copies shipped in the wheel."""
    if SHIPPED_REFERENCE_DIR is not None:
        return SHIPPED_REFERENCE_DIR
    return CHECKOUT / "results" / "reference" if CHECKOUT is not None else REFERENCE_DIR


@contextlib.contextmanager
def stdout_to(path: Path):
    """File descriptor 1 (CMake's progress, printed by a child process) into
    ``path`` for the block; Python's ``sys.stdout`` is flushed first."""
    sys.stdout.flush()
    saved = os.dup(1)
    with open(path, "ab") as log:
        os.dup2(log.fileno(), 1)
        try:
            yield
        finally:
            sys.stdout.flush()
            os.dup2(saved, 1)
            os.close(saved)


def build_all(models, work: Path) -> dict:
    """model -> path of its FMU, built into ``work/fmus`` (the build log beside)."""
    out, log = work / "fmus", work / "fmu_build.log"
    out.mkdir(parents=True, exist_ok=True)
    with stdout_to(log):
        return {m: build_fmu(m, out) for m in models}


def make_pair(model: str, fmu_path: Path, params: dict):
    """The native problem and the FMU problem scoring the native's error components."""
    native = registry.get_problem_class(model)(**params)
    score = SCORE_SEPARATOR.join(native.error_components)
    return native, FmuProblem(path=str(fmu_path), score=score, **params)


def native_reference(native, work_refs: Path):
    """The committed reference of ``native``; computed into ``work_refs`` when
    there is none. Returns the reference and the directory it is in."""
    ref, _ = references.read(native, committed_reference_dir())
    if ref is not None:
        return ref, committed_reference_dir()
    return references.load(native, work_refs), work_refs


def event_digits(a_meta: dict, b_meta: dict, span: float) -> dict | None:
    """Event times of two references compared by order (names ignored): counts and
    ``-log10(max |dt| / span)`` (None when either has no event sequence)."""
    if "events" not in a_meta or "events" not in b_meta:
        return None
    ta = [float(t) for t, _ in a_meta["events"]]
    tb = [float(t) for t, _ in b_meta["events"]]
    out = {"n_fmu": len(ta), "n_native": len(tb), "digits": None, "max_dt": None}
    if len(ta) == len(tb):
        worst = max((abs(x - y) for x, y in zip(ta, tb)), default=0.0)
        out.update(max_dt=worst, digits=float(digits(worst / span)))
    return out


def cross_check(native, fmu, ref_native, ref_fmu) -> dict:
    """Part 1 for one pair of references."""
    if ref_fmu.t.shape != ref_native.t.shape or not np.allclose(ref_fmu.t, ref_native.t,
                                                                 rtol=0, atol=1e-12):
        raise RuntimeError(f"{fmu.label()}: reference output times differ from "
                           f"{native.label()}'s")
    agree = agreement_digits(ref_fmu.Y, ref_native.Y, native.atol_scale_vector())
    span = native.t_span[1] - native.t_span[0]
    return {"components": list(native.components),
            "digits": [float(d) for d in agree],
            "min_digits": float(np.min(agree)),
            "claimed_fmu": ref_fmu.meta["claimed_digits"],
            "claimed_native": ref_native.meta["claimed_digits"],
            "methods_fmu": [m.get("integrator", m.get("method")) for m in ref_fmu.meta["methods"]],
            "methods_native": [m.get("integrator", m.get("method"))
                               for m in ref_native.meta["methods"]],
            "events": event_digits(ref_fmu.meta, ref_native.meta, span)}


def case_of(problem, integrator: str, rtol=None, h=None) -> Case:
    return Case(problem.name, tuple(sorted(problem.params.items())), "ode", integrator,
                rtol=rtol, h=h)


def step_mode(integrator: str, span: float) -> dict:
    """``{"rtol": SAME_RTOL}`` for an adaptive integrator, else ``{"h": span / SAME_STEPS}``."""
    if registry.get_integrator(integrator).adaptive:
        return {"rtol": SAME_RTOL}
    return {"h": span / SAME_STEPS}


def _num(value):
    if value is None or value is pd.NA or (isinstance(value, float) and math.isnan(value)):
        return None
    return value.item() if hasattr(value, "item") else value


def same_integrator(native, fmu, dirs) -> list[dict]:
    """Part 2 for one pair: each integrator on both problems."""
    span = native.t_span[1] - native.t_span[0]
    out = []
    for name in INTEGRATORS:
        mode = step_mode(name, span)
        rec_f = execute(case_of(fmu, name, **mode), reference_dir=dirs["fmu"])
        rec_n = execute(case_of(native, name, **mode), reference_dir=dirs["native"])
        both = rec_f["status"] == rec_n["status"] == CaseStatus.OK
        out.append({"integrator": name, **mode,
                    "status_fmu": rec_f["status"], "status_native": rec_n["status"],
                    "message": "; ".join(f"{w}: {r['message']}" for w, r in
                                         (("fmu", rec_f), ("native", rec_n))
                                         if r["status"] != CaseStatus.OK and r["message"]) or None,
                    "scd_fmu": _num(rec_f["scd"]), "scd_native": _num(rec_n["scd"]),
                    "scd_diff": rec_f["scd"] - rec_n["scd"] if both else None,
                    "nfev_fmu": _num(rec_f["nfev"]), "nfev_native": _num(rec_n["nfev"])})
    return out


def work_precision(fmu, ref_dir, rtols, repeat: int) -> dict:
    """Part 3 for one FMU problem: the records, the CPU ratios and the targets."""
    records = [execute(case_of(fmu, name, rtol=r), reference_dir=ref_dir, repeat=repeat)
               for name in WP_INTEGRATORS for r in rtols]
    keep = ("integrator", "rtol", "status", "message", "scd", "nfev", "njev", "nsteps",
            "cpu_s", "cpu_s_min", "repeat", "nevents", "event_time_err")
    points = [{k: _num(rec.get(k)) for k in keep} for rec in records]
    by = {(p["integrator"], p["rtol"]): p for p in points}
    a, b = WP_INTEGRATORS
    ratios = []
    for r in rtols:
        pa, pb = by[(a, r)], by[(b, r)]
        ok = pa["status"] == pb["status"] == CaseStatus.OK and pa["cpu_s"] and pb["cpu_s"]
        ratios.append({"rtol": r, "cpu_ratio": pa["cpu_s"] / pb["cpu_s"] if ok else None,
                       "nfev_ratio": pa["nfev"] / pb["nfev"] if ok and pb["nfev"] else None})
    table = reach.target_table(pd.DataFrame(records), [10.0 ** -d for d in SCD_TARGETS],
                               measure="scd")
    lines = []
    for row in table.to_dict("records"):
        entry = {"integrator": row["label"]}
        for d in SCD_TARGETS:
            tag = f"{10.0 ** -d:.0e}"
            entry[f"cpu_scd{d}"] = _num(row[f"cpu_{tag}"])
            entry[f"how_scd{d}"] = row[f"how_{tag}"]
            entry[f"nfev_scd{d}"] = _num(row[f"nfev_{tag}"])
        entry["best_scd"] = (None if pd.isna(row["best_err"])
                             else float(-math.log10(row["best_err"])))
        lines.append(entry)
    order = {name: i for i, name in enumerate(WP_INTEGRATORS)}
    lines.sort(key=lambda e: order[e["integrator"]])
    target_ratios = {}
    got = {e["integrator"]: e for e in lines}
    for d in SCD_TARGETS:
        ea, eb = got.get(a, {}), got.get(b, {})
        ca, cb = ea.get(f"cpu_scd{d}"), eb.get(f"cpu_scd{d}")
        sure = {ea.get(f"how_scd{d}"), eb.get(f"how_scd{d}")} <= {"interpolated", "at a point"}
        target_ratios[str(d)] = {"ratio": ca / cb if ca and cb else None, "exact": sure}
    return {"points": points, "cpu_ratios": ratios, "reach": lines,
            "target_ratios": target_ratios}


def _f(x, fmt="{:.2f}"):
    return "–" if x is None else fmt.format(x)


def markdown(results: list[dict], meta: dict) -> str:
    """The three parts' tables."""
    from integrator_bench.harness.tables import markdown_lines

    lines = ["### 1. FMU reference against the native reference (agreement digits)", ""]
    rows = []
    for res in results:
        c = res["cross_check"]
        ev = c["events"]
        rows.append((res["label"],
                     ", ".join(f"{n} {d:.1f}" for n, d in zip(c["components"], c["digits"])),
                     f"{c['min_digits']:.1f}", f"{c['claimed_fmu']} / {c['claimed_native']}",
                     "–" if ev is None else (f"{ev['digits']:.1f} ({ev['n_fmu']} events)"
                                             if ev["digits"] is not None else
                                             f"count differs: {ev['n_fmu']} / {ev['n_native']}"),
                     f"{res['ref_fmu_s']:.1f}"))
    lines += markdown_lines(("problem", "digits per component", "least",
                             "claimed FMU / native", "event times", "FMU ref [s]"),
                            rows, [2, 3, 5])
    lines += ["", f"### 2. Same integrator on the FMU and the native problem (rtol {SAME_RTOL:g}, "
              f"fixed step h = span / {SAME_STEPS})", ""]
    rows = []
    for res in results:
        for s in res["same_integrator"]:
            status = CaseStatus.OK if s["status_fmu"] == s["status_native"] == CaseStatus.OK else \
                f"{s['status_fmu']} / {s['status_native']}"
            rows.append((res["label"], s["integrator"],
                         f"rtol {s['rtol']:g}" if "rtol" in s else f"h {s['h']:g}", status,
                         _f(s["scd_fmu"]), _f(s["scd_native"]), _f(s["scd_diff"], "{:+.2f}"),
                         _f(s["nfev_fmu"], "{:d}"), _f(s["nfev_native"], "{:d}")))
    lines += markdown_lines(("problem", "integrator", "step", "status FMU / native",
                             "scd FMU", "scd native", "diff", "nfev FMU", "nfev native"),
                            rows, [4, 5, 6, 7, 8])
    why = [f"{res['label']} {s['integrator']}: {s['message']}" for res in results
           for s in res["same_integrator"] if s["message"]]
    if why:
        lines += ["", "Not ok: " + "; ".join(why) + "."]
    lines += ["", "### 3. fmpy-cvode against cvode-bdf on the FMU problem "
              f"(CPU: median of {meta['repeat']})", ""]
    rows = []
    for res in results:
        wp = res["work_precision"]
        by = {(p["integrator"], p["rtol"]): p for p in wp["points"]}
        for r in wp["cpu_ratios"]:
            a, b = by[(WP_INTEGRATORS[0], r["rtol"])], by[(WP_INTEGRATORS[1], r["rtol"])]
            cells = [res["label"], f"{r['rtol']:.0e}"]
            for p in (a, b):
                cells += [p["status"] if p["status"] != CaseStatus.OK else _f(p["scd"]),
                          _f(p["nfev"], "{:d}"), _f(p["njev"], "{:d}"),
                          _f(p["nsteps"], "{:d}"), _f(p["cpu_s"], "{:.4f}")]
            cells.append(_f(r["cpu_ratio"]))
            rows.append(cells)
    head = ["problem", "rtol"]
    for name in WP_INTEGRATORS:
        head += [f"scd {name}", "nfev", "njev", "nsteps", "CPU [s]"]
    head.append("CPU ratio")
    lines += markdown_lines(head, rows, list(range(2, len(head))))
    why = [f"{res['label']} {p['integrator']} rtol {p['rtol']:g}: {p['message']}"
           for res in results for p in res["work_precision"]["points"]
           if p["status"] != CaseStatus.OK]
    if why:
        lines += ["", "Not ok: " + "; ".join(why) + "."]
    lines += ["", f"CPU [s] to reach scd >= {', '.join(map(str, SCD_TARGETS))} "
              "(interpolated log-log; ≤ upper bound: the loosest rtol already reaches it) "
              f"and the ratio {WP_INTEGRATORS[0]} / {WP_INTEGRATORS[1]} (~: one of the two "
              "is an upper bound):", ""]
    rows = []
    for res in results:
        wp = res["work_precision"]
        for e in wp["reach"]:
            cells = [res["label"], e["integrator"]]
            for d in SCD_TARGETS:
                cells.append(reach.cpu_cell(e[f"cpu_scd{d}"] if e[f"cpu_scd{d}"] is not None
                                              else math.nan, e[f"how_scd{d}"]))
            cells.append(_f(e["best_scd"]))
            rows.append(cells)
        tr = wp["target_ratios"]
        rows.append([res["label"], "ratio"] + [
            "–" if tr[str(d)]["ratio"] is None else
            f"{'' if tr[str(d)]['exact'] else '~'}{tr[str(d)]['ratio']:.2f}"
            for d in SCD_TARGETS] + [""])
    lines += markdown_lines(["problem", "integrator"] + [f"scd ≥ {d}" for d in SCD_TARGETS]
                            + ["best scd"], rows, [2, 3, 4, 5])
    lines += ["", f"{meta['cases']} cases; wall time {meta['wall_s']:.0f} s (FMU build "
              f"{meta['build_s']:.0f} s, references {meta['reference_s']:.0f} s); "
              f"code {meta['code_version']}."]
    return "\n".join(lines) + "\n"


def _fail(message: str) -> int:
    print(f"fmu_check: error: {message}", file=sys.stderr)
    return 2


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="+", default=list(MODELS),
                    help=f"FMU models (default all: {', '.join(MODELS)})")
    ap.add_argument("--rtols", type=float, nargs="+", default=list(RTOLS),
                    help="tolerances of the work-precision part (default 1e-3 ... 1e-10)")
    ap.add_argument("--repeat", type=int, default=3, help="timed solves per work-precision case")
    ap.add_argument("--quick", action="store_true",
                    help="two_mass at k2 = 100 only (its default set's FMU reference takes a minute)")
    ap.add_argument("--work", type=Path, help="folder for the FMUs and references "
                    "(default: a temporary one, removed at the end)")
    ap.add_argument("--json", action="store_true", help="print one JSON document instead")
    args = ap.parse_args(argv)
    bad = [m for m in args.models if m not in MODELS]
    if bad:
        return _fail(f"--models {bad[0]}: valid are {', '.join(MODELS)}")
    if any(not (math.isfinite(r) and 0 < r < 1) for r in args.rtols):
        return _fail(f"--rtols takes numbers in (0, 1), got {args.rtols}")
    if args.repeat < 1:
        return _fail(f"--repeat {args.repeat}: must be >= 1")
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="fmu_check_") as tmp:
        work = (args.work or Path(tmp)).resolve()
        try:
            fmus = build_all(args.models, work)
        except RuntimeError as exc:
            return _fail(f"{exc} (build log: {work / 'fmu_build.log'})")
        build_s = time.perf_counter() - start
        results, n_cases, ref_s = run_all(fmus, args, work / "reference")
    from integrator_bench.harness.version import code_version

    meta = {"models": args.models, "rtols": sorted(args.rtols, reverse=True),
            "repeat": args.repeat, "same_rtol": SAME_RTOL, "same_steps": SAME_STEPS,
            "integrators": list(INTEGRATORS), "wp_integrators": list(WP_INTEGRATORS),
            "scd_targets": list(SCD_TARGETS), "cases": n_cases,
            "wall_s": time.perf_counter() - start, "build_s": build_s, "reference_s": ref_s,
            "code_version": code_version()}
    if args.json:
        print(json.dumps({**meta, "results": results}, indent=1))
    else:
        print(markdown(results, meta), end="")
    return 0


def run_all(fmus: dict, args, work_refs: Path) -> tuple[list[dict], int, float]:
    """Every model and parameter set: the three parts."""
    variants = QUICK_VARIANTS if args.quick else VARIANTS
    rtols = sorted(args.rtols, reverse=True)
    results, n_cases, ref_s = [], 0, 0.0
    for model, path in fmus.items():
        for params in variants[model]:
            native, fmu = make_pair(model, path, params)
            t0 = time.perf_counter()
            ref_fmu = references.load(fmu, work_refs)
            t1 = time.perf_counter()
            ref_native, native_dir = native_reference(native, work_refs)
            ref_s += time.perf_counter() - t0
            label = native.label()
            same = same_integrator(native, fmu, {"fmu": work_refs, "native": native_dir})
            wp = work_precision(fmu, work_refs, rtols, args.repeat)
            n_cases += 2 * len(same) + len(wp["points"])
            results.append({"model": model, "params": params, "label": label,
                            "ref_fmu_s": t1 - t0,
                            "cross_check": cross_check(native, fmu, ref_native, ref_fmu),
                            "same_integrator": same, "work_precision": wp})
    return results, n_cases, ref_s


if __name__ == "__main__":
    sys.exit(main())
