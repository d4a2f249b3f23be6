"""The scaling measurements: their JSON schema, reader, writer and slope bounds.

A scaling file (``<data dir>/scaling/<problem>.json``, written by
``studies/chain_scaling.py`` through :func:`write_scaling`) is one JSON
object, :class:`Scaling`:

``problem``, ``created``, ``machine``
    what was measured, when (UTC, ISO 8601) and on what (CPU, count, Python);
``rows``
    one object per size: ``n_links``, ``n_states``, CPU seconds per call or
    step in keys ending ``_s`` (``step_*_s`` per accepted step), further
    counts and ``peak_mb``; null where a run failed;
``slopes``
    least-squares slope of log(figure) on log(N) per figure (null when fewer
    than two sizes have it);
``targets``
    the slope bounds: ``rhs_and_jac_slope_max`` for the evaluations (every
    ``*_s`` key but the steps), ``step_slope_max`` for ``step_*_s``
    (:func:`slope_bound`).

The report reads every file of the folder (:func:`load_scaling`) and shows
each as a figure and two tables (:func:`scaling_tables`).
"""

from __future__ import annotations

import dataclasses
import json
import warnings
from pathlib import Path

from integrator_bench.harness.paths import file_name, inside
from integrator_bench.harness.report.names import fmt_value
from integrator_bench.harness.tables import NULL

@dataclasses.dataclass
class Scaling:
    """One scaling file (see the module docstring); ``file`` is its stem, not stored."""

    problem: str
    created: str
    machine: str
    rows: list[dict]
    slopes: dict = dataclasses.field(default_factory=dict)
    targets: dict = dataclasses.field(default_factory=dict)
    file: str = ""

    def timing_keys(self) -> list[str]:
        """The keys ending ``_s`` (CPU seconds) of the rows, in order of appearance."""
        return list(dict.fromkeys(k for r in self.rows for k in r if k.endswith("_s")))

    def to_json(self) -> str:
        """The stored JSON object (every field but ``file``)."""
        data = dataclasses.asdict(self)
        data.pop("file")
        return json.dumps(data, indent=1)


def slope_bound(key: str, targets: dict) -> float | None:
    """The slope bound of a figure ``key``: ``step_*_s`` takes ``step_slope_max``, the
    other timings (``*_s``: right-hand side, residual, Jacobian)
    ``rhs_and_jac_slope_max``; anything else (``peak_mb``) or a missing bound None."""
    if not key.endswith("_s"):
        return None
    value = targets.get("step_slope_max" if key.startswith("step_") else
                        "rhs_and_jac_slope_max")
    return None if value is None else float(value)


def write_scaling(data: Scaling, folder: Path) -> Path:
    """Write ``folder/<problem>.json`` (the folder made if needed; the problem's
    name made a file name by :func:`~integrator_bench.harness.paths.file_name`);
    return its path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = inside(folder, file_name(f"{data.problem}.json"))
    path.write_text(data.to_json(), encoding="utf-8")
    return path


def read_scaling(path: Path) -> Scaling:
    """One scaling file; ValueError when it is not JSON or not a scaling object
    (a JSON object with a list ``rows``)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ValueError(f"not readable as JSON ({exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("rows"), list):
        raise ValueError("not a scaling file (a JSON object with 'rows')")
    return Scaling(problem=str(data.get("problem", path.stem)),
                   created=str(data.get("created", NULL)),
                   machine=str(data.get("machine", NULL)), rows=data["rows"],
                   slopes=dict(data.get("slopes") or {}),
                   targets=dict(data.get("targets") or {}), file=path.stem)


def load_scaling(folder: Path | None) -> list[Scaling]:
    """The scaling files ``folder/*.json``, sorted by file name.

    Parameters
    ----------
    folder : pathlib.Path or None
        Where ``studies/chain_scaling.py`` writes; None or a missing folder
        gives none.

    Returns
    -------
    list of Scaling
        A file that :func:`read_scaling` refuses is left out with a
        ``UserWarning`` naming it, so that one bad file never costs the report.
    """
    if folder is None or not Path(folder).is_dir():
        return []
    out = []
    for path in sorted(Path(folder).glob("*.json")):
        try:
            out.append(read_scaling(path))
        except ValueError as exc:
            warnings.warn(f"{path}: left out of the report, {exc}", stacklevel=2)
    return out


def scaling_tables(data: Scaling) -> tuple[tuple, list, tuple, list]:
    """The slopes table (quantity, slope, bound, within) and the measurements table,
    as ``(header, rows, header, rows)`` of text cells."""
    slopes = []
    for key, slope in data.slopes.items():
        bound = slope_bound(key, data.targets)
        within = NULL if bound is None or slope is None else ("yes" if slope <= bound else "no")
        slopes.append((key, NULL if slope is None else f"{slope:.2f}",
                       NULL if bound is None else f"{bound:g}", within))
    cols = list(dict.fromkeys(k for r in data.rows for k in r))
    body = [[fmt_value(r.get(c)) if r.get(c) is not None else None for c in cols]
            for r in data.rows]
    return ("quantity", "log-log slope", "bound", "within"), slopes, tuple(cols), body
