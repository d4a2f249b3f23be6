"""The runner: every status, durability, resume, and counting."""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.run.execution import execute, finish
from integrator_bench.harness.matrix.record import FIELDS, STATUSES, CaseStatus, empty_record
from integrator_bench.harness.matrix.store import Store, StoreError, load
from integrator_bench.integrators.base import Integrator, Solution, Status, StepFailure
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits

SMALL = "two_mass:c2=1000"


@pytest.mark.parametrize("status", list(CaseStatus))
def test_a_status_is_stored_and_read_back_as_its_plain_string(status, tmp_path):
    """A record holds the status's value: the store, JSON and the DataFrame carry
    plain strings (so stores written before the enum read the same), equal to
    the member."""
    record = finish(empty_record(case_id="c", problem="two_mass"), status, "why")
    assert type(record["status"]) is str and record["status"] == status.value
    assert json.loads(json.dumps(record.to_dict()))["status"] == status
    with Store(tmp_path / "s.sqlite") as store:
        store.add(record)
    stored = load(tmp_path / "s.sqlite").status.tolist()
    assert stored == [status.value] and CaseStatus(stored[0]) is status
    assert f"{status}" == str(status) == status.value  # messages and tables show the value


def test_statuses_are_the_enum_and_nothing_else():
    assert STATUSES == ("ok", "untimed", "failed", "timeout", "crashed", "error", "unsupported",
                        "skipped", "dominated")
    assert STATUSES == tuple(CaseStatus)
    with pytest.raises(ValueError, match="'finished'"):
        finish(empty_record(), "finished")  # a run's status, not a case's


def test_every_failure_status_is_a_record(broken_integrators, store_path, run_cases):
    cases = expand(problems=[SMALL], integrators=list(broken_integrators) + ["scipy-RK45"],
                   rtols=[1e-3])
    with Store(store_path) as store:
        df = run_cases(cases,
                       RunContext(store=store, jobs=2, progress=False, limits=Limits(budget_s=10)))
    status = dict(zip(df.integrator, df.status))
    S = CaseStatus
    assert status == {"test-raises": S.ERROR, "test-gives-up": S.FAILED, "test-nan": S.FAILED,
                      "test-hangs": S.TIMEOUT, "test-segfault": S.CRASHED,
                      "test-memory-hog": S.ERROR, "test-overflow": S.FAILED,
                      "test-mechanical-only": S.UNSUPPORTED, "scipy-RK45": S.OK}
    msg = dict(zip(df.integrator, df.message))
    assert "deliberate failure" in msg["test-raises"]
    assert "step size too small" in msg["test-gives-up"]
    assert "non-finite" in msg["test-nan"]
    assert "SIGSEGV" in msg["test-segfault"]
    assert "diverged" in msg["test-overflow"] and "OverflowError" in msg["test-overflow"]
    assert "10 s" in msg["test-hangs"]
    assert "out of memory" in msg["test-memory-hog"] and "MemoryError" in msg["test-memory-hog"]
    assert df.loc[df.status != CaseStatus.OK, "message"].notna().all()
    assert df.loc[df.status == CaseStatus.OK, "message"].isna().all()
    reason = {i: r if isinstance(r, str) else None for i, r in zip(df.integrator, df.reason)}
    assert reason == {"test-raises": "exception", "test-gives-up": "solver_failure",
                      "test-nan": "nonfinite_output", "test-hangs": "timeout",
                      "test-segfault": "crashed", "test-memory-hog": "out_of_memory",
                      "test-overflow": "diverged", "test-mechanical-only": "unsupported",
                      "scipy-RK45": None}
    stored = load(store_path)
    assert len(stored) == len(cases)
    assert list(stored.columns) == list(FIELDS)
    gives_up = stored[stored.integrator == "test-gives-up"].iloc[0]
    assert gives_up.nfev == 1 and gives_up.nsteps == 0 and pd.isna(gives_up.nlu)


