"""One function of no argument in a forked process, within a budget: the one way the
harness runs a model's code (or any code it does not trust) outside the command's own
process, apart from a case's worker.

:func:`calls` runs its functions one after the other in a forked process, as a case
runs in its :class:`~integrator_bench.harness.run.isolation.Worker`, with the same
budget (:class:`~integrator_bench.harness.forking.budget.Watch`: ``timeout`` CPU
seconds and its backstops), memory cap (``memory_mb``, RLIMIT_AS) and fault
statuses. A function that raises, crashes (a segfault in an FMU) or hangs there
becomes a :class:`~integrator_bench.harness.errors.ModelFault` whose ``status`` is
``error``, ``crashed`` or ``timeout`` and whose message says what happened while
what (``the model crashed (SIGSEGV) while its reference was computed``); the
calls after it run in a new process.

The process ignores Ctrl-C and has a process group of its own: Ctrl-C and SIGTERM
stop the command (its wait polls every
:data:`~integrator_bench.harness.forking.budget.POLL_S` seconds), which kills the
process and whatever it started (it is their reaper,
:func:`~integrator_bench.harness.forking.become_subreaper`); it dies with the
command (``PR_SET_PDEATHSIG``). Its standard output and error are the command's. Only
the calls' results come back, by pickle. Its users: the references, the
fingerprint probe and the stiffness analyses
(:mod:`~integrator_bench.harness.run.model_calls`), a problem plugin's or an FMU's
trial build (:mod:`~integrator_bench.harness.matrix.builds`), and each line of
``ibench check-plugin``.
"""

from __future__ import annotations

import contextlib
import faulthandler
import functools
import gc
import os
import signal
from collections.abc import Callable, Sequence

from integrator_bench.harness.errors import ModelFault
from integrator_bench.harness.forking import (become_subreaper, die_with_parent, flush_output,
                                             fork, kill_adopted, kill_descendants, mark_isolated,
                                             wait_exit)
from integrator_bench.harness.forking.budget import DEFAULT_MEMORY_MB, POLL_S, Watch, limit_memory
from integrator_bench.harness.matrix.record import CaseStatus

#: the first line of a model's exception that a fault's message quotes, at most
EXCEPTION_CHARS = 300


def call(fn: Callable, what: str, timeout: float | None = None,
         memory_mb: float | None = DEFAULT_MEMORY_MB, expected: tuple = (),
         stop: Callable[[], bool] | None = None, who: str = "the model"):
    """``fn()`` in a forked process (:func:`calls`): its value, or the exception
    it raised when of a type in ``expected``, else a
    :class:`~integrator_bench.harness.errors.ModelFault`."""
    [out] = calls([fn], what, timeout, memory_mb, expected, stop, who)
    if isinstance(out, BaseException):
        raise out
    return out


def calls(fns: Sequence[Callable], what: str | Sequence[str], timeout: float | None = None,
          memory_mb: float | None = DEFAULT_MEMORY_MB, expected: tuple = (),
          stop: Callable[[], bool] | None = None, who: str = "the model") -> list:
    """``[fn() for fn in fns]``, run one after the other in a forked process
    (one fork for them all; replaced after a fault).

    Parameters
    ----------
    fns : sequence of callables
        Functions of no argument; each result must pickle.
    what : str or sequence of str
        What each call does, for a fault's message ("its reference was computed").
    timeout : float, optional
        Each call's budget in CPU seconds of its process, with the backstops of a
        case's (:meth:`~integrator_bench.harness.forking.budget.Watch.past`);
        None: no budget.
    memory_mb : float, optional
        Address space the process may add to what it inherits (None: no limit).
    expected : tuple of exception types
        Exceptions a call may raise that are given back as they are (a
        :class:`~integrator_bench.harness.errors.ReferenceFailure`, say).
    stop : callable, optional
        Polled while a call runs: once it returns True the process is killed
        and the call's place holds a ModelFault of status ``interrupted``.
    who : str
        Who a fault's message says failed (``the model crashed (SIGSEGV) while ...``).

    Returns
    -------
    list
        Per call its value, its exception of ``expected``, or a ModelFault.
    """
    whats = [what] * len(fns) if isinstance(what, str) else list(what)
    results: list = []
    while len(results) < len(fns):
        conn, pid = fork(functools.partial(_serve, fns, len(results), os.getpid(), memory_mb))
        try:
            while len(results) < len(fns):
                i = len(results)
                why = _wait(conn, Watch(pid), timeout, stop)
                if why is None:
                    try:
                        ok, value = conn.recv()
                    except (EOFError, OSError):   # died without a result
                        results.append(ModelFault(f"{who} {_death(pid)} while {whats[i]}",
                                                  CaseStatus.CRASHED.value))
                        break
                    results.append(value if ok or isinstance(value, expected)
                                   else _raised(value, whats[i], who))
                    continue
                if why == "stop":
                    results.append(ModelFault(f"interrupted while {whats[i]}", "interrupted"))
                else:
                    results.append(ModelFault(f"{who} gave no result while {whats[i]}: "
                                              f"{why}; killed", CaseStatus.TIMEOUT.value))
                break
        finally:
            _end(conn, pid)
        if results and getattr(results[-1], "status", None) == "interrupted":
            results += [ModelFault(f"interrupted before {w}", "interrupted")
                        for w in whats[len(results):]]
    return results


