"""Provenance: what a run ran on, so figures compare across machines and months.

:func:`collect` gathers, for the ``runs`` table of the store
(:data:`integrator_bench.harness.record.RUN_FIELDS`): the code version, the versions of
Python, numpy, scipy, scikit-sundae, fmpy (null when not installed) and of
every plugin that provides a problem or an integrator, the CPU model (from
``/proc/cpuinfo``), the thread settings, the host and the command line.
:func:`runs_markdown` renders the runs for the report's ``index.md``.
"""

from __future__ import annotations

import json
import os
import platform
import socket
import sys
import uuid
from datetime import datetime, timezone
from importlib import metadata

from integrator_bench.harness.tables import markdown_lines
from integrator_bench.harness.version import code_version

PACKAGES = ("numpy", "scipy", "scikit-sundae", "fmpy", "pandas", "dask", "distributed")
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
    from integrator_bench.harness.registry import BUILTIN_DIST, GROUPS

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
            options: dict | None = None) -> dict:
    """A new run's provenance row (keys of :data:`integrator_bench.harness.record.RUN_FIELDS`)."""
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
    }


def _loads(text):
    try:
        return json.loads(text) if isinstance(text, str) else (text or {})
    except ValueError:
        return {}


def runs_markdown(runs) -> list[str]:
    """Lines of a ``## Runs`` section: one row per run, from the store's ``runs`` table.

    Parameters
    ----------
    runs : pandas.DataFrame
        Rows of :data:`integrator_bench.harness.record.RUN_FIELDS`; empty for a store written
        before provenance was recorded.
    """
    lines = ["## Runs (provenance)", ""]
    if runs is None or len(runs) == 0:
        return lines + ["No run provenance stored (a store from before format 2).", ""]
    header = ("run", "started", "finished", "status", "code", "host", "CPU", "Python", "numpy",
              "scipy", "scikit-sundae", "fmpy", "plugins", "threads", "backend", "command")
    rows = []
    for row in runs.to_dict("records"):
        v = _loads(row.get("versions"))
        threads = _loads(row.get("threads"))
        env = ", ".join(f"{k}={x}" for k, x in (threads.get("env") or {}).items() if x)
        per_worker = threads.get("blas_threads_per_worker")
        thread_text = "; ".join(filter(None, [env or "no thread variables set",
                                              per_worker and f"{per_worker} BLAS thread per case"]))
        backend = _loads(row.get("backend"))
        if backend.get("kind") == "dask":
            workers = backend.get("workers") or []
            hosts = sorted({w.get("host") for w in workers if w.get("host")})
            back = (f"dask {backend.get('scheduler')}: {len(workers)} workers, "
                    f"{sum(w.get('nthreads') or 0 for w in workers)} threads on {', '.join(hosts)}")
        elif backend:
            back = f"local, {backend.get('jobs')} jobs"
        else:
            back = None
        plugins = ", ".join(f"{k} {x}" for k, x in (v.get("plugins") or {}).items()) or "none"
        status = row.get("status")
        if status == "running" and not row.get("finished"):
            status = "running or killed"
        load = _loads(row.get("loadavg"))
        host = f"{row.get('host')} (load {', '.join(map(str, load))})" if load else row.get("host")
        cells = [row.get("run_id"), row.get("started"), row.get("finished"), status,
                 row.get("code_version"), host,
                 f"{row.get('cpu_model')} ({row.get('cpu_count')} cores)", row.get("python"),
                 v.get("numpy"), v.get("scipy"), v.get("scikit-sundae"), v.get("fmpy"),
                 plugins, thread_text, back, f"`{row.get('command')}`"]
        rows.append(cells)
    return lines + markdown_lines(header, rows) + [""]