@pytest.mark.parametrize("name", list(registry.integrators()))
def test_registered_integrator_runs_and_counts_honestly(name):
    """Every live integrator: ok on a stiff linear problem, counts consistent."""
    # rtol 1e-6 when it is adaptive, else h 1e-3 (every integrator is given both)
    cases = expand(problems=[SMALL], integrators=[name], rtols=[1e-6], hs=[1e-3])
    case = next((c for c in cases if not c.unsupported), cases[0])
    if case.unsupported and registry.get_integrator(name).accepts == {"mechanical"}:
        pytest.skip("takes only the mechanical form: run on the i3 pendulum in "
                    "tests/integrators/test_alpha_methods.py::test_runs_in_the_matrix_on_the_i3_pendulum")
    if case.unsupported and registry.get_integrator(name).accepts == {"augmented_lagrangian"}:
        pytest.skip("takes only the al3 form: run on the pendulum in tests/problems/models/test_n_four_bar.py::"
                    "test_al_trapezoidal_runs_in_the_matrix_and_counts_honestly")
    if case.unsupported and registry.get_integrator(name).accepts == {"fmu"}:
        pytest.skip("takes only FMUs: run on them in tests/problems/fmu/test_fmu_problem.py")
    record = execute(case)
    assert record["status"] == CaseStatus.OK, record["message"]
    icls = registry.get_integrator(name)
    # h = 1e-3 over [0, 10]: a first-order fixed-step method is only about 1e-2 accurate
    assert record["scd"] > (1 if not icls.adaptive and icls.order == 1 else 3)
    assert record["nfev"] > 0 and record["cpu_s"] > 0
    counts = record["solver_counts"]
    if "nfev" in counts:
        # the harness counts finite-difference calls too: never fewer than reported
        assert record["nfev"] >= counts["nfev"]
    for key in ("nsteps", "nlu", "nreject", "nniter", "nnfail"):
        assert record[key] == counts.get(key)


def test_a_success_with_a_partly_non_finite_output_is_a_failure(tmp_path):
    """A solver that reports success while one component of its output turns NaN
    after 60 % of the span (the model itself stayed finite: the integrator's own
    fault) fails with ``nonfinite_output``, not ``ok`` with NaN errors."""
    from integrator_bench.integrators.driver import integrate

    class PartlyNaN(Integrator):
        name = "test-partly-nan"
        description = "RK4 whose output's first component turns NaN late (tests only)"
        adaptive = False

        def solve(self, system, *, rtol=None, atol=None, h=None):
            sol = integrate(registry.get_integrator("rk4")(), system, h=h)
            y = sol.y.copy()
            y[sol.t > system.t0 + 0.6 * (system.t_end - system.t0), 0] = np.nan
            return Solution(sol.t, y, True, "", sol.counts)

    registry.register(PartlyNaN, origin="tests")
    try:
        case, = expand(problems=[SMALL], integrators=["test-partly-nan"], hs=[1e-3])
        record = execute(case, reference_dir=None)
    finally:
        registry.unregister("test-partly-nan")
    assert record["status"] == CaseStatus.FAILED, record["message"]
    assert record["reason"] == "nonfinite_output"
    assert "non-finite" in record["message"] and record["err_max"] is None


def test_store_refuses_foreign_and_garbage_files(tmp_path):
    import sqlite3
    other = tmp_path / "other.sqlite"
    sqlite3.connect(other).execute("CREATE TABLE x (a)").connection.commit()
    with pytest.raises(StoreError, match="another program"):
        Store(other)
    garbage = tmp_path / "garbage.sqlite"
    garbage.write_bytes(b"not a database at all" * 100)
    with pytest.raises(StoreError, match="not a readable SQLite"):
        Store(garbage)


def test_resume_skips_stored_cases(store_path, run_cases):
    cases = expand(problems=[SMALL], integrators=["scipy-RK45", "cvode-bdf"], rtols=[1e-3, 1e-5])
    with Store(store_path) as store:
        run_cases(cases[:2], RunContext(store=store, jobs=1, progress=False))
        df = run_cases(cases, RunContext(store=store, jobs=1, resume=True, progress=False))
    assert len(df) == len(cases)
    stored = load(store_path)
    assert sorted(stored.case_id) == sorted(c.case_id for c in cases)


