"""An FMU as a problem, fmpy's solvers as integrators.

The FMUs are the project's own (tests/conftest.py ``built_fmus``: C sources
in problems/fmu_sources, built with the system's C compiler), so every
measure on them has a native twin to agree with.
"""

import json
import os
import re
import shutil
import subprocess
import sys
import zipfile

import numpy as np
import pytest
from fmpy import simulate_fmu

from integrator_bench.harness.measure import references

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import Case, expand
from integrator_bench.harness.run.execution import execute
from integrator_bench.harness.measure.metrics import agreement_digits, scd
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.problems.base import ProblemError
from integrator_bench.problems.fmu import STATE_EVENT, FmuProblem, fmu_problem
from integrator_bench.problems.system import Unsupported, convert

IBENCH = [sys.executable, "-m", "integrator_bench.harness.cli"]
FMU_INTEGRATORS = sorted(n for n, c in registry.integrators().items() if "fmu" in c.accepts)
#: parameter sets of the cross-check: two_mass's stiff spring softened (k2 = 100) so
#: that its DOP853 reference check takes seconds, not a minute
CROSS = {"spring_pendulum": {"k": 100.0}, "two_mass": {"k2": 100.0},
         "bouncing_ball": {}}


def _pair(built_fmus, model, **params):
    """The FMU problem scored as the native one is, and the native problem."""
    native = registry.get_problem_class(model)(**params)
    score = "+".join(native.error_components or native.components)
    return FmuProblem(path=str(built_fmus[model]), score=score, **params), native


@pytest.fixture(scope="module")
def refs(built_fmus, tmp_path_factory):
    """Reference directory holding the FMU problems' and the native problems'
    references of ``CROSS`` (computed here, never in results/reference)."""
    directory = tmp_path_factory.mktemp("fmu_refs")
    for model, params in CROSS.items():
        for problem in _pair(built_fmus, model, **params):
            references.load(problem, directory)
    return directory


def _case(problem, integrator, rtol=None, h=None):
    return Case(problem.name, tuple(sorted(problem.params.items())), "ode", integrator,
                rtol=rtol, h=h)


# ------------------------------------------------------------------ the problem
@pytest.mark.parametrize("model", sorted(CROSS))
def test_problem_is_read_from_the_model_description(built_fmus, model):
    fmu, native = _pair(built_fmus, model)
    assert fmu.components == native.components
    declared = {p.name: p.default for p in fmu.parameters}
    assert declared == {p.name: p.default for p in native.parameters if p.name != "t_end"}
    assert fmu.t_span == native.t_span
    np.testing.assert_array_equal(fmu.atol_scale_vector(), native.atol_scale_vector())
    np.testing.assert_array_equal(fmu.initial_state(), native.initial_state())
    assert fmu.params["path"] == str(built_fmus[model])
    assert fmu.label().startswith("fmu:") and f"path={built_fmus[model]}" in fmu.label()
    assert "path" not in fmu.key_params() and len(fmu.key_params()["fmu"]) == 16
    assert fmu.describe()["fmu"]["event_indicators"] == (model == "bouncing_ball")


def test_parameters_reach_the_equations(built_fmus):
    fmu, native = _pair(built_fmus, "bouncing_ball", h0=2.5, e=0.9)
    np.testing.assert_array_equal(fmu.initial_state(), [2.5, 0.0])
    assert fmu.params["h0"] == 2.5 and fmu.label() != _pair(built_fmus, "bouncing_ball")[0].label()


