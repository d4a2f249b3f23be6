"""The ``ibench`` command line (the contract of its names and options: README.md).

    ibench list {problems,integrators,formulations} [--json]
    ibench run [--preset quick|seeds|full] [-p PROBLEM ...] [-f FORMULATION ...]
               [-i INTEGRATOR ...] [--rtol R ...] [--h H ...]
               [--jobs N | --dask tcp://HOST:PORT|local:N] [--timeout SECONDS]
               [--memory MB] [--repeat N] [--store PATH] [--resume] [--no-skip] [--json]
    ibench report [--store PATH] [--out DIR] [--all] [--error final|max|rms] [--target E]
    ibench reference [-p PROBLEM ...] [--check | --recompute | --unit-costs]
                     [--reference-timeout SECONDS] [--json]
    ibench verify [-i INTEGRATOR ...] [--json]
    ibench stiffness -p PROBLEM [--at T ...] [--store PATH] [--out DIR]
                     [--reference-timeout SECONDS] [--json]
    ibench check-plugin NAME [--timeout SECONDS] [--memory MB] [--json]
    ibench advise -p PROBLEM --target E [--error max|final|rms] [-i INTEGRATOR ...]
                  [-f FORMULATION ...] [--budget DURATION] [--perturbed N]
                  [--jobs N | --dask ADDRESS] [--store PATH] [--[no-]resume] [--json] [--out DIR]

The presets are :data:`integrator_bench.harness.matrix.cases.PRESETS` (the ``seeds``
preset's cases: :func:`integrator_bench.harness.sources.numbers.listed_cases`). An option that
takes several values (``-p``, ``-f``, ``-i``, ``--rtol``, ``--h``, ``--at``)
accumulates them over repeats (``--rtol 1e-6 --rtol 1e-8`` runs both); an
option of one value given twice is refused. Every option has a help line
(``ibench COMMAND --help``). A bad name or value exits with status 2 and one
line on standard error naming it and the valid choices. Output piped into a
reader that stops early (``| head``) ends quietly with status 0. With ``--json``
standard output carries the command's JSON alone (``args.data_out``, where each
command prints it): anything else written there meanwhile goes to standard error
(:func:`~integrator_bench.harness.run.streams.data_output`).

Each command is a module of this package with ``add_parser(sub)`` (its options)
and ``command(args)`` (what it does, returning the exit status); :data:`COMMANDS`
lists them in the order ``ibench --help`` shows them. What several commands
share (the one-line errors, the checked types, ``--error``) is in :mod:`.options`,
the end-of-run summary in :mod:`.summary`.
"""

from __future__ import annotations

import contextlib
import errno
import importlib
import os
import signal
import sys
import threading

from integrator_bench.harness.cli.options import EXIT_BAD_INPUT, Parser, discard_stdout

#: command -> the module of this package that holds it
COMMANDS = {"list": "listing", "run": "run", "report": "report", "check-plugin": "check_plugin",
            "reference": "reference", "stiffness": "stiffness", "advise": "advise",
            "verify": "verify"}


def _module(command: str):
    return importlib.import_module(f"{__name__}.{COMMANDS[command]}")


def build_parser() -> Parser:
    """The parser of ``ibench`` and every command's."""
    parser = Parser(prog="ibench", description="Benchmark ODE/DAE integrators on mechanical systems.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for command in COMMANDS:
        _module(command).add_parser(sub)
    return parser


def main(argv=None) -> int:
    """Run ``ibench`` with ``argv`` (default: the process's); the exit status."""
    from integrator_bench.harness.errors import BadInput, StoreError
    from integrator_bench.harness.matrix import registry

    from integrator_bench.harness.run.streams import data_output
    from integrator_bench.problems.fmu import extraction_folder

    args = build_parser().parse_args(argv)
    args.argv = ["ibench", *(sys.argv[1:] if argv is None else argv)]
    try:
        with extraction_folder(), _interruptions() as caught:
            try:
                # --json: standard output carries the data alone (args.data_out), all
                # else written there (an FMU's log lines, a library's) goes to stderr
                with data_output(bool(getattr(args, "json", False))) as args.data_out:
                    status = _module(args.command).command(args)
                sys.stdout.flush()  # a reader that went away shows here, not at exit
            except KeyboardInterrupt:
                status = EXIT_INTERRUPTED
                print("ibench: interrupted", file=sys.stderr)
            else:
                if caught and status != EXIT_INTERRUPTED:  # swallowed where it arrived
                    print("ibench: interrupted", file=sys.stderr)
                    status = EXIT_INTERRUPTED
        return EXIT_TERMINATED if signal.SIGTERM in caught else status
    except (BadInput, registry.UnknownName, StoreError) as exc:
        print(f"ibench: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except BrokenPipeError:  # `ibench ... | head`: the reader has what it wanted
        discard_stdout()
        return 0
    except OSError as exc:
        if exc.errno not in UNWRITABLE:
            raise
        print(f"ibench: error: cannot write {exc.filename or 'a file'}: "
              f"{exc.strerror or exc}", file=sys.stderr)
        return EXIT_BAD_INPUT


#: what a write to a full disk, a read-only file system or a directory without the
#: right to write raises: one line naming the path, exit 2 (atomic writes leave no
#: partial file, :func:`~integrator_bench.harness.paths.write_atomically`)
UNWRITABLE = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM)


#: the exit status of a command stopped by Ctrl-C (128 + SIGINT), and by SIGTERM
EXIT_INTERRUPTED, EXIT_TERMINATED = 128 + signal.SIGINT, 128 + signal.SIGTERM


@contextlib.contextmanager
def _interruptions():
    """Ctrl-C and SIGTERM end the command with one line, whatever it was doing.

    Ctrl-C raises KeyboardInterrupt (as Python's own handler does) and is noted;
    SIGTERM is handled as Ctrl-C by this process (by whatever SIGINT handler is in
    place: a run finishes its cases in flight as it stops, any other command
    raises KeyboardInterrupt), so the command ends with its one line and removes
    what it made. A KeyboardInterrupt that lands where Python can only ignore it
    (a weakref callback, a ``__del__``) is not printed; the command then ends
    with status 130 all the same. Yields the list of the signals caught. A
    process forked meanwhile (a case's worker) ends on SIGTERM as by default."""
    caught: list = []
    me = os.getpid()

    def on_int(signum, frame):
        caught.append(signum)
        raise KeyboardInterrupt

    def on_term(signum, frame):
        if os.getpid() != me:   # a forked worker: end as by default
            signal.signal(signum, signal.SIG_DFL)
            os.kill(os.getpid(), signum)
            return
        caught.append(signum)
        handler = signal.getsignal(signal.SIGINT)
        if callable(handler) and handler is not on_int:
            handler(signal.SIGINT, frame)   # the run's: stop after the cases in flight
        else:
            raise KeyboardInterrupt

    def unraisable(hook_args):
        if not issubclass(hook_args.exc_type, KeyboardInterrupt):
            hook(hook_args)

    if threading.current_thread() is not threading.main_thread():
        yield caught
        return
    hook, sys.unraisablehook = sys.unraisablehook, unraisable
    previous = {signum: signal.signal(signum, handler)
                for signum, handler in ((signal.SIGINT, on_int), (signal.SIGTERM, on_term))}
    try:
        yield caught
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        sys.unraisablehook = hook
