"""Shared fixtures: deliberately failing integrators, registered in the tests only."""

import os
import signal
import time

import numpy as np
import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.integrators.base import Integrator, Solution


@pytest.fixture(autouse=True)
def _one_timed_sample(request, monkeypatch):
    """A case run in the tests is solved once, counted and timed, and not sampled
    again (the sampling itself, up to ten samples or 0.2 s of CPU, is tested in
    test_timing.py): the suite runs a few thousand cases, and sampling each would
    add minutes to it.
    Worker processes are forked from the test process and inherit the setting."""
    if request.module.__name__.rpartition(".")[2] == "test_timing":
        return
    from integrator_bench.harness.run import execution
    monkeypatch.setattr(execution, "MAX_SAMPLES", 1)


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


class HogsMemory(_Broken):
    """Maps 8 GiB without touching it: harmless unbounded, refused under the
    per-case memory limit (RLIMIT_AS, default 4096 MB)."""
    name = "test-memory-hog"

    def solve(self, system, **kw):
        chunks = [np.empty(2**29, np.uint8) for _ in range(16)]
        return Solution(system.t_eval, np.zeros((system.t_eval.size, system.n)), True,
                        f"mapped {len(chunks) * 512} MiB")


class Overflows(_Broken):
    name = "test-overflow"

    def solve(self, system, **kw):
        import math
        return math.exp(1e6)  # OverflowError, as a diverging solution gives in math.cos etc.


class MechanicalOnly(_Broken):
    name = "test-mechanical-only"
    accepts = frozenset({"mechanical"})


BROKEN = (Raises, GivesUp, ReturnsNaN, Hangs, Segfaults, HogsMemory, Overflows, MechanicalOnly)


@pytest.fixture
def broken_integrators():
    for cls in BROKEN:
        registry.register(cls, origin="tests")
    yield {cls.name: cls for cls in BROKEN}
    for cls in BROKEN:
        registry.unregister(cls.name)


@pytest.fixture(scope="session")
def run_cases():
    """``run_cases(cases, context, **batch)``: ``cases`` run as one batch in a
    :class:`~integrator_bench.harness.run.runner.Session` of ``context`` (a
    :class:`~integrator_bench.harness.run.context.RunContext`), their DataFrame
    returned; ``batch`` is what :meth:`Session.run` takes (``budget_s``,
    ``deadline``, ``on_record``, ``on_dispatch``)."""
    from integrator_bench.harness.run.runner import Session

    def run(cases, context, **batch):
        with Session(context) as session:
            return session.run(cases, **batch)

    return run


@pytest.fixture
def store_path(tmp_path):
    return tmp_path / "store.sqlite"


@pytest.fixture(scope="session")
def built_fmus(tmp_path_factory):
    """model -> path of its FMU, built once per session from the project's C
    sources (problems/fmu_sources) with the system's C compiler."""
    from integrator_bench.problems import fmu_build

    out = tmp_path_factory.mktemp("fmus")
    return {model: fmu_build.build_fmu(model, out) for model in fmu_build.MODELS}


@pytest.fixture(scope="session")
def built_fmus3(tmp_path_factory):
    """model -> path of its FMI 3.0 FMU, built as ``built_fmus`` builds FMI 2.0 ones."""
    from integrator_bench.problems import fmu_build

    out = tmp_path_factory.mktemp("fmus3")
    return {model: fmu_build.build_fmu(model, out, fmi_version="3.0")
            for model in fmu_build.MODELS}


@pytest.fixture(scope="session")
def hostile_fmu(tmp_path_factory):
    """The FMU of ``tests/fmu_hostile``, built once per session: exponential decay
    whose state and parameter are named with path traversals."""
    pytest.importorskip("fmpy")
    from pathlib import Path

    from integrator_bench.problems import fmu_build
    try:
        return fmu_build.build_fmu("hostile", tmp_path_factory.mktemp("hostile"),
                                   source_dir=Path(__file__).resolve().parent / "fmu_hostile")
    except RuntimeError as exc:
        pytest.skip(str(exc))


@pytest.fixture(scope="session")
def chatty_fmus(tmp_path_factory):
    """FMI version -> the FMU of ``tests/fmu_chatty``, built once per session:
    exponential decay that, at the start time, logs a warning through the
    importer's logger and prints a line to C's standard output."""
    pytest.importorskip("fmpy")
    from pathlib import Path

    from integrator_bench.problems import fmu_build
    out = tmp_path_factory.mktemp("chatty")
    try:
        return {v: fmu_build.build_fmu("chatty", out, fmi_version=v,
                                       source_dir=Path(__file__).resolve().parent / "fmu_chatty")
                for v in fmu_build.FMI_VERSIONS}
    except RuntimeError as exc:
        pytest.skip(str(exc))
