"""What travels with a case to a Dask worker, which shares nothing with the client
but the installed package.

The client (:class:`Packer`) hands each task:

* the reference it read and verified before the run
  (:func:`~integrator_bench.harness.run.referencing.prepare_references`), as a
  :class:`~integrator_bench.harness.measure.references.Handed` scattered once per
  problem and parameter set: the worker reads no reference from its disk and
  computes none (a case handed none becomes an ``error`` record saying so);
* the bytes of each file a parameter of the case names (the problem class's
  ``file_params``: an FMU's ``path``), scattered once per file and keyed by
  their SHA-256.

The worker (:func:`unpack`) writes each file once into its local directory,
``<Dask local directory>/ibench-files/<sha256><suffix>``, and runs the case
with the parameter naming that copy (a problem reading it, an FMU, is unpacked
once per worker process, as every problem is built once there before the cases
fork). The record keeps the client's case id and parameters
(:func:`as_client_sees`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import tempfile
from pathlib import Path

from integrator_bench.harness.measure import references
from integrator_bench.harness.paths import write_atomically

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.line import ProblemSpec

FILES_DIR = "ibench-files"  # under the Dask worker's local directory


class Packer:
    """The client's side: what each case takes along (:meth:`pack`), each
    reference and file scattered once and kept for the run; ``build(spec)`` gives a
    case's problem (default: built here; a session's, built once)."""

    def __init__(self, client, reference_dir=None, build=ProblemSpec.build):
        self.client, self.reference_dir = client, reference_dir
        self.build = build
        self.references: dict = {}  # ProblemSpec -> future of a Handed
        self.files: dict = {}       # (path, mtime, size) -> (sha256, future of the bytes)

    def pack(self, case) -> tuple:
        """``(handed, files)`` for ``case``: the future of its
        :class:`~integrator_bench.harness.measure.references.Handed` reference, and
        ``[(parameter, sha256, suffix, future of the bytes), ...]``."""
        try:
            cls = registry.get_problem_class(case.problem)
        except Exception:  # an unknown problem: its worker says so in the record
            cls = None
        files = [(name, *self._file(value)) for name, value in case.params
                 if cls is not None and name in cls.file_params]
        return self._reference(case, cls), [f for f in files if f[1] is not None]

    def _reference(self, case, cls):
        key = case.spec
        if key not in self.references:
            try:
                ref, why = references.stored(self.build(case.spec), self.reference_dir)
            except Exception as exc:  # a problem that fails to build fails in its worker
                ref, why = None, f"the client could not build the problem: {exc}"
            self.references[key] = self.client.scatter(references.Handed(ref, why), hash=False)
        return self.references[key]

    def _file(self, value) -> tuple:
        """``(sha256, suffix, future of the bytes)`` of the file ``value``; (None,
        None, None) when it cannot be read here (the worker then names it missing)."""
        path = Path(value).expanduser().resolve()
        try:
            st = path.stat()
            key = (str(path), st.st_mtime_ns, st.st_size)
            if key not in self.files:
                data = path.read_bytes()
                self.files[key] = (hashlib.sha256(data).hexdigest(),
                                   self.client.scatter(data, hash=False))
        except OSError:
            return None, None, None
        sha, future = self.files[key]
        return sha, path.suffix, future

    def release(self) -> None:
        """Let go of everything scattered (the cluster may drop it)."""
        self.references.clear()
        self.files.clear()


def unpack(case, files):
    """The worker's side: ``case`` with each shipped file's parameter naming this
    worker's copy (written once, checked against its SHA-256)."""
    if not files:
        return case
    params = case.params_dict
    for name, sha, suffix, data in files:
        params[name] = str(local_copy(sha, suffix, data))
    return dataclasses.replace(case, params=tuple(sorted(params.items())))


def as_client_sees(record: dict, case) -> dict:
    """``record`` of an unpacked case under the client's case id and parameters."""
    record.update(case_id=case.case_id, params=case.params_json)
    return record


def local_copy(sha: str, suffix: str, data: bytes) -> Path:
    """``<local directory>/ibench-files/<sha><suffix>`` holding ``data``; written
    (atomically) when it is not there yet. ValueError when ``data`` is not what
    ``sha`` names."""
    path = Path(_local_directory()) / FILES_DIR / f"{sha}{suffix}"
    if not path.is_file():
        if hashlib.sha256(data).hexdigest() != sha:
            raise ValueError(f"the shipped file {sha[:12]}{suffix} does not match its SHA-256")
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomically(path, lambda part: part.write_bytes(data))
    return path


def _local_directory() -> str:
    """This Dask worker's local directory (its scratch space), or the system's
    temporary directory outside a worker."""
    try:
        from distributed import get_worker
        return get_worker().local_directory
    except (ImportError, ValueError):
        return tempfile.gettempdir()
