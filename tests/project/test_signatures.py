"""No function of harness/ takes more than :data:`MOST_PARAMETERS` parameters.

Options that travel together travel as one object (the run's
:class:`~integrator_bench.harness.run.context.RunContext`, the advice's
``Question``, small option dataclasses), not as a list threaded by hand through
every call. Counted: positional-only, positional, keyword-only, ``*args`` and
``**kwargs`` (one each), without ``self`` or ``cls``; methods, nested functions
and lambdas alike.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

HARNESS = Path(__file__).resolve().parents[2] / "harness"
MOST_PARAMETERS = 8


def parameters(node) -> list[str]:
    """The parameters of a function's or lambda's ``ast`` node, without a leading
    ``self`` or ``cls``."""
    a = node.args
    names = [p.arg for p in (*a.posonlyargs, *a.args, *a.kwonlyargs)]
    names += [f"*{a.vararg.arg}"] if a.vararg else []
    names += [f"**{a.kwarg.arg}"] if a.kwarg else []
    return names[1:] if names[:1] in (["self"], ["cls"]) else names


def too_long(source: str, where: str = "<snippet>") -> list[str]:
    """``where:line name (n parameters)`` for every function of ``source`` over the limit."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            n = len(parameters(node))
            if n > MOST_PARAMETERS:
                out.append(f"{where}:{node.lineno} {getattr(node, 'name', 'lambda')} "
                           f"({n} parameters)")
    return out


@pytest.mark.parametrize("source, offending", [
    ("def f(a, b, c, d, e, f, g, h):\n    pass\n", False),
    ("def f(a, b, c, d, e, f, g, h, i):\n    pass\n", True),
    ("def f(a, b, c, d, /, e, *, f, g, h, i=1):\n    pass\n", True),
    ("def f(a, b, c, d, e, f, g, *args, **kwargs):\n    pass\n", True),
    ("class C:\n    def m(self, a, b, c, d, e, f, g, h):\n        pass\n", False),
    ("class C:\n    def m(self, a, b, c, d, e, f, g, h, i):\n        pass\n", True),
    ("def outer():\n    def inner(a, b, c, d, e, f, g, h, i):\n        pass\n", True),
    ("g = lambda a, b, c, d, e, f, g, h, i: a\n", True),
    ("async def f(a, b, c, d, e, f, g, h, i):\n    pass\n", True),
])
def test_the_check_sees_a_function_over_the_limit(source, offending):
    assert bool(too_long(source)) is offending


def test_no_harness_function_takes_more_than_eight_parameters():
    over = [hit for path in sorted(HARNESS.rglob("*.py"))
            for hit in too_long(path.read_text(), str(path.relative_to(HARNESS.parent)))]
    assert not over, "functions over the limit:\n" + "\n".join(over)
