"""A bouncing ball with Newton's restitution law: exact event times and states.

A ball dropped from rest at height ``h0`` falls under gravity ``g``,
``y' = v``, ``v' = -g``, and hits the floor ``y = 0``; at each impact the
velocity is reversed and scaled by the coefficient of restitution ``e``,
``v+ = -e v-`` (Newton's impact law; Glocker, "Set-Valued Force Laws", Springer
2001, sect. 7; the same test case in Hairer, Norsett and Wanner I, sect.
II.6, and in scipy's ``solve_ivp`` documentation). The impact is a terminal
state event ``"impact"`` on ``y`` falling through 0 whose reset applies the law
and restarts the integration.

Closed form (the harness's own check of its event measurement): the first
impact comes at ``t1 = sqrt(2 h0 / g)`` with speed ``v1 = g t1``; the ball leaves
impact ``k`` upward at ``e^k v1`` and flies ``2 e^k t1`` until the next, so

    t_k = t1 (1 + 2 sum_{j=1}^{k-1} e^j),

and between impacts the motion is a parabola. For ``e < 1`` the impacts
accumulate at the Zeno point ``t_inf = t1 (1 + e) / (1 - e)``, where infinitely
many impacts happen in finite time and no integrator can pass. The cut-off:
``t_end`` (parameter, default 3.4 s: 8 impacts with the defaults h0 = 1 m,
g = 9.81 m/s^2, e = 0.8, whose Zeno point is 4.06 s, the 8th impact at 3.306 s
and the 9th at 3.457 s) must lie before ``t_inf``; a ``t_end`` at or past it
is refused with a :class:`~integrator_bench.problems.base.ProblemError` naming
it. ``e = 0`` (the ball stays on the floor, the event function stays 0) is
refused too.
"""

from __future__ import annotations

import math

import numpy as np

from integrator_bench.problems.base import Parameter, Problem, ProblemError
from integrator_bench.problems.system import Event, OdeSystem

IMPACT = "impact"


class BouncingBall(Problem):
    name = "bouncing_ball"
    description = "Ball bouncing on a floor, restitution e: exact impact times and states"
    source = ("Newton's impact law v+ = -e v- (Glocker, Set-Valued Force Laws, 2001); "
              "closed-form parabolas between impacts")
    components = ("y", "v")
    t_span = (0.0, 3.4)
    parameters = (
        Parameter("h0", 1.0, 1e-6, 1e6, "drop height (m), from rest"),
        Parameter("g", 9.81, 1e-6, 1e6, "gravity (m/s^2)"),
        Parameter("e", 0.8, 0.0, 1.0, "coefficient of restitution, in (0, 1]"),
        Parameter("t_end", 3.4, 1e-6, 1e6, "end time (s), before the Zeno point"),
    )
    error_components = ("y",)
    velocity_components = ("v",)
    atol_scale = 1.0

    def __init__(self, **params):
        super().__init__(**params)
        p = self.params
        if p["e"] <= 0.0:
            raise ProblemError(f"parameter e={p['e']:g} is outside its range (0, 1]: "
                               "at e = 0 the ball stays on the floor")
        zeno = self.zeno_time()
        if p["t_end"] >= zeno:
            raise ProblemError(
                f"parameter t_end={p['t_end']:g} is at or past the Zeno point "
                f"t_inf = t1 (1 + e) / (1 - e) = {zeno:.6g} s; give t_end < {zeno:.6g}")
        self.t_span = (0.0, p["t_end"])

    # ------------------------------------------------------------ closed form
    def first_impact(self) -> float:
        """``t1 = sqrt(2 h0 / g)``."""
        return math.sqrt(2.0 * self.params["h0"] / self.params["g"])

    def zeno_time(self) -> float:
        """``t_inf = t1 (1 + e) / (1 - e)``; infinite for ``e = 1``."""
        e = self.params["e"]
        return math.inf if e >= 1.0 else self.first_impact() * (1.0 + e) / (1.0 - e)

    def impact_times(self, t_end: float | None = None) -> np.ndarray:
        """The impact times ``t_k <= t_end`` (default the problem's end time)."""
        t_end = self.t_span[1] if t_end is None else t_end
        t1, e = self.first_impact(), self.params["e"]
        times, t, flight = [], t1, 2.0 * e * t1
        while t <= t_end:
            times.append(t)
            t, flight = t + flight, flight * e
        return np.array(times)

    def exact_events(self) -> list[tuple[float, str, np.ndarray]]:
        """Every impact in the span: ``(t_k, "impact", (0, e^k v1))``, the state
        right after it (on the floor, leaving upward)."""
        v1 = self.params["g"] * self.first_impact()
        e = self.params["e"]
        return [(float(t), IMPACT, np.array([0.0, v1 * e ** (k + 1)]))
                for k, t in enumerate(self.impact_times())]

    def exact(self, t):
        """``(y, v)`` at times ``t``: the parabola of the flight each time is in
        (the state after an impact at an impact time itself)."""
        t = np.asarray(t, float)
        g, e, h0 = self.params["g"], self.params["e"], self.params["h0"]
        times = self.impact_times(float(np.max(t, initial=0.0)))
        v1 = g * self.first_impact()
        k = np.searchsorted(times, t, side="right")          # impacts at or before t
        start = np.concatenate([[0.0], times])[k]
        v0 = np.where(k == 0, 0.0, v1 * e ** k)
        y0 = np.where(k == 0, h0, 0.0)
        s = t - start
        return np.column_stack([y0 + v0 * s - 0.5 * g * s ** 2, v0 - g * s])

    # ------------------------------------------------------------ the system
    def initial_state(self):
        return np.array([self.params["h0"], 0.0])

    def rhs(self, t, y):
        return np.array([y[1], -self.params["g"]])

    def jac(self, t, y):
        return np.array([[0.0, 1.0], [0.0, 0.0]])

    def impact_event(self) -> Event:
        """``y`` falling through 0, terminal; the reset keeps ``y`` and sets
        ``v <- -e v``."""
        e = self.params["e"]
        return Event(lambda t, y: y[0], direction=-1, terminal=True,
                     reset=lambda t, y: np.array([y[0], -e * y[1]]), name=IMPACT)

    def formulate(self, formulation: str = "ode") -> OdeSystem:
        system = super().formulate(formulation)
        system.events = (self.impact_event(),)
        return system
