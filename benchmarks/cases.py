"""The asv suite: one class per registered problem, generated from the registries.

Each class is parametrized over (problem parameter set, formulation,
integrator, tolerance), the cross product of what is registered (see
``_snapshot.py`` for where the names come from). A combination the installed
commit cannot run (the problem lacks the formulation, the integrator cannot
take that kind of system, or the commit does not have the problem, the
integrator or the parameters yet) is skipped in ``setup`` with
NotImplementedError. As in scipy's optimize benchmarks, every case is run once
through the harness (``harness.run.execution.execute``, what ``ibench run`` records)
and the deterministic figures are tracked beside the CPU time:

``time_solve``
    CPU seconds (``time.process_time``) of the integrator's ``timed_solve`` on
    the formulated bare system (no counting wrappers; the library's own loop
    where it has one): the solve ``ibench run`` times for ``cpu_s`` (commits
    older than ``timed_solve`` time ``solve`` on the counted system, as they
    recorded it).
``track_nfev``, ``track_njev``, ``track_nsteps``
    the counts of the record (NaN, shown as n/a, where the integrator cannot
    know a count: never invented).
``track_scd``
    significant correct digits at the final time (more is better).
``track_error``
    ``10**-scd``, the largest relative error at the final time. asv flags an
    *increase* as a regression, so a loss of accuracy shows here.
``track_failed``
    1 when the case did not finish (status failed, error, timeout or
    crashed), else 0: a case that starts failing is flagged as a regression.
    The other benchmarks of such a case are skipped (n/a); the integrator's
    failure is a result, not a broken benchmark.

References
are read, checked against the installed commit's problem definitions (and
recomputed where stale) once per environment, in ``setup_cache``.

Tolerances: ``loose`` is rtol 1e-3 for adaptive integrators and h = span/100 for
fixed-step ones, ``tight`` rtol 1e-6 and h = span/1000 (two rungs of the
``quick`` preset of ``ibench run``).
"""

from __future__ import annotations

import inspect
import json
import math
import os
import shutil
import time
from pathlib import Path

from asv_runner.benchmarks.mark import SkipNotImplemented

from benchmarks._snapshot import REPO, harness_module, snapshot

# the installed commit's modules, whatever its layout (benchmarks/_snapshot.py LAYOUTS)
references, registry, runner = (harness_module(m) for m in ("references", "registry", "runner"))
expand = harness_module("cases").expand


def first_set(spec: str) -> dict:
    """The parameter values of the first set ``spec`` names, as the installed
    commit's parser completes them (a ProblemSpec since it has one, a dict before)."""
    first = harness_module("cases").parse_problem_spec(spec)[0]
    return first if isinstance(first, dict) else first.params_dict


try:
    from integrator_bench.problems.system import convert
except ImportError:  # a commit from before the package namespace (top-level packages)
    from problems.system import convert
# their home modules since the runner was split; older commits keep them in the runner,
# the oldest have no run_isolated
counted = (harness_module("execution") or runner).counted
execute = (harness_module("execution") or runner).execute
run_isolated = getattr(harness_module("isolation") or runner, "run_isolated", None)
# a case's limits as one object since harness.run.limits; before, each one a keyword
limits = harness_module("limits")

# harness.matrix.record.CaseStatus.OK's value, spelled out: asv imports this file against
# every benchmarked commit, and those before the enum have none to import
OK = "ok"
TOLERANCES = {"loose": (1e-3, 100), "tight": (1e-6, 1000)}  # rtol, steps per time span
CASE_TIMEOUT = 60.0  # seconds a case may take before it is recorded as a timeout


def reference_dir() -> Path:
    """The repository's references (``IBENCH_REFERENCE_DIR`` overrides)."""
    return Path(os.environ.get("IBENCH_REFERENCE_DIR") or REPO / "results" / "reference")


def spec_name(spec: str) -> str:
    """The registry name in a problem's or an integrator's spec ``name:key=value,...``:
    the suite's one reader of a spec (asv runs it against commits older than the
    harness's ``ProblemSpec``, so it cannot take the harness's)."""
    return spec.partition(":")[0]


