"""``ibench check-plugin PROBLEM``: the checks of a registered problem.

One line each, with the :class:`~integrator_bench.harness.checks.conformance.Check`
of the integrator check:

``builds``
    the problem builds (its constructor and its initial state: a mechanism's
    consistent start, a symbolic model's compiled functions) at its defaults
    and at each finite end of each parameter's declared range, the other
    parameters at their defaults (:func:`parameter_sets`);
``jacobian``, ``constraint_jac``, ``constraint_t``, ``derivatives``, ``start``
    at each of those parameter sets, the checks of
    :mod:`~integrator_bench.harness.checks.quotients`: every formulation's
    analytic Jacobian, G against dg/dq, g_t against dg/dt (a driven problem),
    the mechanical model's other derivatives against difference quotients, and
    the consistent start (every formulation's start finite, DAE residuals and
    constraint residuals zero there); ``skip`` where they do not apply;
``reference``
    at the defaults, the stored reference, or one computed (and stored, as
    ``ibench run`` stores it) within :data:`REFERENCE_FACTOR` times the
    timeout; it passes when its two runs agree to the problem's
    ``reference_digits``;
``runs <formulation>``
    one case per formulation at the defaults, run as ``ibench run`` runs a case
    (a worker process bounded by the timeout and the memory cap, measured
    against that reference), by the registered integrator that takes the
    formulation's system best (:func:`pick`), at rtol :data:`RTOL` (a
    fixed-step code at the middle of the problem's default step sizes): it
    passes at status ``ok``. Skipped when there is no reference.

Everything that runs the problem's code runs in a forked process
(:func:`~integrator_bench.harness.checks.conformance.in_child`): a model that
raises, hangs or crashes fails the line it was checked for, never the check.
A parameter set is first built alone within the timeout, for its size; its
model checks then share a process with the timeout to build it again and a
budget of CPU seconds scaled by that size (:func:`_budget`: a
range end of 100,000 links is 3,000 times the chain drive's defaults; its
checks took 112 s of CPU, within its ten-fold budget of 600 s at the default
timeout).
"""

from __future__ import annotations

import math

import numpy as np

from integrator_bench.harness.checks import quotients
from integrator_bench.harness.checks.conformance import Check, in_child
from integrator_bench.harness.errors import UnknownName
from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import Case, converted
from integrator_bench.harness.measure import references
from integrator_bench.harness.run.isolation import run_isolated
from integrator_bench.harness.run.limits import DEFAULT_MEMORY_MB, Limits
from integrator_bench.problems.base import ProblemError, format_value

#: the tolerance of the ``runs`` lines' adaptive cases
RTOL = 1e-6
#: a parameter set larger than the defaults may take up to this many times the timeout
#: for its model checks (:func:`_budget`)
SIZE_SCALE = 10
#: the reference may take this many times the per-run timeout (300 s at the default 60 s,
#: ``ibench run``'s ``--reference-timeout``)
REFERENCE_FACTOR = 5


def resolve(name: str, problem: bool = False) -> str:
    """``"integrator"`` or ``"problem"``: what ``name`` names (an integrator first,
    unless ``problem``). :class:`UnknownName`, listing the valid names of both
    kinds (of problems alone with ``problem``), when it names neither."""
    problems = sorted(registry.problems())
    if not problem and name in registry.integrators():
        return "integrator"
    if name in problems:
        return "problem"
    if problem:
        raise UnknownName(f"unknown problem {name!r}; valid: {', '.join(problems)}")
    raise UnknownName(f"unknown integrator or problem {name!r}; valid integrators: "
                      f"{', '.join(registry.integrators())}; valid problems: "
                      f"{', '.join(problems)}")


def parameter_sets(pcls) -> list[dict]:
    """The defaults (``{}``), then each parameter at each finite end of its range
    that differs from its default, the others at their defaults."""
    sets = [{}]
    for p in pcls.parameters:
        for end in (p.low, p.high):
            if math.isfinite(end) and end != p.default and {p.name: end} not in sets:
                sets.append({p.name: end})
    return sets


def _label(params: dict) -> str:
    return ",".join(f"{k}={format_value(v)}" for k, v in params.items()) or "defaults"


def _size(pcls, params) -> int | None:
    """In a child: the number of unknowns of the problem's initial state at
    ``params`` (None when it does not build: :func:`_model_checks` says why)."""
    try:
        return int(np.size(pcls(**params).initial_state()))
    except Exception:  # noqa: BLE001  the checks' own build names the fault
        return None


