"""How the chain drive's cost grows with its size.

For the closed roller chain ``chain_drive`` at N links (default N = 10, 30,
100, 300, 1000; ``--sizes``) this measures, with ``time.process_time``:

``rhs_s``
    one right-hand side of the ``ode`` form (the sparse augmented system
    ``[[M, G^T], [G, 0]]`` assembled and factored by SuperLU, then solved);
``jac_s``
    the model's analytic Jacobian that every formulation's Jacobian is built
    from: ``force_q``, ``force_v``, ``constraint_jac`` and ``gv_q`` (the
    ``ode`` form itself has none: for a closed chain it is structurally dense,
    see :mod:`integrator_bench.problems.mechanical`);
``ggl_res_s``, ``ggl_jac_s``
    the ``ggl`` residual, and its iteration matrix ``dF/dy + cj dF/dy'``
    laid on SUNDIALS' sparse structure (:func:`~integrator_bench.integrators.sparse.on_pattern`),
    as IDA's ``jacfn`` hands it over;
``i3_res_s``, ``i3_jac_s``
    what one Newton iteration of HHT takes from the ``mechanical`` form
    (``force``, ``constraint``, ``constraint_jac`` and the residual
    ``M a + G^T lam - f``), and its ``tangent`` (the blocks K, C);
``step_ida_s``, ``step_hht_s``
    CPU of a whole run of IDA on ``ggl`` and of HHT on ``i3`` over the short
    span ``[0, --t-end]`` at ``--rtol``, divided by the run's accepted steps;
``peak_mb``
    the ``tracemalloc`` peak of building the problem, formulating ``ode``,
    ``ggl`` and ``i3`` and evaluating every piece above once (memory that
    SuperLU allocates in C is not traced; the process's max RSS is printed).

Each evaluation figure is the least, over ``--repeat`` timings, of the mean of
a batch of calls lasting at least ``--min-time`` seconds; each step figure is
the least over runs (repeated until ``--min-time`` is spent, at most
``--repeat`` runs). Slopes are least-squares fits of log(figure) on log(N)
over the sizes >= ``--fit-from`` (all sizes when fewer than two qualify). The
issue's targets: slope <= 1.1 for the evaluations, <= 1.3 for a step.

Pins: ``teeth`` is the problem's default 16 wherever it fits (N >= 18), else
the largest even number of teeth that leaves two spans (N = 10: 8 teeth); all
other parameters are the defaults but ``t_end``.

IDA and the sparsity pattern: the ``ggl`` form of a sparse problem declares
its structural pattern (``MechanicalProblem._dae_sparsity``); above
``sundials.KRYLOV_MIN`` states IDA solves with GMRES preconditioned by the
exact sparse LU of its iteration matrix (see integrators/sundials.py).

    python studies/chain_scaling.py                      # N = 10 ... 1000
    python studies/chain_scaling.py --sizes 30 100 --out /tmp/scaling

Writes ``<data dir>/scaling/chain_drive.json`` (``--out DIR`` overrides the
folder; the schema and writer are the report's,
:mod:`integrator_bench.harness.report.scaling`, which also says which bound
each figure has) and ``chain_drive.svg`` beside it. Exits 1 when a target is missed or
a run fails, 2 on bad input. Not an asv benchmark: no function here is named
``time_``, ``track_``, ``mem_`` or ``peakmem_`` (asv's figures: chain_scaling_asv.py).
"""

from __future__ import annotations

# the harness before numpy: it sets one BLAS thread per process (harness/__init__.py)
from integrator_bench.harness import paths  # isort: skip
from integrator_bench.harness.matrix import registry

import argparse  # noqa: E402
import gc
import math
import multiprocessing
import os
import platform
import resource
import sys
import time
import tracemalloc
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from integrator_bench.problems.base import ProblemError
from integrator_bench.problems.system import convert

# the evaluations and systems measured here are those the asv suite tracks over commits
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.chain_pieces import PROBLEM, ida_system, pieces, problem  # noqa: E402

SIZES = (10, 30, 100, 300, 1000)
EVALS = ("rhs_s", "jac_s", "ggl_res_s", "ggl_jac_s", "i3_res_s", "i3_jac_s")
STEPS = ("step_ida_s", "step_hht_s")
SLOPED = EVALS + STEPS + ("peak_mb",)
TARGETS = {"rhs_and_jac_slope_max": 1.1, "step_slope_max": 1.3}


def cpu_per_call(fn, min_time: float, repeat: int) -> float:
    """Least over ``repeat`` batches of the mean CPU seconds of a call; each batch
    lasts at least ``min_time``."""
    fn()
    number, start = 1, time.process_time()
    while True:  # calibrate the batch size
        for _ in range(number):
            fn()
        spent = time.process_time() - start
        if spent >= min_time:
            break
        number = max(2 * number, int(1.2 * number * min_time / max(spent, 1e-9)))
        start = time.process_time()
    best = spent / number
    for _ in range(repeat - 1):
        start = time.process_time()
        for _ in range(number):
            fn()
        best = min(best, (time.process_time() - start) / number)
    return best


