"""The asv suite (benchmarks/cases.py) is generated from the live registries.

Fast checks, without asv: every registered problem, formulation and integrator
is an axis of the suite; a combination the harness cannot run is skipped in
``setup`` with NotImplementedError; the tracked figures are those that
``integrator_bench.harness.run.execution.execute`` records for the same case.
"""

import math
import subprocess
import sys
from pathlib import Path

import pytest
from asv_runner.benchmarks.mark import SkipNotImplemented

from integrator_bench.harness.measure import references

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.run.execution import execute
from integrator_bench.harness.matrix.record import CaseStatus

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

from benchmarks import cases  # noqa: E402

TRACKS = {"track_nfev": "nfev", "track_njev": "njev", "track_nsteps": "nsteps",
          "track_scd": "scd"}


@pytest.fixture(scope="module")
def state(tmp_path_factory):
    """What ``setup_cache`` hands the benchmarks: references and a record cache."""
    records = tmp_path_factory.mktemp("records")
    return {"references": str(cases.reference_dir()), "records": str(records)}


def _combinations(problem):
    """Every parameter combination of a problem's class, as asv forms them."""
    cls = getattr(cases, problem)
    sets, forms, integrators, tols = cls.params
    return cls, [(s, f, i, t) for s in sets for f in forms for i in integrators for t in tols]


@pytest.mark.parametrize("problem", list(registry.problems()))
def test_every_registered_problem_is_a_class_with_its_sets_and_formulations(problem):
    cls = registry.get_problem_class(problem)
    bench = getattr(cases, problem)
    labels = [cls(**p).label() for p in cls.benchmark_parameters]
    assert bench.params[0] == labels
    assert bench.params[1] == list(cls.formulations)
    assert bench.params[3] == list(cases.TOLERANCES)
    assert bench.param_names == ["problem", "formulation", "integrator", "tolerance"]


@pytest.mark.parametrize("problem", list(registry.problems()))
def test_every_registered_integrator_is_an_axis(problem):
    assert set(registry.integrators()) <= set(getattr(cases, problem).params[2])


def test_axes_are_the_same_in_every_environment():
    # asv maps results to parameters by position: the axes come from the working
    # tree's registrations, cached, not from whatever commit is installed
    assert cases.snapshot() == cases.SNAPSHOT
    assert cases.SNAPSHOT["integrators"] == sorted(cases.SNAPSHOT["integrators"])


@pytest.mark.parametrize("problem", list(registry.problems()))
def test_unsupported_combinations_are_skipped_in_setup(problem, state):
    cls, combos = _combinations(problem)
    unsupported = 0
    for label, form, integ, tol in combos:
        rtol, per_span = cases.TOLERANCES[tol]
        icls = registry.get_integrator(cases.spec_name(integ))   # a spec with settings
        step = {"rtols": [rtol]} if icls.adaptive else {"hs": [1.0]}
        case, = expand(problems=[label], formulations=[form], integrators=[integ], **step)
        if case.unsupported:
            unsupported += 1
            with pytest.raises(NotImplementedError):
                cls().setup(state, label, form, integ, tol)
    if problem in ("pendulum",):  # a constrained problem: DAE forms ODE codes cannot take
        assert unsupported > 0


def test_a_name_the_installed_commit_lacks_is_skipped(state):
    problem = next(iter(registry.problems()))
    cls, combos = _combinations(problem)
    label, form, _, tol = combos[0]
    with pytest.raises(NotImplementedError):
        cls().setup(state, label, form, "no-such-integrator", tol)
    with pytest.raises(NotImplementedError):
        cls().setup(state, label, "no-such-formulation", combos[0][2], tol)


def _one_supported_case_per_integrator():
    """For each registered integrator, its first supported combination at 'loose',
    the problems taken smallest first (by the states of their first parameter set),
    so that a large problem (chain_drive) is not what every integrator runs."""
    found = {}
    problems = registry.problems()
    for problem in sorted(problems, key=lambda name: problems[name](
            **problems[name].benchmark_parameters[0]).dimension):
        _, combos = _combinations(problem)
        for label, form, integ, tol in combos:
            if integ in found or tol != "loose":
                continue
            try:
                found[integ] = (problem, cases.make_case(label, form, integ, tol),
                                (label, form, integ, tol))
            except NotImplementedError:
                continue
    return found


SUPPORTED = _one_supported_case_per_integrator()


