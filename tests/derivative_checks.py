"""A model's derivatives against central differences, for the tests of every
mechanical problem (tests/problems/) and of the large ones (tests/problems/models/)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def fd(fun, x, h=1e-7):
    cols = []
    for j in range(x.size):
        e = np.zeros(x.size)
        e[j] = h * max(1.0, abs(x[j]))
        cols.append((np.asarray(fun(x + e)) - np.asarray(fun(x - e))) / (2 * e[j]))
    return np.column_stack(cols)


def check_model_derivatives(p, t, q, v, a, lam):
    """Every derivative of ``p``'s model at (t, q, v, a, lam) against central
    differences; dense or sparse (compared densely: tests use small models). A
    driven problem's time derivatives too: ``g_t`` and ``G_t`` against
    differences in time, and the acceleration term against the time derivative
    of the velocity constraint ``G v + g_t`` along ``q' = v``, ``v' = 0``. ``p`` may
    be any object with the model's functions (no ``driven``: not driven)."""
    driven = getattr(p, "driven", False)
    at = (t,) if driven else ()
    checks = [
        (p.constraint_jac(q, *at), fd(lambda x: p.constraint(x, *at), q)),
        (p.gv_q(q, v, *at), fd(lambda x: p.constraint_jac(x, *at) @ v, q)),
        (p.force_q(t, q, v), fd(lambda x: p.force(t, x, v), q)),
        (p.force_v(t, q, v), fd(lambda x: p.force(t, q, x), v)),
        (p.mass_q(q, a), fd(lambda x: p.mass(x) @ a, q)),
        (p.gt_q(q, lam, *at), fd(lambda x: p.constraint_jac(x, *at).T @ lam, q)),
    ]
    if driven:
        tt = np.array([t])
        checks += [
            (p.constraint_t(q, t)[:, None], fd(lambda s: p.constraint(q, s[0]), tt)),
            (p.constraint_jac_t(q, t), fd(lambda x: p.constraint_t(x, t), q)),
            (p.constraint_jac_t(q, t).ravel()[:, None],
             fd(lambda s: np.ravel(p.constraint_jac(q, s[0])), tt)),
            (p.accel_term(q, v, t)[:, None],
             fd(lambda s: p.velocity_constraint(t + s[0], q + s[0] * v, v), np.zeros(1))),
        ]
    for analytic, numeric in checks:
        analytic = analytic.toarray() if sp.issparse(analytic) else np.asarray(analytic)
        assert analytic.shape == numeric.shape
        scale = max(1.0, np.max(np.abs(numeric)))
        np.testing.assert_allclose(analytic, numeric, atol=1e-6 * scale, rtol=1e-6)
    if not driven:
        np.testing.assert_allclose(p.accel_term(q, v), p.gv_q(q, v) @ v, rtol=1e-12, atol=1e-12)
