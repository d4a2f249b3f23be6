"""The project's code version: the git commit, plus ``-dirty`` for local changes."""

from __future__ import annotations

import functools
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STAMP = Path(__file__).resolve().parent / "_commit.txt"  # written into wheels by setup.py


def _git(*args) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True,
                          check=True).stdout.strip()


@functools.lru_cache(maxsize=1)
def code_version() -> str:
    """``<commit>`` or ``<commit>-dirty``; ``unknown`` when it cannot be known.

    From a checkout of the project (``ROOT`` is the top of a git work tree) git
    answers; only tracked files count as changes, so generated results and
    references written by a run do not make the tree dirty. An installed wheel
    (asv installs one per benchmarked commit) carries the commit it was built
    from in ``_commit.txt``; git is not asked there, since the repository
    enclosing an installation, if any, is not the one the code came from.
    """
    try:
        if Path(_git("rev-parse", "--show-toplevel")).resolve() == ROOT:
            return _git("rev-parse", "--short=12", "HEAD") + (
                "-dirty" if _git("status", "--porcelain", "--untracked-files=no") else "")
    except (OSError, subprocess.CalledProcessError):
        pass
    try:
        return STAMP.read_text().strip() or "unknown"
    except OSError:
        return "unknown"
