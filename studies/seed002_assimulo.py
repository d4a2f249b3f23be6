"""Seed 002's Assimulo runs, reproduced through the harness with Assimulo itself.

The seed (the Lund FMNN05 "Simulation tools" project report: spring pendulum and
Andrews' squeezer, run in Assimulo and Dymola) gives Assimulo's statistics in its
Table 3 (spring pendulum, k = 100, t = 10, tol 1e-8: CVODE Adams) and Table 5
(squeezer over 0.03 s with IDA: index 2 with a large ATOL on the multipliers,
index 2 with ``algvar``/``suppress_alg``, index 3 with a large ATOL on the
velocities and multipliers), and describes RungeKutta34 on the index-1 (ODE)
squeezer stopping near t = 0.023. Each row below is one case of the matrix
(:func:`~integrator_bench.harness.run.runner.execute`); the report's variants that are
not integrators of the registry are registered here for the run:

* ``-atol``: no ``suppress_alg``; atol 1e10 (or the value in the name) on the
  variables outside the error mask (the report's "setting their ATOL-values
  very high", value not given);
* ``-algvar-lam``: ``suppress_alg`` with ``algvar`` marking the multipliers only
  (velocities kept in the error test: what the report tried on index 3);
* ``-fd``: Assimulo's difference-quotient Jacobian (the report gives no
  Jacobian), so that its statistics count as the report's did.

The report states no tolerances for the squeezer; Assimulo's IDA defaults, rtol
and atol 1e-6, are used. Output: a Markdown table, the report's numbers beside
ours. ``python studies/seed002_assimulo.py`` (about 10 s).
"""

from __future__ import annotations

import argparse

import numpy as np

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.run.execution import execute
from integrator_bench.integrators.assimulo import IDA, AssimuloIntegrator



class IdaAtol(IDA):
    name = "assimulo-ida-atol"
    excluded_atol = 1e10

    def configure(self, solver, system, rtol, atol):
        AssimuloIntegrator.configure(self, solver, system, rtol,
                                     np.where(system.error_mask, atol, self.excluded_atol))


def _atol(value):
    return type(f"IdaAtol{value:g}", (IdaAtol,),
                {"name": f"assimulo-ida-atol{value:g}", "excluded_atol": value})


class IdaAlgvarLam(IDA):
    name = "assimulo-ida-algvar-lam"

    def configure(self, solver, system, rtol, atol):
        AssimuloIntegrator.configure(self, solver, system, rtol, atol)
        solver.algvar = (~system.algebraic).astype(float)
        solver.suppress_alg = True


def _fd(cls):
    return type(cls.__name__ + "FD", (cls,), {"name": cls.name + "-fd", "uses_jacobian": False})


ATOLS = (1e4, 1e5, 1e6)   # the report does not say how high its ATOL was
VARIANTS = [IdaAtol, IdaAlgvarLam, _fd(IDA), _fd(IdaAtol), _fd(IdaAlgvarLam),
            *(_fd(_atol(v)) for v in ATOLS)]

#: (label, problem, formulation, integrator, rtol, the report's numbers)
ROWS = [
    ("Table 3: CVODE (Adams)", "spring_pendulum", "ode", "assimulo-cvode-adams", 1e-8,
     "1007 steps, 1227 f"),
    ("Table 3: Lsodar (Dymola's)", "spring_pendulum", "ode", "assimulo-lsodar", 1e-8,
     "1106 steps, 2309 f"),
    ("Table 5: index 2, ATOL", "squeezer", "i2", "assimulo-ida-atol-fd", 1e-6,
     "910 steps, 1511 f, 75 J, 0 NCF"),
    ("Table 5: index 2, algvar", "squeezer", "i2", "assimulo-ida-fd", 1e-6,
     "617 steps, 1613 f, 120 J, 0 NCF"),
    ("Table 5: index 3, ATOL", "squeezer", "i3", "assimulo-ida-atol-fd", 1e-6,
     "707 steps, 1496 f, 784 J, 120 NCF"),
    *((f"index 3, ATOL {v:g}", "squeezer", "i3", f"assimulo-ida-atol{v:g}-fd", 1e-6, "")
      for v in ATOLS),
    ("index 3, suppress_alg on lambda", "squeezer", "i3", "assimulo-ida-algvar-lam-fd", 1e-6,
     "no result"),
    ("index 3, suppress_alg on v, lambda", "squeezer", "i3", "assimulo-ida-fd", 1e-6, "-"),
    ("index 3, suppress_alg, analytic J", "squeezer", "i3", "assimulo-ida", 1e-6, "-"),
    ("index 3, RADAU5", "squeezer", "i3", "assimulo-radau5", 1e-6, "-"),
    ("index 1 (ODE), RungeKutta34", "squeezer", "ode", "assimulo-rk34", 1e-6,
     "stops near t = 0.023"),
    ("index 1 (ODE), CVode", "squeezer", "ode", "assimulo-cvode-bdf", 1e-6, "reaches 0.03"),
]


def run(rows=ROWS):
    """The records of ``rows``, with the report's variants registered meanwhile."""
    for cls in VARIANTS:
        registry.register(cls, origin="seed002_assimulo")
    try:
        out = []
        for label, problem, form, name, rtol, seed in rows:
            case = next(iter(expand(problems=[problem], formulations=[form],
                                    integrators=[name], rtols=[rtol])))
            out.append((label, seed, execute(case)))
        return out
    finally:
        for cls in VARIANTS:
            registry.unregister(cls.name)


def _own_f(record):
    """Assimulo's f count as the report's tables give it (its ``nfcns``): without the
    calls of difference-quotient Jacobians (``nfev_jac``)."""
    counts = record.get("solver_counts") or {}
    return record["nfev"] - counts.get("nfev_jac", 0)


def table(results) -> str:
    lines = ["| run | seed 002 | status | steps | f | J | error-test fails | NCF | scd |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|"]
    for label, seed, r in results:
        scd = "" if r["scd"] is None else f"{r['scd']:.2f}"
        cells = [r["nsteps"], _own_f(r) if r["status"] == "ok" else None, r["njev"],
                 r["nreject"], r["nnfail"]]
        cells = ["" if c is None else str(c) for c in cells]
        status = r["status"] if r["status"] == "ok" else f"{r['status']} ({r['reason']})"
        lines.append(f"| {label} | {seed} | {status} | " + " | ".join(cells) + f" | {scd} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args(argv)
    print(table(run()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
