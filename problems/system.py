"""The mathematical forms in which a problem is handed to an integrator.

A *problem* (see :mod:`integrator_bench.problems.base`) knows physics; an *integrator* knows
numerics. Between them stands a *system*: one formulation of one problem, as a
plain mathematical object an integrator can take without knowing where it came
from. Each system has a ``kind`` that integrators declare in their ``accepts``:

``"ode"``
    explicit ODE ``y' = f(t, y)`` (:class:`OdeSystem`);
``"dae"``
    implicit DAE ``F(t, y, y') = 0`` of a given index (:class:`DaeSystem`);
``"mechanical"``
    the second-order constrained form ``M(q) q'' = f(t, q, v) - G(q)^T lam``,
    ``g(q) = 0`` (index 3), for HHT-alpha, Newmark and generalized-alpha
    (:class:`MechanicalSystem`); carried by the ``i3`` DAE of a constrained
    mechanism, or with no constraints by the ODE of one with compliant joints;
``"fmu"``
    a model-exchange FMU as a file (:class:`FmuSystem`), carried by the ODE
    of an FMU problem for integrators that simulate FMUs themselves (fmpy's).

An integrator that does not list a kind in ``accepts`` is never handed it.
Each kind names, in ``counted``, the callables the harness counts as function
evaluations (``nfev``) and Jacobian evaluations (``njev``).

Every system maps its state back to the problem's *canonical components*
through :meth:`output`, so that errors are measured against one reference
whatever the formulation.

A large system gives its Jacobian as a scipy.sparse matrix, or its structure in
``jac_sparsity``; one that gives neither, above :data:`DENSE_JACOBIAN_LIMIT`
states, is not handed to integrators that form a Jacobian (see :func:`convert`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.sparse as sp

#: Largest state dimension for which an integrator that forms a Jacobian
#: (``implicit`` or ``uses_jacobian``) is handed a system that gives neither a
#: Jacobian nor its sparsity, so that the integrator builds a dense n x n
#: finite-difference matrix: 2000 states make 32 MB per copy, the ``ode`` form
#: of a 1000-link chain (n = 6004) would make 288 MB and n finite-difference
#: right-hand sides per Jacobian.
DENSE_JACOBIAN_LIMIT = 2000


@dataclass(frozen=True)
class Event:
    """A state event ``value(t, y) = 0``.

    Integrators that locate events (``events = True``) find the crossing in
    a step to about ``4 eps max(|t|, 1)`` and act on it as scipy's
    ``solve_ivp`` and SUNDIALS' root finding do: an event function is
    checked at step ends, and a crossing counts when its sign changes
    strictly (a function already zero where the integration (re)starts is not
    a crossing there).

    Parameters
    ----------
    value : callable
        ``value(t, y) -> float``; the event happens where it changes sign.
    direction : int
        +1 only rising zero crossings, -1 only falling, 0 both.
    terminal : bool
        Whether integration stops at the event. Without ``reset`` the run then
        ends there successfully (outputs after the event are absent, as in
        scipy's ``solve_ivp``).
    reset : callable or None
        Terminal events only. ``reset(t, y) -> y_new`` at the located crossing
        ``(t, y)``: the integration restarts from ``(t, y_new)`` with a fresh
        method (no history, new step size), so an impact law or a mode switch
        is applied exactly there. A problem with modes keeps its mode inside
        the system it formulated (for example in a closure or an attribute
        that ``fun`` reads) and ``reset`` changes it: the functions of the
        system may depend on it after the restart. Returning None means
        "ignore this crossing" (the current mode does not act on it): the
        integration continues as if nothing happened, the crossing is not
        recorded, and only the next sign change of this function counts.
    name : str
        The event's kind (``"impact"``, ``"stick"``, ...), recorded with each
        crossing acted on so that event sequences can be matched by kind and
        order.
    """

    value: Callable[[float, np.ndarray], float]
    direction: int = 0
    terminal: bool = False
    reset: Callable[[float, np.ndarray], np.ndarray | None] | None = None
    name: str = ""

    def __post_init__(self):
        if self.direction not in (-1, 0, 1):
            raise ValueError(f"Event direction {self.direction!r}: give -1, 0 or +1")
        if self.reset is not None and not self.terminal:
            raise ValueError(f"Event {self.name!r} has a reset but is not terminal: a reset "
                             "restarts the integration, give terminal=True")


@dataclass
class System:
    """Fields common to every kind of system.

    Attributes
    ----------
    t0, t_end : float
        Time span.
    y0 : ndarray
        Consistent initial state.
    t_eval : ndarray
        Output times (first ``t0``, last ``t_end``).
    atol_scale : ndarray
        Per-component scale: the absolute tolerance for relative tolerance
        ``rtol`` is ``rtol * atol_scale``.
    error_mask : ndarray of bool
        Components that take part in the integrator's local error test.
    output : callable
        ``output(t, Y) -> ndarray``: maps states ``Y`` (shape ``(m, n)``) to
        the problem's canonical components (shape ``(m, n_canonical)``).
    events : tuple of Event
    unsupported : str or None
        Why no integrator can run this system, in one line (a formulation the
        problem's physics rules out, such as one that needs a constraint
        Jacobian of full row rank on a mechanism with redundant constraints);
        :func:`convert` raises :class:`Unsupported` with it. None: any
        integrator that takes the system's kind may run it.
    """

    t0: float
    t_end: float
    y0: np.ndarray
    t_eval: np.ndarray
    atol_scale: np.ndarray
    error_mask: np.ndarray | None = None
    output: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None
    events: tuple[Event, ...] = ()
    unsupported: str | None = None
    kind = "abstract"

    def __post_init__(self):
        self.y0 = np.asarray(self.y0, dtype=float)
        self.t_eval = np.asarray(self.t_eval, dtype=float)
        n = self.y0.size
        self.atol_scale = np.broadcast_to(np.asarray(self.atol_scale, float), (n,)).copy()
        if self.error_mask is None:
            self.error_mask = np.ones(n, dtype=bool)
        if self.output is None:
            self.output = lambda t, Y: Y

    @property
    def n(self) -> int:
        return self.y0.size

    def atol(self, rtol: float) -> np.ndarray:
        """Absolute tolerance vector that goes with ``rtol``."""
        return rtol * self.atol_scale


@dataclass
class OdeSystem(System):
    """Explicit ODE ``y' = fun(t, y)``.

    Attributes
    ----------
    fun : callable
        ``fun(t, y) -> ndarray``.
    jac : callable or None
        ``jac(t, y) -> ndarray or sparse matrix``, ``J[i, j] = d f_i / d y_j``.
    jac_sparsity : sparse matrix or None
        Structural non-zeros of the Jacobian, for large sparse systems.
    project : callable or None
        ``project(t, y) -> y``: to be applied after every accepted step (the
        projection formulation); only integrators declaring ``projects = True``
        take such a system.
    mechanical : MechanicalSystem or None
        The same problem in second-order form ``y = (q, v)``, ``M q'' = f``
        without constraints (``nc = 0``), for integrators accepting the
        ``"mechanical"`` kind: a mechanism whose joints are compliant
        (bushings) in place of constraints.
    fmu : FmuSystem or None
        The same problem as the FMU file it was read from, for integrators
        accepting the ``"fmu"`` kind (the FMU tool's own solvers).
    """

    fun: Callable[[float, np.ndarray], np.ndarray] = None
    jac: Callable[[float, np.ndarray], np.ndarray] | None = None
    jac_sparsity: sp.spmatrix | None = None
    project: Callable[[float, np.ndarray], np.ndarray] | None = None
    mechanical: "MechanicalSystem | None" = None
    fmu: "FmuSystem | None" = None
    kind = "ode"
    index = 0
    counted = {"fun": "nfev", "jac": "njev"}

    def as_dae(self) -> "DaeSystem":
        """The same problem as the index-0 DAE ``y' - f(t, y) = 0``."""
        fun, jac, n = self.fun, self.jac, self.n

        def residual(t, y, yp):
            return yp - fun(t, y)

        dae_jac = None
        if jac is not None:
            eye = None

            def dae_jac(t, y, yp, cj):
                nonlocal eye
                J = jac(t, y)
                if sp.issparse(J):  # sparse stays sparse
                    return (cj * sp.identity(n, format="csc") - J).tocsc()
                if eye is None:
                    eye = np.eye(n)
                return cj * eye - np.asarray(J)

        sparsity = None
        if self.jac_sparsity is not None:
            sparsity = (sp.csc_matrix(self.jac_sparsity, dtype=bool)
                        + sp.identity(n, dtype=bool, format="csc"))

        return DaeSystem(
            t0=self.t0, t_end=self.t_end, y0=self.y0, t_eval=self.t_eval,
            atol_scale=self.atol_scale, error_mask=self.error_mask,
            output=self.output, events=self.events,
            residual=residual, jac=dae_jac, yp0=np.asarray(fun(self.t0, self.y0), float),
            jac_sparsity=sparsity,
        )


@dataclass
class DaeSystem(System):
    """Implicit DAE ``residual(t, y, yp) = 0``.

    Attributes
    ----------
    residual : callable
        ``residual(t, y, yp) -> ndarray``.
    jac : callable or None
        ``jac(t, y, yp, cj) -> ndarray or sparse matrix``: ``dF/dy + cj dF/dyp``
        (the iteration matrix of BDF-type codes, as in SUNDIALS IDA and DASSL).
    jac_sparsity : sparse matrix or None
        Structural non-zeros of ``dF/dy + cj dF/dyp`` for every ``cj``, for
        large sparse DAEs: when the Jacobian is not given, so that finite
        differences can be grouped by columns of disjoint structure (Curtis,
        Powell and Reid 1974); when it is, for solvers that fix the structure
        before the run (IDA's sparse solvers), since one evaluated Jacobian
        may lack entries that are zero at that point. None when not known.
    yp0 : ndarray
        Consistent initial derivative.
    var_index : ndarray of int
        Index of each variable as RADAU5-type codes count it (Hairer and Wanner
        II, sect. VII.1): 1, 2 or 3 (positions, velocities and multipliers of an
        index-3 mechanical system are 1, 2, 3); all 1 for an ODE.
    algebraic : ndarray of bool
        Variables whose derivative does not appear (multipliers).
    mechanical : MechanicalSystem or None
        The same problem in second-order form, for integrators accepting the
        ``"mechanical"`` kind.
    """

    residual: Callable[[float, np.ndarray, np.ndarray], np.ndarray] = None
    jac: Callable | None = None
    yp0: np.ndarray = None
    var_index: np.ndarray = None
    algebraic: np.ndarray = None
    mechanical: "MechanicalSystem | None" = None
    jac_sparsity: sp.spmatrix | None = None
    kind = "dae"
    counted = {"residual": "nfev", "jac": "njev"}

    def __post_init__(self):
        super().__post_init__()
        self.yp0 = np.asarray(self.yp0, dtype=float)
        if self.var_index is None:
            self.var_index = np.ones(self.n, dtype=int)
        self.var_index = np.asarray(self.var_index, dtype=int)
        if self.algebraic is None:
            self.algebraic = np.zeros(self.n, dtype=bool)
        self.algebraic = np.asarray(self.algebraic, dtype=bool)

    @property
    def index(self) -> int:
        """Differentiation index: 0 without algebraic variables, else the largest variable index."""
        return int(self.var_index.max(initial=1)) if self.algebraic.any() else 0


@dataclass
class MechanicalSystem(System):
    """``M(q) q'' = f(t, q, v) - G(q)^T lam``, ``g(q) = 0``: index-3 second-order form.

    The state handed back in a :class:`~integrator_bench.integrators.base.Solution` is
    ``y = (q, v, lam)`` (length ``2 nq + nc``); ``y0`` holds consistent
    ``(q0, v0, lam0)`` and ``a0`` the consistent initial acceleration.
    ``error_mask`` marks the positions q.

    Attributes
    ----------
    nq, nc : int
        Numbers of coordinates and of constraints.
    mass : callable
        ``mass(q) -> (nq, nq)`` (dense or sparse).
    force : callable
        ``force(t, q, v) -> (nq,)`` applied and gyroscopic forces f.
    constraint : callable
        ``constraint(q) -> (nc,)``, g.
    constraint_jac : callable
        ``constraint_jac(q) -> (nc, nq)``, G = dg/dq (dense or sparse).
    accel_term : callable
        ``accel_term(q, v) -> (nc,)``, (d(G v)/dq) v, so that G a + accel_term = 0
        is the acceleration-level constraint.
    tangent : callable
        ``tangent(t, q, v, a, lam) -> (K, C)`` with
        ``K = d(M(q) a - f + G(q)^T lam)/dq`` and ``C = -df/dv``: the stiffness and
        damping blocks of the Newton matrix of HHT-type methods (dense or
        sparse, as the mass matrix).
    a0 : ndarray
        Consistent initial acceleration.
    constraint_t : callable or None
        ``constraint_t(q, t) -> (nc,)``, g_t = dg/dt, for constraints that depend
        on time, ``g(q, t) = 0`` (a driven mechanism); None when they do not.
        When given, ``constraint``, ``constraint_jac`` and ``accel_term`` take
        the time as their last argument, ``constraint(q, t)``,
        ``constraint_jac(q, t)``, ``accel_term(q, v, t)``, the last then being
        ``(d(G v)/dq) v + 2 G_t v + g_tt``; the velocity constraint is ``G v + g_t
        = 0``. Integrators call them with ``*system.at(t)``, which serves both.
    """

    nq: int = 0
    nc: int = 0
    mass: Callable = None
    force: Callable = None
    constraint: Callable = None
    constraint_jac: Callable = None
    accel_term: Callable = None
    tangent: Callable = None
    a0: np.ndarray = None
    constraint_t: Callable | None = None
    kind = "mechanical"
    index = 3
    counted = {"force": "nfev", "tangent": "njev"}

    def at(self, t) -> tuple:
        """The time as the constraint callables take it: ``(t,)`` when they depend on
        it (``constraint_t`` given), else ``()``: ``constraint(q, *system.at(t))``."""
        return () if self.constraint_t is None else (t,)

    def velocity_term(self, q, t):
        """``g_t(q, t)``, zero when the constraints do not depend on time: the
        velocity constraint is ``G v + velocity_term = 0``."""
        if self.constraint_t is None:
            return np.zeros(self.nc)
        return np.asarray(self.constraint_t(q, t), float)

    def split(self, y):
        """``(q, v, lam)`` views of a state vector."""
        nq = self.nq
        return y[:nq], y[nq:2 * nq], y[2 * nq:]


@dataclass
class AugmentedLagrangianSystem(MechanicalSystem):
    """The index-3 mechanical system ``M q'' = f - G^T lam``, ``g(q) = 0`` (or
    ``g(q, t) = 0``), to be solved in the augmented Lagrangian form of Bayo and
    Ledesma (Nonlinear Dyn. 9 (1996) 113-130): ``M q'' + G^T (lam* + alpha g) =
    f`` with the multipliers ``lam*`` iterated, ``lam* <- lam* + alpha g``, until
    ``g = 0``, then the velocities and accelerations projected mass-orthogonally
    onto ``G v = 0`` (``G v + g_t = 0`` when driven) and ``G a + accel_term =
    0``. The matrices it inverts are ``M`` plus penalty terms ``alpha G^T G``,
    never the saddle-point matrix, so a rank-deficient G (redundant constraints, singular configurations) is
    allowed. Fields as :class:`MechanicalSystem`, plus the formulation's
    settings (the ``al3`` formulation of
    :mod:`integrator_bench.problems.formulations`):

    Attributes
    ----------
    penalty : float
        The penalty relative to the problem's scales: ``alpha beta h^2 =
        penalty * mass_scale / jacobian_scale^2`` in a step of size ``h`` of a
        Newmark-type rule (``beta`` = 1/4 for the trapezoidal rule), so that
        one multiplier update reduces the constraint violation by about
        ``1 / (1 + penalty)`` whatever the step.
    tolerance : float
        The iteration stops when the largest change of a position is at most
        ``tolerance`` times the position scale and the constraints hold to
        ``tolerance`` times the scale of ``G q``.
    mass_scale, jacobian_scale : float
        The largest diagonal entry of ``M`` and the largest entry of ``G`` at
        the start.
    """

    penalty: float = 1e4
    tolerance: float = 1e-8
    mass_scale: float = 1.0
    jacobian_scale: float = 1.0
    kind = "augmented_lagrangian"


@dataclass
class FmuSystem(System):
    """A model-exchange FMU (FMI 2.0 or 3.0) as a file, for integrators that simulate
    it through the FMU interface themselves (fmpy's solvers).

    Its state is the problem's canonical components (``variables``); the FMU
    handles its own events (``events`` lists them only so
    that :func:`convert` hands the system to event-capable integrators).

    Attributes
    ----------
    unzipdir : str
        Directory of the extracted FMU (model description and binary).
    start_values : dict
        Parameter values to set before initialization, by variable name.
    variables : tuple of str
        The variables recorded, the problem's canonical components: the
        continuous states in order, then any outputs the error is scored on.
    elements : tuple of (str, int or None)
        Where each of ``variables`` is in the FMU tool's results: the model
        variable, and the element's index in its flattened (row-major) array
        value, None for a scalar.
    event_name : str
        The kind recorded for every state event the FMU acts on.
    refused : str
        Why the FMU tool cannot run this FMU as the problem has it ("" when it
        can): integrators taking it are then given nothing, the message saying why.
    """

    unzipdir: str = ""
    start_values: dict = None
    variables: tuple = ()
    elements: tuple = ()
    event_name: str = ""
    refused: str = ""
    kind = "fmu"
    counted = {}   # the FMU's calls are counted by the integrator (fmpy's call logger)


#: the names of the FMI status values (FMI 2.0.4 sect. 2.1.3, FMI 3.0.1 sect. 2.2.3: the same)
FMU_STATUS = ("OK", "WARNING", "DISCARD", "ERROR", "FATAL", "PENDING")


def fmu_log_to_stderr(*args) -> None:
    """The logger callback of an FMU's own log lines (:func:`fmu_instance`), written
    to standard error as fmpy writes them to standard output (``[WARNING]
    message``): never among a command's data on standard output (``--json``).

    Takes FMI 2.0's arguments (environment, instance name, status, category,
    message, the message formatted by fmpy's proxy) and FMI 3.0's (environment,
    status, category, message) alike: the last three are the same.
    """
    import sys

    status, _, message = args[-3:]
    label = FMU_STATUS[status] if 0 <= status < len(FMU_STATUS) else str(status)
    text = message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message)
    print(f"[{label}] {text}", file=sys.stderr, flush=True)


#: the one set of FMI 2.0 callbacks every instance is given (made once, never freed)
_FMI2_CALLBACKS: list = []


def _fmi2_callbacks():
    """FMI 2.0's callbacks with :func:`fmu_log_to_stderr` as logger, behind fmpy's
    proxy that formats the FMU's variadic message. The proxy keeps the logger in one
    global of its library (the last one given), so every instance gets this one
    set, alive as long as the process: a logger made per instance and freed with it
    left the proxy calling freed memory (a segmentation fault)."""
    if not _FMI2_CALLBACKS:
        from ctypes import byref

        from fmpy import calloc, free
        from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                               fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
        from fmpy.logging import addLoggerProxy

        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(fmu_log_to_stderr)
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        addLoggerProxy(byref(callbacks))
        _FMI2_CALLBACKS.append(callbacks)
    return _FMI2_CALLBACKS[0]


def fmu_instance(unzipdir: str, model_description):
    """A fresh model-exchange instance (fmpy's ``FMU2Model`` or ``FMU3Model``) of the
    FMU extracted into ``unzipdir``, instantiated with its log lines going to
    standard error (:func:`fmu_log_to_stderr`)."""
    from fmpy.fmi2 import FMU2Model
    from fmpy.fmi3 import FMU3Model

    md = model_description
    fmi3 = str(md.fmiVersion).startswith("3.")
    fmu = (FMU3Model if fmi3 else FMU2Model)(
        guid=md.guid, unzipDirectory=unzipdir,
        modelIdentifier=md.modelExchange.modelIdentifier, instanceName="integrator_bench")
    if fmi3:
        fmu.instantiate(logMessage=fmu_log_to_stderr)   # kept by the instance; no proxy
    else:
        fmu.instantiate(callbacks=_fmi2_callbacks())
    return fmu


class Unsupported(Exception):
    """An integrator cannot take a system (or a run mode): the message says why.

    Raised by :func:`convert`; the harness records the case as ``unsupported``
    with this message, and runs nothing.
    """


def _describe(system) -> str:
    idx = f" of index {system.index}" if system.kind == "dae" else ""
    return f"a{'n' if system.kind[0] in 'aeio' else ''} {system.kind}{idx}"


def convert(system: System, integrator) -> System:
    """``system`` in a form ``integrator`` (a class) declares it takes.

    An ODE becomes an index-0 DAE for integrators that take only DAEs; a DAE
    carrying its second-order form goes to integrators accepting
    ``"mechanical"``; a system that must be projected after every step goes only
    to integrators declaring ``projects``. A DAE is never turned into an ODE
    here: that is a formulation (see :mod:`integrator_bench.problems.mechanical`).
    An ODE read from an FMU goes as the FMU itself to integrators accepting
    ``"fmu"``.
    A system with ``events`` goes only to integrators declaring ``events``
    (they locate the crossings); its second-order form goes with it only when
    that form carries events of its own.

    An integrator that forms a Jacobian (``implicit`` or ``uses_jacobian``)
    is not given an ODE or DAE of more than :data:`DENSE_JACOBIAN_LIMIT`
    states that has neither ``jac`` nor ``jac_sparsity``: it would build a
    dense n x n finite-difference Jacobian (the ``ode`` forms of a large
    closed chain, whose every acceleration depends on every coordinate).

    A system that says why no integrator can run it (``unsupported``) goes to none.

    Raises
    ------
    Unsupported
        When the integrator takes no form of ``system``, naming why.
    """
    accepts = integrator.accepts
    name = getattr(integrator, "name", "") or integrator.__name__
    if system.unsupported:
        raise Unsupported(system.unsupported)
    if system.events and not getattr(integrator, "events", False):
        raise Unsupported(f"{name} cannot locate state events, which this problem has")
    if getattr(system, "project", None) is not None and not getattr(integrator, "projects", False):
        raise Unsupported(f"{name} does not project after each step, which this "
                          "formulation needs")
    if getattr(system, "mechanical", None) is not None and "mechanical" in accepts:
        if system.events and not system.mechanical.events:
            raise Unsupported(f"{name} takes the second-order form, which does not carry "
                              "this problem's state events")
        return system.mechanical
    if getattr(system, "fmu", None) is not None and "fmu" in accepts:
        if system.fmu.refused:
            raise Unsupported(f"{name}: {system.fmu.refused}")
        return system.fmu
    limit = f" up to index {integrator.max_index}" if "dae" in accepts else ""
    why = f"{name} accepts {'/'.join(sorted(accepts))}{limit}; the system is {_describe(system)}"
    if system.kind in accepts:
        if system.kind == "dae" and system.index > integrator.max_index:
            raise Unsupported(why)
        return _jacobian_fits(system, integrator, name)
    if system.kind == "ode" and "dae" in accepts and system.project is None:
        return _jacobian_fits(system, integrator, name).as_dae()
    raise Unsupported(why)


def _jacobian_fits(system: System, integrator, name: str) -> System:
    """``system``, unless ``integrator`` would build it a dense finite-difference
    Jacobian of more than :data:`DENSE_JACOBIAN_LIMIT` states (see :func:`convert`)."""
    forms = getattr(integrator, "implicit", False) or getattr(integrator, "uses_jacobian", False)
    n = system.n
    if (forms and system.kind in ("ode", "dae") and n > DENSE_JACOBIAN_LIMIT
            and system.jac is None and system.jac_sparsity is None):
        raise Unsupported(
            f"{name} forms a Jacobian, and this system's is dense: n = {n} states "
            f"(more than {DENSE_JACOBIAN_LIMIT}) with neither an analytic Jacobian nor a "
            f"sparsity pattern, a {n * n * 8 / 1e6:.0f} MB finite-difference matrix")
    return system


def takes(system: System, integrator) -> bool:
    """Whether :func:`convert` gives ``integrator`` a form of ``system``."""
    try:
        convert(system, integrator)
    except Unsupported:
        return False
    return True
