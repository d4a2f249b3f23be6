"""A model's code called outside the command's process (harness/forking/child.py):
a model that raises, crashes or hangs becomes a fault of its own call, with the
status a case would have, and the calls after it still run."""

from __future__ import annotations

import ctypes
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from integrator_bench.harness.errors import ModelFault, ReferenceFailure
from integrator_bench.harness.forking import child as model_calls
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits


def _segfault():
    ctypes.string_at(0)


def _raise():
    raise ValueError("operands could not be broadcast together with shapes (3,) (2,)\nline 2")


def _spin():
    while True:
        pass


def _sleep():
    time.sleep(3600)


def _expected():
    raise ReferenceFailure("no reference")


def test_each_fault_is_its_calls_own_and_the_others_run():
    out = model_calls.calls([lambda: 1, _segfault, lambda: 2, _raise, _expected, _spin,
                             _sleep, lambda: 3], "its reference was computed", timeout=0.5,
                            expected=(ReferenceFailure,))
    assert out[0] == 1 and out[2] == 2 and out[7] == 3
    assert isinstance(out[1], ModelFault) and out[1].status == "crashed"
    assert str(out[1]) == "the model crashed (SIGSEGV) while its reference was computed"
    assert out[3].status == "error" and str(out[3]) == (
        "the model raised ValueError: operands could not be broadcast together with shapes "
        "(3,) (2,) while its reference was computed")
    assert isinstance(out[4], ReferenceFailure) and str(out[4]) == "no reference"
    for hung in out[5:7]:
        assert hung.status == "timeout" and "no result" in str(hung) and "killed" in str(hung)


def test_call_raises_the_fault_and_a_fault_pickles():
    with pytest.raises(ModelFault, match="crashed"):
        model_calls.call(_segfault, "x")
    import pickle
    fault = pickle.loads(pickle.dumps(ModelFault("m", "timeout")))
    assert fault.status == "timeout" and str(fault) == "m"


def test_a_stop_kills_the_call_at_once():
    started = time.monotonic()
    [out] = model_calls.calls([_spin], "x", stop=lambda: time.monotonic() - started > 0.3)
    assert out.status == "interrupted" and time.monotonic() - started < 2


def test_the_memory_cap_holds_in_the_calls_process():
    import numpy as np
    out = model_calls.calls([lambda: np.ones(2**28).sum()], "x", memory_mb=100)
    assert isinstance(out[0], ModelFault) and "MemoryError" in str(out[0])


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_the_command_answers_a_signal_within_a_second_and_leaves_no_process(tmp_path, signum):
    """A hanging model's call stops on Ctrl-C or SIGTERM at once: the process running
    it, and a child it started in a session of its own (out of its process group),
    are gone."""
    pidfile = tmp_path / "child"
    script = textwrap.dedent(f"""
        import subprocess, sys, time
        from integrator_bench.harness.cli import _interruptions
        from integrator_bench.harness.forking import child as model_calls

        def hang():
            child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"],
                                     start_new_session=True)
            open({str(pidfile)!r}, "w").write(str(child.pid))
            while True:
                pass

        with _interruptions():
            try:
                model_calls.call(hang, "x")
            except KeyboardInterrupt:
                print("interrupted", flush=True)
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    end = time.monotonic() + 30
    while not pidfile.exists() or not pidfile.read_text():
        assert time.monotonic() < end
        time.sleep(0.05)
    child = int(pidfile.read_text())
    sent = time.monotonic()
    proc.send_signal(signum)
    out, _ = proc.communicate(timeout=10)
    assert time.monotonic() - sent < 1.5 and "interrupted" in out
    time.sleep(0.2)
    assert not alive(child)


def alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie no one reaped yet does not)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return f.read().rsplit(b")", 1)[1].split()[0] != b"Z"
    except OSError:
        return False


def _detach(pidfile) -> None:
    """Start a child in a session of its own, its pid written to ``pidfile``."""
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"],
                             start_new_session=True)
    pidfile.write_text(str(child.pid))


def _detach_then_segfault(pidfile):
    """Start a child in a session of its own, then crash."""
    _detach(pidfile)
    ctypes.string_at(0)


def test_a_crashed_calls_child_in_a_session_of_its_own_is_killed(tmp_path):
    """A model's call that starts a detached child and segfaults: its fault is
    ``crashed``, and the child, orphaned when the call's process died, is killed
    here (this process is their reaper), not left to init."""
    import functools

    pidfile = tmp_path / "child"
    [out] = model_calls.calls([functools.partial(_detach_then_segfault, pidfile)], "x")
    assert out.status == "crashed"
    time.sleep(0.2)
    assert not alive(int(pidfile.read_text()))


@pytest.mark.parametrize("fault, status", [("hang", "timeout"), ("crash", "crashed")])
def test_a_cases_child_in_a_session_of_its_own_is_gone_after_its_case(tmp_path, fault, status,
                                                                      run_cases):
    """An integrator plugin that starts a child in a new session (out of its worker's
    process group), then hangs (killed at its timeout) or crashes its worker
    (SIGSEGV): the child is killed with the worker, which is the reaper of whatever
    its cases leave, or, the worker dead, by the run, which is the reaper of what
    its workers leave."""
    from integrator_bench.harness.matrix import registry
    from integrator_bench.harness.matrix.cases import expand
    from integrator_bench.integrators.base import Integrator

    pidfile = tmp_path / "child"

    class Detaches(Integrator):
        name, description, accepts = "test-detaches", "starts a daemon, then fails", \
            frozenset({"ode"})
        adaptive, order = True, 1

        def solve(self, system, **kw):
            if fault == "crash":
                _detach_then_segfault(pidfile)
            _detach(pidfile)
            time.sleep(600)

    registry.register(Detaches, origin="tests")
    try:
        cases = expand(problems=["two_mass:c2=0.1"], integrators=["test-detaches"],
                       rtols=[1e-3])
        df = run_cases(cases,
                       RunContext(jobs=1, progress=False,
                                  limits=Limits(budget_s=0.5 if fault == "hang" else 30)))
    finally:
        registry.unregister("test-detaches")
    assert list(df["status"]) == [status]
    time.sleep(0.2)
    assert not alive(int(pidfile.read_text()))
