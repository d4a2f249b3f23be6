"""Where the harness keeps its data: the store, the reference cache and reports.

One rule decides the data directory:

1. ``IBENCH_DATA_DIR``, when set, names it.
2. Otherwise, running from a checkout of the project (an editable install: the
   folder holding the ``harness`` package has a ``pyproject.toml`` naming
   ``integrator-bench``: :mod:`.layout`), it is ``<checkout>/results``.
3. Otherwise (an installed wheel) it is ``./results`` under the current working
   directory, where the user runs ``ibench``. Nothing is ever written beside
   the installed code: site-packages may be read-only and is shared by every
   user of the environment.

Under the data directory live ``ibench.sqlite`` (the default store),
``reference/`` (references computed at run time), ``plugin-reference/`` (those of
problems from plugins, apart from the project's) and ``report/`` (``ibench
report`` writes beside its store unless told otherwise). The references
committed to the project ship in the wheel as package data,
``integrator_bench/reference_data/`` (the checkout's ``results/reference/``);
they are read-only and are used for every problem whose reference is not in
the data directory (see ``harness.measure.references``).
``IBENCH_REFERENCE_DIR``, when set, replaces ``<data>/reference`` and
``<data>/plugin-reference``.

The paths are decided once, at import, from the environment and working
directory of that moment.

A file or folder named after anything a model, a plugin or a user names (a
problem, a parameter or FMU variable, a start option) is named through
:func:`file_name` and joined through :func:`inside`, which checks that it lies
inside its folder: a name such as ``../../x`` cannot place a file elsewhere.
"""

from __future__ import annotations

import hashlib
import os
import re
from pathlib import Path
from urllib.parse import quote

from integrator_bench.harness import layout

PACKAGE_DIR = Path(__file__).resolve().parent  # the harness package


def checkout_root(package_dir: Path = PACKAGE_DIR) -> Path | None:
    """The project checkout ``package_dir`` lies in, or None for an installed copy
    (:func:`.layout.checkout_root`)."""
    return layout.checkout_root(package_dir)


def data_dir(package_dir: Path = PACKAGE_DIR, environ=os.environ,
             cwd: Path | None = None) -> Path:
    """The data directory by the module's rule (absolute)."""
    if environ.get("IBENCH_DATA_DIR"):
        return Path(environ["IBENCH_DATA_DIR"]).expanduser().resolve()
    root = checkout_root(package_dir)
    if root is not None:
        return root / "results"
    return Path(cwd or Path.cwd()).resolve() / "results"


def shipped_reference_dir(package_dir: Path = PACKAGE_DIR) -> Path | None:
    """The references shipped as package data; None in a checkout, whose
    ``results/reference/`` is where they come from."""
    if checkout_root(package_dir) is not None:
        return None
    return Path(package_dir).resolve().parent / "reference_data"


#: the characters a name keeps in a file name besides letters, digits and ``_.-~``
#: (every other one, ``/``, ``\\`` and NUL among them, is percent-encoded)
FILE_NAME_SAFE = "=+,"
#: the longest name :func:`file_name` gives (file systems stop at 255 bytes; room
#: is left for suffixes such as ``.npz`` and a temporary file's)
MAX_FILE_NAME = 160


def file_name(text: str) -> str:
    """``text`` as one file-name component: every character but letters, digits
    and ``_.-~=+,`` percent-encoded as its UTF-8 bytes (RFC 3986 sect. 2.1), and
    a leading ``.`` as ``%2E``, so that no name is ``.``, ``..``, hidden or holds
    a separator; the empty name is ``%`` (which no other name gives). Names of
    only those characters (every built-in problem's and parameter's) are
    unchanged, and distinct names stay distinct; one longer than
    :data:`MAX_FILE_NAME` keeps its first 140 characters and ends with ``-`` and
    16 hex digits of the SHA-256 of ``text``."""
    name = quote(str(text), safe=FILE_NAME_SAFE) or "%"
    name = "%2E" + name[1:] if name.startswith(".") else name
    if len(name) > MAX_FILE_NAME:
        digest = hashlib.sha256(str(text).encode("utf-8", "surrogatepass")).hexdigest()
        name = f"{name[:140]}-{digest[:16]}"
    return name


def inside(directory, *names: str) -> Path:
    """``directory / name / ...`` for names made by :func:`file_name`.

    Raises
    ------
    ValueError
        When the path would not lie inside ``directory`` (checked on the path as
        written, not through links the user put there): a name not made by
        :func:`file_name` (``..``, one holding a separator) is refused here.
    """
    path = Path(directory).joinpath(*names)
    base = os.path.abspath(directory).rstrip(os.sep) + os.sep
    full = os.path.normpath(os.path.abspath(path))
    if not names or not full.startswith(base) or any(
            n in ("", ".", "..") or os.sep in n or (os.altsep and os.altsep in n)
            for n in names):
        raise ValueError(f"{'/'.join(map(str, names))!r} does not name a file inside "
                         f"{base.rstrip(os.sep)!r}")
    return path


def write_atomically(path, write) -> Path:
    """Fill ``path`` through ``write(temporary path)`` and then rename the temporary
    file onto it (``os.replace``, atomic): an interrupted write (Ctrl-C, a kill)
    leaves the old file or the new one, never half a file. The temporary file,
    ``<name>.<random>.part`` beside ``path``, is unique to the call, so two
    processes writing one file do not write into each other's; it is removed
    when ``write`` fails (an OSError of the temporary file, a full disk's, is
    raised naming ``path``)."""
    path = Path(path)
    part = path.with_name(f"{path.name}.{os.urandom(8).hex()}.part")
    try:
        write(part)
        os.replace(part, path)
    except OSError as exc:   # a full disk, say: named by the file meant, not the part
        if exc.errno is None or exc.filename not in (None, str(part), part):
            raise
        raise OSError(exc.errno, exc.strerror, str(path)) from exc
    finally:
        part.unlink(missing_ok=True)
    return path


#: the name of a temporary file of :func:`write_atomically`
PART = re.compile(r".\.[0-9a-f]{16}\.part$")


def remove_parts(folder) -> None:
    """Remove the temporary files of :func:`write_atomically` under ``folder``: what
    a process killed partway through a write (a report's drawing process, stopped
    with SIGKILL when the report is) leaves, removed by the process that killed it.
    A write of another process into ``folder`` at that moment loses its file (and
    fails)."""
    for part in Path(folder).rglob("*.part"):
        if PART.search(part.name):
            part.unlink(missing_ok=True)


CHECKOUT = checkout_root()
DATA_DIR = data_dir()
DEFAULT_STORE = DATA_DIR / "ibench.sqlite"
REFERENCE_DIR = Path(os.environ.get("IBENCH_REFERENCE_DIR") or DATA_DIR / "reference")
#: the references of problems from plugins (a checkout's ``results/reference/`` is committed
#: with the project: a problem installed from outside keeps its own apart, untracked)
PLUGIN_REFERENCE_DIR = Path(os.environ.get("IBENCH_REFERENCE_DIR")
                            or DATA_DIR / "plugin-reference")
SHIPPED_REFERENCE_DIR = shipped_reference_dir()

__all__ = ["CHECKOUT", "DATA_DIR", "DEFAULT_STORE", "REFERENCE_DIR", "PLUGIN_REFERENCE_DIR",
           "SHIPPED_REFERENCE_DIR",
           "checkout_root", "data_dir", "file_name", "inside", "shipped_reference_dir",
           "remove_parts", "write_atomically"]
