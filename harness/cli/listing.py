"""``ibench list {problems,integrators,formulations}``: what is registered, with
the problems' parameters and the integrators' settings."""

from __future__ import annotations

import json

from integrator_bench.harness.cli.options import JSON_HELP
from integrator_bench.harness.matrix import registry
from integrator_bench.harness.tables import text_table


def add_parser(sub) -> None:
    p = sub.add_parser("list", help="list problems, integrators or formulations")
    p.add_argument("what", choices=["problems", "integrators", "formulations"],
                   help="what to list")
    p.add_argument("--json", action="store_true", help=f"{JSON_HELP}: one JSON array")


def command(args) -> int:
    """The registered problems, integrators or formulations: a table, or JSON.

    Problems come with a second table: each parameter, its default and its
    valid range.
    """
    extra = ""
    if args.what == "problems":
        items = [{**problem.describe(), "origin": getattr(problem, "origin", "built-in")}
                 for problem in registry.built_problems().values()]
        rows = [(d["name"], d["origin"], d["dimension"], ",".join(d["formulations"]),
                 d["description"]) for d in items]
        header = ("name", "origin", "dim", "formulations", "description")
        extra = "\n\nparameters:\n" + parameter_table(items) + "\n\nnamed with their parameters:\n" \
            + "\n".join(f"  {name}: {cls.description}" for name, cls in registry.FAMILIES.items())
    elif args.what == "integrators":
        items = [{"name": name, "origin": cls.origin, "description": cls.description,
                  "reference": cls.reference, **cls.capabilities()}
                 for name, cls in registry.integrators().items()]
        rows = [(d["name"], d["origin"],
                 "/".join(d["accepts"]) + (f"<=i{d['max_index']}" if d["max_index"] else ""),
                 d["order"] if d["order"] is not None else "var", _step_kind(d),
                 "yes" if d["events"] else "no", d["description"]) for d in items]
        header = ("name", "origin", "accepts", "order", "step", "events", "description")
        extra = ("\n\nsettings (-i NAME:setting=value,...; value|value|... sweeps one):\n"
                 + settings_table(items))
    else:
        items = [{"name": f, "problems": [n for n, c in registry.problems().items()
                                          if f in c.formulations]}
                 for f in registry.formulations()]
        rows = [(d["name"], ", ".join(d["problems"])) for d in items]
        header = ("name", "problems")
    if args.json:
        print(json.dumps(items, indent=1), file=args.data_out)
    else:
        print(text_table(header, rows) + extra)
    return 0


def settings_table(items: list[dict]) -> str:
    """Each integrator's settings: default, valid values, the seed's control
    it corresponds to, and meaning."""
    rows = [(d["name"], s["name"], "code's own" if s["default"] is None else s["default"],
             s["valid"], s["control"] or "", s["meaning"])
            for d in items for s in d["settings"]]
    return text_table(("integrator", "setting", "default", "valid", "control", "meaning"), rows)


def _step_kind(capabilities: dict) -> str:
    """``both``, ``adaptive`` or ``fixed``: how an integrator can be driven."""
    if capabilities["adaptive"]:
        return "both" if capabilities["fixed_step"] else "adaptive"
    return "fixed"


def parameter_table(problems: list[dict]) -> str:
    """One row per parameter of each described problem: default and valid range.

    Parameters
    ----------
    problems : list of dict
        :meth:`~integrator_bench.problems.base.Problem.describe` of each problem.
    """
    def bound(value, infinite):
        return infinite if value is None else f"{value:g}"

    rows = [(d["name"], p["name"], f"{p['default']:g}",
             f"[{bound(p['low'], '-inf')}, {bound(p['high'], 'inf')}]", p["description"])
            for d in problems for p in d["parameters"]]
    return text_table(("problem", "parameter", "default", "range", "description"), rows)


