"""docs/plugins.md is enough to write a plugin: each of its Python blocks is a complete
plugin, and each passes every line of check-plugin."""

import re
from pathlib import Path

import pytest

from integrator_bench.harness.model import registry
from integrator_bench.harness.checks.conformance import check_plugin
from integrator_bench.integrators.base import Integrator

PAGE = Path(__file__).resolve().parents[1] / "docs" / "plugins.md"


def blocks() -> list[str]:
    """The page's Python code blocks, in order."""
    return re.findall(r"```python\n(.*?)```", PAGE.read_text(), flags=re.S)


def plugins(source: str) -> list[type]:
    """The integrators a code block defines, run as a module of its own."""
    namespace = {"__name__": "plugin_from_docs"}
    exec(compile(source, str(PAGE), "exec"), namespace)
    return [v for v in namespace.values()
            if isinstance(v, type) and issubclass(v, Integrator) and v is not Integrator]


def test_the_page_has_a_stepper_and_an_own_loop_plugin():
    found = [cls for source in blocks() for cls in plugins(source)]
    assert len(blocks()) == 2 and len(found) == 2
    assert found[0].has_stepper() and not found[1].has_stepper()


@pytest.mark.parametrize("index", [0, 1])
def test_each_plugin_of_the_page_passes_check_plugin(index):
    cls, = plugins(blocks()[index])
    registry.register(cls, origin="docs/plugins.md")
    try:
        lines = {c.name: c for c in check_plugin(cls.name, timeout=120)}
    finally:
        registry.unregister(cls.name)
    assert all(c.passed is not False for c in lines.values()), \
        [c.line() for c in lines.values()]
    for name in ("declarations", "runs ode", "counts", "inputs", "order", "accuracy",
                 "fails raise", "fails nan", "fails blowup"):
        assert lines[name].passed, lines[name].line()
