"""What a command decides once for all the cases it runs: :class:`RunContext`.

``ibench run`` and ``ibench advise`` open one context each, from their options,
and hand it down as one object: the store, the backend (local workers or a
Dask client), the reference directory, the resume and skip policies, the
progress bar, the command line kept with the provenance, and each case's
:class:`~integrator_bench.harness.run.limits.Limits`.
:class:`~integrator_bench.harness.run.runner.Session` runs batches of cases in
it: one Dask connection, one provenance row, the store read once, the cost model
fitted once, however many batches (an advice's rounds) it runs.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from pathlib import Path

from integrator_bench.harness.run.limits import Limits


@dataclass(frozen=True)
class RunContext:
    """The options every case of a command runs under, opened once by the command.

    Attributes
    ----------
    store : Store, path or None
        Where each record is committed as it arrives, and the run's provenance
        (:mod:`integrator_bench.harness.matrix.provenance`) with it; a path is
        opened by the session (:class:`~integrator_bench.harness.run.runner.Session`),
        after the Dask connection, so that a bad ``--dask`` writes nothing.
    jobs : int or None
        Local worker processes at once (default: the number of cores).
    dask : distributed.Client, str or None
        Run the cases on Dask instead of local workers: a client, a scheduler
        address ``tcp://HOST:PORT`` or ``local:N``, connected once by the
        session (:mod:`integrator_bench.harness.run.dask_backend`). Records,
        progress and store writes stay here; each case takes its reference and
        the files its parameters name along
        (:mod:`integrator_bench.harness.run.shipping`).
    reference_dir : path or None
        Where the references are read and computed (None: the committed ones).
    resume : bool
        Skip cases already in ``store`` for this code version (their stored
        records are returned; a ``skipped`` one only when it was skipped under
        this run's policy); a case another run stored meanwhile is not stored
        twice. The stored records of a line are evidence for its cases still to run.
    skip : bool
        Record ``skipped`` the cases that their line's records make hopeless
        (:mod:`integrator_bench.harness.run.schedule`); False (``--no-skip``, and
        every advice) runs every case.
    progress : bool
        A progress bar on standard error, and the references' progress lines.
    command : str or None
        The command line stored with the provenance (default: ``sys.argv``).
    purpose : str
        What the run is for, stored with its provenance (``runs.purpose``):
        ``run``, or ``advise`` for the cases of an advice, which the report
        keeps apart from the problems' own records.
    limits : Limits
        Each case's timeout, samples and memory, and a missing reference's time.
    race : object or None
        The run's race (:class:`~integrator_bench.harness.ranking.racing.Race`):
        ``learn(record)`` takes each record, ``bound(case)`` gives the case's race
        bound; None (``--exhaustive``, the quick preset, every advice) runs every
        case to its budget. The command makes it: the run engine does not import
        the ranking.
    """

    store: object = None
    jobs: int | None = None
    dask: object = None
    reference_dir: Path | str | None = None
    resume: bool = False
    skip: bool = True
    progress: bool = True
    command: str | None = None
    purpose: str = "run"
    limits: Limits = field(default_factory=Limits)
    race: object = None

    def __post_init__(self):
        if self.dask is not None and self.jobs is not None:
            raise ValueError("jobs and dask exclude each other: the Dask workers set the "
                             "parallelism")

    @property
    def parallel(self) -> int:
        """Cases run at once: ``jobs``, or the number of cores (on Dask: as many as
        here, a guess)."""
        return self.jobs or os.cpu_count() or 1

    def replace(self, **changes) -> "RunContext":
        """This context with ``changes`` (fields of the context or of its limits)."""
        limits = {k: changes.pop(k) for k in list(changes)
                  if k in {f.name for f in dataclasses.fields(Limits)}}
        return dataclasses.replace(self, **changes,
                                   limits=dataclasses.replace(self.limits, **limits))
