"""Tangent parametrization (TP) of a constrained mechanical system, as Sudarsan
and Keerthi specialize it (Appl. Math. Comput. 92 (1998) 195-218, Section 4.1,
Procedure TP-CMS; after Mani et al., its Ref. [7]): the ``tangent`` formulation
(:mod:`integrator_bench.problems.formulations`).

A chart at a point ``q0`` of the position manifold: the QR decomposition
``G(q0)^T = [V U] [R1; 0]``, so that the columns of ``V`` (``nq x nc``) span the
row space of ``G`` and those of ``U`` (``nq x (nq - nc)``) the tangent plane.
What is integrated is ``Y = (y, y')``, ``2 (nq - nc)`` numbers, with
``q = q0 + U y + V z`` and ``v = U y' + V z'``: given ``Y``, ``z`` solves
``g(q0 + U y + V z) = 0`` (Newton with the Jacobian ``G V``; the paper's "MNR iteration")
and ``z'`` the velocity constraint ``G V z' = -G U y'``; the ODE is
``Y' = diag(U, U)^T f(q, v) = (y', U^T a(q, v))`` (the paper's eq. (4.2)).

A new chart is taken at the current point when ``||y'|| / ||v||`` falls below
``p = 0.5`` (the paper's criterion after Mani et al.): a terminal state event
``||y'|| - p ||v|| = 0`` whose reset restarts the integration in the new chart
(``Y = (0, U^T v)``), "an integration restart" as the paper says; the number of
new charts is the record's ``nevents`` (the paper's NP). The outputs map each
``Y`` to ``(q, v, lam)`` through the chart in force at its time.

Differences from the paper, named: the error test is on ``Y`` with the problem's
position and velocity scales, not the paper's weights transformed from ``(q, v)``
(its ``W_y``); the Newton iteration renews ``G V`` at every iteration (the paper's
MNR, not spelled out in its text, reads as a modified Newton-Raphson that keeps it);
dense problems only (the QR is dense), and a Jacobian of full row rank (``nc``
independent constraints). A driven problem (``g(q, t) = 0``) lifts at the time
of each evaluation, ``z'`` from ``G V z' = -(G U y' + g_t)``, and its criterion
is measured on the tangential part of ``v`` (:func:`tangential_ratio`): ``v``
itself also carries the driving, normal to the manifold.
"""

from __future__ import annotations

import numpy as np

from integrator_bench.problems.system import Event, OdeSystem

#: a new chart when ||y'|| / ||v|| falls below this (Sudarsan and Keerthi, "say, p = 0.5")
RATIO = 0.5
NEWTON_ITERATIONS = 20


class Charts:
    """The charts of one run: the one in force, and from which time each held."""

    def __init__(self, problem, q0, t0):
        self.problem = problem
        self.history: list[tuple[float, dict]] = []
        self.new(t0, q0)

    def new(self, t, q) -> dict:
        """A chart at ``q`` (on the position manifold), in force from ``t`` on."""
        nc = self.problem.nc
        Q, _ = np.linalg.qr(np.asarray(self.problem.constraint_jac(q, *self.problem.at(t)),
                                       float).T, mode="complete")
        chart = {"q0": np.array(q, float), "V": Q[:, :nc], "U": Q[:, nc:],
                 "z": np.zeros(nc)}
        self.history.append((float(t), chart))
        return chart

    @property
    def current(self) -> dict:
        return self.history[-1][1]

    def at(self, t) -> dict:
        """The chart in force at ``t`` (a chart taken at ``t`` holds from ``t`` on)."""
        for start, chart in reversed(self.history):
            if start <= t:
                return chart
        return self.history[0][1]

    def lift(self, chart, Y, t, z=None):
        """``(q, v)`` of ``Y`` in ``chart`` at time ``t`` (the constraints of a driven
        problem move), Newton starting from ``z`` (default: the
        chart's last solution, kept for the next; the normal line may meet the
        manifold again a turn of a crank away, so Newton starts near the point
        sought); LinAlgError when Newton does not reach the position manifold."""
        p, k = self.problem, chart["U"].shape[1]
        U, V = chart["U"], chart["V"]
        y, yd = Y[:k], Y[k:]
        base = chart["q0"] + U @ y
        keep = z is None
        z = chart["z"].copy() if keep else np.array(z, float)
        scale = 1e-13 * max(1.0, float(np.max(np.abs(base))))
        at = p.at(t)
        for _ in range(NEWTON_ITERATIONS):
            q = base + V @ z
            r = p.constraint(q, *at)
            G = np.asarray(p.constraint_jac(q, *at), float)
            if np.max(np.abs(r)) <= scale:
                break
            z = z - np.linalg.solve(G @ V, r)
        else:
            raise np.linalg.LinAlgError("no point of the chart's normal plane on the "
                                        "position constraints")
        if keep:
            chart["z"] = z             # the next solve starts here
        else:
            self.last_z = z
        rhs = -(G @ (U @ yd))
        if p.driven:                   # G V z' = -(G U y' + g_t)
            rhs = rhs - p.constraint_t(q, t)
        zd = np.linalg.solve(G @ V, rhs)
        return q, U @ yd + V @ zd


