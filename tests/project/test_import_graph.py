"""The modules of problems/, integrators/ and harness/ import each other without a
cycle, and each package only what its place allows.

Every ``from integrator_bench.<package>... import ...`` and ``import
integrator_bench.<package>...`` in a package, at module level or inside a
function alike (a deferred import is still a dependency), is an edge; ``from
package import name`` points at the submodule ``package.name`` when there is
one, else at the package.
"""

from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
HARNESS = REPO / "harness"
PREFIX = "integrator_bench.harness"
#: the installed packages and the folders they come from (pyproject.toml's package-dir)
PACKAGES = {"integrator_bench.problems": REPO / "problems",
            "integrator_bench.integrators": REPO / "integrators",
            "integrator_bench.harness": HARNESS}


def module_name(path: Path, root: Path = HARNESS, prefix: str = PREFIX) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join([prefix, *parts])


def import_graph(roots: dict[str, Path] | None = None) -> dict[str, set[str]]:
    """Module -> the modules of ``roots`` (prefix -> folder; default harness/ only)
    it imports."""
    roots = roots or {PREFIX: HARNESS}
    modules = {module_name(p, root, prefix): p
               for prefix, root in roots.items() for p in root.rglob("*.py")}
    graph = {}
    for name, path in modules.items():
        edges = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                    and node.module.startswith(tuple(roots)):
                for alias in node.names:
                    sub = f"{node.module}.{alias.name}"
                    edges.add(sub if sub in modules else node.module)
            elif isinstance(node, ast.Import):
                edges.update(a.name for a in node.names if a.name.startswith(tuple(roots)))
        graph[name] = {e for e in edges if e in modules and e != name}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str]:
    """One cycle of ``graph`` as a list of nodes (first repeated last), or []."""
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == "open":
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        state[node] = "done"
        stack.pop()
        return []

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return []


def test_the_cycle_finder_finds_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) == []


def test_the_graph_sees_deferred_imports():
    graph = import_graph()
    # the report command imports the report inside its function
    assert f"{PREFIX}.report" in graph[f"{PREFIX}.cli.report"]
    assert f"{PREFIX}.report.document" in graph[f"{PREFIX}.report.html"]


def test_harness_has_no_import_cycle():
    assert find_cycle(import_graph()) == []


def test_the_three_packages_have_no_import_cycle():
    assert find_cycle(import_graph(PACKAGES)) == []


def test_the_base_and_driver_cycle_would_be_seen():
    graph = import_graph(PACKAGES)
    base, driver = ("integrator_bench.integrators." + m for m in ("base", "driver"))
    assert driver in graph[base]            # the interface runs its steppers on the driver
    assert find_cycle({**graph, driver: graph[driver] | {base}}) != []


def test_each_package_imports_only_what_its_place_allows():
    """problems/ knows physics only, integrators/ numerics only (and the systems
    problems/ hands it), harness/ joins them."""
    graph = import_graph(PACKAGES)
    for module, imports in graph.items():
        if module.startswith("integrator_bench.problems"):
            assert not {i for i in imports if not i.startswith("integrator_bench.problems")}, \
                module
        if module.startswith("integrator_bench.integrators"):
            assert not {i for i in imports if i.startswith("integrator_bench.harness")}, module


def test_the_problems_machinery_imports_no_model():
    """The models (problems/models/) build on the machinery of problems/, never the
    other way round: a model can be added or removed without touching it."""
    graph = import_graph(PACKAGES)
    models = "integrator_bench.problems.models"
    machinery = [m for m in graph if m.startswith("integrator_bench.problems")
                 and not m.startswith(models)]
    assert any(m.startswith(models + ".") for m in graph)
    assert {m: {i for i in graph[m] if i.startswith(models)} for m in machinery} \
        == {m: set() for m in machinery}


#: each subpackage of the harness -> the subpackages it may import (besides itself, the
#: base modules errors, paths, version, forking, layout and tables, problems/ and integrators/); what each
#: package's ``__init__`` docstring says
HARNESS_LAYERS = {
    "matrix": set(),
    "measure": {"matrix"},
    "run": {"matrix", "measure"},
    "checks": {"matrix", "measure", "run"},
    "ranking": {"matrix", "measure"},
    "report": {"matrix", "measure", "ranking"},
    "sources": {"matrix", "measure", "ranking", "report"},
    "contend": {"matrix", "measure", "run", "ranking"},
    "advise": {"matrix", "measure", "run", "ranking", "contend"},
    "cli": {"matrix", "measure", "run", "checks", "ranking", "report", "sources", "advise",
            "contend"},
}
BASE = {"errors", "paths", "version", "forking", "layout", "tables"}


def _place(module: str) -> str | None:
    """``model`` for ``integrator_bench.harness.matrix.cases``; the base module's
    name for the base modules; None outside the harness."""
    if not module.startswith(PREFIX + "."):
        return None
    return module[len(PREFIX) + 1:].split(".")[0]


def layer_violations(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """Each harness module of ``graph`` -> the modules it imports that its place in
    :data:`HARNESS_LAYERS` does not allow (only modules with some)."""
    wrong = {}
    for module, imports in graph.items():
        place = _place(module)
        if place not in HARNESS_LAYERS:
            continue
        allowed = HARNESS_LAYERS[place] | {place} | BASE
        bad = {i for i in imports if _place(i) not in allowed | {None}}
        if bad:
            wrong[module] = bad
    return wrong


def test_each_harness_subpackage_imports_only_the_layers_below_it():
    graph = import_graph(PACKAGES)
    places = {_place(m) for m in graph} - {None}
    assert places <= set(HARNESS_LAYERS) | BASE, places - set(HARNESS_LAYERS) - BASE
    assert layer_violations(graph) == {}


def test_the_layer_rule_would_see_a_report_importing_the_run_engine():
    graph = import_graph(PACKAGES)
    graph[f"{PREFIX}.report.write"].add(f"{PREFIX}.run.execution")
    assert layer_violations(graph) == {f"{PREFIX}.report.write": {f"{PREFIX}.run.execution"}}


def test_the_layer_rule_would_see_the_advice_or_the_ranking_importing_the_report():
    graph = import_graph(PACKAGES)
    graph[f"{PREFIX}.advise.page"].add(f"{PREFIX}.report.ranking_text")
    graph[f"{PREFIX}.ranking.reach"].add(f"{PREFIX}.report.names")
    assert layer_violations(graph) == {f"{PREFIX}.advise.page": {f"{PREFIX}.report.ranking_text"},
                                       f"{PREFIX}.ranking.reach": {f"{PREFIX}.report.names"}}


def test_no_module_imports_a_private_name_of_another():
    """``from x import _name`` across modules couples to what ``x`` may change
    freely (tests aside; a package's ``__init__`` is held to it too)."""
    offenders = []
    for root in PACKAGES.values():
        for path in root.rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.ImportFrom) and node.module \
                        and node.module.startswith("integrator_bench"):
                    offenders += [f"{path.relative_to(REPO)}: {node.module}.{a.name}"
                                  for a in node.names
                                  if a.name.startswith("_") and not a.name.startswith("__")]
    assert not offenders, offenders


