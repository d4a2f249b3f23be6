"""``ibench check-plugin NAME``: the conformance check for any registered integrator.

It reads only what the integrator declares and checks, one line each:

``declarations``
    the class attributes have the types and values the rules in
    :mod:`integrator_bench.integrators.base` allow (``accepts`` within ``"ode"``,
    ``"dae"``, ``"mechanical"``; ``fixed_step`` a bool or None;
    ``dense_output`` a bool; a mode it can run in), and it implements
    :meth:`stepper` or :meth:`solve`;
``runs <kind>``
    for every system kind it accepts, a small registered problem in a
    formulation of that kind runs to ``ok`` (in a worker process, with a
    timeout, through the same runner as ``ibench run``);
``unsupported``
    a registered formulation it does not accept is recorded as
    ``unsupported``, not run;
``counts``
    on each case of the ``runs`` lines, solved again in a forked process with
    the problem's code watched (:func:`~integrator_bench.harness.measure.counting.watch_model`):
    it reports only known counters, its own ``nfev``/``njev`` agree with
    the harness's counting of the calls as every record compares them
    (:func:`integrator_bench.harness.run.execution.count_mismatch`): ``nfev``
    equal for an explicit integrator or one that uses a given Jacobian, never
    more than the harness saw otherwise (finite-difference calls it may leave
    out); ``njev`` equal for one that declares ``uses_jacobian``; and the
    model saw no evaluation outside the counted callables (the line names how
    many and the first caller);
``inputs``
    on the same solves, the system's arrays unchanged after the run and no
    write into the state the driver hands a stepper (rule 10 of
    :mod:`integrator_bench.integrators.base`), each change named;
``order``
    ``ibench verify``'s order verdict: the observed order, fitted on the step
    sizes the harness hands over and on the evaluations it counts, matches the
    declared one, in a worker process bounded by ten times the per-run
    timeout; the ladders stop at a work budget
    (:data:`integrator_bench.harness.checks.verify.WORK_BUDGET`). The stability
    verdict is not folded in: it has its own line;
``stability``
    the declared ``"A"`` or ``"L"`` checked where it bites: ``|R(z)|`` sampled
    on the imaginary axis, in the left half-plane and on the negative real axis
    up to ``|z| = 1e6``, and for ``"L"`` small at the largest ``|z|`` with and
    without a phase (:func:`integrator_bench.harness.checks.method_checks.stability`);
``accuracy``
    an adaptive integrator keeps what its tolerance promises on a problem with
    a known answer that needs rejected steps: the error within a bound of
    ``rtol``, falling as ``rtol`` falls, and at least one rejection when it
    reports ``nreject`` (:func:`integrator_bench.harness.checks.method_checks.accuracy`);
``fails <how>``
    an exception raised by the right-hand side becomes an ``error`` record
    with reason ``exception``; a NaN from the right-hand side a ``failed``
    record with reason ``nonfinite_state`` whose message names the model's NaN
    (the harness notices a failed run whose model returned NaN last, whatever
    the integrator made of it); a solution that blows up in finite time
    (``y' = y^2``, ``y = 1/(1 - t)`` on ``[0, 2]``) is judged on what the
    integrator returns, in a worker process: it must give up (any typed
    status) before ``t = 1``, after evaluating the model past ``t = 0.9``,
    never report success past the singularity, raise or hang. A ``fails`` line
    passes only on the fault it injected: a run that ended so before the fault
    fired (read from the faulty problem in the checking process) failed on
    something else, and the line says so. The verdicts read the record's
    ``reason`` or the Solution's status, never a message.

Each method check runs in a forked process bounded by the timeout
(:func:`in_child`): a plugin that hangs gets a failed line, not a hung check.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from integrator_bench.harness.errors import ModelFault
from integrator_bench.harness.forking.child import call
from integrator_bench.harness.matrix import builds, registry
from integrator_bench.harness.matrix.cases import Case
from integrator_bench.harness.measure import unit_costs
from integrator_bench.harness.measure.counting import counted, model_files, watch_model
from integrator_bench.harness.run.execution import count_mismatch, execute
from integrator_bench.harness.run.isolation import run_isolated
from integrator_bench.harness.run.limits import DEFAULT_MEMORY_MB, Limits
from integrator_bench.harness.run.streams import silenced
from integrator_bench.harness.checks import method_checks
from integrator_bench.harness.matrix.record import EXCEPTION
from integrator_bench.integrators.base import COUNTERS, InputModified, Integrator, Status
from integrator_bench.problems.base import Problem
from integrator_bench.problems.system import Unsupported, convert, takes

KINDS = ("ode", "dae", "mechanical", "augmented_lagrangian", "fmu")


@dataclass
class Check:
    name: str
    passed: bool | None  # None: not applicable
    detail: str

    def line(self) -> str:
        mark = {True: "pass", False: "FAIL", None: "skip"}[self.passed]
        return f"{mark:4} {self.name}: {self.detail}"

    def to_dict(self) -> dict:
        return {"check": self.name, "passed": self.passed, "detail": self.detail}


class DeliberateFault(RuntimeError):
    """Raised by the faulty test problems of the conformance check."""


class _Faulty:
    """Mixin: force evaluations go wrong after ``FAULT_AFTER`` calls."""

    FAULT_AFTER = 50
    fault = "raise"
    fired = False   # set on the class once the fault is injected (read in the checking child)

    def _tick(self):
        self._calls = getattr(self, "_calls", 0) + 1
        if self._calls > self.FAULT_AFTER:
            type(self).fired = True
        return self._calls > self.FAULT_AFTER

    def force(self, t, q, v):
        f = super().force(t, q, v)
        if self._tick():
            if self.fault == "raise":
                raise DeliberateFault("deliberate fault in the right-hand side")
            return np.full_like(f, np.nan)
        return f


class BlowUp(Problem):
    """``y' = y^2``, ``y(0) = 1``: the solution ``1/(1 - t)`` blows up at t = 1."""

    SINGULARITY = 1.0
    #: the farthest time the model was evaluated at (read in the checking child): a
    #: run that gave up before :data:`NEAR` of the singularity gave up on something else
    reached = 0.0
    NEAR = 0.9

    name = "_check_blowup"
    description = "finite-time blow-up (conformance check)"
    components = ("y",)
    t_span = (0.0, 2.0)

    def initial_state(self):
        return np.array([1.0])

    def rhs(self, t, y):
        type(self).reached = max(type(self).reached, float(t))
        return y * y

    def jac(self, t, y):
        return np.array([[2.0 * y[0]]])


