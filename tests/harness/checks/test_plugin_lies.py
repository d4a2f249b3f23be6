"""Plugins with one plausible flaw each, as a plugin author might write them from the
docs: check-plugin fails each on the line that names its flaw, and the matrix's
record says so too. Their honest twin is the Heun example (tests/harness/checks/test_plugins.py)."""

import numpy as np
import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.checks.conformance import check_plugin
from integrator_bench.harness.measure.counting import counted, model_files, watch_model
from integrator_bench.harness.run.execution import execute
from integrator_bench.harness.matrix.record import INPUT_MODIFIED, NONFINITE_OUTPUT
from integrator_bench.integrators.base import Step, Solution, Stepper
from integrator_bench.problems.models.pendulum import Pendulum
from integrator_bench.problems.system import convert

from test_plugins import OwnLoopEulerHonest, load_example

HEUN = load_example()


def _raw(fn):
    """The model's own function behind a counted one, dug out of its closure."""
    for cell in fn.__closure__ or ():
        if callable(cell.cell_contents):
            return cell.cell_contents
    return fn


class RawStepper(Stepper):
    """Heun whose second stage calls the model's raw function, out of sight."""

    error_order = 1

    def step(self, t, y, h):
        f = self.system.fun
        k1 = np.asarray(f(t, y), float)
        k2 = np.asarray(_raw(f)(t + h, y + h * k1), float)
        return Step(y + 0.5 * h * (k1 + k2), error=0.5 * h * (k2 - k1))


class UnderReports(HEUN):
    """Makes two evaluations a step, lets the harness see one."""

    name = "test-lie-under-reports"

    def stepper(self, system, counts, rtol=None, atol=None):
        return RawStepper(system, counts, rtol, atol)


class InPlaceStepper(Stepper):
    """Heun that updates the state it is handed in place."""

    error_order = 1

    def step(self, t, y, h):
        f = self.system.fun
        k1 = np.asarray(f(t, y), float)
        k2 = np.asarray(f(t + h, y + h * k1), float)
        y += 0.5 * h * (k1 + k2)
        return Step(y, error=0.5 * h * (k2 - k1))


class WritesState(HEUN):
    name = "test-lie-writes-state"

    def stepper(self, system, counts, rtol=None, atol=None):
        return InPlaceStepper(system, counts, rtol, atol)


class WritesSystem(OwnLoopEulerHonest):
    """An own loop that scales the tolerances it was handed by changing the system."""

    name = "test-lie-writes-system"

    def solve(self, system, *, rtol=None, atol=None, h=None):
        system.atol_scale *= 10.0
        system.y0[0] += 0.0     # a write that changes nothing is no change
        return super().solve(system, rtol=rtol, atol=atol, h=h)


class NaNAfter60(OwnLoopEulerHonest):
    """Reports success with NaN in one component after 60 % of the span."""

    name = "test-lie-nan"
    stability = "A"

    def solve(self, system, *, rtol=None, atol=None, h=None):
        sol = super().solve(system, rtol=rtol, atol=atol, h=h)
        y = np.array(sol.y, float)
        y[sol.t >= system.t0 + 0.6 * (system.t_end - system.t0), -1] = np.nan
        return Solution(sol.t, y, True, "", sol.counts)


class StartsWithNone(HEUN):
    """A stepper whose start() forgets to return the state."""

    name = "test-lie-start-none"

    def stepper(self, system, counts, rtol=None, atol=None):
        stepper = super().stepper(system, counts, rtol, atol)
        stepper.start = lambda t0, y0: None
        return stepper


LIARS = (UnderReports, WritesState, WritesSystem, NaNAfter60, StartsWithNone)


@pytest.fixture(scope="module")
def liars():
    for cls in LIARS:
        registry.register(cls, origin="tests")
    yield
    for cls in LIARS:
        registry.unregister(cls.name)


def _lines(name, only):
    return {c.name: c for c in check_plugin(name, timeout=120, only=only)}


def _record(name, **mode):
    mode = mode or {"rtols": [1e-4]}
    case, = [c for c in expand(problems=["pendulum"], formulations=["ode"], integrators=[name],
                               **mode)]
    return execute(case)


def test_the_raw_model_is_not_an_attribute_of_what_a_plugin_is_handed():
    system, counters = counted(convert(Pendulum().formulate("ode"), HEUN))
    assert vars(system.fun) == {} and system.mechanical is None
    assert not any(callable(v) for v in vars(system).values()
                   if v is not system.fun and v is not system.output)
    system.fun(0.0, system.y0)
    assert counters["nfev"].n == 1


def test_the_model_watch_sees_a_call_past_the_counters():
    problem = Pendulum()
    system, counters = counted(convert(problem.formulate("ode"), HEUN))
    with watch_model(model_files(problem)) as view:
        system.fun(0.0, system.y0)
        _raw(system.fun)(0.0, system.y0)
    assert (view.counted, view.unseen, counters["nfev"].n) == (1, 1, 1)
    assert "test_plugin_lies.py" in view.verdict()


def test_under_reporting_fails_the_counts_line(liars):
    line = _lines(UnderReports.name, ("runs",))["counts"]
    assert line.passed is False, line.line()
    assert "outside the counted callables" in line.detail and "in step" in line.detail


