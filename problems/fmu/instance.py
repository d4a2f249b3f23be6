"""An FMU's instance: its C functions, through fmpy's ctypes binding, as a problem calls them.

:class:`FmuInstance` is one initialized model-exchange instance of a described FMU
(:class:`~.description.FmuDescription`) in continuous-time mode: its state
derivatives, its Jacobian (the FMU's directional derivatives, one call per column),
its outputs and event indicators, and its action at an event (``fmi2EnterEventMode``,
``fmi2NewDiscreteStates`` until it needs no more, ``fmi2EnterContinuousTimeMode``; in
FMI 3.0 ``fmi3UpdateDiscreteStates``).

Parameters and state starts are set as fmpy's own simulation sets start values
(:func:`fmpy.simulation.apply_start_values`): those settable in the instantiated
state before ``fmi2EnterInitializationMode`` (``fmi3EnterInitializationMode``),
the rest of them in initialization mode. An FMU that schedules a time event is
refused at initialization.

The FMU's own log lines (its logger callback) are written to standard error
(:func:`~integrator_bench.problems.system.fmu_instance`), never to standard
output, where a command's data goes.
"""

from __future__ import annotations

import weakref
from ctypes import POINTER, c_double

import numpy as np

from integrator_bench.problems.base import ProblemError
from integrator_bench.problems.fmu.description import INTEGER_TYPES, FmuDescription, configure
from integrator_bench.problems.system import fmu_instance


def _apply_start_values(fmu, desc: FmuDescription, values: dict, settable) -> dict:
    """Set the start values ``values`` (variable name -> value, a list of its
    elements for an array) of the variables ``settable`` says may be set now, as
    :func:`fmpy.simulation.apply_start_values` does (which it does for the
    scalars; an array is set here, at the size its structural parameters give
    it, which that function takes from their start values); the values left."""
    from fmpy.simulation import apply_start_values

    left = {k: v for k, v in values.items() if k not in desc.arrays}
    left = apply_start_values(fmu, desc.model_description, left, settable=settable)
    for v in desc.model_description.modelVariables:
        if v.name in desc.arrays and v.name in values:
            if settable(v):
                cast = int if v.type in INTEGER_TYPES else float
                getattr(fmu, "set" + v.type)([v.valueReference],
                                             [cast(x) for x in values[v.name]])
            else:
                left[v.name] = values[v.name]
    return left