def _faulty_problems() -> list[type[Problem]]:
    from integrator_bench.problems.models.pendulum import Pendulum

    out = [BlowUp]
    for fault in ("raise", "nan"):
        out.append(type(f"Faulty{fault.title()}Pendulum", (_Faulty, Pendulum),
                        {"name": f"_check_{fault}", "fault": fault,
                         "description": f"pendulum whose forces {fault} (conformance check)"}))
    return out


def _declarations(icls) -> Check:
    problems = []
    if not icls.has_stepper() and icls.solve is Integrator.solve:
        problems.append("implements neither stepper() nor solve()")
    if not icls.accepts or not set(icls.accepts) <= set(KINDS):
        problems.append(f"accepts {sorted(icls.accepts)!r} must be a non-empty subset of {KINDS}")
    if not (icls.order is None or (isinstance(icls.order, int) and icls.order > 0)):
        problems.append(f"order {icls.order!r} must be a positive int or None")
    if icls.stability not in (None, "A", "L"):
        problems.append(f"stability {icls.stability!r} must be 'A', 'L' or None")
    for attr in ("implicit", "adaptive", "events", "uses_jacobian", "projects", "dense_output"):
        if not isinstance(getattr(icls, attr), bool):
            problems.append(f"{attr} must be a bool")
    if icls.fixed_step is not None and not isinstance(icls.fixed_step, bool):
        problems.append("fixed_step must be a bool or None")
    if not icls.adaptive and not icls.takes_h():
        problems.append("neither adaptive nor fixed_step: it can run in no mode")
    if not isinstance(icls.max_index, int) or icls.max_index < 0 or \
            (("dae" in icls.accepts) != (icls.max_index > 0)
             and not icls.accepts & {"mechanical", "augmented_lagrangian"}):
        problems.append(f"max_index {icls.max_index!r} does not fit accepts")
    if not icls.description:
        problems.append("description is empty")
    return Check("declarations", not problems, "; ".join(problems) or "attributes as the rules say")


def _tolerance(icls, problem) -> dict:
    """The run of a check: rtol 1e-6, or at a fixed step the finest of the problem's
    default step sizes (explicit Euler grows the spring pendulum's amplitude past
    its own size at the middle one, 0.01 s; the finest keeps every built-in
    fixed-step method inside its stability region on the oscillators)."""
    if icls.adaptive:
        return {"rtol": 1e-6}
    return {"h": min(problem.default_step_sizes())}


