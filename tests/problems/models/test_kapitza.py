"""Kapitza's pendulum (problems/models/kapitza.py), the driven mechanism: its reference
against the one-degree-of-freedom ODE in the angle solved by another code, its
averaged dynamics (the inverted position stable above Kapitza's threshold, with
Landau and Lifshitz's slow frequency), and every formulation of the quick preset
on it."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.harness.measure import references
from integrator_bench.harness.run.execution import execute


def kapitza(**params):
    return registry.get_problem_class("kapitza")(**params)


def reduced(p, t_eval, rtol=1e-12):
    """The canonical rows ``(x, y, v_x, v_y, lam)`` from ``theta'' = -(g + s'') sin(theta)
    / L``, solved by LSODA (the reference was computed by Radau and DOP853 on the
    Cartesian formulations), the multiplier from the radial balance ``m a . r = -m g
    (y - s) - lam L^2``."""
    m, L, g = (p.params[k] for k in ("m", "L", "g"))

    def rhs(t, z):
        return [z[1], -(g + p.support(t)[2]) * np.sin(z[0]) / L]

    sol = solve_ivp(rhs, (t_eval[0], t_eval[-1]), [p.params["theta0"], 0.0], method="LSODA",
                    t_eval=t_eval, rtol=rtol, atol=1e-14 * np.pi)
    assert sol.success, sol.message
    th, w = sol.y
    s, ds, dds = p.support(t_eval)
    wd = -(g + dds) * np.sin(th) / L
    x, y = L * np.sin(th), s - L * np.cos(th)
    ax = L * (np.cos(th) * wd - np.sin(th) * w**2)
    ay = dds + L * (np.sin(th) * wd + np.cos(th) * w**2)
    lam = -(m * (ax * x + ay * (y - s)) + m * g * (y - s)) / L**2
    return np.column_stack([x, y, L * np.cos(th) * w, ds + L * np.sin(th) * w, lam])


@pytest.mark.parametrize("params", [{}, registry.get_problem_class("kapitza").undriven],
                         ids=["driven", "undriven twin"])
def test_the_reference_is_the_solution_of_the_ode_in_the_angle(params):
    """The driven set's committed reference, and its undriven twin's (A = 0: the
    pendulum falls from 0.3 rad off upright), which the quick preset runs beside it."""
    p = kapitza(**params)
    ref = references.load(p, compute_missing=False)
    exact = reduced(p, ref.t)
    scale = np.max(np.abs(exact), axis=0)
    error = np.max(np.abs(ref.Y - exact), axis=0) / scale
    assert error[:4].max() < 1e-9, error          # positions and velocities
    assert error[4] < 1e-8, error                  # the multiplier


def slow_motion(p, t_end):
    """``theta - pi`` along a run of the problem's Cartesian ``ode`` form (DOP853)."""
    system = p.formulate("ode")
    t = np.linspace(0.0, t_end, 20001)
    sol = solve_ivp(system.fun, (0.0, t_end), system.y0, method="DOP853", t_eval=t,
                    rtol=1e-10, atol=1e-12)
    assert sol.success, sol.message
    Y = system.output(sol.t, sol.y.T)
    return t, np.mod(p.angle(t, Y), 2 * np.pi) - np.pi


def test_a_fast_drive_holds_the_pendulum_upright_at_the_averaged_frequency():
    """Landau and Lifshitz, Mechanics, sect. 30, problem 1: upright is stable when
    ``A^2 omega^2 > 2 g L``, with ``Omega^2 = A^2 omega^2 / (2 L^2) - g / L``
    (the second derivative of their effective potential); A = 0.02, omega = 500
    (``A^2 omega^2 / (2 g L)`` = 5.1): ``Omega`` = 6.34 rad/s. Below the threshold
    (omega = 200: 0.82) the pendulum falls."""
    p = kapitza(A=0.02, omega=500.0, theta0=np.pi - 0.1)
    t, d = slow_motion(p, 3.0)
    assert np.max(np.abs(d)) < 0.12
    up = np.flatnonzero((d[:-1] < 0) & (d[1:] >= 0))
    period = np.mean(np.diff(t[up]))
    A, w, g, L = 0.02, 500.0, 9.81, 1.0
    averaged = 2 * np.pi / np.sqrt(A**2 * w**2 / (2 * L**2) - g / L)
    assert len(up) >= 2 and abs(period / averaged - 1) < 0.03, (period, averaged)
    _, d = slow_motion(kapitza(A=0.02, omega=200.0, theta0=np.pi - 0.1), 3.0)
    assert np.max(np.abs(d)) > 1.0


@pytest.mark.parametrize("form, integrator, step", [
    ("ode", "cvode-bdf", {"rtols": [1e-6]}),
    ("i3", "ida", {"rtols": [1e-6]}),
    ("ggl", "ida", {"rtols": [1e-6]}),
    ("projection", "scipy-DOP853", {"rtols": [1e-6]}),
    ("i3", "hht", {"rtols": [1e-5]}),
    ("al3", "al-trapezoidal", {"hs": [2e-4]}),
])
def test_the_driven_mechanism_runs_to_ok_under_each_formulation(form, integrator, step):
    """i3, ggl, projection and al3 with IDA, CVODE, HHT, the augmented Lagrangian:
    each ends ``ok`` and agrees with the reference (the driving terms right in each)."""
    case = next(iter(expand(problems=["kapitza"], formulations=[form],
                            integrators=[integrator], **step)))
    record = execute(case, repeat=1)
    assert record["status"] == CaseStatus.OK, record["message"]
    assert record["mescd"] > 2, record["mescd"]


