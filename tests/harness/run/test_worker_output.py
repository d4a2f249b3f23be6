"""What a case writes to its standard output and error: captured by its worker at the
file-descriptor level, summarized in the record's message, never on the terminal."""

import ctypes
import os
import signal
import time

import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.run.isolation import output_summary, run_isolated
from integrator_bench.harness.run.limits import Limits
from integrator_bench.integrators.base import Integrator
from integrator_bench.harness.run.context import RunContext

SMALL = "two_mass:c2=1000"


def _chatter():
    """Write as a C library does: through C's buffered stdout (not flushed here) and
    straight onto file descriptor 2, bypassing Python's streams."""
    libc = ctypes.CDLL(None)
    libc.printf(b"[WARNING] chatty C line\n")
    for _ in range(2):
        os.write(2, b"chatty stderr line\n")


class _Chatty(Integrator):
    """scipy-RK45's solution, after writing like a C library (tests only)."""
    name = "test-chatty"
    description = "writes to stdout and stderr from C (tests only)"
    accepts = frozenset({"ode"})

    def solve(self, system, **kw):
        _chatter()
        return registry.get_integrator("scipy-RK45")().solve(system, **kw)


class _ChattyCrash(_Chatty):
    name = "test-chatty-crash"

    def solve(self, system, **kw):
        os.write(2, b"last words\n")
        os.kill(os.getpid(), signal.SIGKILL)


class _ChattyHang(_Chatty):
    name = "test-chatty-hang"

    def solve(self, system, **kw):
        os.write(1, b"still thinking\n")
        time.sleep(30)


@pytest.fixture
def chatty():
    classes = (_Chatty, _ChattyCrash, _ChattyHang)
    for cls in classes:
        registry.register(cls, origin="tests")
    yield
    for cls in classes:
        registry.unregister(cls.name)


@pytest.mark.parametrize("integrator, status, said", [
    ("test-chatty", "ok", ["[WARNING] chatty C line (x1)", "chatty stderr line (x2)"]),
    ("test-chatty-crash", "crashed", ["SIGKILL", "output: last words (x1)"]),
    ("test-chatty-hang", "timeout", ["output: still thinking (x1)"]),
])
def test_worker_output_goes_into_the_message_not_onto_the_terminal(chatty, capfd, integrator,
                                                                   status, said, run_cases):
    cases = expand(problems=[SMALL], integrators=[integrator], rtols=[1e-3])
    df = run_cases(cases,
                   RunContext(jobs=1, progress=False,
                              limits=Limits(budget_s=1 if status == "timeout" else 60)))
    record = df.iloc[0]
    assert record.status == status, record.message
    for text in said:
        assert text in record.message, record.message
    out, err = capfd.readouterr()
    for text in ("chatty", "last words", "still thinking"):
        assert text not in out and text not in err


def test_a_dask_task_captures_the_output_too(chatty, capfd):
    """:func:`run_isolated`, what each Dask task runs, goes through the same worker."""
    case = expand(problems=[SMALL], integrators=["test-chatty"], rtols=[1e-3])[0]
    record = run_isolated(case, limits=Limits(budget_s=60))
    assert record["status"] == "ok"
    assert record["message"].startswith("output: chatty stderr line (x2); [WARNING] chatty C")
    out, err = capfd.readouterr()
    assert "chatty" not in out + err


def test_output_summary_counts_lines_and_names_the_most_frequent():
    data = b"a\n\nb\na\n  c  \nd\ne\n" + bytes([0xff]) + b"\n"
    assert output_summary(data) == "output: a (x2); b (x1); c (x1); 3 other kinds"
    assert output_summary(b"") is None and output_summary(b"\n \n") is None


def test_work_in_the_calling_process_writes_its_output_to_stderr(capfd):
    """A reference computed before a run (C solvers' messages) keeps standard
    output, the JSON records' stream, clean."""
    from integrator_bench.harness.run.streams import stdout_to_stderr

    with stdout_to_stderr():
        _chatter()
        print("from python")
    print("after")
    out, err = capfd.readouterr()
    assert out == "after\n"
    assert "[WARNING] chatty C line" in err and "from python" in err


def test_each_workers_captured_output_is_closed(chatty, run_cases):
    """No file descriptor is left open per case (a long run would exhaust them)."""
    cases = expand(problems=[SMALL], integrators=["test-chatty", "test-chatty-crash",
                                                  "test-chatty-hang"], rtols=[1e-3])
    before = len(os.listdir("/proc/self/fd"))
    df = run_cases(cases, RunContext(jobs=2, progress=False, limits=Limits(budget_s=5)))
    assert sorted(df.status) == ["crashed", "ok", "timeout"]
    assert len(os.listdir("/proc/self/fd")) == before