def _candidates():
    """(problem, formulation, system) over the project's own problems (origin
    ``built-in``), smallest first: the verdict on an integrator never depends on
    the problem plugins installed beside it."""
    items = []
    for name, built in registry.built_problems().items():
        pcls = builds.class_of(built)
        if name.startswith("_check_") or getattr(pcls, "origin", None) != registry.BUILT_IN:
            continue
        for params in pcls.benchmark_parameters[:1]:
            problem = pcls(**params)
            for form in problem.formulations:
                items.append((problem.dimension, name, form, problem))
    items.sort(key=lambda x: (x[0], x[1], x[2]))
    for _, _, form, problem in items:
        yield problem, form, problem.formulate(form)


def _case(icls, problem, form, **tol) -> Case:
    return Case(problem.name, tuple(sorted(problem.params.items())), form, icls.name, **tol)


def _runs(icls, timeout, memory_mb=None) -> tuple[list[Check], list[tuple]]:
    checks, ran, seen, unsupported = [], [], set(), None
    for problem, form, system in _candidates():
        try:
            taken = convert(system, icls)
        except Unsupported:
            if unsupported is None:
                unsupported = (problem, form)
            continue
        key = (taken.kind, getattr(taken, "index", 0))  # a DAE code: each index once
        if key in seen:
            continue
        seen.add(key)
        tol = _tolerance(icls, problem)
        record = run_isolated(_case(icls, problem, form, **tol),
                              limits=Limits(budget_s=timeout, memory_mb=memory_mb))
        ok = record["status"] == "ok"
        detail = (f"{problem.name}/{form} at {next(iter(tol))}={next(iter(tol.values())):g}: "
                  f"{record['status']}" + (f", scd {record['scd']:.2f}, nfev {record['nfev']}"
                                           if ok else f" ({record['message']})"))
        label = taken.kind + (f" index {key[1]}" if taken.kind == "dae" else "")
        checks.append(Check(f"runs {label}", ok, detail))
        ran.append((problem, form, tol))
    for kind in sorted(set(icls.accepts) - {kind for kind, _ in seen}):
        checks.append(Check(f"runs {kind}", None, f"no built-in problem gives a {kind} system"))
    if unsupported is None:
        checks.append(Check("unsupported", None, "it takes every registered formulation"))
    else:
        problem, form = unsupported
        from integrator_bench.harness.matrix.cases import expand
        case = next(c for c in expand(problems=[problem.label()], formulations=[form],
                                      integrators=[icls.name], rtols=[1e-6], hs=[1e-3]))
        record = run_isolated(case, limits=Limits(budget_s=timeout, memory_mb=memory_mb))
        checks.append(Check("unsupported", record["status"] == "unsupported",
                            f"{problem.name}/{form}: {record['status']} ({record['message']})"))
    return checks, ran


def _watched_solve(icls, problem, form, tol) -> dict:
    """One solve of ``problem`` in ``form`` on a counted system, the model watched
    (:func:`~integrator_bench.harness.measure.counting.watch_model`): what the integrator
    reported, what the model saw, and what it changed of its inputs."""
    system, counters = counted(convert(problem.formulate(form), icls))
    rtol = tol.get("rtol")
    counts, modified = {}, None
    with watch_model(model_files(problem)) as view:
        try:
            counts = icls().solve(system, rtol=rtol, atol=system.atol(rtol) if rtol else None,
                                  h=tol.get("h")).counts
        except InputModified as exc:   # the driver's state, written into by the stepper
            modified = str(exc)
        except Exception:  # the runs line has said why; the counts are judged as far as they go
            pass
    return {"unknown": sorted(set(counts) - set(COUNTERS) - {"nevents"}
                              - set(icls.extra_counters)),
            "mismatch": count_mismatch(counts, counters, icls),
            "own": [f"{k}: own {counts[k]}, harness {counters[k].n}" for k in ("nfev", "njev")
                    if counts.get(k) is not None and counters[k] is not None],
            "unseen": view.verdict(), "entries": view.counted + view.unseen,
            "changed": counters.changed_inputs(system) or modified}


