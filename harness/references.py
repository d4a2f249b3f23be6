"""Reference solutions: computed and verified by the project, never typed in.

For each problem and parameter set the reference is either the exact solution
(``Problem.exact``), cross-checked against a tight numerical solution, or the
solution of one method at tight tolerance, verified against a second,
independent method (different formulation or different integrator). Stored in
``<reference dir>/<problem>/<params>.npz`` (times and canonical components)
with ``.json`` metadata: methods, tolerances, per-component agreement digits,
the claim (the floor of the smallest agreement), code version, the problem's
definition fingerprint and a checksum of the data. A reference whose problem
definition changed, or whose data no longer matches its checksum, is never
used: it is recomputed.

Where (``harness.paths``): references are read from ``REFERENCE_DIR``
(``IBENCH_REFERENCE_DIR``, else ``<data dir>/reference``; in a checkout the
committed ``results/reference/``) and, for a problem with none there, from the
read-only copies shipped in the wheel (``SHIPPED_REFERENCE_DIR``). Computed
references are written to ``REFERENCE_DIR`` only, never beside the installed code.
"""

from __future__ import annotations

import hashlib
import json
import warnings
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from integrator_bench.harness import registry
from integrator_bench.harness.errors import ReferenceFailure
from integrator_bench.harness.metrics import agreement_digits
from integrator_bench.harness.paths import REFERENCE_DIR, SHIPPED_REFERENCE_DIR
from integrator_bench.harness.version import code_version
from integrator_bench.problems.base import Problem
from integrator_bench.problems.system import Unsupported, convert

# Radau IIA (implicit, order 5) checked by DOP853 (explicit, order 8): independent
# methods; at rtol 1e-13 they agree to 11 or more digits on every built-in problem.
DEFAULT_METHODS = (("ode", "scipy-Radau", 1e-13), ("ode", "scipy-DOP853", 1e-13))
EXACT_CHECK = ("ode", "scipy-DOP853", 1e-13)
NOT_STORED = "no stored reference"


@dataclass
class Reference:
    t: np.ndarray
    Y: np.ndarray
    meta: dict

    @property
    def id(self) -> str:
        return f"{self.meta['label']}@{self.meta['checksum'][:12]}"


# file names longer than this (a problem with many parameters) are shortened
MAX_STEM = 120


def paths(problem: Problem, directory: Path | None = None) -> tuple[Path, Path]:
    """The .npz and .json files of ``problem``'s reference.

    The stem lists every parameter (``k=v,...``); when that is longer than
    ``MAX_STEM`` characters (file systems stop at 255), it lists the parameters
    that differ from their defaults followed by a hash of all of them.
    """
    directory = Path(directory or REFERENCE_DIR) / problem.name
    stem = ",".join(f"{k}={v:g}" for k, v in sorted(problem.params.items())) or "default"
    if len(stem) > MAX_STEM:
        defaults = {p.name: p.default for p in problem.parameters}
        changed = ",".join(f"{k}={v:g}" for k, v in sorted(problem.params.items())
                           if v != defaults.get(k))
        digest = hashlib.sha256(json.dumps(problem.params, sort_keys=True).encode()).hexdigest()
        stem = f"{changed or 'default'}-{digest[:10]}"
    return directory / f"{stem}.npz", directory / f"{stem}.json"


def _checksum(t, Y) -> str:
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(t, float).tobytes())
    h.update(np.ascontiguousarray(Y, float).tobytes())
    return h.hexdigest()


def solve_canonical(problem: Problem, formulation: str, integrator: str, rtol: float):
    """Canonical components at the output times from one tight run."""
    system = problem.formulate(formulation)
    icls = registry.get_integrator(integrator)
    try:
        system = convert(system, icls)
    except Unsupported as exc:
        raise ReferenceFailure(f"{problem.name}/{formulation}: {exc}") from None
    sol = icls().solve(system, rtol=rtol, atol=system.atol(rtol))
    if not sol.success or sol.t.size != system.t_eval.size:
        raise ReferenceFailure(f"{integrator} failed on {problem.label()}: {sol.message}")
    return np.asarray(system.output(sol.t, sol.y), float)


