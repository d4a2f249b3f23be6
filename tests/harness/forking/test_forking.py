"""Forked processes (:mod:`integrator_bench.harness.forking`): the one parallel
map of the package (references side by side, a report's pages), what it does when a
call fails, a process dies, or Ctrl-C comes."""

from __future__ import annotations

import functools
import os
import signal
import subprocess
import sys
import time

import pytest

from integrator_bench.harness.forking import in_parallel


def _started(path, name, result):
    """A call of the ordering test: note its start in ``path``, then answer."""
    with open(path, "a", encoding="utf-8") as f:
        f.write(f"{name} {os.getpid()}\n")
    time.sleep(0.3)     # the other process takes the next call meanwhile
    return result


def test_results_come_in_the_order_of_the_calls_from_at_most_jobs_processes():
    pids = in_parallel([os.getpid] * 5, jobs=2)
    assert 1 <= len(set(pids)) <= 2 and os.getpid() not in pids
    assert in_parallel([lambda k=k: k * k for k in range(5)], jobs=2) == [0, 1, 4, 9, 16]


def test_one_job_or_one_call_runs_here():
    assert in_parallel([os.getpid] * 2, jobs=1) == [os.getpid()] * 2
    assert in_parallel([os.getpid], jobs=2) == [os.getpid()]
    assert in_parallel([], jobs=None) == []


def test_the_costliest_are_started_first(tmp_path):
    log = tmp_path / "log"
    calls = [functools.partial(_started, log, name, name * 2) for name in "abcd"]
    got = in_parallel(calls, jobs=2, cost=[1, 5, 2, 9])
    assert got == ["aa", "bb", "cc", "dd"]
    started = [line.split() for line in log.read_text().splitlines()]
    assert {name for name, _ in started[:2]} == {"d", "b"}   # the two costliest
    assert {name for name, _ in started[2:]} == {"c", "a"}
    assert str(os.getpid()) not in {pid for _, pid in started}


def test_a_calls_exception_is_raised_here():
    with pytest.raises(ZeroDivisionError):
        in_parallel([lambda: 1, lambda: 1 / 0], jobs=2)


@pytest.mark.parametrize("die", [lambda: os._exit(3),
                                 lambda: os.kill(os.getpid(), signal.SIGKILL)],
                         ids=["exit", "sigkill"])
def test_a_process_that_dies_raises_at_once_and_never_hangs(die):
    """A process that dies without its result (killed, ``os._exit``) is an error
    raised here as soon as it dies: ``multiprocessing.Pool``, which the report
    used before, waits for such a result for ever."""
    start = time.monotonic()
    with pytest.raises(RuntimeError, match="died without a result"):
        in_parallel([lambda: 1, die, lambda: 2], jobs=2)
    assert time.monotonic() - start < 30


_SLOW_CALLS = """
import os, signal, sys, time
signal.signal(signal.SIGINT, signal.default_int_handler)  # as in a terminal
from integrator_bench.harness.forking import in_parallel

def call():
    with open(sys.argv[1], "a") as f:
        f.write(f"{os.getpid()}\\n")
    time.sleep(120)

in_parallel([call, call, call], jobs=2)
"""


def test_ctrl_c_leaves_no_process(tmp_path):
    """Ctrl-C (SIGINT to the whole process group, as a terminal sends it) ends the
    map at once: its processes ignore it and are killed by it."""
    pids = tmp_path / "pids"
    proc = subprocess.Popen([sys.executable, "-c", _SLOW_CALLS, str(pids)],
                            start_new_session=True, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    while (not pids.exists() or len(pids.read_text().split()) < 2) and \
            time.monotonic() < deadline:
        time.sleep(0.05)
    workers = [int(p) for p in pids.read_text().split()]
    os.killpg(proc.pid, signal.SIGINT)
    proc.communicate(timeout=30)
    assert proc.returncode != 0
    for pid in workers:
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)
