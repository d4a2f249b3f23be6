"""Timing fidelity: the harness's CPU against plain calls of the library.

A fixed set of cases, every library integrator (:data:`LIBRARY_FAMILIES`: scipy's
six ``solve_ivp`` methods, SUNDIALS' ``cvode-bdf``, ``cvode-adams`` and ``ida``,
and with the extra ``[assimulo]`` Assimulo's eight) on :data:`PROBLEMS` (``ode``
formulation) at :data:`RTOLS`, is timed in this process twice per round: through
the harness, :class:`~integrator_bench.harness.run.isolation.Isolated` (a forked
worker kept from case to case, as ``ibench run``'s pool runs them; its ``cpu_s``, the
median of its samples, the first of them the case's counted solve;
a case over :data:`TIMEOUT_S` is left out, and so are its tighter tolerances),
and by calling the library plainly on the same formulated system with the same
``rtol``, ``atol``, output times and Jacobian (``solve_ivp``; scikit-sundae's
``CVODE(...).solve``/``IDA(...).solve``; Assimulo's ``simulate``; their output
discarded), sampled by the same
rule (:func:`~integrator_bench.harness.run.execution.samples`) and its median taken.
The two alternate, case by case, for ``--rounds`` rounds; a case's ratio is the
median over the rounds of the harness's CPU over the median of the plain one's.
Prints the ratio per case, their median and the largest; the targets are a
median of at most :data:`MAX_MEDIAN` and none above :data:`MAX_RATIO`.

For the in-house steppers (whose loop is the shared driver,
:mod:`integrator_bench.integrators.driver`) there is no plain call to compare
with: the script profiles one solve of each on ``two_mass`` (``cProfile``) and
prints the share of its time spent in the driver's own code (the package
``driver/`` and ``control.py``, the functions' own time), beside the solve's CPU.

    python studies/fidelity.py              # the fixed set, 3 rounds (minutes)
    python studies/fidelity.py --quick      # two_mass at 1e-6, two codes, rk4 (seconds)
    python studies/fidelity.py --problem squeezer --rtol 1e-6   # a part of the fixed set

Exits 1 when a target is missed, 2 on bad input. Not an asv benchmark (no
``time_``/``track_`` names).
"""

from __future__ import annotations

import argparse
import cProfile
import math
import pstats
import statistics
import sys
import time

# the harness before numpy, as ``ibench`` imports them: one BLAS thread per process
from integrator_bench.harness.run import isolation  # noqa: F401  isort: skip

import numpy as np  # noqa: E402
import scipy.integrate as si
from sksundae import ida

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import Case, expand
from integrator_bench.harness.matrix.line import spec_name
from integrator_bench.harness.run.execution import MAX_SAMPLES, MIN_CPU_S, samples, timed
from integrator_bench.harness.run.isolation import Isolated
from integrator_bench.harness.run.limits import Limits
from integrator_bench.harness.run.streams import silenced
from integrator_bench.integrators.scipy_ivp import ScipyIVP
from integrator_bench.integrators.sundials import SundialsIntegrator
from integrator_bench.problems.base import format_label
from integrator_bench.problems.system import convert

PROBLEMS = ("two_mass:c1=0.1,c2=1000,k1=10,k2=10000", "squeezer", "slider_crank",
            "chain_bushing:n_links=30")
RTOLS = (1e-3, 1e-6, 1e-9)
FORMULATION = "ode"
MAX_MEDIAN = 1.05   # the target: median ratio harness / plain at most this
MAX_RATIO = 1.15    # and none above this
TIMEOUT_S = 20.0    # a case's budget in the harness (a slower one is left out, timeout)
QUICK = dict(problems=("two_mass",), rtols=(1e-6,), integrators=("scipy-RK45", "cvode-bdf"),
             steppers=("rk4",), rounds=1)
STEPPER_PROBLEM = "two_mass"
STEPPER_RTOL = 1e-6     # the adaptive steppers' tolerance
STEPPER_STEPS = 2000    # the fixed-step ones' steps over the span
#: the driver's own code: the modules of the package integrators/driver/ and control.py
DRIVER_FILES = tuple(f"integrators/driver/{m}.py" for m in (
    "__init__", "segments", "outputs", "events", "budget", "stepping")) + (
    "integrators/control.py",)


