"""The chain drive's pieces that the asv suite and ``studies/chain_scaling.py`` time.

One place for the systems and evaluations measured at each size: the asv class
``chain_scaling_asv.ChainScaling`` follows them over commits, the study fits
their log-log slopes. The package is imported inside the functions, so that asv
can import this module in an environment whose installed commit lacks it (the
benchmark then skips in ``setup``).
"""

from __future__ import annotations

from benchmarks._snapshot import harness_module

PROBLEM = "chain_drive"
CJ = 1e4  # the cj of a step of about 1e-4 s, for the iteration matrix


def problem(n_links: int, t_end: float):
    """The chain at ``n_links`` with default parameters, 16 teeth where they fit."""
    registry = harness_module("registry")

    teeth = 16 if n_links >= 18 else max(4, n_links - 2 - n_links % 2)
    return registry.get_problem_class(PROBLEM)(n_links=n_links, teeth=teeth, t_end=t_end)


def ida_system(chain):
    """The ``ggl`` system as IDA gets it."""
    registry = harness_module("registry")
    from integrator_bench.problems.system import convert

    return convert(chain.formulate("ggl"), registry.get_integrator("ida"))


def pieces(chain) -> dict:
    """The evaluations timed, each a callable without arguments."""
    import numpy as np

    registry = harness_module("registry")
    from integrator_bench.integrators.sparse import on_pattern, pattern
    from integrator_bench.problems.system import convert

    ode, ggl = chain.formulate("ode"), ida_system(chain)
    mech = convert(chain.formulate("i3"), registry.get_integrator("hht"))
    q, v, a, lam = chain.consistent_start()
    t = 0.25 * chain.t_span[1]  # inside the drive's ramp
    y_ode, y, yp = ode.y0, ggl.y0, ggl.yp0
    P = pattern(ggl.jac_sparsity)

    def jac():
        return (chain.force_q(t, q, v), chain.force_v(t, q, v), chain.constraint_jac(q),
                chain.gv_q(q, v))

    def i3_res():
        f, g, G = mech.force(t, q, v), mech.constraint(q), mech.constraint_jac(q)
        return np.concatenate([mech.mass(q) @ a + G.T @ lam - f, g])

    return {"rhs_s": lambda: ode.fun(t, y_ode), "jac_s": jac,
            "ggl_res_s": lambda: ggl.residual(t, y, yp),
            "ggl_jac_s": lambda: on_pattern(ggl.jac(t, y, yp, CJ), P),
            "i3_res_s": i3_res, "i3_jac_s": lambda: mech.tangent(t, q, v, a, lam)}