def test_the_quick_preset_resolves_the_drive_at_its_fixed_steps():
    """32 drive periods in the span: the quick preset's fixed steps are 1000 and 2000
    per span for it (at 100 and 200, 3 and 6 a period, every fixed-step code but
    the projected ones failed), 100 and 200 for the others."""
    steps = {c.h for c in expand(problems=["kapitza", "pendulum"], formulations=["i3"],
                                 integrators=["hht"]) if c.h and c.problem == "kapitza"}
    assert steps == {2.0 / 1000, 2.0 / 2000}
    assert {c.h for c in expand(problems=["pendulum"], formulations=["i3"],
                                integrators=["hht"]) if c.h} == {10.0 / 100, 10.0 / 200}


def numeric_kapitza():
    """The pendulum written by hand as a ``MechanicalProblem`` with ``driven = True``
    (the numeric path of a driven model, no sympy), beside the symbolic one."""
    from integrator_bench.problems.mechanical import MechanicalProblem
    symbolic = registry.get_problem_class("kapitza")

    class Numeric(MechanicalProblem):
        name = "test-numeric-kapitza"
        coordinates, n_constraints, t_span = ("x", "y"), 1, symbolic.t_span
        parameters, driven = symbolic.parameters, True
        start, support = symbolic.start, symbolic.support

        def mass(self, q):
            return self.params["m"] * np.eye(2)

        def force(self, t, q, v):
            return np.array([0.0, -self.params["m"] * self.params["g"]])

        def force_q(self, t, q, v):
            return np.zeros((2, 2))

        force_v = force_q

        def mass_q(self, q, a):
            return np.zeros((2, 2))

        def constraint(self, q, t):
            return np.array([(q[0] ** 2 + (q[1] - self.support(t)[0]) ** 2
                              - self.params["L"] ** 2) / 2])

        def constraint_jac(self, q, t):
            return np.array([[q[0], q[1] - self.support(t)[0]]])

        def gv_q(self, q, v, t):
            return v.reshape(1, 2).copy()

        def gt_q(self, q, lam, t):
            return lam[0] * np.eye(2)

        def constraint_t(self, q, t):
            s, ds, _ = self.support(t)
            return np.array([-(q[1] - s) * ds])

        def constraint_jac_t(self, q, t):
            return np.array([[0.0, -self.support(t)[1]]])

        def accel_term(self, q, v, t):
            s, ds, dds = self.support(t)
            return np.array([v @ v - 2 * ds * v[1] + ds * ds - (q[1] - s) * dds])

    return Numeric(), symbolic()


def test_a_driven_model_written_by_hand_gives_every_formulation_the_symbolic_one_does():
    """The numeric path of a driven ``MechanicalProblem`` (its own constraint functions
    of the time, the base class's solves) against the symbolic model (compiled, the
    augmented system in one call): the same derivatives, consistent start, and
    right-hand sides, residuals, Jacobians and projections of every formulation."""
    from test_mechanical import check_model_derivatives
    numeric, symbolic = numeric_kapitza()
    rng = np.random.default_rng(5)
    t, q, v = 0.37, np.array([0.3, 1.0]), rng.standard_normal(2)
    lam, a = rng.standard_normal(1), rng.standard_normal(2)
    check_model_derivatives(numeric, t, q, v, a, lam)
    for name, args in (("constraint", (q, t)), ("constraint_jac", (q, t)),
                       ("gv_q", (q, v, t)), ("accel_term", (q, v, t)), ("gt_q", (q, lam, t)),
                       ("constraint_t", (q, t)), ("constraint_jac_t", (q, t))):
        np.testing.assert_allclose(getattr(numeric, name)(*args), getattr(symbolic, name)(*args),
                                   rtol=1e-13, atol=1e-13, err_msg=name)
    for x, y in zip(numeric.consistent_start(), symbolic.consistent_start()):
        np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-12)
    for form in numeric.formulations:
        ns, ss = numeric.formulate(form), symbolic.formulate(form)
        y = ns.y0 + 1e-3 * rng.standard_normal(ns.n)
        if ns.kind == "dae":
            yp = ns.yp0 + 1e-3 * rng.standard_normal(ns.n)
            pairs = [(ns.residual(t, y, yp), ss.residual(t, y, yp))]
            if ns.jac is not None:
                pairs.append((ns.jac(t, y, yp, 2.0), ss.jac(t, y, yp, 2.0)))
        elif ns.kind == "ode":
            pairs = [(ns.fun(t, y), ss.fun(t, y)), (ns.output(t, y), ss.output(t, y))]
            if ns.project is not None:
                pairs.append((ns.project(t, y), ss.project(t, y)))
        else:                                     # al3: the mechanical callables
            qs = y[:2]
            pairs = [(ns.constraint(qs, t), ss.constraint(qs, t)),
                     (ns.accel_term(qs, y[2:4], t), ss.accel_term(qs, y[2:4], t)),
                     (ns.velocity_term(qs, t), ss.velocity_term(qs, t))]
        for got, want in pairs:
            np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-10, err_msg=form)
