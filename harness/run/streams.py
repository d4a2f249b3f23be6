"""Standard output and error at the file-descriptor level, where C libraries
(SUNDIALS' ``[WARNING]`` lines, a Fortran code's ``EXIT OF RADAU5``) write
them, bypassing Python's streams."""

from __future__ import annotations

import contextlib
import os
import sys

from integrator_bench.harness.forking import flush_output  # noqa: F401  (its users import it here too)


@contextlib.contextmanager
def redirected(targets: dict[int, int]):
    """Point each file descriptor ``fd`` of ``targets`` (1, 2) at the open
    descriptor ``targets[fd]`` inside the block, flushing the buffered streams
    on the way in and out so that nothing written inside lands outside."""
    flush_output()
    saved = {fd: os.dup(fd) for fd in targets}
    try:
        for fd, target in targets.items():
            os.dup2(target, fd)
        yield
    finally:
        flush_output()
        for fd, old in saved.items():
            os.dup2(old, fd)
            os.close(old)


@contextlib.contextmanager
def stdout_to_stderr():
    """Send what is written to standard output inside the block, at the
    file-descriptor level (a C library's own messages too), to standard error.

    For work done in the calling process, not in a worker (computing a missing
    reference before a run): its diagnostics reach the user but never the data
    on standard output (``ibench run --json``'s records).
    """
    with redirected({1: 2}), contextlib.redirect_stdout(sys.stderr):  # a replaced sys.stdout too
        yield


@contextlib.contextmanager
def silenced():
    """Discard what is written to standard output and error inside the block,
    at the file-descriptor level: the timed re-solves of a case repeat what its
    counted solve has already said (:mod:`integrator_bench.harness.run.execution`)."""
    with open(os.devnull, "w") as null, redirected({1: null.fileno(), 2: null.fileno()}), \
            contextlib.redirect_stdout(null), contextlib.redirect_stderr(null):
        yield


@contextlib.contextmanager
def data_output(enabled: bool = True):
    """Standard output kept for a command's data (``--json``): yields the stream
    the data goes to, where standard output pointed, while everything else
    written to standard output inside the block -- a ``print``, an FMU's log
    lines, a C library's own messages at the file-descriptor level, in this
    process and in the processes it forks -- goes to standard error
    (:func:`stdout_to_stderr`). Without ``enabled``, yields ``sys.stdout`` and
    redirects nothing.

    The data stream is a line-buffered copy of standard output's file
    descriptor (a stream without one, a test's capture, is used as it is).
    A reader that went away (``| head``) shows as ``BrokenPipeError`` where a
    line is written; what is left unwritten then is dropped on the way out.
    """
    if not enabled:
        yield sys.stdout
        return
    stdout = sys.stdout
    try:
        fd = stdout.fileno()
    except (AttributeError, ValueError, OSError):  # replaced by a stream of Python's only
        fd = None
    flush_output()
    data = stdout if fd is None else os.fdopen(
        os.dup(fd), "w", buffering=1, encoding=getattr(stdout, "encoding", None) or "utf-8",
        errors=getattr(stdout, "errors", None) or "strict")
    try:
        with stdout_to_stderr():
            yield data
    finally:
        if data is not stdout:
            try:
                data.close()
            except BrokenPipeError:  # closed all the same; the reader has what it wanted
                pass