def _counts(icls, ran, timeout, memory_mb=None) -> list[Check]:
    """The ``counts`` and ``inputs`` lines, from one watched solve of each case of
    the ``runs`` lines (:func:`_watched_solve`, in a forked process bounded by
    ``timeout``).

    ``counts``: known counter names only; ``nfev``/``njev`` as
    :func:`~integrator_bench.harness.run.execution.count_mismatch` compares them for
    every record; and every evaluation of the model made through a counted
    callable (none through a path the harness does not count). ``inputs``: the
    system's arrays unchanged after the run, and no write into the state the
    driver hands a stepper."""
    if not ran:
        return [Check("counts", None, "nothing ran"), Check("inputs", None, "nothing ran")]
    counts, inputs = [], []
    for problem, form, tol in ran:
        seen, why = in_child(_watched_solve, (icls, problem, form, tol), timeout, memory_mb)
        where = f"{problem.name}/{form}"
        if seen is None:
            counts.append((False, f"{where}: {why}"))
            continue
        flaws = ([f"unknown counters {seen['unknown']}"] if seen["unknown"] else []) + \
            ([f"disagree: {seen['mismatch']}"] if seen["mismatch"] else []) + \
            ([seen["unseen"]] if seen["unseen"] else [])
        counts.append((not flaws, f"{where}: " + "; ".join(
            flaws or seen["own"] + [f"all {seen['entries']} calls of the model counted"])))
        changed = seen["changed"]
        inputs.append((changed is None, f"{where}: " + (
            f"the integrator changed its inputs: {changed}" if changed
            else "the system's arrays unchanged")))
    return [_merged("counts", counts), _merged("inputs", inputs)]


def _merged(name, results) -> Check:
    """One line from ``(passed, detail)`` per case: failed when any failed, the
    failing details first."""
    if not results:
        return Check(name, None, "nothing ran")
    results = sorted(results, key=lambda r: r[0])
    return Check(name, all(ok for ok, _ in results), "; ".join(d for _, d in results))


def in_child(fn, args, timeout, memory_mb=None, what: str = "the check ran"):
    """``fn(*args)`` in a forked process (:func:`~integrator_bench.harness.forking.child.call`)
    within a budget of ``timeout`` CPU seconds (with a case's backstops: a process
    that hangs without using CPU is stopped a second past it) and, as a case's
    worker is, ``memory_mb`` MiB of address space on top of what it inherits
    (None: no cap; an allocation past it raises MemoryError there).

    Returns ``(value, None)``, or ``(None, why)`` when it raised, hung or died
    (``why`` the fault's message: ``its process crashed (SIGSEGV) while the check ran``).
    """
    try:
        return call(functools.partial(fn, *args), what, timeout, memory_mb,
                    who="its process"), None
    except ModelFault as exc:
        return None, str(exc)


def _verdict(name):
    from integrator_bench.harness.checks.verify import verify

    return verify(name).to_dict()


def _order(name, timeout, memory_mb=None) -> Check:
    """``ibench verify``'s order verdict for one integrator, in a forked process."""
    verdict, why = in_child(_verdict, (name,), timeout, memory_mb)
    if verdict is None:
        return Check("order", False, f"ibench verify: {why}")
    passed = verdict.get("order_passed")
    observed = verdict.get("observed_order")
    detail = (f"declared {verdict.get('declared_order')}, observed "
              f"{observed if observed is None else round(observed, 2)}")
    per_problem = [f"{o['problem']} {o['observed_order']:.2f} on "
                   + ("an h ladder" if o["method"] == "h" else "an rtol ladder by harness nfev")
                   if o.get("observed_order") is not None
                   else f"{o['problem']}: no order ({o['detail']})"   # why it cannot judge
                   for o in verdict.get("orders", [])]
    if per_problem:
        detail += f" ({'; '.join(per_problem)})"
    if verdict.get("note"):
        detail += f" ({verdict['note']})"
    elif passed is None:
        detail += " (no declared order: reported, not judged)"
    return Check("order", passed, detail)


def _method_check(label, judge, icls, timeout, memory_mb=None) -> Check:
    """One of :mod:`~integrator_bench.harness.checks.method_checks`' verdicts, in a forked process."""
    verdict, why = in_child(judge, (icls,), timeout, memory_mb)
    return Check(label, False, why) if verdict is None else Check(label, *verdict)


def _blowup_solve(icls, pcls):
    """What ``icls`` returns on the blow-up: ``(status, message, last output time
    reached, the state there, formulation)``."""
    problem = pcls()
    form = next(f for f in problem.formulations if takes(problem.formulate(f), icls))
    system, _ = counted(convert(problem.formulate(form), icls))
    tol = _tolerance(icls, problem)
    rtol = tol.get("rtol")
    sol = icls().solve(system, rtol=rtol, atol=system.atol(rtol) if rtol else None,
                       h=tol.get("h"))
    t = float(sol.t[-1]) if len(sol.t) else system.t0
    y = np.asarray(sol.y, float)[-1].tolist() if len(sol.t) else []
    return sol.status.value, sol.message, t, y, form, pcls.reached


