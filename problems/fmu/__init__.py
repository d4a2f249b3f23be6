"""An FMU file as a problem (``-p fmu:path=model.fmu[,name=value...]``), in three modules.

:mod:`.description`
    the model description (``modelDescription.xml``): read, checked and extracted,
    as an :class:`~.description.FmuDescription` (states, parameters, arrays, outputs);
:mod:`.instance`
    an instance of the FMU, its C functions through fmpy's ctypes binding
    (:class:`~.instance.FmuInstance`: derivatives, Jacobian, outputs, events);
:mod:`.problem`
    the problem adapter (:class:`~.problem.FmuProblem`, :func:`~.problem.fmu_problem`).

Each module imports the ones above it, :mod:`integrator_bench.problems.base` and
:mod:`integrator_bench.problems.system`, and fmpy; nothing of the integrators or the
harness. The package exports what callers use.
"""

from integrator_bench.problems.fmu.description import (element_names, extraction_folder,
                                                    file_checksum)
from integrator_bench.problems.fmu.problem import STATE_EVENT, FmuProblem, fmu_problem

__all__ = ["STATE_EVENT", "FmuProblem", "element_names", "extraction_folder",
           "file_checksum", "fmu_problem"]