def _serve(fns, first: int, parent: int, memory_mb, conn) -> None:
    """The forked process: isolated as a case's worker is (inherited objects frozen,
    its own process group, Ctrl-C left to the parent, no fault dump, death with
    the parent, memory capped), it runs
    ``fns[first:]`` in turn and sends ``(True, value)`` or ``(False, exception)``
    for each."""
    gc.freeze()   # the inherited objects never traversed here: their pages stay shared
    mark_isolated()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.setpgid(0, 0)
    become_subreaper()
    faulthandler.disable()
    die_with_parent(parent)
    limit_memory(memory_mb)
    for fn in fns[first:]:
        try:
            out = (True, fn())
        except BaseException as exc:  # the parent says what it was
            out = (False, exc)
        flush_output()
        try:
            conn.send(out)
        except Exception as exc:  # noqa: BLE001  a result or exception that does not pickle
            conn.send((False, RuntimeError(f"{type(exc).__name__}: {exc}")))


def _wait(conn, watch: Watch, timeout, stop) -> str | None:
    """Wait for the call's result: None once it (or the end of the pipe) is
    there, ``"stop"`` when ``stop()`` says so, else why its budget is over."""
    while not conn.poll(POLL_S):
        if stop is not None and stop():
            return "stop"
        if timeout is not None:
            why = watch.past(timeout)
            if why:
                return why
    return None


def _raised(exc: BaseException, what: str, who: str) -> ModelFault:
    """The fault of a call whose model raised ``exc``."""
    text = str(exc).strip().splitlines()
    said = f"{type(exc).__name__}: {text[0][:EXCEPTION_CHARS]}" if text else type(exc).__name__
    return ModelFault(f"{who} raised {said} while {what}", CaseStatus.ERROR.value)


def _death(pid: int) -> str:
    """How the process ``pid`` that closed its pipe without a result ended
    (``crashed (SIGSEGV)``), once it has exited (waited up to 5 s; left unreaped
    for :func:`_end`)."""
    wait_exit(pid, 5.0)
    try:
        info = os.waitid(os.P_PID, pid, os.WEXITED | os.WNOHANG | os.WNOWAIT)
    except ChildProcessError:
        info = None
    if info is None:
        return "closed its pipe without a result"
    if info.si_code == os.CLD_EXITED:
        return f"exited with status {info.si_status} without a result"
    try:
        return f"crashed ({signal.Signals(info.si_status).name})"
    except ValueError:
        return f"crashed (signal {info.si_status})"


def _end(conn, pid: int) -> None:
    """Kill the process and what the model started (its group, and whatever below it
    detached itself), reap it, close the pipe."""
    kill_descendants(pid)
    for kill in (os.killpg, os.kill):
        with contextlib.suppress(ProcessLookupError, PermissionError):
            kill(pid, signal.SIGKILL)
    with contextlib.suppress(ChildProcessError):
        os.waitpid(pid, 0)
    kill_adopted(pid)   # what it left when it died (a crash) came here: killed
    conn.close()
