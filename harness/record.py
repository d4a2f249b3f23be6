"""The result record: one per case, as in ../shared/CONTRACT.md.

``FIELDS`` maps each field to its SQL type; the store, the DataFrame and the
JSON output all follow it. A count an integrator cannot report is None (null),
never a made-up number.
"""

from __future__ import annotations

STATUSES = ("ok", "failed", "timeout", "crashed", "error", "unsupported")

FIELDS = {
    "case_id": "TEXT",          # hash of the case key: problem, params, formulation, integrator, rtol, h
    "problem": "TEXT",
    "params": "TEXT",           # JSON object of every parameter value
    "formulation": "TEXT",
    "integrator": "TEXT",
    "origin": "TEXT",           # built-in, or the plugin package and version
    "rtol": "REAL",
    "atol": "REAL",             # smallest component of the absolute tolerance vector
    "h": "REAL",
    "status": "TEXT",
    "message": "TEXT",
    "scd": "REAL",
    "mescd": "REAL",
    "err_max": "REAL",
    "err_vel": "REAL",
    "err_lambda": "REAL",
    "drift_pos": "REAL",
    "drift_vel": "REAL",
    "cpu_s": "REAL",
    "wall_s": "REAL",
    "nfev": "INTEGER",          # counted by the harness, finite-difference calls included
    "njev": "INTEGER",          # the integrator's count if it reports one, else the harness's
    "nlu": "INTEGER",
    "nsteps": "INTEGER",
    "nreject": "INTEGER",
    "nniter": "INTEGER",
    "nnfail": "INTEGER",
    "nevents": "INTEGER",
    "solver_counts": "TEXT",    # JSON: the integrator's own counters, as it reported them
    "reference": "TEXT",        # id of the reference the errors were measured against
    "code_version": "TEXT",
    "created": "TEXT",          # UTC ISO 8601
}

KEY_FIELDS = ("problem", "params", "formulation", "integrator", "rtol", "h")


def empty_record(**known) -> dict:
    record = dict.fromkeys(FIELDS)
    record.update(known)
    return record