def compute(problem: Problem) -> Reference:
    """Compute a reference and its agreement digits (not stored)."""
    t = problem.t_eval
    methods = getattr(problem, "reference_methods", DEFAULT_METHODS)
    exact = problem.exact(t)
    if exact is not None:
        Y = np.asarray(exact, float)
        check = solve_canonical(problem, *EXACT_CHECK)
        used = [{"method": "exact"}, dict(zip(("formulation", "integrator", "rtol"), EXACT_CHECK))]
    else:
        (fa, ia, ra), (fb, ib, rb) = methods[:2]
        Y = solve_canonical(problem, fa, ia, ra)
        check = solve_canonical(problem, fb, ib, rb)
        used = [dict(formulation=f, integrator=i, rtol=r) for f, i, r in methods[:2]]
    err = problem.component_index(problem.error_components)
    digits = agreement_digits(check, Y, problem.atol_scale_vector())
    meta = {
        "problem": problem.name,
        "params": problem.params,
        "label": problem.label(),
        "fingerprint": problem.fingerprint(),
        "methods": used,
        "agreement_digits": dict(zip(problem.components, map(float, np.round(digits, 2)))),
        "claimed_digits": int(np.floor(digits[err].min())),
        "code_version": code_version(),
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "checksum": _checksum(t, Y),
        "final": dict(zip(problem.components, map(float, Y[-1]))),
    }
    return Reference(t, Y, meta)


def save(ref: Reference, problem: Problem, directory: Path | None = None) -> None:
    npz, js = paths(problem, directory)
    _verified.pop((npz, js), None)
    npz.parent.mkdir(parents=True, exist_ok=True)
    np.savez(npz, t=ref.t, Y=ref.Y)
    js.write_text(json.dumps(ref.meta, indent=1, sort_keys=True) + "\n")


def read(problem: Problem, directory: Path | None = None) -> tuple[Reference | None, str]:
    """The stored reference, or (None, why it cannot be used).

    With ``directory`` None: the one in ``REFERENCE_DIR``, else the one shipped
    with the package (``SHIPPED_REFERENCE_DIR``, absent in a checkout).
    """
    ref, why = _read(problem, directory)
    if directory is None and why == NOT_STORED and SHIPPED_REFERENCE_DIR is not None:
        return _read(problem, SHIPPED_REFERENCE_DIR)
    return ref, why


# (npz, json) -> (their stat signature, Reference): each file read and verified once per
# process, and by a forked worker not at all (it inherits the runner's, read beforehand)
_verified: dict = {}


def _read(problem: Problem, directory: Path | None) -> tuple[Reference | None, str]:
    npz, js = paths(problem, directory)
    try:
        signature = tuple((st.st_mtime_ns, st.st_ctime_ns, st.st_size, st.st_ino)
                          for st in (npz.stat(), js.stat()))
    except OSError:
        return None, NOT_STORED
    cached = _verified.get((npz, js))
    if cached is not None and cached[0] == signature:  # unchanged files, checksum verified
        t, Y, meta = cached[1].t, cached[1].Y, cached[1].meta
    else:
        meta = json.loads(js.read_text())
        with np.load(npz) as data:
            t, Y = data["t"], data["Y"]
        if _checksum(t, Y) != meta.get("checksum"):
            return None, "stored data does not match its checksum"
        t.flags.writeable = Y.flags.writeable = False  # shared by every later reader
        _verified[(npz, js)] = (signature, Reference(t, Y, meta))
    if meta.get("fingerprint") != problem.fingerprint():
        return None, "the problem definition changed since the reference was computed"
    return Reference(t, Y, dict(meta)), ""


def load(problem: Problem, directory: Path | None = None, compute_missing: bool = True) -> Reference:
    """The reference for ``problem``; recomputed and stored when stale or missing."""
    ref, why = read(problem, directory)
    if ref is not None:
        return ref
    if not compute_missing:
        raise ReferenceFailure(f"{problem.label()}: {why}")
    if why != NOT_STORED:
        warnings.warn(f"reference for {problem.label()} recomputed: {why}", stacklevel=2)
    ref = compute(problem)
    save(ref, problem, directory)
    return ref


def check(problem: Problem, directory: Path | None = None) -> tuple[bool, str]:
    """Recompute and compare with what the stored metadata claims.

    Fails when the stored reference is unusable, when the recomputed methods
    agree to fewer digits than claimed, or when the stored data and the
    recomputation differ by more than the claim.
    """
    ref, why = read(problem, directory)
    if ref is None:
        return False, why
    new = compute(problem)
    claim = ref.meta["claimed_digits"]
    err = problem.component_index(problem.error_components)
    now = new.meta["claimed_digits"]
    stored_vs_new = float(agreement_digits(new.Y[:, err], ref.Y[:, err],
                                           problem.atol_scale_vector()[err]).min())
    ok = now >= claim and stored_vs_new >= claim
    return ok, (f"claimed {claim} digits; recomputed methods agree to {now}, "
                f"stored vs recomputed {stored_vs_new:.1f}")
