"""The integrator interface: what every registered integrator declares and does.

Rules for implementers
----------------------
An integrator is a class deriving from :class:`Integrator`, registered under the
entry-point group ``integrator_bench.integrators`` with its registry name (for
example ``scipy-RK45 = "integrator_bench.integrators.scipy_ivp:RK45"``). Built-ins and plugins are
registered the same way. It knows numerics only: it never imports a particular
problem or the harness.

1. **Declare what it is**, as class attributes (the harness reads these and
   never branches on an integrator's identity):

   ``accepts``
       the system kinds it takes (:mod:`integrator_bench.problems.system`): ``"ode"``,
       ``"dae"``. An ODE is handed as an index-0 DAE to a DAE-only integrator.
   ``max_index``
       the highest DAE index it handles (0 when it takes no DAE).
   ``order``
       its classical order of convergence, or None when it varies (variable
       order codes); ``ibench verify`` compares it with the observed order.
   ``implicit``, ``adaptive``, ``events``, ``uses_jacobian``
       booleans. An adaptive integrator is driven by ``rtol``/``atol``; a
       fixed-step one by ``h``.
   ``stability``
       ``"A"``, ``"L"`` or None, for the stability check of ``ibench verify``.
   ``projects``
       True when it applies ``system.project(t, y)`` after every accepted
       step (the ``projection`` formulation); such systems go only to these.
   ``description``, ``reference``
       one line each: what it is and the publication it implements.

2. **Implement** :meth:`solve`, returning a :class:`Solution` with the state
   at every time in ``system.t_eval`` that was reached. Call only the
   callables of the system it is given (``fun``/``jac`` or
   ``residual``/``jac``): the harness wraps them to count evaluations,
   finite-difference calls included.

3. **Report, never invent, counts** in ``Solution.counts`` with the n-prefix
   vocabulary: ``nfev``, ``njev``, ``nlu``, ``nsteps``, ``nreject``,
   ``nniter``, ``nnfail``. Leave out a count it cannot know; the record then
   says null.

4. **Fail by returning**, not by raising: when the method gives up (step size
   underflow, Newton failure, too many steps), return a Solution with
   ``success=False``, a message, and whatever was reached. An exception is
   recorded as status ``error``; non-finite states are recorded as ``failed``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from integrator_bench.problems.system import System

COUNTERS = ("nfev", "njev", "nlu", "nsteps", "nreject", "nniter", "nnfail")


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
    """

    t: np.ndarray
    y: np.ndarray
    success: bool = True
    message: str = ""
    counts: dict = field(default_factory=dict)


class Integrator:
    """Base class of every integrator; see the module docstring for the rules."""

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    reference: ClassVar[str] = ""
    accepts: ClassVar[frozenset[str]] = frozenset({"ode"})
    max_index: ClassVar[int] = 0
    order: ClassVar[int | None] = None
    implicit: ClassVar[bool] = False
    adaptive: ClassVar[bool] = True
    events: ClassVar[bool] = False
    uses_jacobian: ClassVar[bool] = False
    stability: ClassVar[str | None] = None
    projects: ClassVar[bool] = False

    def solve(self, system: System, *, rtol: float | None = None,
              atol: np.ndarray | float | None = None,
              h: float | None = None) -> Solution:
        """Integrate ``system`` over ``[system.t0, system.t_end]``.

        Parameters
        ----------
        system : System
            A system of a kind listed in ``accepts``.
        rtol, atol : float, array
            Tolerances (adaptive integrators).
        h : float
            Step size (fixed-step integrators).
        """
        raise NotImplementedError

    @classmethod
    def capabilities(cls) -> dict:
        """What the integrator declares, for ``ibench list integrators``."""
        return {
            "accepts": sorted(cls.accepts),
            "max_index": cls.max_index,
            "order": cls.order,
            "implicit": cls.implicit,
            "adaptive": cls.adaptive,
            "events": cls.events,
            "uses_jacobian": cls.uses_jacobian,
            "stability": cls.stability,
            "projects": cls.projects,
        }


def outputs_between(t_eval: np.ndarray, t_old: float, t_new: float) -> np.ndarray:
    """Indices of output times in ``(t_old, t_new]`` (forward integration)."""
    lo = np.searchsorted(t_eval, t_old, side="right")
    hi = np.searchsorted(t_eval, t_new, side="right")
    return np.arange(lo, hi)