def _blowup(icls, pcls, timeout, memory_mb=None) -> Check:
    """Judge the blow-up on what the integrator returned (no reference involved):
    it must give up, and not before it evaluated the model within ``NEAR`` of the
    singularity (a plugin that gives up at the start for a fault of its own has
    not met the blow-up)."""
    out, why = in_child(_blowup_solve, (icls, pcls), timeout, memory_mb)
    if out is None:
        return Check("fails blowup", False, why)
    status, message, t, y, form, reached = out
    if status == Status.SUCCESS.value:
        return Check("fails blowup", False,
                     f"{form}: reported success through t={t:g} (y = {y}), past the "
                     f"singularity at t={pcls.SINGULARITY:g}: it stepped over the blow-up")
    if reached < pcls.NEAR * pcls.SINGULARITY:
        return Check("fails blowup", False,
                     f"{form}: gave up with status {status} ({message}) with the model "
                     f"evaluated up to t={reached:g} only, before the blow-up at "
                     f"t={pcls.SINGULARITY:g}: it failed on something else")
    return Check("fails blowup", True,
                 f"{form}: gave up with status {status}, last output at t={t:g} ({message})")


def _faulty_record(case, pcls):
    """The record of ``case`` (on a faulty problem, run here) and whether its fault
    fired: the model's calls the integrator's alone (no unit costs measured on it)."""
    with silenced(), unit_costs.not_measured():
        record = execute(case)
    return record, pcls.fired


def _failures(icls, timeout, memory_mb=None) -> list[Check]:
    checks = []
    for pcls in _faulty_problems():
        label = pcls.name.removeprefix("_check_")
        problem = pcls()
        form = next((f for f in problem.formulations
                     if takes(problem.formulate(f), icls)), None)
        if form is None:
            checks.append(Check(f"fails {label}", None, "no form of this test it takes"))
            continue
        if pcls is BlowUp:
            checks.append(_blowup(icls, pcls, timeout, memory_mb))
            continue
        registry.register(pcls, origin="check-plugin")
        try:
            out, why = in_child(_faulty_record, (_case(icls, problem, form,
                                                       **_tolerance(icls, problem)), pcls),
                                timeout, memory_mb)
        finally:
            registry.unregister(pcls.name)
        if out is None:
            checks.append(Check(f"fails {label}", False, f"{form}: {why}"))
            continue
        record, fired = out
        if label == "raise":   # the problem's own exception: an error record
            good = record["status"] == "error" and record["reason"] == EXCEPTION
        else:                  # the model's NaN, named as such
            good = (record["status"] == "failed"
                    and record["reason"] == Status.NONFINITE_STATE.value)
        detail = f"{form}: {record['status']}, reason {record['reason']} ({record['message']})"
        if not fired:   # it ended before the fault was injected: another flaw
            good, detail = False, (f"{detail}, before the injected fault (after "
                                   f"{pcls.FAULT_AFTER} evaluations): it failed on something "
                                   "else")
        checks.append(Check(f"fails {label}", good, detail))
    return checks


GROUPS = ("declarations", "runs", "order", "stability", "accuracy", "fails")


def check_plugin(name: str, timeout: float = 60.0, only=None,
                 memory_mb: float | None = DEFAULT_MEMORY_MB) -> list[Check]:
    """The conformance checks of integrator ``name``, in order.

    Parameters
    ----------
    name : str
        A registered integrator.
    timeout : float
        Seconds per run (the ``order`` line gets ten times as much).
    memory_mb : float or None
        MiB of address space each run may add to what its forked process
        inherits (RLIMIT_AS), as ``ibench run --memory`` caps a case (the same
        default); None: no cap.
    only : iterable of str, optional
        The groups of :data:`GROUPS` to run (default: all); ``runs`` brings
        the ``unsupported``, ``counts`` and ``inputs`` lines with it.
    """
    only = set(GROUPS if only is None else only)
    bad = only - set(GROUPS)
    if bad:
        raise ValueError(f"unknown check group(s) {sorted(bad)}; choose from {', '.join(GROUPS)}")
    icls = registry.get_integrator(name)
    checks = [_declarations(icls)] if "declarations" in only else []
    if "runs" in only:
        runs, ran = _runs(icls, timeout, memory_mb)
        checks += runs + _counts(icls, ran, timeout, memory_mb)
    if "order" in only:
        checks.append(_order(name, 10 * timeout, memory_mb))
    for label in ("stability", "accuracy"):
        if label in only:
            checks.append(_method_check(label, getattr(method_checks, label), icls, timeout,
                                        memory_mb))
    if "fails" in only:
        checks += _failures(icls, timeout, memory_mb)
    return checks