def test_resume_reruns_what_another_code_version_stored(store_path, monkeypatch, run_cases):
    """``--resume`` goes on with the cases of *this* code version: records of
    another version are kept, never taken as done."""
    from integrator_bench.harness.run import execution, runner
    cases = expand(problems=[SMALL], integrators=["scipy-RK45", "cvode-bdf"], rtols=[1e-3, 1e-5])
    for module in (execution, runner):
        monkeypatch.setattr(module, "code_version", lambda: "aaaaaaaaaaaa")
    with Store(store_path) as store:
        run_cases(cases[:2], RunContext(store=store, jobs=1, progress=False))
    for module in (execution, runner):
        monkeypatch.setattr(module, "code_version", lambda: "bbbbbbbbbbbb")
    with Store(store_path) as store:
        df = run_cases(cases, RunContext(store=store, jobs=1, resume=True, progress=False))
    assert len(df) == len(cases) and set(df.code_version) == {"bbbbbbbbbbbb"}
    stored = load(store_path)
    by_version = stored.groupby("code_version").case_id.apply(sorted).to_dict()
    assert by_version == {"aaaaaaaaaaaa": sorted(c.case_id for c in cases[:2]),
                          "bbbbbbbbbbbb": sorted(c.case_id for c in cases)}


def test_interrupted_run_resumes_without_loss_or_duplicates(store_path):
    """Interrupt a real `ibench run` with SIGINT, then finish it with --resume."""
    args = [sys.executable, "-m", "integrator_bench.harness.cli", "run", "-p", SMALL, "-i", "scipy-RK45",
            "-i", "scipy-RK23", "-i", "cvode-bdf", "--rtol", "1e-3", "1e-4", "1e-5", "1e-6",
            "--jobs", "1", "--store", str(store_path), "--json"]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    first = proc.stdout.readline()          # one case finished and stored
    assert json.loads(first)["status"] == CaseStatus.OK
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "--resume" in err
    done_before = len(load(store_path))
    assert 1 <= done_before < 12
    subprocess.run(args + ["--resume"], check=True, capture_output=True, timeout=300)
    stored = load(store_path)
    assert len(stored) == 12
    assert stored.case_id.is_unique


class _Euler(Integrator):
    """Explicit Euler at the fixed step h, reporting its nfev times `claim` (tests only)."""
    name = "test-euler"
    description = "explicit Euler (tests only)"
    accepts = frozenset({"ode"})
    adaptive, fixed_step = False, True
    claim = 1.0  # reported nfev = claim * calls made

    def solve(self, system, *, rtol=None, atol=None, h=None):
        t, y, nfev, out = system.t0, system.y0.copy(), 0, [system.y0.copy()]
        for t_next in system.t_eval[1:]:
            n = max(1, int(np.ceil((t_next - t) / h - 1e-9)))
            step = (t_next - t) / n
            for _ in range(n):
                y = y + step * system.fun(t, y)
                t, nfev = t + step, nfev + 1
            out.append(y.copy())
        return Solution(system.t_eval, np.array(out), counts={"nfev": int(self.claim * nfev)})


class _Doubles(_Euler):
    name = "test-doubles-nfev"
    claim = 2.0


class _Halves(_Euler):
    """Claims half its calls: honest for an implicit method whose finite-difference
    Jacobian calls it leaves out, a lie for an explicit one."""
    name = "test-halves-nfev"
    claim = 0.5


class _ImplicitHalves(_Halves):
    name = "test-implicit-halves-nfev"
    implicit = True


@pytest.fixture
def counting_integrators():
    classes = (_Euler, _Doubles, _Halves, _ImplicitHalves)
    for cls in classes:
        registry.register(cls, origin="tests")
    yield [cls.name for cls in classes]
    for cls in classes:
        registry.unregister(cls.name)


def test_count_mismatch_is_recorded_and_warned_once_per_integrator(counting_integrators,
                                                                   capsys, run_cases):
    cases = expand(problems=[SMALL], integrators=counting_integrators, hs=[1e-3, 5e-4])
    df = run_cases(cases, RunContext(jobs=2, progress=False))
    assert (df.status == CaseStatus.OK).all(), df.message.tolist()
    for _, rec in df.iterrows():
        own = json.loads(rec.solver_counts)["nfev"]
        calls = int(round(own / {"test-euler": 1, "test-doubles-nfev": 2}.get(rec.integrator,
                                                                               0.5)))
        assert abs(rec.nfev - calls) <= 1  # the harness's count is kept, never the claim
        lies = rec.integrator in ("test-doubles-nfev", "test-halves-nfev")
        if lies:
            assert rec.count_mismatch == f"nfev: own {own}, harness {rec.nfev}"
        else:  # exact, or fewer from an implicit method that may use finite differences
            assert pd.isna(rec.count_mismatch), rec.count_mismatch
    warnings = [line for line in capsys.readouterr().err.splitlines() if "disagree" in line]
    assert sorted(w.split()[2] for w in warnings) == ["test-doubles-nfev", "test-halves-nfev"]