def _model_checks(pcls, params) -> dict:
    """In a child: the problem built at ``params`` and each model check's
    ``(passed, detail)`` (an exception fails its check alone); ``{"builds":
    (False, why)}`` when it does not build."""
    try:
        problem = pcls(**params)
        size = np.size(problem.initial_state())
    except ProblemError as exc:  # the problem's own refusal: one of a range end, not a flaw
        return {"builds": (False if not params else None, _why(exc))}
    except Exception as exc:
        return {"builds": (False, _why(exc))}
    out = {"builds": (True, ""), "size": size}
    for name, check in quotients.CHECKS:
        try:
            out[name] = check(problem)
        except Exception as exc:
            out[name] = (False, f"raised {_why(exc)}")
    return out


def _why(exc: Exception) -> str:
    return f"{type(exc).__name__}: {exc}".splitlines()[0]


def _budget(timeout: float, size: int, defaults: int | None) -> float:
    """Seconds the model checks of a set of ``size`` unknowns may take once built:
    ``timeout`` times its size over the defaults' (``defaults`` unknowns; the
    checks are a fixed number of evaluations, each costing in proportion to the
    size), at least once and at most :data:`SIZE_SCALE` times."""
    scale = size / defaults if defaults else 1.0
    return timeout * min(SIZE_SCALE, max(1.0, scale))


def _model_lines(pcls, timeout, memory_mb) -> list[Check]:
    """The ``builds`` line and the model checks' lines, over :func:`parameter_sets`
    (the defaults first: their size scales the others' budgets, :func:`_budget`)."""
    results, defaults = [], None
    for params in parameter_sets(pcls):
        # its size first (one build within the timeout), then the build again and
        # the checks within the timeout and the budget its size gives
        size, why = in_child(_size, (pcls, params), timeout, memory_mb,
                             what="the problem was built")
        found = None
        if why is None:
            budget = timeout + (_budget(timeout, size, defaults) if size else 0.0)
            found, why = in_child(_model_checks, (pcls, params), budget, memory_mb)
        if not params and found:
            defaults = found.get("size")
        results.append((_label(params), found or {"builds": (False, why)}))
    names = ["builds", *(name for name, _ in quotients.CHECKS)]
    return [_merged(name, results) for name in names]


def _merged(name: str, results: list) -> Check:
    """One line from the per-set results: failed when one failed, naming each set
    that failed and why; skipped when it applies at no set; else the first set's
    detail (the defaults', when they built) and how many sets passed."""
    failed = [f"{label}: {out[name][1]}" for label, out in results
              if out.get(name, (None,))[0] is False]
    built = [label for label, out in results if out["builds"][0]]
    if failed:
        return Check(name, False, "; ".join(failed))
    if name == "builds":
        return _builds(results)
    verdicts = [out[name] for _, out in results if name in out]
    if not verdicts:
        return Check(name, None, "the problem never built")
    if all(passed is None for passed, _ in verdicts):
        return Check(name, None, verdicts[0][1])
    return Check(name, True, f"{verdicts[0][1]} (at {len(built)} parameter sets)")


def _builds(results) -> Check:
    """The ``builds`` line when nothing failed: the range ends it built at, and
    those it refused with a ProblemError (a combination with the other defaults
    the problem rules out, saying why)."""
    refused = [f"{label} ({out['builds'][1]})" for label, out in results
               if out["builds"][0] is None]
    ends = len(results) - 1
    detail = f"at the defaults and {ends - len(refused)} of {ends} range ends"
    return Check("builds", True, detail + (f"; refused at {'; '.join(refused)}"
                                           if refused else ""))


def _reference(pcls, reference_dir, seconds) -> tuple:
    """In a child: ``(reference, how, claimed digits, demanded digits)`` at the defaults."""
    problem = pcls()
    stored, _ = references.read(problem, reference_dir)
    ref = stored or references.load(problem, reference_dir, limit=seconds)
    return (ref, "stored" if stored else "computed and stored",
            references.claimed_digits(ref, problem), problem.reference_digits)


def _reference_line(pcls, reference_dir, timeout, memory_mb) -> tuple:
    """The ``reference`` line and the reference (None when there is none)."""
    seconds = REFERENCE_FACTOR * timeout
    out, why = in_child(_reference, (pcls, reference_dir, seconds), seconds + 30, memory_mb)
    if out is None:
        return Check("reference", False, why), None
    ref, how, claimed, demanded = out
    methods = " against ".join(m.get("integrator", m.get("method", "?"))
                               for m in ref.meta["methods"])
    return (Check("reference", claimed >= demanded,
                  f"{how}: {methods}, agreeing to {claimed} digits (the problem demands "
                  f"{demanded})"), ref)