def cpu_per_step(name: str, system, rtol: float, min_time: float, repeat: int):
    """``(cpu per accepted step, nsteps)`` of ``name`` on ``system``: least over runs.

    Raises RuntimeError when a run fails."""
    icls = registry.get_integrator(name)
    best, spent, runs = math.inf, 0.0, 0
    while runs < max(1, repeat) and (runs == 0 or spent < min_time):
        start = time.process_time()
        sol = icls().solve(system, rtol=rtol, atol=system.atol(rtol))
        cpu = time.process_time() - start
        if not sol.success or not sol.counts.get("nsteps"):
            raise RuntimeError(f"{name} failed: {sol.message.strip()}")
        best, spent, runs = min(best, cpu), spent + cpu, runs + 1
    return best / sol.counts["nsteps"], int(sol.counts["nsteps"])


def cpu_per_step_isolated(name: str, system, rtol: float, min_time: float, repeat: int):
    """:func:`cpu_per_step` in a forked child, so that a solver that aborts the process
    (SuperLU_MT out of its preallocated memory does) costs one figure, not the table.

    Returns ``(cpu per step, nsteps, None)`` or ``(None, None, why)``.
    """
    ctx = multiprocessing.get_context("fork")
    receive, send = ctx.Pipe(duplex=False)

    def child():
        try:
            send.send(("ok", cpu_per_step(name, system, rtol, min_time, repeat)))
        except Exception as exc:  # reported by the parent
            send.send(("error", f"{type(exc).__name__}: {exc}"))

    proc = ctx.Process(target=child)
    proc.start()
    send.close()
    try:
        kind, value = receive.recv()
    except EOFError:
        kind, value = "error", None
    proc.join()
    if kind == "ok":
        return (*value, None)
    return None, None, value or f"{name}'s process died (exit code {proc.exitcode})"


def peak_memory(n_links: int, t_end: float) -> float:
    """tracemalloc peak (MB) of building, formulating and evaluating every piece once."""
    gc.collect()
    tracemalloc.start()
    try:
        for fn in pieces(problem(n_links, t_end)).values():
            fn()
        return tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()


def measure(n_links: int, args) -> tuple[dict, dict]:
    """One row of the table, and the failures of its runs (figure key -> why)."""
    chain = problem(n_links, args.t_end)
    row, failed = {"n_links": n_links, "n_states": 2 * chain.nq}, {}
    for key, fn in pieces(chain).items():
        row[key] = cpu_per_call(fn, args.min_time, args.repeat)
    mech = convert(chain.formulate("i3"), registry.get_integrator("hht"))
    for name, system in (("ida", ida_system(chain)), ("hht", mech)):
        step, nsteps, why = cpu_per_step_isolated(name, system, args.rtol, args.min_time,
                                              args.repeat)
        row[f"step_{name}_s"], row[f"nsteps_{name}"] = step, nsteps
        if why:
            failed[f"step_{name}_s"] = why
    row["peak_mb"] = peak_memory(n_links, args.t_end)
    return row, failed


def slopes(rows: list[dict], fit_from: int) -> tuple[dict, list[int]]:
    """Least-squares slopes of log(figure) on log(N) over the sizes >= ``fit_from``
    (all sizes when fewer than two qualify), and those sizes; a figure missing
    (a failed run) is left out of its fit, and a fit of fewer than two sizes is None."""
    fitted = [r for r in rows if r["n_links"] >= fit_from]
    if len(fitted) < 2:
        fitted = rows
    out = {}
    for k in SLOPED:
        pts = [(r["n_links"], r[k]) for r in fitted if r[k] is not None]
        out[k] = (float(np.polyfit(np.log([n for n, _ in pts]), np.log([y for _, y in pts]), 1)[0])
                  if len(pts) >= 2 else None)
    return out, [r["n_links"] for r in fitted]


def verdicts(slope: dict, incomplete=()) -> list[tuple[str, float, float, bool]]:
    """``(figure, slope, target, met)`` for every target of the issue; a figure in
    ``incomplete`` (missing at a fitted size: a failed run) is never met."""
    from integrator_bench.harness.report.scaling import slope_bound

    out = [(k, slope[k], slope_bound(k, TARGETS)) for k in EVALS + STEPS]
    return [(k, s, t, s is not None and s <= t and k not in incomplete) for k, s, t in out]


