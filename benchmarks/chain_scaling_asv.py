"""asv figures of the chain drive's cost against its size.

One class, parametrized over the number of links (10, 100, 1000), so that asv
follows over commits how the closed chain ``chain_drive`` scales; the full
table and its log-log slopes come from ``studies/chain_scaling.py``; both time
the pieces of :mod:`benchmarks.chain_pieces` (the same evaluations, systems and runs):

``time_ggl_residual``, ``time_ggl_jacobian``
    the ``ggl`` residual, and its iteration matrix laid on SUNDIALS' sparse
    structure, as IDA's callbacks get them;
``time_ida_run``, ``time_hht_run``
    one run of IDA on ``ggl`` and of HHT on ``i3`` over ``[0, T_END]`` at
    ``RTOL`` (CPU seconds, ``time.process_time``);
``track_ida_cpu_per_step``, ``track_hht_cpu_per_step``
    the CPU of one such run divided by its accepted steps;
``track_ida_nsteps``, ``track_hht_nsteps``
    those steps (a change of the step count explains a change of the run time).

A commit without ``chain_drive`` (or without the harness package layout the
script needs) skips every combination in ``setup`` with NotImplementedError,
as ``benchmarks/cases.py`` skips what a commit cannot run.
"""

from __future__ import annotations

import time

from benchmarks._snapshot import harness_module

T_END = 0.01  # s: the start of the drive's ramp, about 150 IDA and 40 HHT steps
RTOL = 1e-5


def _script():
    """:mod:`benchmarks.chain_pieces` with the installed commit's packages, or
    NotImplementedError when that commit cannot provide them."""
    from benchmarks import chain_pieces

    try:
        registry = harness_module("registry")
        from integrator_bench.integrators.sparse import on_pattern  # noqa: F401
    except ImportError as exc:  # a commit before the package namespace or the sparse path
        raise NotImplementedError(f"not at this commit: {exc}") from None
    if chain_pieces.PROBLEM not in registry.problems():
        raise NotImplementedError(f"{chain_pieces.PROBLEM} is not registered at this commit")
    return chain_pieces


class ChainScaling:
    """The chain drive at 10, 100 and 1000 links."""

    params = [[10, 100, 1000]]
    param_names = ["n_links"]
    timer = time.process_time
    timeout = 600.0

    def setup(self, n_links):
        cs = self.cs = _script()
        registry = harness_module("registry")
        from integrator_bench.problems.system import convert

        chain = cs.problem(n_links, T_END)
        self.pieces = cs.pieces(chain)
        self.ida = cs.ida_system(chain)
        self.hht = convert(chain.formulate("i3"), registry.get_integrator("hht"))
        self.integrators = {"ida": registry.get_integrator("ida"),
                            "hht": registry.get_integrator("hht")}

    def _run(self, name):
        system = self.ida if name == "ida" else self.hht
        sol = self.integrators[name]().solve(system, rtol=RTOL, atol=system.atol(RTOL))
        if not sol.success:
            raise RuntimeError(f"{name} failed on chain_drive: {sol.message}")
        return sol

    def _per_step(self, name):
        start = time.process_time()
        sol = self._run(name)
        return (time.process_time() - start) / sol.counts["nsteps"]

    def time_ggl_residual(self, n_links):
        self.pieces["ggl_res_s"]()

    def time_ggl_jacobian(self, n_links):
        self.pieces["ggl_jac_s"]()

    def time_ida_run(self, n_links):
        self._run("ida")

    time_ida_run.number = 1
    time_ida_run.repeat = (1, 5, 60.0)

    def time_hht_run(self, n_links):
        self._run("hht")

    time_hht_run.number = 1
    time_hht_run.repeat = (1, 5, 60.0)

    def track_ida_cpu_per_step(self, n_links):
        return self._per_step("ida")

    track_ida_cpu_per_step.unit = "CPU s per step"

    def track_hht_cpu_per_step(self, n_links):
        return self._per_step("hht")

    track_hht_cpu_per_step.unit = "CPU s per step"

    def track_ida_nsteps(self, n_links):
        return self._run("ida").counts["nsteps"]

    track_ida_nsteps.unit = "steps"

    def track_hht_nsteps(self, n_links):
        return self._run("hht").counts["nsteps"]

    track_hht_nsteps.unit = "steps"