def _tolerance(icls, problem) -> dict:
    if icls.adaptive:
        return {"rtol": RTOL}
    steps = sorted(problem.default_step_sizes())
    return {"h": steps[len(steps) // 2]}


def pick(problem, form, system) -> tuple:
    """``(integrator, tolerance)`` for a run of ``system`` (formulation ``form``):
    of the registered integrators that take it, one that takes it in its own kind
    (a DAE code a DAE), adaptive, implicit and using the given Jacobian, by
    preference in that order, then by name; ``(None, None)`` when none takes it."""
    best = None
    for name, icls in sorted(registry.integrators().items()):
        tol = _tolerance(icls, problem)
        taken, _ = converted(system, icls, form, **tol)
        if taken is None:
            continue
        rank = (taken.kind != system.kind, not icls.adaptive, not icls.implicit,
                not icls.uses_jacobian)
        if best is None or rank < best[0]:
            best = (rank, name, tol)
    return (None, None) if best is None else best[1:]


def _plan(pcls) -> tuple:
    """In a child: the defaults' parameters and ``(form, integrator, tolerance,
    why not)`` for each formulation."""
    problem = pcls()
    plan = []
    for form in problem.formulations:
        system = problem.formulate(form)
        if system.unsupported:
            plan.append((form, None, None, system.unsupported))
            continue
        name, tol = pick(problem, form, system)
        plan.append((form, name, tol, None if name else "no registered integrator takes it"))
    return tuple(sorted(problem.params.items())), plan


def _run_lines(pcls, ref, timeout, memory_mb) -> list[Check]:
    """One ``runs <formulation>`` line each."""
    out, why = in_child(_plan, (pcls,), timeout, memory_mb)
    if out is None:
        return [Check("runs", False, why)]
    params, plan = out
    limits = Limits(budget_s=timeout, memory_mb=memory_mb)
    lines = []
    for form, name, tol, why_not in plan:
        if why_not or ref is None:
            lines.append(Check(f"runs {form}", None, why_not or "no reference to measure against"))
            continue
        record = run_isolated(Case(pcls.name, params, form, name, **tol),
                              references.Handed(ref), limits)
        lines.append(Check(f"runs {form}", record["status"] == "ok", _run_detail(name, tol,
                                                                                  record)))
    return lines


def _run_detail(name, tol, record) -> str:
    (key, value), = tol.items()
    if record["status"] != "ok":
        return f"{name} at {key}={value:g}: {record['status']} ({record['message']})"
    return (f"{name} at {key}={value:g}: ok, scd {record['scd']:.2f}, "
            f"nfev {record['nfev']}")


#: the groups of lines :func:`check_problem` may run: the builds and model checks; the
#: reference and the runs
GROUPS = ("model", "runs")


def check_problem(name: str, timeout: float = 60.0,
                  memory_mb: float | None = DEFAULT_MEMORY_MB,
                  reference_dir=None, only=GROUPS) -> list[Check]:
    """The checks of registered problem ``name``, in order (module docstring).

    Parameters
    ----------
    name : str
        A registered problem (:class:`UnknownName` otherwise).
    timeout : float
        CPU seconds each forked check and each run may take (the reference
        :data:`REFERENCE_FACTOR` times as much; a parameter set's model checks,
        once it is built, up to :data:`SIZE_SCALE` times as much by its size,
        :func:`_budget`).
    memory_mb : float or None
        MiB of address space each forked process may add (RLIMIT_AS), as
        ``ibench run --memory``; None: no cap.
    reference_dir : path, optional
        Where the reference is read and a computed one stored (default: where
        ``ibench run`` keeps them).
    only : iterable of str
        The groups of :data:`GROUPS` to run: ``model`` (``builds`` and the
        model checks), ``runs`` (``reference`` and the ``runs`` lines).
    """
    bad = set(only) - set(GROUPS)
    if bad:
        raise ValueError(f"unknown check group(s) {sorted(bad)}; choose from {', '.join(GROUPS)}")
    resolve(name, problem=True)
    pcls = registry.problems()[name]
    checks = _model_lines(pcls, timeout, memory_mb) if "model" in only else []
    if "runs" in only:
        reference, ref = _reference_line(pcls, reference_dir, timeout, memory_mb)
        checks += [reference] + _run_lines(pcls, ref, timeout, memory_mb)
    return checks