@pytest.mark.parametrize("model", ["spring_pendulum", "two_mass"])
def test_rhs_and_directional_jacobian_are_the_native_ones(built_fmus, model):
    fmu, native = _pair(built_fmus, model)
    system = fmu.formulate()
    rng = np.random.default_rng(3)
    for _ in range(5):
        t, y = rng.uniform(0, 10), native.initial_state() + rng.standard_normal(4)
        np.testing.assert_allclose(system.fun(t, y), native.rhs(t, y), rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(system.jac(t, y), native.jac(t, y), rtol=1e-13, atol=1e-13)


def test_without_directional_derivatives_the_system_has_no_jacobian(built_fmus):
    """bouncing_ball declares none: integrators difference fun, counted as nfev."""
    fmu, _ = _pair(built_fmus, "bouncing_ball")
    system = fmu.formulate()
    assert system.jac is None and len(system.events) == 1
    assert system.events[0].name == STATE_EVENT and system.fmu.kind == "fmu"


def test_each_formulate_starts_a_fresh_instance(built_fmus):
    """An event changes the FMU's state; the next system starts from the start."""
    fmu, _ = _pair(built_fmus, "bouncing_ball")
    first = fmu.formulate()
    event = first.events[0]
    assert np.allclose(event.reset(0.45, np.array([0.0, -4.4])), [0.0, 0.8 * 4.4])
    assert event.reset(0.5, np.array([1e-3, 3.0])) is None       # rising: nothing changes
    second = fmu.formulate()
    np.testing.assert_array_equal(second.y0, [1.0, 0.0])
    assert second.fun(0.0, second.y0)[1] == -9.81


def _rezip(src, dst, edit):
    """A copy of the FMU ``src`` at ``dst`` with ``edit(name, data) -> (name, data)``
    applied to each member (None drops it)."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            out = edit(item.filename, zin.read(item.filename))
            if out is not None:
                zout.writestr(out[0], out[1])
    return dst


def test_a_changed_fmu_changes_its_key_a_moved_one_does_not(built_fmus, tmp_path):
    src = built_fmus["spring_pendulum"]
    moved = shutil.copy(src, tmp_path / "moved.fmu")
    changed = _rezip(src, tmp_path / "changed.fmu", lambda n, d: (n, d.replace(
        b'description="', b'description="edited: ', 1) if n == "modelDescription.xml" else d))
    a, b, c = (FmuProblem(path=str(p)) for p in (src, moved, changed))
    assert a.key_params() == b.key_params() and a.fingerprint() == b.fingerprint()
    assert references.paths(a) == references.paths(b)
    assert a.key_params() != c.key_params() and a.fingerprint() != c.fingerprint()
    assert references.paths(a) != references.paths(c)


def test_named_fmu_problem_registers_like_any_problem(built_fmus):
    cls = fmu_problem("pendulum_fmu", built_fmus["spring_pendulum"],
                      error_components=("x", "y"), velocity_components=("vx", "vy"))
    registry.register(cls)
    try:
        problem = registry.get_problem_class("pendulum_fmu")()
        assert problem.label() == "pendulum_fmu:k=100" and problem.error_components == ("x", "y")
        assert [c.integrator for c in expand(problems=["pendulum_fmu"], rtols=[1e-4])
                if not c.unsupported and c.integrator.startswith("fmpy")] == ["fmpy-cvode"]
        with pytest.raises(ProblemError, match="takes no path"):
            cls(path="other.fmu")
    finally:
        registry.unregister("pendulum_fmu")


# ------------------------------------------------------------------ scored outputs
def test_an_output_scored_is_a_component_after_the_states(built_fmus, tmp_path):
    """spring_pendulum's FMU outputs its energy: scored, it is a canonical component,
    its reference agrees with the native invariant along the native reference, and
    the harness's integrators and fmpy's alike are scored on it."""
    fmu = FmuProblem(path=str(built_fmus["spring_pendulum"]), score="x+y+energy")
    native = registry.get_problem_class("spring_pendulum")()
    assert fmu.components == ("x", "y", "vx", "vy", "energy")
    assert fmu.error_components == ("x", "y", "energy")
    assert fmu.initial_state()[4] == pytest.approx(1.0 + 50.0 * (np.sqrt(2.0) - 1.0) ** 2)
    ref = references.load(fmu, tmp_path)
    native_ref = references.load(native, compute_missing=False)
    energy = native.invariants()["energy"](native_ref.t, native_ref.Y)
    assert agreement_digits(ref.Y[:, 4:], energy[:, None], np.ones(1)).min() >= 10
    for integrator, rtol in (("cvode-bdf", 1e-8), ("fmpy-cvode", 1e-8)):
        record = execute(_case(fmu, integrator, rtol), reference_dir=tmp_path)
        assert record["status"] == CaseStatus.OK, record["message"]
        # fmpy records the energy itself, the adapter evaluates it from the states
        system = convert(fmu.formulate(), registry.get_integrator(integrator))
        sol = registry.get_integrator(integrator)().solve(system, rtol=rtol,
                                                          atol=system.atol(rtol))
        Y = system.output(sol.t, sol.y)
        assert Y.shape == ref.Y.shape
        np.testing.assert_allclose(Y[:, 4], native.invariants()["energy"](sol.t, Y[:, :4]),
                                   rtol=1e-13)


def test_outputs_of_an_fmu_with_events_are_not_scored(built_fmus):
    with pytest.raises(ProblemError, match=r"score='y\+energy' names outputs \(energy\) of an "
                                           r"FMU with event indicators.*score its states: y, v"):
        FmuProblem(path=str(built_fmus["bouncing_ball"]), score="y+energy")


# ------------------------------------------------------------------ FMI 3.0
def test_fmi3_fmu_is_the_same_problem(built_fmus, built_fmus3):
    """The FMI 3.0 build of each model reads and evaluates as the FMI 2.0 one."""
    for model in CROSS:
        two, three = FmuProblem(path=str(built_fmus[model])), FmuProblem(path=str(built_fmus3[model]))
        assert three.fmu.fmi3 and not two.fmu.fmi3
        assert (three.components, three.t_span, three.parameters, three.fmu.n_indicators,
                three.fmu.directional) == (two.components, two.t_span, two.parameters,
                                           two.fmu.n_indicators, two.fmu.directional)
        a, b = two.formulate(), three.formulate()
        rng = np.random.default_rng(5)
        for _ in range(3):
            t, y = rng.uniform(*two.t_span), a.y0 + rng.standard_normal(a.n)
            np.testing.assert_array_equal(b.fun(t, y), a.fun(t, y))
            if a.jac is not None:
                np.testing.assert_array_equal(b.jac(t, y), a.jac(t, y))
            for ea, eb in zip(a.events, b.events):
                assert eb.value(t, y) == ea.value(t, y)


@pytest.mark.parametrize("integrator,rtol", [("cvode-bdf", 1e-8), ("scipy-RK45", 1e-8),
                                             ("fmpy-cvode", 1e-8)])
def test_fmi3_bouncing_ball_runs_through_the_harness(built_fmus, built_fmus3, refs,
                                                    integrator, rtol):
    """Events of an FMI 3.0 FMU (fmi3UpdateDiscreteStates), under the in-house
    adapter and fmpy's own loop, scored against the FMI 2.0 twin's reference."""
    two, _ = _pair(built_fmus, "bouncing_ball")
    three = FmuProblem(path=str(built_fmus3["bouncing_ball"]), score="y")
    record_two = execute(_case(two, integrator, rtol), reference_dir=refs)
    system = convert(three.formulate(), registry.get_integrator(integrator))
    sol = registry.get_integrator(integrator)().solve(system, rtol=rtol, atol=system.atol(rtol))
    assert sol.success and len(sol.events) == record_two["nevents"] == 8, sol.message
    Y = system.output(sol.t, sol.y)
    ref = references.load(two, refs, False)
    assert scd(Y[-1, :1], ref.Y[-1, :1]) == pytest.approx(record_two["scd"], abs=0.02)
    if integrator == "fmpy-cvode":
        assert sol.counts["nfev"] > 100


# ------------------------------------------------------------------ bad FMUs
def _cosim_only(n, d):
    """The model description with its ModelExchange element swapped for a
    CoSimulation one (the binary stays: the interface is what is refused)."""
    if n == "modelDescription.xml":
        start = d.index(b"<ModelExchange")
        end = d.index(b">", start) + 1
        if d[end - 2:end] != b"/>":
            end = d.index(b"</ModelExchange>") + len(b"</ModelExchange>")
        identifier = re.search(rb'modelIdentifier="([^"]+)"', d[start:end]).group(1)
        d = d[:start] + b'<CoSimulation modelIdentifier="' + identifier + b'"/>' + d[end:]
    return n, d


BAD = {
    "missing": (lambda src, tmp: tmp / "nowhere.fmu", "does not exist"),
    "malformed": (lambda src, tmp: _write(tmp / "text.fmu", b"not a zip"), "is malformed"),
    "no description": (lambda src, tmp: _rezip(src, tmp / "nodesc.fmu", lambda n, d: None
                                               if n == "modelDescription.xml" else (n, d)),
                       "is malformed"),
    "co-simulation only": (lambda src, tmp: _rezip(src, tmp / "cs.fmu", _cosim_only),
                           "is co-simulation only"),
    "other platform": (lambda src, tmp: _rezip(src, tmp / "win.fmu", lambda n, d: (
        n.replace("binaries/linux64/", "binaries/win64/").replace(".so", ".dll"), d)),
                       "has no binary for this platform"),
    # a state the binary does not have: its fmi2GetContinuousStates fails at set-up
    "calls fail at set-up": (lambda src, tmp: _rezip(src, tmp / "calls.fmu", _one_state_less),
                             "fails at set-up (FMICallException"),
}


def _one_state_less(n, d):
    """The model description with its last state derivative left out: fmpy asks the
    binary for one state less than it has, which it refuses."""
    if n == "modelDescription.xml":
        start = d.index(b"<Derivatives>")
        end = d.index(b"</Derivatives>", start)
        last = d.rindex(b"<Unknown", start, end)
        d = d[:last] + d[d.index(b"/>", last) + 2:]
    return n, d


def _write(path, data):
    path.write_bytes(data)
    return path


def _ibench(*args, tmp_path):
    env = {**os.environ, "IBENCH_DATA_DIR": str(tmp_path / "data"),
           "IBENCH_REFERENCE_DIR": str(tmp_path / "data" / "reference")}
    return subprocess.run([*IBENCH, *args], capture_output=True, text=True, timeout=600,
                          env=env, cwd=tmp_path)


@pytest.mark.parametrize("kind", sorted(BAD))
def test_bad_fmu_is_one_line_exit_2_nothing_written(built_fmus, tmp_path, kind):
    make, expected = BAD[kind]
    path = make(built_fmus["spring_pendulum"], tmp_path)
    r = _ibench("run", "-p", f"fmu:path={path}", "-i", "cvode-bdf", tmp_path=tmp_path)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0] and str(path) in lines[0], r.stderr
    assert not (tmp_path / "data").exists()


@pytest.mark.parametrize("spec,expected", [
    ("fmu", "problem fmu needs the FMU file: fmu:path=FILE.fmu"),
    ("fmu:path={path},stiffness=3", "unknown parameter 'stiffness' for problem fmu; valid: k"),
    ("fmu:path={path},k=0.5", "parameter k=0.5 is outside its range"),
    ("fmu:path={path},score=x+z",
     "score='x+z' names 'z', not a state or output; valid: x, y, vx, vy, energy"),
])
def test_bad_fmu_parameters(built_fmus, tmp_path, spec, expected):
    spec = spec.format(path=built_fmus["spring_pendulum"])
    r = _ibench("run", "-p", spec, "-i", "cvode-bdf", tmp_path=tmp_path)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert expected in r.stderr and not (tmp_path / "data").exists()


# ------------------------------------------------------------------ cross-check
@pytest.mark.parametrize("model", sorted(CROSS))
def test_fmu_and_native_references_agree_to_10_digits(built_fmus, refs, model):
    fmu, native = _pair(built_fmus, model, **CROSS[model])
    a, b = references.load(fmu, refs, False), references.load(native, refs, False)
    digits = agreement_digits(a.Y, b.Y, native.atol_scale_vector())
    assert digits.min() >= 10, dict(zip(native.components, digits))
    assert len(a.events) == len(b.events)
    if a.events:
        span = native.t_span[1] - native.t_span[0]
        gap = max(abs(ta - tb) for (ta, _, _), (tb, _, _) in zip(a.events, b.events))
        assert -np.log10(gap / span) >= 10 and {e[1] for e in a.events} == {STATE_EVENT}


#: library and in-house integrators, adaptive and fixed-step, with and without events
SAME_ON_BOTH = [("scipy-RK45", 1e-6, None), ("scipy-Radau", 1e-6, None),
                ("cvode-bdf", 1e-6, None), ("ida", 1e-6, None), ("gbs", 1e-6, None),
                ("rk4", None, 1e-2), ("bdf3", None, 1e-2), ("sdirk3", None, 1e-2)]


@pytest.mark.parametrize("model", sorted(CROSS))
@pytest.mark.parametrize("integrator,rtol,h", SAME_ON_BOTH)
def test_each_integrator_errs_alike_on_fmu_and_native(built_fmus, refs, model, integrator,
                                                      rtol, h):
    fmu, native = _pair(built_fmus, model, **CROSS[model])
    a = execute(_case(fmu, integrator, rtol, h), reference_dir=refs)
    b = execute(_case(native, integrator, rtol, h), reference_dir=refs)
    assert a["status"] == b["status"], (a["message"], b["message"])
    if b["status"] == CaseStatus.UNSUPPORTED:            # no events located: both refuse
        return
    assert b["status"] == CaseStatus.OK, b["message"]
    # errors below what the FMU's reference resolves (its own error, measured
    # against the native one) cannot be told apart; a Jacobian by differences
    # (bouncing_ball's FMU gives no directional derivatives) moves the Newton
    # iterates a little
    ref_a, ref_b = references.load(fmu, refs, False), references.load(native, refs, False)
    err = native.component_index(native.error_components)
    resolved = scd(ref_a.Y[-1, err], ref_b.Y[-1, err]) - 0.3
    close = 0.02 if fmu.fmu.directional else 0.1
    assert min(a["scd"], resolved) == pytest.approx(min(b["scd"], resolved), abs=close)
    assert a["nevents"] == b["nevents"] and a["nsteps"] == pytest.approx(b["nsteps"], rel=0.05)
    if b["event_time_err"] is not None:
        gap = max(abs(x[0] - y[0]) for x, y in zip(ref_a.events, ref_b.events))
        assert a["event_time_err"] == pytest.approx(b["event_time_err"], abs=2 * gap + 1e-12)


# ------------------------------------------------------------------ fmpy's solvers
@pytest.mark.parametrize("integrator", FMU_INTEGRATORS)
def test_fmpy_solvers_take_only_fmus(integrator):
    native = registry.get_problem_class("spring_pendulum")()
    with pytest.raises(Unsupported, match=f"^{integrator} accepts fmu; the system is an ode$"):
        convert(native.formulate(), registry.get_integrator(integrator))


def test_fmpy_cvode_converges_and_counts_its_fmu_calls(built_fmus, refs):
    fmu, _ = _pair(built_fmus, "spring_pendulum", **CROSS["spring_pendulum"])
    loose, tight = (execute(_case(fmu, "fmpy-cvode", rtol), reference_dir=refs)
                    for rtol in (1e-4, 1e-8))
    assert loose["status"] == tight["status"] == CaseStatus.OK, (loose["message"], tight["message"])
    assert tight["scd"] > loose["scd"] + 2.5 and tight["nfev"] > loose["nfev"] > 100
    assert loose["njev"] is None and loose["nsteps"] is None    # unknown to fmpy
    # the count is the calls fmpy's own FMI call logger lists for the same run
    logged = []
    simulate_fmu(str(built_fmus["spring_pendulum"]), fmi_type="ModelExchange",
                 relative_tolerance=1e-4, output_interval=0.1, start_values={"k": 100.0},
                 fmi_call_logger=lambda m: logged.append(m.startswith("fmi2GetDerivatives(")))
    assert loose["nfev"] == sum(logged)


def test_fmpy_euler_is_first_order_with_one_call_per_step(built_fmus, refs):
    fmu, _ = _pair(built_fmus, "two_mass", **CROSS["two_mass"])
    records = [execute(_case(fmu, "fmpy-euler", h=h), reference_dir=refs) for h in (2e-3, 1e-3)]
    assert all(r["status"] == CaseStatus.OK for r in records), [r["message"] for r in records]
    assert [r["nfev"] for r in records] == [r["nsteps"] for r in records] == [5000, 10000]
    order = (records[1]["scd"] - records[0]["scd"]) / np.log10(2)
    assert order == pytest.approx(1.0, abs=0.3)
    bad = execute(_case(fmu, "fmpy-euler", h=3e-3), reference_dir=refs)
    assert bad["status"] == CaseStatus.FAILED and "does not divide the output spacing" in bad["message"]


def test_fmpy_cvode_finds_the_impacts(built_fmus, refs):
    fmu, native = _pair(built_fmus, "bouncing_ball")
    record = execute(_case(fmu, "fmpy-cvode", 1e-8), reference_dir=refs)
    assert record["status"] == CaseStatus.OK, record["message"]
    assert record["nevents"] == len(native.impact_times()) == 8
    assert record["events_missed"] == record["events_spurious"] == 0
    assert record["event_time_err"] < 1e-6


# ------------------------------------------------------------------ through the matrix
def test_matrix_and_report_on_an_fmu(built_fmus, tmp_path):
    """`ibench run` on an FMU under library, in-house and fmpy integrators, then the report."""
    path = built_fmus["spring_pendulum"]
    r = _ibench("run", "-p", f"fmu:path={path},k=100", "-i", "cvode-bdf", "-i", "rk4",
                "-i", "fmpy-cvode", "-i", "fmpy-euler", "-i", "scipy-RK45",
                "--rtol", "1e-6", "--h", "0.001", "--json", tmp_path=tmp_path)
    assert r.returncode == 0, r.stderr
    rows = [json.loads(line) for line in r.stdout.splitlines() if line.startswith("{")]
    status = {(x["integrator"], x["rtol"] is not None): x["status"] for x in rows}
    assert status[("cvode-bdf", True)] == status[("fmpy-cvode", True)] == CaseStatus.OK
    assert status[("rk4", False)] == status[("scipy-RK45", True)] == CaseStatus.OK
    assert status[("fmpy-euler", True)] == CaseStatus.UNSUPPORTED     # no error estimate
    assert all(x["problem"] == "fmu" for x in rows)
    assert list((tmp_path / "data" / "reference" / "fmu").glob("fmu=*,k=100.npz"))
    report = _ibench("report", tmp_path=tmp_path)
    assert report.returncode == 0, report.stderr
    text = (tmp_path / "data" / "report" / "index.md").read_text()
    assert "fmpy-cvode" in text and "fmu" in text
