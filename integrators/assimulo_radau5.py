"""Hairer's RADAU5 through Assimulo, with the index of a DAE's variables declared.

On an ODE Assimulo's ``Radau5ODE`` runs. On a DAE ``F(t, y, y') = 0`` the wrapper
runs Assimulo's ``Radau5DAE``, which hands the problem to the Fortran RADAU5
(Hairer and Wanner, Solving ODEs II, sect. IV.8 and VII.1) as the doubled system
``y' = z``, ``0 = F(t, y, z)`` (RADAU5's ``M1 = M2 = n`` structure), but with
RADAU5's index counts ``IWORK(5..7)`` set from the system's ``var_index``, as
the IVP Test Set runs its mechanical problems: the variables of index 2 and 3
have their error scaled by ``h`` and ``h^2`` (RADAU5 needs them ordered by
index; a system whose are not is declined), and ``z = y'`` is out of the error
test (absolute tolerance ``EXCLUDED_ATOL``). Assimulo's own ``Radau5DAE``
declares every ``y`` of index 1 and every ``z`` of index 2: on the squeezer's
``i3`` form at rtol 1e-6 it stops at t = 0.0078 (step size too small); with the
index counts but ``z`` in the error test the angle beta ends at 16.30 instead
of 15.81. The analytic Jacobian ``[dF/dy, dF/dz]`` is two calls of the system's
``jac`` (``c = 0`` and ``c = 1``; the iteration matrix is affine in ``c``), so
``njev`` counts both.
"""

from __future__ import annotations

import numpy as np
from assimulo import solvers

from integrator_bench.integrators.assimulo import AssimuloIntegrator
from integrator_bench.integrators.sparse import dense

EXCLUDED_ATOL = 1e10      # RADAU5's absolute tolerance on z = y' (out of its error test)


class _IndexedRadau5:
    """Hairer's RADAU5 as Assimulo's ``Radau5DAE`` calls it (its module
    ``assimulo.lib.radau5``), with the index counts ``IWORK(5..7)`` of the
    system's variables, ``z = y'`` out of the error test, and the analytic
    Jacobian ``[dF/dy, dF/dz]`` of ``0 = F(t, y, z)`` when the system has one.

    Counters RADAU5 keeps and Assimulo drops: ``nniter`` is NSOL (IWORK(20), one
    forward-backward substitution per simplified Newton iteration), ``nnfail``
    is NSTEP - NACCPT - NREJCT: the steps computed but neither accepted nor
    counted rejected, RADAU5's "unexpected step rejections" (Newton
    divergence, a singular matrix) plus any error-test rejection before the
    first accepted step, which RADAU5 leaves out of NREJCT (Hairer and Wanner's
    radau5.f, labels 78 and the rejection branch).

    ``nind`` are the numbers of variables of index 1, 2 and 3 of the doubled
    state ``(y, z)``: ``y`` by ``var_index`` (non-decreasing), every ``z``
    counted with index 3.
    """

    def __init__(self, lib, system, atol, jac):
        n = system.n
        self.lib, self.n, self.jac = lib, n, jac
        self.nind = list(_index_counts(system))
        self.atol = np.concatenate([atol, np.full(n, EXCLUDED_ATOL)])
        self.njev = self.nniter = self.nnfail = 0

    def contr5(self, *args):
        return self.lib.contr5(*args)

    def _jacobian(self, t, Y):
        n = self.n
        y, z = Y[:n], Y[n:]
        J0, J1 = dense(self.jac(t, y, z, 0.0)), dense(self.jac(t, y, z, 1.0))
        self.njev += 2
        return np.hstack([J0, J1 - J0]), np.zeros(1, dtype=np.intc)

    def radau5(self, fcn, x, y, xend, h, rtol, atol, itol, jac, ijac, mljac, mujac, mas, imas,
               mlmas, mumas, solout, iout, work, iwork):
        iwork[4:7] = self.nind
        if self.jac is not None:
            jac, ijac = self._jacobian, 1
        out = self.lib.radau5(fcn, x, y, xend, h, rtol, self.atol, itol, jac, ijac, mljac,
                              mujac, mas, imas, mlmas, mumas, solout, iout, work, iwork)
        iwork = out[3]   # NSTEP, NACCPT, NREJCT, NDEC, NSOL in IWORK(16..20)
        self.nniter += int(iwork[19])
        self.nnfail += int(iwork[15] - iwork[16] - iwork[17])
        return out


