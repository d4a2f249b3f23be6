"""``ibench verify``: observed against declared order, stability and stability
interval of each integrator."""

from __future__ import annotations

import json

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.cli.options import json_default


def add_parser(sub) -> None:
    p = sub.add_parser("verify", help="observed order and stability of integrators")
    p.add_argument("-i", "--integrator", action="append", metavar="INTEGRATOR",
                   help="registry name (repeatable; default: every registered integrator)")
    p.add_argument("--json", action="store_true", help="print one JSON object per integrator")


def command(args) -> int:
    """Observed vs declared order and stability per integrator; exit 1 when a check fails."""
    from integrator_bench.harness.run.streams import stdout_to_stderr
    from integrator_bench.harness.checks.verify import verify

    names = args.integrator or list(registry.integrators())
    for name in names:
        registry.get_integrator(name)  # a bad name exits 2 before anything runs
    failed = 0
    if not args.json:
        print(f"{'integrator':16} {'declared':>8} {'observed':>8}  order  stability  interval  "
              "verdict")
    for name in names:
        with stdout_to_stderr():  # a C solver's messages never among the JSON lines
            v = verify(name)
        failed += v.passed is False
        if args.json:
            print(json.dumps(v.to_dict(), default=json_default), file=args.data_out, flush=True)
            continue
        obs = f"{v.observed_order:.2f}" if v.observed_order is not None else "-"
        decl = "var" if v.declared_order is None else v.declared_order
        stab = "-" if v.stability is None else \
            f"{v.stability.declared}:{'ok' if v.stability.passed else 'FAIL'}"
        verdict = {True: "pass", False: "FAIL", None: "no verdict"}[v.passed]
        interval = "-" if v.interval is None else _mark(v.interval.passed)
        print(f"{name:16} {decl!s:>8} {obs:>8}  {_mark(v.order_passed):5}  {stab:9}  "
              f"{interval:8}  {verdict}"
              f"{'  (' + v.note + ')' if v.note else ''}", flush=True)
    return 1 if failed else 0


def _mark(passed) -> str:
    return {True: "ok", False: "FAIL", None: "-"}[passed]