def plain_scipy(integrator, system, rtol, atol):
    """``solve_ivp`` as a user calls it, with the options the wrapper gives the solver."""
    options, _, _ = integrator.solver_options(system, rtol, atol)
    span = (system.t0, system.t_end)
    return lambda: si.solve_ivp(system.fun, span, system.y0, method=integrator.solver_class,
                                t_eval=system.t_eval, **options)


def plain_sundials(integrator, system, rtol, atol):
    """scikit-sundae's solver built and ``solve``d over the output times."""
    fn, options, *_ = integrator.library_options(system, rtol, atol)
    args = (system.t_eval, system.y0) + ((system.yp0,) if integrator.solver_class is ida.IDA
                                         else ())
    return lambda: integrator.solver_class(fn, **options).solve(*args)


def plain_assimulo(integrator, system, rtol, atol):
    """Assimulo's solver built as a user would and ``simulate``d over the output times."""
    return lambda: integrator.library_solver(system, rtol, atol).simulate(
        system.t_end, ncp_list=system.t_eval)


#: the library families with a plain call: base class -> the call's maker
LIBRARY_FAMILIES = {ScipyIVP: plain_scipy, SundialsIntegrator: plain_sundials}
try:  # the optional extra [assimulo]
    from integrator_bench.integrators.assimulo import AssimuloIntegrator
    LIBRARY_FAMILIES[AssimuloIntegrator] = plain_assimulo
except ImportError:
    pass


def plain_call(name, system, rtol, atol):
    """A zero-argument plain call of the library behind integrator ``name``, or None."""
    icls = registry.get_integrator(name)
    for base, make in LIBRARY_FAMILIES.items():
        if issubclass(icls, base):
            return make(icls(), system, rtol, atol)
    return None


def library_integrators() -> list[str]:
    """Every registered integrator of :data:`LIBRARY_FAMILIES`."""
    return [n for n, c in registry.integrators().items()
            if any(issubclass(c, base) for base in LIBRARY_FAMILIES)]


def bare_system(case: Case):
    problem = case.spec.build()
    system = convert(problem.formulate(case.formulation), registry.get_integrator(case.integrator))
    return system, None if case.rtol is None else system.atol(case.rtol)


def make_cases(problems, integrators, rtols, hs=None) -> list[Case]:
    """The supported cases of ``problems`` x ``integrators`` x ``rtols`` (and ``hs``
    for the fixed-step codes), formulation :data:`FORMULATION`."""
    return [c for c in expand(problems=list(problems), formulations=[FORMULATION],
                              integrators=list(integrators), rtols=list(rtols), hs=hs)
            if not c.unsupported]


def measure(cases, rounds: int, repeat: int = MAX_SAMPLES, stream=None,
            timeout: float = TIMEOUT_S, run=None) -> list[dict]:
    """Each case timed through the harness (``run(case) -> record``; by default one
    forked worker kept from case to case, :class:`Isolated`, as ``ibench run``'s pool
    runs them, within ``timeout`` seconds of CPU a case) and plainly, alternating,
    ``rounds`` times; with ``stream``, each case's table line is written there once
    measured."""
    if run is None:
        with Isolated(limits=Limits(budget_s=timeout, repeat=repeat, memory_mb=None)) as worker:
            return measure(cases, rounds, repeat, stream, timeout, worker)
    rows = [{"case": c, "harness": [], "plain": [], "status": None, "note": None,
             "ratio": None} for c in cases]
    timed_out = {}      # (problem, integrator) -> the loosest rtol that timed out
    for k in range(rounds):
        for row in rows:
            case = row["case"]
            line = (case.problem, case.params, case.integrator)
            if row["status"] is None and case.rtol <= timed_out.get(line, 0.0):
                row.update(status="skipped", note=f"rtol {timed_out[line]:.0e} timed out")
            if row["status"] not in (None, "ok"):
                continue
            system, atol = bare_system(case)
            call = plain_call(case.integrator, system, case.rtol, atol)

            def plain():
                return timed(call)[1:]

            def harness():
                record = run(case)
                row.update(status=record["status"], timing=record["timing"],
                           note=record["timing_mismatch"] or (record["message"] or None))
                return record["cpu_s"]
            print(f"round {k + 1}/{rounds}: {case.label()}", file=sys.stderr, flush=True)
            order = (harness, plain) if k % 2 == 0 else (plain, harness)
            for what in order:
                if row["status"] not in (None, "ok"):
                    break            # the harness's run failed: nothing to compare
                if what is harness:
                    row["harness"].append(harness())
                else:
                    try:   # the library's own messages (a Fortran code's) not in the table
                        with silenced():
                            cpus, _ = samples(plain, repeat, MIN_CPU_S)
                    except Exception as exc:   # the plain call failed: nothing to compare
                        row.update(status="plain call failed", note=f"{type(exc).__name__}: "
                                                                    f"{exc}")
                        break
                    row["plain"].append(statistics.median(cpus))
            if row["status"] == "timeout":     # as ``ibench run`` skips a line's tighter cases
                timed_out[line] = max(timed_out.get(line, 0.0), case.rtol)
            if k == rounds - 1:
                row["ratio"] = ratio(row)
                if stream:                 # the case's line as soon as it is measured
                    print(table([row])[-1], file=stream, flush=True)
    return rows