def _index_counts(system) -> tuple[int, int, int]:
    """RADAU5's ``IWORK(5..7)`` of the doubled state ``(y, z)``: the variables of
    index 1, 2 and 3, ``y`` by ``var_index``, every ``z`` of index 3."""
    index = system.var_index
    return (int(np.sum(index == 1)), int(np.sum(index == 2)),
            int(np.sum(index == 3)) + system.n)


class Radau5(AssimuloIntegrator):
    """RADAU5: Assimulo's ``Radau5ODE`` on an ODE, ``Radau5DAE`` with the index
    counts of :class:`_IndexedRadau5` on a DAE (module docstring)."""

    name = "assimulo-radau5"
    description = ("Hairer's RADAU5 through Assimulo: Radau IIA of order 5, ODEs and DAEs "
                   "up to index 3 (variables' index declared)")
    reference = "Hairer and Wanner, Solving ODEs II (1996), sect. IV.8 and VII.1"
    accepts = frozenset({"ode", "dae"})
    max_index = 3
    order = 5
    implicit = uses_jacobian = events = True
    stability = "L"
    solver_ode = "Radau5ODE"
    solver_dae = "Radau5DAE"

    def declines(self, system):
        if system.kind == "dae" and np.any(np.diff(system.var_index) < 0):
            return (f"{self.name} needs a DAE's variables ordered by index (RADAU5's "
                    "IWORK(5..7)); this system's are not")
        return super().declines(system)

    def make_solver(self, system, problem):
        if system.kind != "dae":
            return super().make_solver(system, problem)
        solver = _Radau5DAE(problem)
        solver.indexed = lambda lib: _IndexedRadau5(lib, system, solver.atol, system.jac)
        return solver

    def library_call(self, system, rtol, atol):
        """Assimulo's call (:meth:`AssimuloIntegrator.library_call`), and on a DAE the
        index counts RADAU5 is given past Assimulo's interface, in ``beyond_options``."""
        call = super().library_call(system, rtol, atol)
        if call is not None and system.kind == "dae":
            n1, n2, n3 = _index_counts(system)
            call["beyond_options"] = [
                f"RADAU5's IWORK(5), IWORK(6), IWORK(7) (the numbers of variables of index "
                f"1, 2 and 3) = {n1}, {n2}, {n3}: the state y by its variables' index "
                f"{list(map(int, system.var_index))}, every derivative z = y' counted of "
                f"index 3 and given the absolute tolerance {EXCLUDED_ATOL:g} (out of the "
                "error test); Assimulo's Radau5DAE sets no such "
                "option: set them in the IWORK array of its call to the Fortran RADAU5, "
                "as integrators/assimulo_radau5.py does"]
        return call

    def counts(self, solver):
        counts = super().counts(solver)
        lib = getattr(solver, "radau5", None)
        if isinstance(lib, _IndexedRadau5) and lib.jac is not None:
            # Assimulo adds n calls per Jacobian to nfcnjacs as if it were one of
            # finite differences: it is the system's, two calls of its jac
            counts.update(nfev=int(solver.statistics["nfcns"]), njev=lib.njev)
            counts.pop("nfev_jac", None)
        if isinstance(lib, _IndexedRadau5):
            counts.update(nniter=lib.nniter, nnfail=lib.nnfail)
        return counts


class _Radau5DAE(solvers.Radau5DAE):
    """Assimulo's Radau5DAE calling RADAU5 through ``indexed(module)``."""

    indexed = None

    def initialize(self):
        super().initialize()          # loads the Fortran module as self.radau5
        self.radau5 = self.indexed(self.radau5)