def exact_spec(label: str) -> str:
    """The problem spec of the benchmark parameter set whose label is ``label``.

    A label (``name:k=v,...``, values printed with ``%g``) rounds its values, so
    parsing it back gives, e.g., ``drive_speed=3.14159`` instead of pi: another
    problem, without a stored reference, whose reference ``prepare`` would
    compute for minutes. When ``label`` is the label of one of the installed
    problem's benchmark sets, that set's exact values are used instead (the
    set's own keys in full precision, or its first parameter's default for the
    default set); any other label is returned as it is.
    """
    name = spec_name(label)
    try:
        pcls = registry.get_problem_class(name)
        sets = [(bp, pcls(**bp).params) for bp in pcls.benchmark_parameters]
    except ValueError:      # unknown name or parameters at this commit
        return label
    for bp, params in sets:
        if _label(name, params) == label and pcls.parameters:
            given = bp or {pcls.parameters[0].name: pcls.parameters[0].default}
            return f"{name}:" + ",".join(f"{k}={float(v)!r}" for k, v in given.items())
    return label


def _label(name: str, params: dict) -> str:
    try:
        from integrator_bench.problems.base import format_label
    except ImportError:     # a commit from before the package namespace
        from problems.base import format_label
    return format_label(name, params)


def make_case(label: str, formulation: str, integrator: str, tolerance: str):
    """The harness case for one parameter combination, as the installed commit builds it.

    Raises NotImplementedError when this commit cannot build or run it.
    """
    rtol, per_span = TOLERANCES[tolerance]
    try:
        name = spec_name(label)
        pcls = registry.get_problem_class(name)
        icls = registry.get_integrator(spec_name(integrator))  # a spec with settings
        if formulation not in pcls.formulations:
            raise NotImplementedError(f"{name} has no formulation {formulation!r}")
        spec = exact_spec(label)
        t0, t1 = pcls(**first_set(spec)).t_span
        # an adaptive integrator is benchmarked at rtol, a fixed-step one at h
        tol = {"rtols": [rtol]} if icls.adaptive else {"hs": [t1 / per_span - t0 / per_span]}
        cases = expand(problems=[spec], formulations=[formulation], integrators=[integrator],
                       **tol)
    except ValueError as exc:  # unknown name, parameters or formulation at this commit
        raise NotImplementedError(f"not at this commit: {exc}") from None
    if len(cases) != 1:
        raise NotImplementedError(f"{label} names {len(cases)} parameter sets at this commit")
    if cases[0].unsupported:
        raise NotImplementedError(cases[0].unsupported)
    return cases[0]


def prepare(directory: Path, problems=None) -> dict:
    """Per-environment state: references valid for the installed commit, a record cache.

    Each stored reference of the repository whose problem definition matches
    the installed commit is copied to ``directory``; the others are computed
    there by that commit's own code (never written into the repository).
    ``problems`` limits this to some problem names (default: the whole suite).
    """
    refs, records = directory / "reference", directory / "records"
    records.mkdir(parents=True, exist_ok=True)
    source = reference_dir()
    for name, info in snapshot()["problems"].items():
        if name not in registry.problems() or (problems is not None and name not in problems):
            continue
        for label in info["sets"]:
            try:
                problem = registry.get_problem_class(name)(
                    **first_set(exact_spec(label)))
            except ValueError:
                continue  # parameters this commit does not know
            stored, _ = references.read(problem, source)
            if stored is not None:
                for path in references.paths(problem, source):
                    target = refs / path.relative_to(source)
                    target.parent.mkdir(parents=True, exist_ok=True)
                    shutil.copy2(path, target)
            else:
                try:
                    references.load(problem, refs)
                except Exception as exc:  # its cases then fail with this reason
                    print(f"benchmarks: no reference for {label}: {exc}")
    return {"references": str(refs), "records": str(records)}


def _limits():
    """A case's limits: :data:`CASE_TIMEOUT` CPU seconds (the field ``budget_s``, named
    ``timeout`` at older commits), no memory cap."""
    budget = "budget_s" if "budget_s" in limits.Limits.__dataclass_fields__ else "timeout"
    return limits.Limits(**{budget: CASE_TIMEOUT, "memory_mb": None})


def record_for(case, state: dict) -> dict:
    """The harness's record of ``case``, run once per environment and cached.

    Run as ``ibench run`` runs it: in a forked worker with the harness's
    timeout (``harness.run.isolation.run_isolated``), or by ``execute`` in this
    process at commits older than the isolated runner.
    """
    path = Path(state["records"]) / f"{case.case_id}.json"
    if path.exists():
        return json.loads(path.read_text())
    refs = Path(state["references"])
    if run_isolated is not None:
        record = run_isolated(case, reference_dir=refs, limits=_limits()) \
            if limits is not None else \
            run_isolated(case, timeout=CASE_TIMEOUT, reference_dir=refs)
    else:
        record = execute(case, reference_dir=refs)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(dict(record), default=float))
    tmp.replace(path)
    return record


