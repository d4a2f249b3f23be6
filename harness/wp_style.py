"""Fixed plot style and family of each integrator, for the report's figures.

An integrator keeps one colour and one marker in every figure of every run:
built-ins by a fixed table of registry names, every other name (plugins,
integrators no longer registered) by a hash of the name into a palette, never
by its position in the current run. The family (the panel a line goes to) is
read from the integrator's declared attributes (``implicit``, ``accepts``) and
from the kind of system the formulation gives, never from names.
"""

from __future__ import annotations

import functools
import hashlib

PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf",
           "#bcbd22", "#393b79", "#637939", "#8c6d31", "#843c39", "#7b4173", "#3182bd",
           "#e6550d", "#31a354", "#756bb1", "#636363", "#fd8d3c", "#6baed6")
MARKERS = ("o", "s", "^", "v", "D", "P", "*", "<", ">", "X", "h", "p")
FAILED_COLOR = "#7f7f7f"
#: built-in registry names -> (palette index, marker index); never reorder, only append
BUILTIN = {"scipy-RK45": (0, 0), "scipy-RK23": (1, 1), "scipy-DOP853": (2, 2),
           "rk4": (3, 3), "euler": (4, 4), "euler-extrap": (5, 5), "gbs": (6, 6),
           "rkc": (7, 7), "scipy-Radau": (8, 0), "scipy-BDF": (9, 1), "scipy-LSODA": (10, 2),
           "cvode-bdf": (11, 3), "cvode-adams": (12, 4), "bdf2": (13, 5), "bdf3": (14, 6),
           "bdf4": (15, 7), "implicit-euler": (16, 8), "trapezoidal": (17, 9),
           "sdirk3": (18, 10), "sw2": (19, 11), "w1": (0, 8), "ida": (1, 9),
           "hht": (2, 10), "newmark": (3, 11), "gen-alpha": (4, 9)}

FAMILIES = (("explicit", "Explicit"), ("implicit", "Implicit and stiff"),
            ("dae", "DAE and mechanical forms"),
            ("unknown", "Integrators no longer registered"))


def style(integrator: str) -> tuple[str, str]:
    """The ``(colour, marker)`` of an integrator in every figure.

    Parameters
    ----------
    integrator : str
        Registry name.

    Returns
    -------
    tuple of str
        A hex colour of ``PALETTE`` and a matplotlib marker of ``MARKERS``:
        from ``BUILTIN`` for a built-in name, else from the SHA-256 of the
        name, so a plugin's style depends on its name alone.
    """
    if integrator in BUILTIN:
        color, marker = BUILTIN[integrator]
    else:
        digest = int.from_bytes(hashlib.sha256(integrator.encode()).digest()[:8], "big")
        color, marker = digest % len(PALETTE), (digest // len(PALETTE)) % len(MARKERS)
    return PALETTE[color], MARKERS[marker]


@functools.lru_cache(maxsize=None)
def formulation_kind(problem: str, formulation: str) -> str | None:
    """The system kind (``ode``, ``dae``, ``mechanical``) a problem's formulation gives,
    from the registered problem with default parameters; None when the problem is
    not registered or does not offer the formulation."""
    from integrator_bench.harness import registry

    cls = registry.problems().get(problem)
    if cls is None or formulation not in cls.formulations:
        return None
    try:
        return cls().formulate(formulation).kind
    except Exception:  # a problem that fails to build only loses its panel placement
        return None


def family(integrator: str, formulation: str, problem: str) -> str:
    """The panel of a line: ``explicit``, ``implicit``, ``dae`` or ``unknown``.

    A DAE or mechanical form of the problem, or an integrator that accepts no
    ODE (DAE and mechanical solvers), gives ``dae``; otherwise the registered
    integrator's ``implicit`` attribute decides. An integrator no longer
    registered gives ``unknown`` unless the formulation is a DAE form.
    """
    from integrator_bench.harness import registry

    kind = formulation_kind(problem, formulation)
    cls = registry.integrators().get(integrator)
    if kind in ("dae", "mechanical") or (cls is not None and "ode" not in cls.accepts):
        return "dae"
    if cls is None:
        return "unknown"
    return "implicit" if cls.implicit else "explicit"
