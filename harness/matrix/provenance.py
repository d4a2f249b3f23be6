"""Provenance: what a run ran on, so figures compare across machines and months.

:func:`collect` gathers, for the ``runs`` table of the store
(:data:`integrator_bench.harness.matrix.record.RUN_FIELDS`): the code version, the versions of
Python, numpy, scipy, scikit-sundae, fmpy (null when not installed) and of
every plugin that provides a problem or an integrator, the CPU model (from
``/proc/cpuinfo``), the thread settings, the host and the command line.
The report shows the runs
(:func:`integrator_bench.harness.report.sections.runs_part`).
"""

from __future__ import annotations

import functools
import os
import platform
import socket
import sys
import uuid
from datetime import datetime, timezone
from importlib import metadata

from integrator_bench.harness.version import code_version

PACKAGES = ("numpy", "scipy", "scikit-sundae", "fmpy", "pandas", "dask", "distributed")
#: the packages whose versions a record's numbers depend on (the solvers and the
#: models): a Dask worker must have the client's (:func:`installation`)
RESULT_PACKAGES = ("numpy", "scipy", "scikit-sundae", "fmpy", "assimulo-testing")
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
               "BLIS_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")
BLAS_THREADS_PER_WORKER = 1  # every case runs with one BLAS/OpenMP thread (isolation._one_thread)


def now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def package_version(name: str) -> str | None:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def plugin_versions() -> dict[str, str]:
    """``{distribution: version}`` of every package other than this one that
    registers a problem or an integrator."""
    from integrator_bench.harness.matrix.registry import BUILTIN_DIST, GROUPS

    found = {}
    for group in GROUPS.values():
        for ep in metadata.entry_points(group=group):
            dist = getattr(ep, "dist", None)
            if dist is not None and dist.metadata["Name"] != BUILTIN_DIST:
                found[dist.metadata["Name"]] = dist.version
    return dict(sorted(found.items()))


def versions() -> dict:
    out = {name: package_version(name) for name in PACKAGES}
    out["plugins"] = plugin_versions()
    return out


@functools.lru_cache(maxsize=1)
def installation() -> dict:
    """What a record's numbers depend on besides the machine: the code version,
    the Python version and the versions of :data:`RESULT_PACKAGES` (null when
    not installed) and of every plugin. A Dask worker whose installation
    differs from its client's runs no case
    (:mod:`integrator_bench.harness.run.dask_backend`)."""
    return {"code_version": code_version(), "python": platform.python_version(),
            "packages": {name: package_version(name) for name in RESULT_PACKAGES},
            "plugins": plugin_versions()}


def installation_differences(mine: dict, theirs: dict) -> list[str]:
    """``["numpy 2.1.0 (here 2.0.2)", ...]``: where installation ``theirs`` differs
    from ``mine`` ("here"; both from :func:`installation`); [] when they agree."""
    flat = [(key, mine.get(key), theirs.get(key)) for key in ("code_version", "python")]
    for group in ("packages", "plugins"):
        a, b = mine.get(group) or {}, theirs.get(group) or {}
        flat += [(name, a.get(name), b.get(name)) for name in sorted({*a, *b})]
    return [f"{key} {theirs_v or 'not installed'} (here {mine_v or 'not installed'})"
            for key, mine_v, theirs_v in flat if mine_v != theirs_v]


def cpu_model() -> str | None:
    """The ``model name`` line of ``/proc/cpuinfo`` (None where there is none)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key.strip() in ("model name", "Model", "cpu model"):
                    return value.strip()
    except OSError:
        pass
    return platform.processor() or None


def thread_settings() -> dict:
    """Thread environment variables as set (null: unset) and the per-worker limit."""
    return {"env": {v: os.environ.get(v) for v in THREAD_VARS},
            "blas_threads_per_worker": BLAS_THREADS_PER_WORKER}


def machine() -> dict:
    """Host, CPU model, core count and load averages of this process's machine
    (Dask workers report theirs): timings taken on a busy machine show it."""
    try:
        load = [round(x, 2) for x in os.getloadavg()]
    except OSError:
        load = None
    return {"host": socket.gethostname(), "cpu_model": cpu_model(), "cpu_count": os.cpu_count(),
            "loadavg": load}


def collect(command: str | None = None, backend: dict | None = None,
            options: dict | None = None, purpose: str = "run") -> dict:
    """A new run's provenance row (keys of :data:`integrator_bench.harness.matrix.record.RUN_FIELDS`);
    ``purpose``: ``run`` (a matrix) or ``advise`` (the cases of an advice)."""
    started = now()
    return {
        "run_id": started.replace("-", "").replace(":", "")[:15] + "-" + uuid.uuid4().hex[:8],
        "started": started, "finished": None, "status": "running",
        "code_version": code_version(),
        "python": platform.python_version(),
        "versions": versions(),
        **machine(),
        "threads": thread_settings(),
        "platform": platform.platform(),
        "command": command if command is not None else " ".join(sys.argv),
        "backend": backend or {},
        "options": options or {},
        "purpose": purpose,
    }


#: the ``purpose`` of a run of the matrix (``ibench run``), and of the cases of an advice
#: (``ibench advise``: its searches and the robustness check's perturbed sets)
RUN, ADVISE = "run", "advise"


def backfill_runs(runs):
    """``runs`` (a DataFrame of provenance rows) with ``purpose`` filled in where a
    run lacks it (a store written before that field): ``advise`` for a run whose
    stored command line, split as a shell splits it, is ``ibench advise ...``,
    else ``run``. Runs that have it keep it."""
    import shlex

    if runs.empty or "purpose" in runs.columns and runs["purpose"].notna().all():
        return runs

    def purpose(given, command):
        if isinstance(given, str):
            return given
        try:
            words = shlex.split(command) if isinstance(command, str) else []
        except ValueError:       # unbalanced quotes: not a command ibench stored
            words = []
        return ADVISE if words[:2] == ["ibench", ADVISE] else RUN

    given = runs["purpose"] if "purpose" in runs.columns else [None] * len(runs)
    return runs.assign(purpose=[purpose(p, c) for p, c in zip(given, runs["command"])])