def tangential_ratio(problem, chart, t, q, v) -> float:
    """The chart criterion of a driven problem: ``||U^T w|| - p ||w||`` for ``w`` the
    component of ``v`` in the current tangent plane (``v`` less its part along
    the rows of ``G``, which carries the driving, ``-g_t``). Without driving ``w
    = v`` and ``U^T w = y'``: the paper's ``||y'|| - p ||v||``; with it, ``v`` also
    moves normal to the manifold, which says nothing about how well the chart
    still fits it."""
    G = np.asarray(problem.constraint_jac(q, *problem.at(t)), float)
    w = v - G.T @ np.linalg.solve(G @ G.T, G @ v)
    return float(np.linalg.norm(chart["U"].T @ w) - RATIO * np.linalg.norm(w))


def tangent_system(problem, q0, v0, common) -> OdeSystem:
    """The ``tangent`` formulation of ``problem`` from the consistent start ``(q0,
    v0)``: the ODE in ``Y = (y, y')`` with its re-parametrizing event."""
    charts = Charts(problem, q0, common["t0"])
    nq = problem.nq

    def fun(t, Y):
        """``(y', U^T a)``; NaN, left to the integrator's failure handling, where the
        chart's normal plane misses the manifold or the augmented matrix is singular."""
        chart = charts.current
        try:
            q, v = charts.lift(chart, Y, t)
            a, _ = problem.accelerations(t, q, v)
        except np.linalg.LinAlgError:
            return np.full_like(Y, np.nan)
        k = chart["U"].shape[1]
        return np.concatenate([Y[k:], chart["U"].T @ a])

    def ratio(t, Y):
        chart = charts.current
        k = chart["U"].shape[1]
        try:
            q, v = charts.lift(chart, Y, t)
        except np.linalg.LinAlgError:
            return -1.0
        if problem.driven:
            return tangential_ratio(problem, chart, t, q, v)
        return float(np.linalg.norm(Y[k:]) - RATIO * np.linalg.norm(v))

    def reparametrize(t, Y):
        q, v = charts.lift(charts.current, Y, t)
        chart = charts.new(t, q)
        return np.concatenate([np.zeros(chart["U"].shape[1]), chart["U"].T @ v])

    def output(t, Ys):
        """``(q, v, lam)`` of each row through the chart in force at its time, Newton
        following the rows from the chart's point on (rows in time order)."""
        Ys = np.atleast_2d(Ys)
        ts = np.broadcast_to(np.asarray(t, float), (len(Ys),))
        rows, follow = [], {}
        for ti, Y in zip(ts, Ys):
            chart = charts.at(ti)
            try:
                q, v = charts.lift(chart, Y, ti, follow.get(id(chart), np.zeros(problem.nc)))
                follow[id(chart)] = charts.last_z
                lam = problem.accelerations(ti, q, v)[1]
            except np.linalg.LinAlgError:
                q = v = np.full(nq, np.nan)
                lam = np.full(problem.nc, np.nan)
            rows.append(np.concatenate([q, v, lam]))
        return np.array(rows).reshape(len(Ys), 2 * nq + problem.nc)

    k = nq - problem.nc
    U = charts.current["U"]
    scale = np.concatenate([np.full(k, problem.position_scale),
                            np.full(k, problem.velocity_scale)])
    system = OdeSystem(
        y0=np.concatenate([np.zeros(k), U.T @ v0]), atol_scale=scale, output=output,
        fun=fun, jac=None,
        events=(Event(ratio, -1, True, reparametrize, "new_chart"),), **common)
    system.charts = charts          # read-only view for diagnostics and tests
    return system