class _Cases:
    """Base of the generated classes (the leading underscore keeps asv from collecting it)."""

    param_names = ["problem", "formulation", "integrator", "tolerance"]
    timer = time.process_time
    timeout = 300.0
    # one solve per sample, each after a setup that formulates a fresh system: a
    # problem with modes (the woodpecker's) keeps its mode in the system, and a
    # second solve of the same system would start in the mode the first ended in
    number = 1
    warmup_time = 0.0

    def setup_cache(self):
        return prepare(Path.cwd())

    setup_cache.timeout = 3600.0

    def setup(self, state, label, formulation, integrator, tolerance):
        self.case = make_case(label, formulation, integrator, tolerance)
        self.record = record_for(self.case, state)
        if self.record["status"] == OK:
            self.setup_solve()

    def _ok(self) -> dict:
        if self.record["status"] != OK:
            raise SkipNotImplemented(f"{self.case.label()}: {self.record['status']}: "
                                     f"{self.record['message']}")
        return self.record

    def setup_solve(self):
        """The system, tolerances and the call ``time_solve`` times, built as
        ``execute`` builds them for its timed solves (bare, from commits that time
        ``timed_solve``; ``TimedCall.run`` alone from those that have ``timed_call``)."""
        case = self.case
        problem = registry.get_problem_class(case.problem)(**case.params_dict)
        self.icls = registry.get_integrator(case.integrator)
        self.settings = dict(getattr(case, "settings", ()))  # none before settings existed
        system = problem.formulate(case.formulation)
        if len(inspect.signature(convert).parameters) == 2:  # convert(system, integrator)
            system = convert(system, self.icls)
        else:  # older commits: convert(system, accepts, max_index)
            system = convert(system, self.icls.accepts, self.icls.max_index)
        timed = getattr(self.icls, "timed_solve", None)
        self.system = system if timed is not None else counted(system)[0]
        self.atol = self.system.atol(case.rtol) if case.rtol is not None else None
        mode = dict(rtol=case.rtol, atol=self.atol, h=case.h)
        if hasattr(self.icls, "timed_call"):   # the part ``execute`` times, its options made here
            self.run = self.icls(**self.settings).timed_call(self.system, **mode).run
        else:   # older commits: the whole timed solve, or the counted one before it existed
            solve = timed or self.icls.solve
            self.run = lambda: solve(self.icls(**self.settings), self.system, **mode)

    def time_solve(self, *params):
        self._ok()
        self.run()

    def _count(self, key):
        value = self._ok()[key]
        return math.nan if value is None else value

    def track_nfev(self, *params):
        return self._count("nfev")

    track_nfev.unit = "evaluations"

    def track_njev(self, *params):
        return self._count("njev")

    track_njev.unit = "evaluations"

    def track_nsteps(self, *params):
        return self._count("nsteps")

    track_nsteps.unit = "steps"

    def track_scd(self, *params):
        return self._ok()["scd"]

    track_scd.unit = "digits"

    def track_error(self, *params):
        return 10.0 ** -self._ok()["scd"]

    track_error.unit = "relative error"

    def track_failed(self, *params):
        return 0.0 if self.record["status"] == OK else 1.0

    track_failed.unit = "failed"


def _generate(names: dict) -> dict[str, type]:
    """One ``_Cases`` subclass per problem of the snapshot ``names``."""
    classes = {}
    for problem, info in names["problems"].items():
        classes[problem] = type(problem, (_Cases,), {
            "__doc__": f"Problem {problem}: each of its formulations under every integrator.",
            "__module__": __name__,
            "params": [info["sets"], info["formulations"], names["integrators"],
                       list(TOLERANCES)],
        })
    return classes


def warm_up(names: dict) -> None:
    """Load the registries and build each problem in each formulation once.

    asv's forkserver imports this module once per environment and forks a
    process per combination: what is done here (importing the integrator
    modules, symbolic derivation and compilation of mechanical problems) is
    not repeated in every one.
    """
    registry.integrators()
    for name, info in names["problems"].items():
        try:
            cls = registry.get_problem_class(name)
            for label in info["sets"]:
                problem = cls(**first_set(label))
                for formulation in problem.formulations:
                    problem.formulate(formulation)
        except Exception:  # not at this commit: its combinations are skipped in setup
            continue


SNAPSHOT = snapshot()
globals().update(_generate(SNAPSHOT))
warm_up(SNAPSHOT)
