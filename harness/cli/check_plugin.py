"""``ibench check-plugin NAME``: the conformance checks of a registered integrator, or
the checks of a registered problem (:mod:`integrator_bench.harness.checks.problem_check`)."""

from __future__ import annotations

import json

from integrator_bench.harness.cli.options import JSON_HELP, Once, finite_float, memory


def add_parser(sub) -> None:
    p = sub.add_parser("check-plugin", help="conformance check of a registered integrator "
                                            "or problem")
    p.add_argument("name", help="integrator or problem registry name")
    p.add_argument("--problem", action="store_true",
                   help="check the problem NAME (needed only when an integrator has that name)")
    p.add_argument("--timeout", type=finite_float("--timeout"), default=60.0, action=Once,
                   metavar="SECONDS", help="seconds each run of the check may take "
                                           "(default: 60)")
    from integrator_bench.harness.run.limits import DEFAULT_MEMORY_MB

    p.add_argument("--memory", type=memory, default=DEFAULT_MEMORY_MB, metavar="MB",
                   action=Once,
                   help="address space each run of the check may allocate, in MiB (RLIMIT_AS, "
                        "as ibench run caps a case; 'none': no limit; default: "
                        f"{DEFAULT_MEMORY_MB:g})")
    p.add_argument("--json", action="store_true", help=f"{JSON_HELP}: one object per check")


def command(args) -> int:
    """One line per check; exit 1 when one fails."""
    from integrator_bench.harness.checks.conformance import check_plugin
    from integrator_bench.harness.checks.problem_check import check_problem, resolve
    from integrator_bench.harness.run.streams import stdout_to_stderr

    kind = resolve(args.name, args.problem)  # a bad name exits 2 before anything runs
    checked = check_problem if kind == "problem" else check_plugin
    with stdout_to_stderr():  # what runs here (not in a worker) never mixes with the lines
        checks = checked(args.name, timeout=args.timeout, memory_mb=args.memory)
    for check in checks:
        print(json.dumps(check.to_dict()) if args.json else check.line(), file=args.data_out,
              flush=True)
    return 1 if any(c.passed is False for c in checks) else 0