@pytest.mark.parametrize("integrator", sorted(SUPPORTED))
def test_tracked_figures_are_what_execute_records(integrator, state):
    problem, case, combo = SUPPORTED[integrator]
    bench = getattr(cases, problem)()
    bench.setup(state, *combo)
    record = execute(case, reference_dir=Path(state["references"]))
    assert bench.record["status"] == record["status"]
    assert bench.track_failed() == (0.0 if record["status"] == CaseStatus.OK else 1.0)
    if record["status"] != CaseStatus.OK:  # the case's figures are n/a, its failure is tracked
        for method in [*TRACKS, "track_error", "time_solve"]:
            with pytest.raises(SkipNotImplemented, match=record["status"]):
                getattr(bench, method)()
        return
    for method, key in TRACKS.items():
        value = getattr(bench, method)()
        expected = math.nan if record[key] is None else record[key]
        assert value == pytest.approx(expected, nan_ok=True), method
    assert bench.track_error() == pytest.approx(10.0 ** -record["scd"])
    bench.time_solve()  # the timed call runs on the prepared system


def test_every_registered_integrator_has_a_supported_case():
    # a registered integrator that no problem and formulation can feed would
    # appear in the suite only as skipped combinations; those taking FMUs only
    # (fmpy's solvers) are the exception: an FMU is a file named on the command
    # line, never a registered problem, so the suite has none to give them
    fmu_only = {n for n, c in registry.integrators().items() if c.accepts == {"fmu"}}
    # (an integrator with settings, ``cvode-bdf:max_order=2``, counts as its base)
    assert {cases.spec_name(name) for name in SUPPORTED} == set(registry.integrators()) - fmu_only


def test_references_for_the_installed_commit_are_prepared_once(tmp_path):
    problem = "two_mass"
    state = cases.prepare(tmp_path, problems=[problem])
    refs = Path(state["references"])
    cls = registry.get_problem_class(problem)
    for params in cls.benchmark_parameters:
        ref, why = references.read(cls(**params), refs)
        assert ref is not None, why
    assert not any((refs / other).exists() for other in registry.problems() if other != problem)


def test_a_case_that_fails_is_tracked_as_failed_and_its_figures_skipped(state, broken_integrators):
    label = registry.get_problem_class("two_mass")(
        **registry.get_problem_class("two_mass").benchmark_parameters[0]).label()
    bench = cases.two_mass()
    bench.setup(state, label, "ode", "test-gives-up", "loose")
    assert bench.record["status"] == CaseStatus.FAILED
    assert bench.track_failed() == 1.0
    with pytest.raises(SkipNotImplemented, match="failed"):
        bench.track_nfev()


@pytest.mark.parametrize("problem", list(registry.problems()))
def test_labels_resolve_to_the_exact_benchmark_sets_and_their_stored_references(problem):
    """A label rounds its values (drive_speed=3.14159 for pi); the suite's cases and
    its prepared references must use the exact set, whose reference is committed, or
    prepare would compute a reference of a rounded twin for minutes."""
    from integrator_bench.harness.matrix.cases import parse_problem_spec
    from integrator_bench.problems.base import format_label

    cls = registry.get_problem_class(problem)
    for bp in cls.benchmark_parameters:
        exact = cls(**bp).params
        label = format_label(problem, exact)
        (spec,) = parse_problem_spec(cases.exact_spec(label))
        params = spec.params_dict
        assert cls(**params).params == exact
        ref, why = references.read(cls(**params))
        assert ref is not None, why



# what an optional extra of pyproject.toml provides: asv's environment may lack it
EXTRAS_MODULES = ("assimulo", "dask", "distributed", "websocket", "virtualenv")


def _import_without_extras(module: str, cwd: Path) -> subprocess.CompletedProcess:
    """Import ``module`` in a fresh interpreter in which the extras cannot be imported."""
    code = ("import sys\n"
            "class Hide:\n"
            "    def find_spec(self, name, path=None, target=None):\n"
            f"        if name.partition('.')[0] in {EXTRAS_MODULES!r}:\n"
            "            raise ImportError(f'{name} hidden: an optional extra')\n"
            "sys.meta_path.insert(0, Hide())\n"
            f"import {module}\n")
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, text=True,
                          capture_output=True, timeout=300)


@pytest.mark.parametrize("module", sorted(
    p.stem for p in (REPO / "benchmarks").glob("*.py") if p.stem != "__init__"))
def test_every_suite_module_imports_without_the_optional_extras(module):
    # asv imports every module of benchmark_dir in its own environment: a module that
    # needs an extra at import time breaks the whole suite there
    proc = _import_without_extras(f"benchmarks.{module}", REPO)
    assert proc.returncode == 0, proc.stderr[-3000:]


def test_the_hidden_extras_check_can_fail(tmp_path):
    (tmp_path / "needs_assimulo.py").write_text("import assimulo\n")
    proc = _import_without_extras("needs_assimulo", tmp_path)
    assert proc.returncode != 0 and "hidden: an optional extra" in proc.stderr
