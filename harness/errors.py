"""The exceptions and warnings of the harness, in one place.

Defined here:

* :class:`BadInput` -- a bad name or value on the command line (``ibench``
  exits with status 2 and one line naming it);
* :class:`UnknownName` -- an unknown problem or integrator name (a
  :class:`BadInput` too, raised by :mod:`~integrator_bench.harness.matrix.registry`);
* :class:`RegistryWarning` -- a plugin that could not be loaded (warned, never
  raised, by :mod:`~integrator_bench.harness.matrix.registry`);
* :class:`StoreError` -- a file that is not a usable result store;
* :class:`ReferenceFailure` -- a reference solution that could not be
  computed or verified;
* :class:`ModelFault` -- a model's code that raised, crashed or hung in the
  process it was called in
  (:mod:`~integrator_bench.harness.run.model_calls`);
* :class:`BackendLost` -- the Dask scheduler went away during a run;
* :class:`WorkerMismatch` -- a Dask worker whose installation differs from
  the client's was handed a case (it ran none).

Re-exported for users, so one import gives every exception a run can meet:
:class:`~integrator_bench.problems.system.Unsupported` (a system an
integrator cannot take, raised by ``convert``) and
:class:`~integrator_bench.integrators.base.StepFailure` (a step that could
not be completed, with its typed :class:`~integrator_bench.integrators.base.Status`)
and :class:`~integrator_bench.integrators.base.InputModified` (an integrator that
wrote into the state the driver handed it).
"""

from __future__ import annotations

from integrator_bench.integrators.base import InputModified, Status, StepFailure
from integrator_bench.problems.system import Unsupported


class BadInput(ValueError):
    """A bad name or value on the command line (exit status 2)."""


class UnknownName(BadInput):
    """An unknown problem or integrator name (exit status 2)."""


class RegistryWarning(UserWarning):
    """A plugin could not be loaded."""


class StoreError(RuntimeError):
    """The file is not a usable integrator-bench store."""


class ReferenceFailure(RuntimeError):
    """A reference could not be computed or verified."""


class BackendLost(RuntimeError):
    """The Dask scheduler went away during the run (finished cases are stored)."""


class WorkerMismatch(BackendLost):
    """A Dask worker of another installation (code or package versions) than the
    client's joined during the run; it ran no case, and the run stops (finished
    cases are stored)."""


class ModelFault(RuntimeError):
    """A model's code (a problem plugin, an FMU) raised, crashed or hung in the
    isolated process it was called in; ``status`` is what its cases become
    (``error``, ``crashed`` or ``timeout``), the message says what happened and
    while what (``the model crashed (SIGSEGV) while its reference was computed``)."""

    def __init__(self, message: str, status: str):
        super().__init__(message)
        self.status = status

    def __reduce__(self):
        return type(self), (str(self), self.status)


class ReferenceOverBudget(ReferenceFailure):
    """A reference solve stopped past the time limit of references."""


__all__ = ["BadInput", "UnknownName", "RegistryWarning", "StoreError", "ReferenceFailure",
           "ReferenceOverBudget", "ModelFault", "BackendLost", "WorkerMismatch", "Unsupported",
           "StepFailure", "Status", "InputModified"]
