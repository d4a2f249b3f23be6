"""Fixed plot style of each integrator, for the report's figures.

Every integrator keeps one colour and one marker in every figure of every run,
and no two integrators of a report share a colour: built-ins take theirs from
a fixed table of registry names (:data:`BUILTIN`); every other name (plugins,
built-ins missing from the table, integrators no longer registered) takes a
colour of :data:`PLUGIN_COLORS`, which no built-in uses, starting at a hash of
its name and moving on past the colours that names sorted before it took
(:func:`styles`). So a plugin's colour depends on its name and on the other
plugin names present, never on the order of a run. A line of an integrator run
with settings (its label ``cvode-bdf (max_order=2)``,
:attr:`~integrator_bench.harness.matrix.line.Line.label`) takes its integrator's
colour and a marker of its own (:func:`styles`). The panel a line
goes to is its family (:attr:`~integrator_bench.harness.matrix.line.Line.family`).
"""

from __future__ import annotations

import hashlib

MARKERS = ("o", "s", "^", "v", "D", "P", "*", "<", ">", "X", "h", "p")
FAILED_COLOR = "#7f7f7f"
#: built-in registry names -> (colour, marker); never change one, only append
BUILTIN = {"scipy-RK45": ("#1f77b4", "o"), "scipy-RK23": ("#ff7f0e", "s"),
           "scipy-DOP853": ("#2ca02c", "^"), "rk4": ("#9467bd", "v"),
           "euler": ("#8c564b", "D"), "euler-extrap": ("#e377c2", "P"),
           "gbs": ("#17becf", "*"), "rkc": ("#bcbd22", "<"), "scipy-Radau": ("#393b79", "o"),
           "scipy-BDF": ("#637939", "s"), "scipy-LSODA": ("#8c6d31", "^"),
           "cvode-bdf": ("#843c39", "v"), "cvode-adams": ("#7b4173", "D"),
           "bdf2": ("#3182bd", "P"), "bdf3": ("#e6550d", "*"), "bdf4": ("#31a354", "<"),
           "implicit-euler": ("#d62728", ">"), "trapezoidal": ("#756bb1", "X"),
           "sdirk3": ("#fd8d3c", "h"), "sw2": ("#6baed6", "p"), "w1": ("#1b9e77", ">"),
           "ida": ("#d95f02", "X"), "hht": ("#7570b3", "h"), "newmark": ("#e7298a", "p"),
           "gen-alpha": ("#66a61e", "X"), "dumka3": ("#e6ab02", "D"),
           "fmpy-cvode": ("#a6761d", "s"), "fmpy-euler": ("#e41a1c", "^"),
           "assimulo-cvode-bdf": ("#1f78b4", "h"), "assimulo-cvode-adams": ("#6a3d9a", "*"),
           "assimulo-ida": ("#b15928", "<"), "assimulo-radau5": ("#33a02c", "D"),
           "assimulo-rodas": ("#e31a1c", "P"), "assimulo-dopri5": ("#fdbf6f", "X"),
           "assimulo-rk34": ("#a6cee3", "p"), "assimulo-lsodar": ("#cab2d6", "v"),
           "rock2": ("#b10026", "<"), "serk2v2": ("#005a32", ">"),
           "al-trapezoidal": ("#4d004b", "d")}
#: the colours of every other integrator: none of them is a built-in's
PLUGIN_COLORS = ("#377eb8", "#4daf4a", "#984ea3", "#ff7f00", "#a65628", "#f781bf",
                 "#5254a3", "#6b6ecf", "#8ca252", "#b5cf6b", "#bd9e39", "#e7ba52",
                 "#ad494a", "#d6616b", "#a55194", "#ce6dbd", "#9ecae1", "#fdae6b",
                 "#74c476", "#9e9ac8", "#aec7e8", "#ffbb78", "#98df8a", "#ff9896",
                 "#c5b0d5", "#c49c94", "#f7b6d2", "#dbdb8d", "#9edae5", "#e7969c",
                 "#a1d99b", "#bcbddc")


def _digest(name: str) -> int:
    return int.from_bytes(hashlib.sha256(name.encode()).digest()[:8], "big")


def styles(names, integrators: dict | None = None) -> dict[str, tuple[str, str]]:
    """The ``(colour, marker)`` of each integrator of a report.

    Parameters
    ----------
    names : iterable of str
        Registry names and line labels: every integrator the report draws (the
        figures of one report take one call, so that its colours are distinct).
    integrators : dict, optional
        Label -> registry name of the labels of integrators run with settings (a
        name not in it is a registry name).

    Returns
    -------
    dict of str to (str, str)
        A built-in's entry of :data:`BUILTIN`; for every other name, in
        sorted order, the first colour of :data:`PLUGIN_COLORS` not yet taken,
        counted from the SHA-256 of the name, and a marker from the same hash.
        Only with more than ``len(PLUGIN_COLORS)`` such names do two share a
        colour (their markers then still tell them apart). A variant with
        settings takes its base integrator's colour and the markers after the
        base's in :data:`MARKERS`, one per variant in sorted order.
    """
    names = sorted(set(names))
    base_of = {n: (integrators or {}).get(n, n) for n in names}
    bases = set(base_of.values())
    out = _base_styles(sorted(bases))
    for base in sorted(bases):
        colour, marker = out[base]
        start = MARKERS.index(marker) if marker in MARKERS else 0
        variants = [n for n in names if n != base and base_of[n] == base]
        for k, name in enumerate(variants, start=1):
            out[name] = (colour, MARKERS[(start + k) % len(MARKERS)])
    return {n: out[n] for n in names}


def _base_styles(names) -> dict[str, tuple[str, str]]:
    """:func:`styles` of registry names (no variants)."""
    out, taken = {}, set()
    for name in names:
        if name in BUILTIN:
            out[name] = BUILTIN[name]
            continue
        digest = _digest(name)
        first = digest % len(PLUGIN_COLORS)
        order = [PLUGIN_COLORS[(first + k) % len(PLUGIN_COLORS)]
                 for k in range(len(PLUGIN_COLORS))]
        colour = next((c for c in order if c not in taken), order[0])
        taken.add(colour)
        out[name] = (colour, MARKERS[(digest // len(PLUGIN_COLORS)) % len(MARKERS)])
    return out


def style(integrator: str) -> tuple[str, str]:
    """The ``(colour, marker)`` of ``integrator`` among the registered integrators
    (:func:`styles` of their names and ``integrator``)."""
    from integrator_bench.harness.matrix import registry

    return styles([*registry.integrators(), integrator])[integrator]