class _StatusReporter(Integrator):
    """Gives up with a typed status and a message that names another outcome."""
    name = "test-status"
    description = "typed failure (tests only)"
    accepts = frozenset({"ode"})

    def solve(self, system, **kw):
        return Solution(system.t_eval[:1], system.y0[None, :], message="diverged? no: Newton",
                        status=Status.NEWTON_FAILURE)


class _StepRaiser(_StatusReporter):
    name = "test-step-raiser"

    def solve(self, system, **kw):
        raise StepFailure(Status.METHOD_LIMIT, "too many stages")


def test_reason_is_the_solutions_status_not_its_message():
    for cls in (_StatusReporter, _StepRaiser):
        registry.register(cls, origin="tests")
    try:
        cases = expand(problems=[SMALL], integrators=["test-status", "test-step-raiser"],
                       rtols=[1e-3])
        records = {c.integrator: execute(c) for c in cases}
    finally:
        for cls in (_StatusReporter, _StepRaiser):
            registry.unregister(cls.name)
    assert records["test-status"]["status"] == CaseStatus.FAILED
    assert records["test-status"]["reason"] == "newton_failure"
    assert records["test-step-raiser"]["status"] == CaseStatus.FAILED
    assert records["test-step-raiser"]["reason"] == "method_limit"
    assert "too many stages" in records["test-step-raiser"]["message"]


def test_a_diverged_run_is_failed_and_keeps_its_errors():
    """Explicit Euler at h = 0.1 on the stiff two_mass ends about 1e224 off."""
    case = next(iter(expand(problems=[SMALL], integrators=["euler"], hs=[0.1])))
    record = execute(case)
    assert (record["status"], record["reason"]) == (CaseStatus.FAILED, "diverged")
    assert record["mescd"] < -100 and record["scd"] < -100 and record["err_max"] > 1e100
    assert "diverged" in record["message"] and "exceeds the bound 1" in record["message"]


class _Warns(Integrator):
    """scipy-RK45's solution, after three numpy overflows and a UserWarning."""
    name = "test-warns"
    description = "warns while solving (tests only)"
    accepts = frozenset({"ode"})

    def solve(self, system, **kw):
        import warnings
        for _ in range(3):
            np.float64(1e300) * np.float64(1e300)  # RuntimeWarning: overflow
        warnings.warn("deliberate", UserWarning)
        return registry.get_integrator("scipy-RK45")().solve(system, **kw)


def test_worker_warnings_go_into_the_message_not_onto_the_terminal(capfd, run_cases):
    registry.register(_Warns, origin="tests")
    try:
        cases = expand(problems=[SMALL], integrators=["test-warns"], rtols=[1e-3])
        df = run_cases(cases, RunContext(jobs=1, progress=False))  # in a forked worker
    finally:
        registry.unregister(_Warns.name)
    record = df.iloc[0]
    assert record.status == CaseStatus.OK, record.message
    assert record.message.startswith("warnings: RuntimeWarning: overflow encountered in ")
    assert record.message.endswith(" (x3); UserWarning: deliberate (x1)")
    assert "Warning" not in capfd.readouterr().err


@pytest.mark.parametrize("integrator", [name for name, cls in registry.integrators().items()
                                        if cls.projects and cls.adaptive])
def test_projecting_integrators_count_their_re_evaluations(integrator):
    """After a projection the stored slope is evaluated again; an integrator's own
    nfev counts that call, so it agrees with the harness's count."""
    case = next(c for c in expand(problems=["pendulum"], formulations=["projection"],
                                  integrators=[integrator], rtols=[1e-4]))
    record = execute(case)
    assert record["status"] == CaseStatus.OK, record["message"]
    assert record["count_mismatch"] is None, record["count_mismatch"]
