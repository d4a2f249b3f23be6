"""SUNDIALS' own counters of a scikit-sundae solver, read from the C library.

scikit-sundae 1.2 returns ``nfev`` and ``njev`` only; every other counter of a
run (steps, error-test failures, linear-solver setups, nonlinear iterations
and convergence failures) is kept by SUNDIALS in the solver's memory and read
by its documented getters (``CVodeGetNumSteps``, ``IDAGetNumSteps``, ...;
Hindmarsh et al., *User Documentation for CVODE* and *for IDA*, "Optional
output functions"). The Python API does not expose that memory: the pointer
is the first ``cdef`` field (``void* mem``) of the Cython class
(``sksundae/_cy_cvode.pyx``, ``_cy_ida.pyx``), right after the object header
and the class's virtual-method table. :func:`read` finds it there only after
checking the layout (the slot before it must hold the class's own vtable, the
pointer published in its ``__pyx_vtable__`` capsule) and checks the result
against the counts scikit-sundae itself returns (``nfev``, ``njev``): where
either check fails, nothing is read and the counters stay unknown, as before.
The scikit-sundae version is pinned in ``pyproject.toml``.

With these the library's own loop (``solve`` over the output times, SUNDIALS'
``'normal'`` mode) reports the counts the one-step loop used to count from
Python, so a case is counted and timed in one solve.
"""

from __future__ import annotations

import ctypes
import glob
import os

import sksundae

#: record counter -> the getter's name after the ``CVodeGetNum``/``IDAGetNum`` prefix
GETTERS = {"nsteps": "Steps", "nreject": "ErrTestFails", "nlu": "LinSolvSetups",
           "nniter": "NonlinSolvIters", "nnfail": "NonlinSolvConvFails"}
#: the counts scikit-sundae returns itself, read again to check the memory found
CHECKS = {"nfev": ("RhsEvals", "ResEvals"), "njev": ("JacEvals", "JacEvals")}

_LIBS = os.path.join(os.path.dirname(sksundae.__file__), os.pardir, "scikit_sundae.libs")
_loaded: dict = {}


def _library(kind: str):
    """The bundled SUNDIALS library of ``kind`` (``"cvode"`` or ``"ida"``), the one
    scikit-sundae's extension loaded, or None when it is not found."""
    if kind not in _loaded:
        found = sorted(glob.glob(os.path.join(_LIBS, f"libsundials_{kind}-*.so*")))
        try:
            _loaded[kind] = ctypes.CDLL(found[0]) if found else None
        except OSError:
            _loaded[kind] = None
    return _loaded[kind]


_capsule_pointer = ctypes.pythonapi.PyCapsule_GetPointer
_capsule_pointer.restype, _capsule_pointer.argtypes = ctypes.c_void_p, [ctypes.py_object,
                                                                          ctypes.c_char_p]
_capsule_name = ctypes.pythonapi.PyCapsule_GetName
_capsule_name.restype, _capsule_name.argtypes = ctypes.c_char_p, [ctypes.py_object]
_HEADER = ctypes.sizeof(ctypes.c_ssize_t) + ctypes.sizeof(ctypes.c_void_p)  # PyObject_HEAD


def _memory(cy_solver) -> int | None:
    """The ``mem`` pointer of a scikit-sundae Cython solver object, or None when its
    layout is not the one expected (module docstring)."""
    capsule = type(cy_solver).__dict__.get("__pyx_vtable__")
    if capsule is None:
        return None
    try:
        vtable = _capsule_pointer(capsule, _capsule_name(capsule))
    except (ValueError, TypeError):
        return None
    address = id(cy_solver) + _HEADER
    if not vtable or ctypes.c_void_p.from_address(address).value != vtable:
        return None
    return ctypes.c_void_p.from_address(address + ctypes.sizeof(ctypes.c_void_p)).value


_getters: dict = {}


def _getter(library, name):
    """The C function ``name`` of ``library`` with its signature set, found once."""
    key = (id(library), name)
    if key not in _getters:
        function = getattr(library, name, None)
        if function is not None:
            function.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_long)]
            function.restype = ctypes.c_int
        _getters[key] = function
    return _getters[key]


def read(solver, kind: str, nfev: int, njev: int | None) -> dict:
    """SUNDIALS' counters of ``solver`` (a ``sksundae.cvode.CVODE`` or
    ``sksundae.ida.IDA`` after its run), as record counters; ``{}`` when they
    cannot be read safely.

    Parameters
    ----------
    solver
        The scikit-sundae solver whose run just ended.
    kind : {"cvode", "ida"}
    nfev, njev : int
        The counts scikit-sundae returned for the run: the memory read must
        give the same, or nothing is read.
    """
    library = _library(kind)
    cy_solver = getattr(solver, f"_{type(solver).__name__}__{type(solver).__name__}", None)
    if library is None or cy_solver is None:
        return {}
    mem = _memory(cy_solver)
    if not mem:
        return {}
    prefix = "CVodeGetNum" if kind == "cvode" else "IDAGetNum"
    which = 0 if kind == "cvode" else 1

    def get(suffix):
        function, value = _getter(library, prefix + suffix), ctypes.c_long()
        if function is None or function(mem, ctypes.byref(value)) != 0:
            return None
        return int(value.value)

    if get(CHECKS["nfev"][which]) != nfev:
        return {}
    if njev is not None and get(CHECKS["njev"][which]) not in (njev, None):
        return {}
    counts = {key: get(suffix) for key, suffix in GETTERS.items()}
    return {key: value for key, value in counts.items() if value is not None}