def ratio(row) -> float | None:
    """The median harness CPU over the median plain CPU of a measured case."""
    ok = row["status"] == "ok" and row["harness"] and row["plain"]
    return statistics.median(row["harness"]) / statistics.median(row["plain"]) if ok else None


def table(rows) -> list[str]:
    lines = ["| problem | integrator | rtol | timing | harness CPU [s] | plain CPU [s] | ratio |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        c = r["case"]
        label = format_label(c.problem, c.params_dict)
        label = label if len(label) <= 40 else c.problem   # chain_bushing: its defaults
        if r["ratio"] is None:
            lines.append(f"| {label} | {c.integrator} | {c.rtol:.0e} | – | – | – | "
                         f"{r['status']}: {str(r['note'])[:60]} |")
            continue
        note = f" ({r['note']})" if r["note"] else ""
        lines.append(f"| {label} | {c.integrator} | "
                     f"{c.rtol:.0e} | {r['timing']} | {statistics.median(r['harness']):.4g} | "
                     f"{statistics.median(r['plain']):.4g} | {r['ratio']:.3f}{note} |")
    return lines


def summary(rows) -> tuple[list[str], list[str]]:
    """The median and largest ratio, and the targets missed."""
    ratios = [(r["ratio"], r["case"]) for r in rows if r["ratio"] is not None]
    if not ratios:
        return ["no case timed"], ["no case timed"]
    med = statistics.median(x for x, _ in ratios)
    top, case = max(ratios, key=lambda p: p[0])
    lines = [f"cases timed: {len(ratios)} of {len(rows)}",
             f"median ratio harness / plain: {med:.3f} (target <= {MAX_MEDIAN})",
             f"largest ratio: {top:.3f} ({case.problem}, {case.integrator}, rtol {case.rtol:.0e};"
             f" target <= {MAX_RATIO})"]
    missed = ([f"median ratio {med:.3f} > {MAX_MEDIAN}"] if med > MAX_MEDIAN else []) + \
             ([f"largest ratio {top:.3f} > {MAX_RATIO}"] if top > MAX_RATIO else [])
    return lines, missed


def stepper_case(name: str, problem: str = STEPPER_PROBLEM) -> Case | None:
    """The case a stepper is profiled on: ``problem``'s first parameter set, at
    :data:`STEPPER_RTOL` when it is adaptive, else at :data:`STEPPER_STEPS` steps
    over the span; None when it cannot run it."""
    span = registry.get_problem_class(problem)().t_span
    cases = make_cases([problem], [name], [STEPPER_RTOL], [(span[1] - span[0]) / STEPPER_STEPS])
    return cases[0] if cases else None


def driver_share(case: Case) -> tuple[float, float]:
    """``(cpu_s, share)``: the CPU of one solve of ``case`` through ``timed_solve``,
    and the share of a profiled solve's time spent in the driver's own code
    (:data:`DRIVER_FILES`, the functions' own time)."""
    icls = registry.get_integrator(case.integrator)
    system, atol = bare_system(case)
    _, cpu, _ = timed(lambda: icls().timed_solve(system, rtol=case.rtol, atol=atol, h=case.h))
    system, atol = bare_system(case)
    profile = cProfile.Profile()
    profile.runcall(lambda: icls().timed_solve(system, rtol=case.rtol, atol=atol, h=case.h))
    stats = pstats.Stats(profile).stats
    total = sum(v[2] for v in stats.values())
    own = sum(v[2] for (path, _, _), v in stats.items()
              if path.replace("\\", "/").endswith(DRIVER_FILES))
    return cpu, own / total if total else float("nan")


def steppers() -> list[str]:
    """Every registered integrator whose loop is the shared driver."""
    return [n for n, c in registry.integrators().items() if c.has_stepper()]


def _names(problems) -> list[str]:
    """The problems' names without their parameters."""
    return [spec_name(spec) for spec in problems]


def parse_args(argv):
    p = argparse.ArgumentParser(prog="fidelity.py", description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true",
                   help="two_mass at rtol 1e-6, scipy-RK45 and cvode-bdf, one round, rk4's "
                        "driver share (seconds)")
    p.add_argument("--rounds", type=int, default=3, help="alternating rounds (default 3)")
    p.add_argument("--problem", action="append", default=None, metavar="NAME",
                   help="only this problem of the fixed set (repeatable; default all: "
                        f"{', '.join(_names(PROBLEMS))})")
    p.add_argument("--rtol", action="append", type=float, default=None, metavar="R",
                   help="only this tolerance (repeatable; default "
                        f"{', '.join(f'{r:g}' for r in RTOLS)})")
    p.add_argument("--repeat", type=int, default=MAX_SAMPLES,
                   help=f"samples per timing at most (default {MAX_SAMPLES}, fewer past "
                        f"{MIN_CPU_S:g} s CPU)")
    args = p.parse_args(argv)
    for name in args.problem or ():
        if name not in _names(PROBLEMS):
            p.exit(2, f"fidelity.py: error: --problem {name!r} is not in the fixed set; choose "
                      f"from {', '.join(_names(PROBLEMS))}\n")
    for r in args.rtol or ():
        if not r > 0:
            p.exit(2, f"fidelity.py: error: --rtol {r:g} must be positive\n")
    for option in ("rounds", "repeat"):
        value = getattr(args, option)
        if value is not None and value < 1:
            p.exit(2, f"fidelity.py: error: --{option} {value} must be at least 1\n")
    return args


def main(argv=None) -> int:
    args = parse_args(argv)
    if args.quick:
        problems, rtols, names = QUICK["problems"], QUICK["rtols"], QUICK["integrators"]
        names_of_steppers, rounds = QUICK["steppers"], QUICK["rounds"]
    else:
        problems = [spec for spec in PROBLEMS
                    if args.problem is None or spec_name(spec) in args.problem]
        rtols, names = tuple(args.rtol or RTOLS), library_integrators()
        names_of_steppers, rounds = steppers(), args.rounds
    # the middle tolerance first, every problem early: a run cut short still covers them
    order = {r: i for i, r in enumerate(sorted(rtols, key=lambda r: abs(math.log10(r) + 6)))}
    cases = sorted(make_cases(problems, names, rtols),
                   key=lambda c: (order[c.rtol], c.integrator, c.problem))
    wall0, cpu0 = time.perf_counter(), time.process_time()
    rows = measure(cases, rounds, args.repeat, stream=sys.stderr)
    lines, missed = summary(rows)
    print("\n".join(table(rows) + [""] + lines + [""]))
    print(f"in-house steppers on {STEPPER_PROBLEM} (rtol {STEPPER_RTOL:g}, or "
          f"{STEPPER_STEPS} fixed steps): the driver's share of the solve (cProfile, own "
          "time of driver/ and control.py)")
    print("| stepper | mode | CPU [s] | driver share |\n|---|---|---|---|")
    for name in names_of_steppers:
        case = stepper_case(name)
        if case is None:
            continue
        cpu, share = driver_share(case)
        mode = f"rtol {case.rtol:g}" if case.rtol is not None else f"h {case.h:.3g}"
        print(f"| {name} | {mode} | {cpu:.3g} | {100 * share:.1f} % |")
    print(f"\nwall {time.perf_counter() - wall0:.1f} s, CPU {time.process_time() - cpu0:.1f} s, "
          f"{rounds} round(s)")
    for line in missed:
        print(f"target missed: {line}")
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