def test_writing_into_the_state_fails_at_once_and_is_named(liars):
    record = _record(WritesState.name)
    assert (record["status"], record["reason"]) == ("failed", INPUT_MODIFIED), record
    assert "wrote into the state y" in record["message"]
    line = _lines(WritesState.name, ("runs",))["inputs"]
    assert line.passed is False and "wrote into the state y" in line.detail, line.line()


def test_changing_the_systems_arrays_is_named(liars):
    record = _record(WritesSystem.name)
    assert (record["status"], record["reason"]) == ("failed", INPUT_MODIFIED), record
    assert "system.atol_scale changed in place" in record["message"]
    assert "y0" not in record["message"]
    line = _lines(WritesSystem.name, ("runs",))["inputs"]
    assert line.passed is False and "system.atol_scale changed in place" in line.detail


def test_a_nan_is_named_on_every_line_it_affects(liars):
    record = _record(NaNAfter60.name)
    assert (record["status"], record["reason"]) == ("failed", NONFINITE_OUTPUT)
    assert "non-finite output at t=" in record["message"]
    lines = _lines(NaNAfter60.name, ("runs", "order", "stability", "accuracy"))
    for name in ("runs ode", "order", "stability", "accuracy"):
        assert lines[name].passed is False, lines[name].line()
        assert "non-finite output at t=" in lines[name].detail, lines[name].line()


def test_a_start_returning_none_is_named_and_fails_no_fault_line(liars):
    record = _record(StartsWithNone.name)
    assert record["reason"] == "exception" and "start() returned None" in record["message"]
    lines = _lines(StartsWithNone.name, ("fails",))
    for name in ("fails raise", "fails nan", "fails blowup"):
        assert lines[name].passed is False, lines[name].line()
        assert "start() returned None" in lines[name].detail, lines[name].line()
    assert all("something else" in lines[f"fails {k}"].detail for k in ("raise", "nan"))


class IgnoresRtol(OwnLoopEulerHonest):
    """Runs at rtol 1e-5 whatever it is asked."""

    name = "test-lie-ignores-rtol"

    def solve(self, system, *, rtol=None, atol=None, h=None):
        return super().solve(system, rtol=1e-5, atol=system.atol(1e-5), h=h)


def test_a_line_that_ignores_rtol_is_marked_in_the_report_and_the_summary(tmp_path):
    from integrator_bench.harness.cli.summary import summary
    from integrator_bench.harness.report import write_report
    from integrator_bench.harness.ranking.records import unresponsive
    from integrator_bench.harness.run.runner import to_dataframe

    registry.register(IgnoresRtol, origin="tests")
    registry.register(HEUN, origin="tests")
    try:
        records = [execute(c) for c in expand(problems=["pendulum"], formulations=["ode"],
                                              integrators=[IgnoresRtol.name, HEUN.name],
                                              rtols=[1e-3, 1e-4])]
        df = to_dataframe(records)
        assert set(df["status"]) == {"ok"}
        found = unresponsive(df)
        assert [(f["label"], f["rtols"]) for f in found] == [(IgnoresRtol.name, [1e-3, 1e-4])]
        text = summary(df)
        assert f"{IgnoresRtol.name}/ode does not respond to rtol" in text
        assert f"{HEUN.name}/ode does not" not in text
        write_report(df, tmp_path / "report")
        pages = " ".join(p.read_text() for p in (tmp_path / "report").rglob("*.md"))
        assert "Does not respond to rtol" in pages and IgnoresRtol.name in pages
    finally:
        registry.unregister(IgnoresRtol.name)
        registry.unregister(HEUN.name)


def test_a_line_exact_at_every_tolerance_is_not_marked():
    """Identical records whose error is below the tightest rtol: a method exact on the
    problem (RADAU5 on the bouncing ball's parabolas), not one that ignores rtol."""
    from integrator_bench.harness.ranking.records import unresponsive
    from records_frame import records_frame

    row = dict(problem="p", params="{}", integrator="i", formulation="ode", status="ok",
               reason=None, nfev=10, njev=1, nlu=1, nsteps=5, nreject=0, nniter=None,
               nnfail=None, scd=11.3, mescd=12.9)
    rows = [dict(row, rtol=r, err_max=e) for r, e in ((1e-3, 7e-13), (1e-6, 7e-13))]
    assert unresponsive(records_frame(rows)) == []
    rows = [dict(row, rtol=r, err_max=e) for r, e in ((1e-3, 0.15), (1e-6, 0.15))]
    assert [line["rtols"] for line in unresponsive(records_frame(rows))] == [[1e-3, 1e-6]]


class NaNStepper(Stepper):
    """A stable-looking step that turns one component NaN from t = 10 on."""

    error_order = 1

    def step(self, t, y, h):
        y_new = y / (1.0 + h)                      # implicit Euler on y' = -y, whatever f
        if t >= 10.0:
            y_new = y_new.copy()
            y_new[-1] = np.nan
        return Step(y_new, error=np.zeros_like(y))


class NaNClaimsA(HEUN):
    name = "test-lie-nan-claims-a"
    stability = "A"

    def stepper(self, system, counts, rtol=None, atol=None):
        return NaNStepper(system, counts, rtol, atol)


def test_the_stability_line_names_a_nan_not_a_modulus():
    from integrator_bench.harness.checks.method_checks import stability

    passed, detail = stability(NaNClaimsA)
    assert passed is False
    assert "no usable run" in detail and "non-finite" in detail and "|R(z)|" not in detail
