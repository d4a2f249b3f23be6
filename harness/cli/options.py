"""What every command's parser shares: one-line errors with exit 2, the checked
value types, an option that may be given once, and the help texts and options
several commands repeat."""

from __future__ import annotations

import argparse
import math
import os
import re
import sys

EXIT_BAD_INPUT = 2
JSON_HELP = "print JSON instead of a table"


# a negative number in any notation: argparse's own pattern misses -1e-3
_NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


class Parser(argparse.ArgumentParser):
    """Errors in one line with exit status 2; a negative number (``--rtol -1e-3``)
    is read as a value, so its check names it, never as an unknown option."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NEGATIVE_NUMBER

    def error(self, message):  # one line, exit 2
        self.exit(EXIT_BAD_INPUT, f"ibench: error: {message}\n")


def finite_float(name, positive=True, below=None):
    """An argparse type: a finite float, positive unless ``positive`` is False,
    and less than ``below`` when given (``--rtol``: below 1, where a relative
    tolerance stops asking for any correct digit)."""
    what = "a positive finite number" if positive else "a finite number"
    if below is not None:
        what = f"{what} below {below:g}"

    def parse(text):
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} {text!r} is not a number") from None
        if not (math.isfinite(value) and (value > 0 or not positive)
                and (below is None or value < below)):
            raise argparse.ArgumentTypeError(f"{name} {text!r} must be {what}")
        return value
    return parse


def positive_int(text, name="--jobs", least=1):
    """An argparse value: a whole number of at least ``least``."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name} {text!r} is not a whole number") from None
    if value < least:
        raise argparse.ArgumentTypeError(f"{name} {text!r} must be at least {least}")
    return value


def memory(text):
    if text.lower() in ("none", "unlimited"):
        return None
    return finite_float("--memory")(text)


class Once(argparse.Action):
    """Store the option's value; the option given a second time is an error (exit 2)
    rather than a silent choice of the last value."""

    def __call__(self, parser, namespace, values, option_string=None):
        given = namespace.__dict__.setdefault("_given_once", set())
        if self.dest in given:
            parser.error(f"{option_string} given twice ({shown(getattr(namespace, self.dest))} "
                         f"and {shown(values)}); give it once")
        given.add(self.dest)
        setattr(namespace, self.dest, values)


def shown(value) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)




def usable_directory(path, option: str = "--out"):
    """``path`` when it can be the output directory (an existing writable
    directory, or one that can be made: its nearest existing ancestor is a
    writable directory); BadInput naming it otherwise, before any work is done
    and without making it."""
    from pathlib import Path

    from integrator_bench.harness.errors import BadInput

    path = Path(path)
    nearest = path.absolute()
    while not nearest.exists() and nearest != nearest.parent:
        nearest = nearest.parent
    if nearest.exists() and not nearest.is_dir():
        what = ("is an existing file" if nearest == path.absolute()
                else f"lies under the file {str(nearest)!r}")
        raise BadInput(f"{option} {str(path)!r} {what}, not a directory; name a directory")
    if not os.access(nearest, os.W_OK | os.X_OK):
        raise BadInput(f"{option} {str(path)!r}: the directory {str(nearest)!r} is not writable")
    return path


def error_option() -> dict:
    """``--error``'s arguments, the same for ``run`` and ``report``."""
    from integrator_bench.harness.ranking.reach import DEFAULT_ERROR, ERRORS

    return dict(
        choices=sorted(ERRORS), default=DEFAULT_ERROR, action=Once,
        help="the error lines are ranked by: the largest mixed error |y - r| / (floor + |r|) "
             "of the error components at the final time (final), over the output times (max), "
             "or its root-mean-square over them (rms); floor: the problem's absolute scale "
             f"(default: {DEFAULT_ERROR})")


def cost_option() -> dict:
    """``--cost``'s arguments, the same for ``report`` and ``advise``."""
    from integrator_bench.harness.ranking.cost import COSTS, DEFAULT_COST

    return dict(
        choices=list(COSTS), default=DEFAULT_COST, action=Once,
        help="what lines are ranked by: the CPU of the solve here (cpu), or the method's work, "
             "its counted evaluations, factorizations and solves times the problem's unit "
             "costs (work; records without one are not ranked) "
             f"(default: {DEFAULT_COST})")


def store_help() -> str:
    from integrator_bench.harness.matrix.store import DEFAULT_STORE

    return f"the SQLite store of the records (default: {DEFAULT_STORE})"


def json_default(value):
    if hasattr(value, "item"):
        return value.item()
    raise TypeError(type(value))




def discard_stdout() -> None:
    """Point standard output at /dev/null, so the interpreter's last flush of
    what is still buffered for a closed pipe raises nothing."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)


def built(pspecs, what: str) -> tuple[list, int]:
    """``(the problems of pspecs that built, how many did not)``, one from outside
    the project as the stand-in of its build in a process of its own
    (:mod:`~integrator_bench.harness.matrix.builds`): one whose build raised,
    crashed or hung there is one line on standard error, ``ibench: no WHAT for
    SPEC: the fault``, and the others go on."""
    from integrator_bench.harness.errors import ModelFault

    problems, failed = [], 0
    for pspec in pspecs:
        try:
            problems.append(pspec.build())
        except ModelFault as exc:
            failed += 1
            print(f"ibench: no {what} for {pspec.text}: {exc}", file=sys.stderr, flush=True)
    return problems, failed