class FmuInstance:
    """One initialized instance of a model-exchange FMU in continuous-time mode.

    Parameters
    ----------
    desc : FmuDescription
    values : dict
        Start values by variable name: every parameter's, and the state starts
        given (:attr:`~.problem.FmuProblem.fmu_values`).
    """

    def __init__(self, desc: FmuDescription, values: dict):
        from fmpy.simulation import settable_in_initialization_mode, settable_in_instantiated

        md = desc.model_description
        self.desc = desc
        self.fmu = fmu_instance(desc.unzipdir, md)   # its log lines on standard error
        weakref.finalize(self, _free, self.fmu)
        t0, t1 = desc.t_span
        if desc.fmi3:
            self._get_derivatives = self.fmu.getContinuousStateDerivatives
            self._update_discrete = self.fmu.updateDiscreteStates
        else:
            self.fmu.setupExperiment(startTime=t0, stopTime=t1)
            self._get_derivatives = self.fmu.getDerivatives
            self._update_discrete = self.fmu.newDiscreteStates
        configure(self.fmu, desc.structural, desc.reconfigured)
        # as fmpy's simulate_fmu sets them: first those settable before initialization
        left = _apply_start_values(self.fmu, desc, values, settable_in_instantiated)
        if desc.fmi3:
            self.fmu.enterInitializationMode(startTime=t0, stopTime=t1)
        else:
            self.fmu.enterInitializationMode()
        left = _apply_start_values(self.fmu, desc, left, settable_in_initialization_mode)
        if left:   # FmuProblem checks the names: a value no mode takes is a bug
            raise ProblemError(f"FMU {desc.path!r} takes no start value for "
                               f"{', '.join(left)}")
        self.fmu.exitInitializationMode()
        self._discrete_update(t0)
        self.fmu.enterContinuousTimeMode()
        n, nz = len(desc.states), desc.n_indicators
        self._x, self._dx, self._z = np.zeros(n), np.zeros(n), np.zeros(max(nz, 1))
        self._px, self._pdx, self._pz = (a.ctypes.data_as(POINTER(c_double))
                                         for a in (self._x, self._dx, self._z))
        self.fmu.getContinuousStates(self._px, n)
        self.y0 = self._x.copy()

    def _discrete_update(self, t) -> bool:
        """``fmi2NewDiscreteStates`` (``fmi3UpdateDiscreteStates``) until the
        FMU needs no more; whether the continuous states changed."""
        needed, changed = True, False
        while needed:
            needed, terminate, _, values_changed, time_event, _ = self._update_discrete()
            changed |= values_changed
            if terminate:
                raise RuntimeError(f"the FMU requested termination at t = {t:.17g}")
            if time_event:
                raise ProblemError(f"FMU {self.desc.path!r} schedules a time event at "
                                   f"t = {t:g}; time events are not supported")
        return changed

    def _set(self, t, y):
        self.fmu.setTime(float(t))
        self._x[:] = y
        self.fmu.setContinuousStates(self._px, self._x.size)

    def derivatives(self, t, y) -> np.ndarray:
        """The FMU's state derivatives at ``(t, y)``."""
        self._set(t, y)
        self._get_derivatives(self._pdx, self._dx.size)
        return self._dx.copy()

    def jacobian(self, t, y) -> np.ndarray:
        """``d der(x) / d x`` by the FMU's directional derivatives, a column per
        call: every derivative and state variable, the seed and the sensitivity
        an entry per element (an array's elements in row-major order)."""
        self._set(t, y)
        n = self._x.size
        J = np.empty((n, n))
        unknowns, knowns = list(self.desc.derivative_refs), list(self.desc.state_refs)
        sizes = {"nSensitivity": n} if self.desc.fmi3 else {}
        seed = [0.0] * n
        for j in range(n):
            seed[j] = 1.0
            J[:, j] = self.fmu.getDirectionalDerivative(unknowns, knowns, seed, **sizes)
            seed[j] = 0.0
        return J

    def outputs(self, t, Y, names) -> np.ndarray:
        """The output elements ``names`` (:attr:`FmuDescription.outputs`) at each
        time of ``t`` and row of ``Y``: their variables read in one call, an
        array's with all its elements."""
        sizes = {}                    # value reference -> (first value, size)
        for name in names:
            vr, size, _, _ = self.desc.outputs[name]
            if vr not in sizes:
                sizes[vr] = (sum(n for _, n in sizes.values()), size)
        refs = list(sizes)
        columns = [sizes[self.desc.outputs[n][0]][0] + self.desc.outputs[n][2] for n in names]
        n_values = sum(n for _, n in sizes.values())
        out = np.empty((len(t), len(names)))
        for k, (tk, y) in enumerate(zip(t, Y)):
            self._set(tk, y)
            values = (self.fmu.getFloat64(refs, nValues=n_values) if self.desc.fmi3
                      else self.fmu.getReal(refs))
            out[k] = np.asarray(values)[columns]
        return out

    def indicator(self, i: int):
        """``value(t, y)`` of event indicator ``i``."""
        def value(t, y):
            self._set(t, y)
            self.fmu.getEventIndicators(self._pz, self.desc.n_indicators)
            return float(self._z[i])
        return value

    def event(self, t, y) -> np.ndarray | None:
        """Let the FMU act on an event at ``(t, y)``: the state to restart from,
        or None when it changed neither its states nor its right-hand side."""
        before = self.derivatives(t, y)
        self.fmu.enterEventMode()
        changed = self._discrete_update(t)
        self.fmu.enterContinuousTimeMode()
        self.fmu.getContinuousStates(self._px, self._x.size)
        y_new = self._x.copy()
        if changed or not np.array_equal(before, self.derivatives(t, y_new)):
            return y_new
        return None


def _free(fmu):
    try:
        fmu.terminate()
    except Exception:  # already terminated or in error: free it all the same
        pass
    fmu.freeInstance()

