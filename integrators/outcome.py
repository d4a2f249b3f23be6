"""What a run and a step of an integrator end with: the typed :class:`Status`, the
:class:`Solution` a run returns, and the exceptions a step raises.

A leaf of the package: the shared driver (:mod:`integrator_bench.integrators.driver`)
and the interface (:mod:`integrator_bench.integrators.base`, which re-exports these
names, the place integrators import them from) both import it, so neither imports the
other's module in a cycle.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np


class Status(str, enum.Enum):
    """Why a run ended: the typed outcome of a :class:`Solution`.

    The value is the fixed code stored in the result record's ``reason``
    (compare scipy's ``OdeResult.status`` and diffrax's ``RESULTS``).
    """

    SUCCESS = "success"
    #: the step size fell below the smallest the method allows
    STEP_SIZE_UNDERFLOW = "step_size_underflow"
    #: the Newton (corrector) iteration did not converge, with a fresh Jacobian
    NEWTON_FAILURE = "newton_failure"
    #: a state or a stage became NaN or infinite
    NONFINITE_STATE = "nonfinite_state"
    #: the right-hand side overflowed, or the solution grew beyond any bound
    DIVERGED = "diverged"
    #: the step limit was reached before ``t_end``
    MAX_STEPS = "max_steps"
    #: a limit of the method itself (too many stages, no spectral radius, ...)
    METHOD_LIMIT = "method_limit"
    #: a library code reported failure (its own message says why)
    SOLVER_FAILURE = "solver_failure"
    #: the local error test failed repeatedly (or could not be met: the accuracy
    #: asked for is beyond the working precision)
    ERROR_TEST_FAILURE = "error_test_failure"
    #: the linear solver's setup (factorization) or solve failed unrecoverably
    LINEAR_SOLVER_FAILURE = "linear_solver_failure"
    #: stopped by its time budget (:class:`~integrator_bench.integrators.driver.Budget`;
    #: the harness records a ``timeout``)
    OVER_BUDGET = "over_budget"


class StepFailure(Exception):
    """A step could not be completed.

    Parameters
    ----------
    status : Status
        Why (``NEWTON_FAILURE``, ``METHOD_LIMIT``, ``NONFINITE_STATE``, ...).
    message : str
        One line for the record.
    retry : bool
        True when a smaller step may succeed: the adaptive driver then cuts
        the step and tries again; at a fixed step the run ends.
    """

    def __init__(self, status: Status, message: str, retry: bool = True):
        super().__init__(message)
        self.status, self.retry = Status(status), retry


class InputModified(Exception):
    """An integrator changed in place what it was handed: an array of the system,
    or the state the shared driver handed its stepper (which the driver keeps
    read-only, rule 10). The message names it; the harness records the run
    ``failed`` with reason ``input_modified``."""


@dataclass
class Solution:
    """What an integrator returns.

    Attributes
    ----------
    t : ndarray, shape (m,)
        Output times reached (a prefix of ``system.t_eval``).
    y : ndarray, shape (m, n)
        States at those times.
    success : bool
        False when the integrator gave up before ``t_end``.
    message : str
        Why it gave up, or a note.
    counts : dict
        The integrator's own counters (keys from ``COUNTERS``), only those it
        knows.
    status : Status, optional
        The typed outcome; when not given, ``SUCCESS`` for a successful run
        and ``SOLVER_FAILURE`` otherwise. A given status decides ``success``.
    events : list of (float, str, ndarray)
        The state events acted on, in order (rule 7): ``(t, name, y_after)``
        with the located time, the :class:`~integrator_bench.problems.system.Event`'s
        ``name`` and the state after it (after the reset, if one applied);
        ``counts["nevents"]`` is their number. Empty for a system without events.
    """

    t: np.ndarray
    y: np.ndarray
    success: bool = True
    message: str = ""
    counts: dict = field(default_factory=dict)
    status: Status | None = None
    events: list = field(default_factory=list)

    def __post_init__(self):
        if self.status is None:
            self.status = Status.SUCCESS if self.success else Status.SOLVER_FAILURE
        self.status = Status(self.status)
        self.success = self.status is Status.SUCCESS
