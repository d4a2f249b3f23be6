"""Forked processes: one process per call, a pipe back, nothing shared but what fork copies.

:func:`fork` is the one way this package forks (a case's
:class:`~integrator_bench.harness.run.isolation.Worker`, a reference computed
beside others, a report's page); :func:`in_parallel` maps calls over as many
forked processes as asked, each with a pipe of its own. No lock, queue or
thread is shared with the children (``multiprocessing.Pool`` shares all three; its result waits
forever for a task whose process died, and its ``terminate`` can wait on a
lock an idle process holds): a child that dies is seen at once, by the end of
its pipe, and reaped. What a forked process leaves when it dies comes back to
the process that forked it (a subreaper), which kills it (:func:`kill_adopted`).

Its modules: :mod:`~integrator_bench.harness.forking.budget` (a forked process's
CPU budget and memory cap) and :mod:`~integrator_bench.harness.forking.child`
(a function run in a forked process within them: the one way code the harness
does not trust runs outside a case's worker).
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import select
import signal
import socket
import sys
import time
from multiprocessing.connection import Connection, wait



def flush_output() -> None:
    """Flush Python's and the C library's buffered standard streams (before a
    fork, so that nothing buffered is written twice, and before a forked
    process exits through ``os._exit``, which flushes nothing)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):  # closed or replaced by the case
            pass
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):
        pass


_forked: dict = {}     # pid -> start time of each process fork() made here (the latest)
_reaping = [False]     # whether this process was made a subreaper by fork()


def fork(body) -> tuple:
    """Fork a process that runs ``body(conn)``, ``conn`` its end of a two-way
    pipe (a socket pair, as ``multiprocessing.Pipe`` makes), and exits (status 0
    when ``body`` returned): ``(this end of the pipe, its pid)``.

    The forking process becomes the reaper of what its forked processes leave when
    they die (:func:`become_subreaper`): a crashed worker's detached children come
    here, where :func:`kill_adopted` finds them, not to init."""
    ours, theirs = socket.socketpair()
    for stream in (sys.stdout, sys.stderr):
        stream.flush()  # no buffered output written twice
    if not _reaping[0]:
        become_subreaper()
        _reaping[0] = True
    pid = os.fork()
    if pid == 0:  # the child: never returns
        code = 1
        try:
            ours.close()
            body(Connection(theirs.detach()))
            code = 0
        finally:
            os._exit(code)
    theirs.close()
    _forked[pid] = _stat(pid)[0]
    return Connection(ours.detach()), pid


def _stat(pid: int) -> tuple:
    """``(start time, process group)`` of process ``pid`` from ``/proc/PID/stat``
    (Linux; the start in clock ticks since boot); ``(None, None)`` where it cannot
    be read."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            fields = f.read().rsplit(b")", 1)[1].split()
        return int(fields[19]), int(fields[2])   # fields 22 and 5 of proc(5)
    except (OSError, IndexError, ValueError):
        return None, None


def kill_adopted(pid: int) -> None:
    """Kill and reap what the process ``pid`` (one :func:`fork` made, now dead: a
    case's worker, a model's call) started and left behind when it died (a
    segfault, SIGKILL), adopted by this process because :func:`fork` made it a
    subreaper, however it detached itself (its own session, a double fork): each
    child of this process that :func:`fork` did not make, that is out of this
    process's group and that started after ``pid`` did. What this process started
    itself in its own group (a ``subprocess`` child) is left alone."""
    since, own = _forked.get(pid), os.getpgrp()
    if since is None:
        return
    for child in children(os.getpid()):
        start, group = _stat(child)
        if start is None or _forked.get(child) == start or group == own or start < since:
            continue
        kill_descendants(child)
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.kill(child, signal.SIGKILL)
        with contextlib.suppress(ChildProcessError):
            os.waitpid(child, 0)


_isolated = [False]


def mark_isolated() -> None:
    """Note that this process runs code the harness does not trust within a budget of
    its own (a case's worker, a model's call): what it builds is its own fault
    (:func:`isolated`)."""
    _isolated[0] = True


def isolated() -> bool:
    """Whether this process was marked by :func:`mark_isolated` (a forked process
    inherits the mark of its parent)."""
    return _isolated[0]


def die_with_parent(parent: int) -> None:
    """Have the kernel kill this (forked) process when the thread that forked it
    dies (Linux): a parent killed with SIGKILL leaves no orphan behind."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent:  # the parent died before prctl took effect
        os._exit(1)


