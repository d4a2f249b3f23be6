"""Shared fixtures: deliberately failing integrators, registered in the tests only."""

import os
import signal
import time

import numpy as np
import pytest

from harness import registry
from integrators.base import Integrator, Solution


class _Broken(Integrator):
    description = "deliberately broken (tests only)"
    accepts = frozenset({"ode"})


class Raises(_Broken):
    name = "test-raises"

    def solve(self, system, **kw):
        raise RuntimeError("deliberate failure")


class GivesUp(_Broken):
    name = "test-gives-up"

    def solve(self, system, **kw):
        system.fun(system.t0, system.y0)
        return Solution(system.t_eval[:1], system.y0[None, :], False, "step size too small",
                        {"nsteps": 0})


class ReturnsNaN(_Broken):
    name = "test-nan"

    def solve(self, system, **kw):
        return Solution(system.t_eval, np.full((system.t_eval.size, system.n), np.nan))


class Hangs(_Broken):
    name = "test-hangs"

    def solve(self, system, **kw):
        while True:
            time.sleep(0.05)


class Segfaults(_Broken):
    name = "test-segfault"

    def solve(self, system, **kw):
        os.kill(os.getpid(), signal.SIGSEGV)


class MechanicalOnly(_Broken):
    name = "test-mechanical-only"
    accepts = frozenset({"mechanical"})


BROKEN = (Raises, GivesUp, ReturnsNaN, Hangs, Segfaults, MechanicalOnly)


@pytest.fixture
def broken_integrators():
    for cls in BROKEN:
        registry.register(cls, origin="tests")
    yield {cls.name: cls for cls in BROKEN}
    for cls in BROKEN:
        registry.unregister(cls.name)


@pytest.fixture
def store_path(tmp_path):
    return tmp_path / "store.sqlite"
