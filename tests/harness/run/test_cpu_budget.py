"""A case's budget is CPU seconds of its own process: its status and counts do
not depend on what else the machine runs.

The same cases run alone and beside busy processes that keep every core
loaded several times over; under the load their wall time grows several-fold
(a wall-clock budget of the same seconds would time them out), while their
statuses and counts stay the same: a case well within its budget is ``ok``
both times, one well past it a ``timeout`` both times.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import time

import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.harness.run.execution import execute
from integrator_bench.integrators.base import Integrator
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits

SMALL = "two_mass:c1=0.1,c2=1000,k1=10,k2=10000"
COUNTS = ("nfev", "njev", "nlu", "nsteps", "nreject", "nniter", "nnfail")
#: busy processes per core beside the run: the worker gets about a fifth of a core
LOAD_PER_CORE = 4


@contextlib.contextmanager
def busy_machine():
    """Busy processes (``while True: pass``), LOAD_PER_CORE per core, for the block."""
    spinners = [subprocess.Popen([sys.executable, "-c", "while True: pass"])
                for _ in range(LOAD_PER_CORE * (os.cpu_count() or 1))]
    try:
        yield
    finally:
        for p in spinners:
            p.kill()
            p.wait()


def outcome(df):
    return {row.case_id: (row.status, *(getattr(row, k) for k in COUNTS))
            for row in df.itertuples()}


@pytest.mark.parametrize("integrator, step", [("scipy-RK45", {"rtols": [1e-10]}),
                                              ("rk4", {"hs": [2e-4]})])
def test_status_and_counts_do_not_change_under_load(integrator, step, run_cases):
    """A library loop (scipy's, stopped by its worker's budget) and the shared
    driver (stopped in its process) alike."""
    case, = expand(problems=[SMALL], integrators=[integrator], **step)
    cpu = execute(case, repeat=1)["cpu_s"]
    within, past = 4 * cpu + 0.2, cpu / 4       # budgets in CPU seconds
    context = {budget: RunContext(jobs=1, progress=False,
                                  limits=Limits(budget_s=budget, repeat=1))
               for budget in (within, past)}
    alone = {budget: run_cases([case], c) for budget, c in context.items()}
    with busy_machine():
        loaded = {budget: run_cases([case], c) for budget, c in context.items()}
    assert alone[within].status.iloc[0] == CaseStatus.OK
    assert alone[past].status.iloc[0] == CaseStatus.TIMEOUT
    for budget in (within, past):
        assert outcome(loaded[budget]) == outcome(alone[budget]), budget
    # the load was real: the ok case took several times its CPU in wall time
    slow = loaded[within].iloc[0]
    assert slow.wall_s > 2 * slow.cpu_s, (slow.wall_s, slow.cpu_s)


class SpawnsAndHangs(Integrator):
    """Starts a process of its own (its pid written to the file named by
    ``IBENCH_TEST_CHILD_PID``), then hangs without using CPU."""
    name = "test-spawns-and-hangs"
    description = "deliberately broken (tests only)"

    def solve(self, system, **kw):
        child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
        with open(os.environ["IBENCH_TEST_CHILD_PID"], "w") as f:
            f.write(str(child.pid))
        while True:
            time.sleep(0.05)


@pytest.fixture
def spawns_and_hangs():
    registry.register(SpawnsAndHangs, origin="tests")
    yield SpawnsAndHangs
    registry.unregister(SpawnsAndHangs.name)


def alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie, dead but not yet reaped, does not)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def test_a_case_that_hangs_ends_with_what_it_started(spawns_and_hangs, tmp_path, monkeypatch,
                                                     run_cases):
    """A case that started a process and then hangs without using CPU is killed
    once its wall time passed its budget and it used no CPU for a second
    (``timeout``), and the process it started ends with it: each worker is a
    process group of its own, killed as a whole."""
    pid_file = tmp_path / "child.pid"
    monkeypatch.setenv("IBENCH_TEST_CHILD_PID", str(pid_file))
    case, = expand(problems=[SMALL], integrators=["test-spawns-and-hangs"], rtols=[1e-3])
    df = run_cases([case], RunContext(jobs=1, progress=False, limits=Limits(budget_s=1.0)))
    assert df.status.iloc[0] == CaseStatus.TIMEOUT and "hung" in df.message.iloc[0]
    child = int(pid_file.read_text())
    assert not alive(child)