def machine() -> str:
    """CPU model, count and Python version, in one short line."""
    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            model = next(ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{model}, {os.cpu_count()} CPUs, Python {platform.python_version()}"


def figure(result, path: Path) -> None:
    """Log-log figure of every figure of ``result`` (a
    :class:`~integrator_bench.harness.report.scaling.Scaling`) against N, with a slope-1
    guide, as SVG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows, slope = result.rows, result.slopes
    n = np.array([r["n_links"] for r in rows], float)
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2))
    for ax, keys, unit in ((axes[0], EVALS, "CPU s per evaluation"),
                           (axes[1], STEPS, "CPU s per step"), (axes[2], ("peak_mb",), "MB")):
        for k in keys:
            y = np.array([np.nan if r[k] is None else r[k] for r in rows], float)
            label = "n/a" if slope[k] is None else f"{slope[k]:.2f}"
            ax.loglog(n, y, "o-", label=f"{k} (slope {label})")
        ref = np.array([r[keys[0]] or np.nan for r in rows], float)
        ax.loglog(n, ref[0] * n / n[0], "k:", lw=1, label="slope 1")
        ax.set_xlabel("links N")
        ax.set_ylabel(unit)
        ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=0.3)
    axes[2].set_title("tracemalloc peak")
    fig.suptitle(f"chain_drive scaling ({result.machine})", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2
        self.exit(2, f"chain_scaling.py: error: {message}\n")


def parse_args(argv=None) -> argparse.Namespace:
    ap = _Parser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=list(SIZES),
                    help="numbers of links (even, >= 10)")
    ap.add_argument("--t-end", type=float, default=0.02, help="span of the IDA and HHT runs [s]")
    ap.add_argument("--rtol", type=float, default=1e-5)
    ap.add_argument("--min-time", type=float, default=0.2, help="CPU seconds per timing batch")
    ap.add_argument("--repeat", type=int, default=5, help="timings (batches, runs) per figure")
    ap.add_argument("--fit-from", type=int, default=30, help="smallest N in the slope fits")
    ap.add_argument("--out", type=Path, default=None,
                    help="output folder (default <data dir>/scaling)")
    args = ap.parse_args(argv)
    for name in ("t_end", "rtol", "min_time"):
        if not getattr(args, name) > 0:
            ap.error(f"--{name.replace('_', '-')} must be > 0, got {getattr(args, name)}")
    if args.repeat < 1:
        ap.error(f"--repeat must be >= 1, got {args.repeat}")
    for n in args.sizes:
        try:
            problem(n, args.t_end)
        except (ProblemError, ValueError) as exc:
            ap.error(f"--sizes {n}: {exc} (valid: even numbers of links >= 10)")
    args.sizes = sorted(set(args.sizes))
    return args


def main(argv=None) -> int:
    # imported here, not above: chain_scaling_asv.py times pieces() on older commits too,
    # whose packages have no report package
    from integrator_bench.harness.report.scaling import Scaling, write_scaling

    args = parse_args(argv)
    out = args.out or paths.DATA_DIR / "scaling"
    rows = []
    head = ("N", "states", *EVALS, *STEPS, "steps ida/hht", "peak MB")
    print(" ".join(f"{h:>11}" for h in head))
    failures = []
    for n in args.sizes:
        row, failed = measure(n, args)
        rows.append(row)
        failures += [f"N = {n}: {k}: {why}" for k, why in failed.items()]
        cells = [f"{row['n_links']:>11d}", f"{row['n_states']:>11d}"]
        cells += ["{:>11}".format("failed" if row[k] is None else f"{row[k]:.3e}")
                  for k in EVALS + STEPS]
        steps = "/".join("-" if row[k] is None else str(row[k])
                         for k in ("nsteps_ida", "nsteps_hht"))
        cells += [f"{steps:>13}", f"{row['peak_mb']:>11.2f}"]
        print(" ".join(cells), flush=True)
    slope, fitted = slopes(rows, args.fit_from)
    created = datetime.now(timezone.utc).isoformat(timespec="seconds")
    result = Scaling(problem=PROBLEM, created=created, machine=machine(), rows=rows,
                     slopes=slope, targets=dict(TARGETS))
    print(f"\nlog-log slopes, least squares over N = {', '.join(map(str, fitted))}:")
    missed = 0
    incomplete = {k for r in rows if r["n_links"] in fitted for k in SLOPED if r[k] is None}
    for key, s, target, met in verdicts(slope, incomplete):
        shown = "   n/a" if s is None else f"{s:6.2f}"
        why = " (runs failed at fitted sizes)" if key in incomplete else ""
        print(f"  {key:<11} {shown}   target <= {target}: {'met' if met else 'MISSED'}{why}")
        missed += not met
    if slope["peak_mb"] is not None:
        print(f"  {'peak_mb':<11} {slope['peak_mb']:6.2f}")
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"max RSS of this process: {rss:.0f} MB; timings: {machine()} (process_time, least of "
          f"{args.repeat}; shared machines are noisy, the slopes are what counts)")
    path = write_scaling(result, out)
    figure(result, out / f"{PROBLEM}.svg")
    print(f"wrote {path} and {out / f'{PROBLEM}.svg'}")
    for line in failures:
        print(f"run failed: {line}")
    return 1 if missed or failures else 0


if __name__ == "__main__":
    sys.exit(main())