def become_subreaper() -> None:
    """Make this process the reaper of every process orphaned below it (Linux
    ``PR_SET_CHILD_SUBREAPER``): a descendant that detached itself (a new session,
    a double fork) stays in this process's tree, where :func:`kill_descendants`
    finds it, rather than joining init's."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(36, 1, 0, 0, 0)  # PR_SET_CHILD_SUBREAPER
    except (OSError, AttributeError):
        pass


def descendants(pid: int) -> list[int]:
    """The processes below ``pid`` (children first), from
    ``/proc/PID/task/TID/children`` (Linux); [] where that cannot be read."""
    found, todo = [], [pid]
    while todo:
        below = children(todo.pop())
        found += below
        todo += below
    return found


def children(pid: int) -> list[int]:
    """The children of process ``pid``, from ``/proc/PID/task/TID/children`` (Linux);
    [] where that cannot be read."""
    try:
        tasks = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return []
    found = []
    for tid in tasks:
        try:
            with open(f"/proc/{pid}/task/{tid}/children", encoding="ascii") as f:
                found += [int(c) for c in f.read().split()]
        except (OSError, ValueError):
            continue
    return found


def kill_descendants(pid: int) -> None:
    """Kill (SIGKILL) every process below ``pid``, whatever its session or group: what
    a forked worker (a :func:`become_subreaper`) started and left, detached or not.
    Twice, for a process forked while the first pass ran."""
    for _ in range(2):
        for child in descendants(pid):
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.kill(child, signal.SIGKILL)


def wait_exit(pid: int, timeout: float) -> None:
    """Wait until process ``pid`` exits or ``timeout`` seconds pass (it stays unreaped).

    Woken by the exit itself through a pidfd (Linux 5.3 and later); elsewhere,
    sleeps 10 ms (the caller polls).
    """
    try:
        fd = os.pidfd_open(pid)
    except (AttributeError, OSError):
        time.sleep(min(timeout, 0.01))
        return
    try:
        select.select([fd], [], [], timeout)
    finally:
        os.close(fd)


def death(exitcode) -> str:
    """How a process that sent no result ended, from its exit code
    (:func:`os.waitstatus_to_exitcode`)."""
    if exitcode is not None and exitcode < 0:
        try:
            return f"worker killed by signal {signal.Signals(-exitcode).name}"
        except ValueError:
            return f"worker killed by signal {-exitcode}"
    return f"worker exited with status {exitcode} without a result"


def in_parallel(calls, jobs: int | None = None, cost=None) -> list:
    """``[call() for call in calls]`` on up to ``jobs`` forked processes, the
    results in the order of ``calls``.

    Parameters
    ----------
    calls : sequence of callables
        Functions of no argument. The processes are forked with ``calls`` and
        everything loaded here, and each serves calls one after the other (what
        a first call loads, its next ones find), so only an index goes out and
        a call's result (or exception) comes back, by pickle: both must pickle.
    jobs : int, optional
        Processes at once; None: one per core. With one job, or one call, the
        calls run here, one after the other, and fork nothing.
    cost : sequence of float, optional
        One number per call: the costliest are started first, so that the
        processes finish together.

    Each process dies with this one (``PR_SET_PDEATHSIG``) and ignores Ctrl-C,
    which stops this one, which kills them: no call is left running. An
    exception a call raises is raised here once it arrives (the processes
    killed); a process that dies without a result raises ``RuntimeError`` as
    soon as it dies.
    """
    jobs = (os.cpu_count() or 1) if jobs is None else jobs
    if jobs <= 1 or len(calls) <= 1:
        return [call() for call in calls]
    pending = sorted(range(len(calls)), key=lambda i: -cost[i]) if cost else list(range(len(calls)))
    results, processes, running = [None] * len(calls), {}, {}   # running: pipe -> index
    parent = os.getpid()
    try:
        for _ in range(min(jobs, len(calls))):
            conn, pid = fork(functools.partial(_serve_calls, calls, parent))
            processes[conn] = pid
            running[conn] = pending.pop(0)
            conn.send(running[conn])
        while running:
            for conn in wait(list(running)):
                i = running.pop(conn)
                try:
                    ok, value = conn.recv()
                except (EOFError, OSError):
                    _, status = os.waitpid(processes.pop(conn), 0)
                    raise RuntimeError(f"a forked process died without a result "
                                       f"({death(os.waitstatus_to_exitcode(status))})") from None
                if not ok:
                    raise value
                results[i] = value
                if pending:
                    running[conn] = pending.pop(0)
                    conn.send(running[conn])
    finally:
        for conn, pid in processes.items():
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            conn.close()
    return results


def _serve_calls(calls, parent: int, conn) -> None:
    """The body of an :func:`in_parallel` process: run ``calls[i]`` for each
    index ``i`` received, send back ``(True, its result)`` or ``(False, the
    exception)``, until the pipe closes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent(parent)
    while True:
        try:
            i = conn.recv()
        except EOFError:
            return
        try:
            out = (True, calls[i]())
        except BaseException as exc:  # sent to the parent, which raises it
            out = (False, exc)
        try:
            conn.send(out)
        except Exception as exc:  # a result or exception that does not pickle
            conn.send((False, RuntimeError(f"{type(exc).__name__}: {exc}")))
        flush_output()
