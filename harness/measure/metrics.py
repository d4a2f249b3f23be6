"""Error and drift measures, as the IVP Test Set defines them.

For a computed solution ``y`` and a reference ``r`` at the final time, over the
problem's declared error components ``I``:

* ``scd = -log10(max_{i in I} |y_i - r_i| / |r_i|)`` (significant correct digits);
* ``mescd = -log10(max_{i in I} |y_i - r_i| / (atol/rtol + |r_i|))`` (mixed), where
  ``atol/rtol`` is the problem's absolute-tolerance scale;
* ``err_max``: the largest mixed error ``|y_i - r_i| / (scale_i + |r_i|)`` over all
  output times and error components; ``err_vel`` and ``err_lambda`` the same over
  velocity and multiplier components; ``err_rms`` the root-mean-square of the same
  mixed errors over the output times and error components;
* ``err_max_rel`` and ``err_rms_rel``: the same over the output times in the
  pure relative form, without a floor: ``|y_i - r_i| / max_t |r_i|``, each
  component's error relative to its largest reference magnitude over the
  output times (a pointwise ``|y - r| / |r|`` is unbounded at every zero
  crossing of a component); ``err_floor`` the floor ``scale`` of the mixed
  forms (the least over the error components);
* ``final_degenerate``: 1 when the reference's final state is near zero or at
  rest on every error component, against that component's own range over the
  run (:data:`REST`: ``|r_i(t_end)| <= REST max_t |r_i|``, or ``r_i`` within
  ``REST (max_t r_i - min_t r_i)`` of its final value over the last tenth of
  the output times): a ball at rest on the ground, a decayed oscillation. Every
  run that ends there has a small final error whatever its path, so the
  final-time error says nothing of the run; 0 otherwise.

A run whose mixed error at the final time exceeds :data:`DIVERGENCE_BOUND` (1:
its positions are off by more than their own size plus the absolute scale,
``mescd < 0``) has diverged (:func:`divergence`): the harness records it as
``failed`` with reason ``diverged`` and keeps these measures, so a report can
still show how far off it was.

Reference: Mazzia and Magherini, "Test Set for Initial Value Problem Solvers",
release 2.4 (2008), University of Bari, sect. II ("scd" and "mescd").
"""

from __future__ import annotations

import json
import math

import numpy as np

_TINY = 1e-300

#: a component is near zero, or at rest, at the final time within this share of its range
REST = 1e-3

#: the largest final-time mixed error (``10**-mescd``) of a run that has not diverged
DIVERGENCE_BOUND = 1.0


def first_nonfinite(t, Y, names=()) -> str | None:
    """``"non-finite output at t=0.62 (component 3, x2: nan)"``: where the outputs
    ``Y`` (one row per time of ``t``) first hold NaN or an infinite value, the
    first such component of that row (named from ``names`` when given); None when
    every value is finite."""
    Y = np.asarray(Y, float)
    Y = Y.reshape(len(t), -1) if len(t) else Y.reshape(0, 0)
    bad = ~np.isfinite(Y)
    if not bad.any():
        return None
    row = int(np.argmax(bad.any(axis=1)))
    col = int(np.argmax(bad[row]))
    name = f", {names[col]}" if col < len(names) else ""
    return f"non-finite output at t={float(t[row]):.6g} (component {col}{name}: {Y[row, col]})"


def digits(rel_error: float) -> float:
    """``-log10`` of an error; an exact result counts as 16 digits."""
    return float(-np.log10(max(rel_error, 1e-16))) if np.isfinite(rel_error) else float("nan")


def scd(y: np.ndarray, ref: np.ndarray) -> float:
    """Significant correct digits of ``y`` against ``ref`` (final-time vectors)."""
    return digits(np.max(np.abs(y - ref) / np.maximum(np.abs(ref), _TINY)))


def mescd(y: np.ndarray, ref: np.ndarray, scale: np.ndarray) -> float:
    """Mixed-error significant correct digits with absolute scale ``scale = atol/rtol``."""
    return digits(np.max(np.abs(y - ref) / (scale + np.abs(ref))))


def divergence(mescd_digits: float) -> str | None:
    """Why a run with final-time mixed digits ``mescd_digits`` has diverged, or None.

    A run has diverged when its final-time mixed error ``10**-mescd_digits``
    exceeds :data:`DIVERGENCE_BOUND`; a NaN (an error too large for a float)
    counts as exceeding it.
    """
    if mescd_digits >= -math.log10(DIVERGENCE_BOUND):
        return None
    error = "inf" if math.isnan(mescd_digits) else f"{10.0 ** min(-mescd_digits, 308.0):.3g}"
    return (f"diverged: mixed error {error} at the final time exceeds the bound "
            f"{DIVERGENCE_BOUND:g}")


def mixed_max(Y: np.ndarray, R: np.ndarray, scale: np.ndarray) -> float | None:
    """Largest mixed error over all rows (times) and columns (components)."""
    if Y.shape[1] == 0:
        return None
    return float(np.max(np.abs(Y - R) / (scale + np.abs(R))))


def measure(Y: np.ndarray, R: np.ndarray, scale: np.ndarray, groups: dict) -> dict:
    """All error measures of canonical outputs ``Y`` against reference rows ``R``.

    Parameters
    ----------
    Y, R : ndarray, shape (m, n)
        Computed and reference canonical components at the same output times;
        the last row is the final time.
    scale : ndarray, shape (n,)
        Absolute-tolerance scale of each component.
    groups : dict
        ``{"error": idx, "velocity": idx, "lambda": idx}`` of column indices.
    """
    err = groups["error"]
    out = {
        "scd": scd(Y[-1, err], R[-1, err]),
        "mescd": mescd(Y[-1, err], R[-1, err], scale[err]),
        "err_max": mixed_max(Y[:, err], R[:, err], scale[err]),
        **trajectory_errors(Y[:, err], R[:, err], scale[err]),
    }
    for key, name in (("err_vel", "velocity"), ("err_lambda", "lambda")):
        idx = groups.get(name, [])
        out[key] = mixed_max(Y[:, idx], R[:, idx], scale[idx]) if len(idx) else None
    return out


def trajectory_errors(Y: np.ndarray, R: np.ndarray, scale: np.ndarray) -> dict:
    """``err_rms``, ``err_max_rel``, ``err_rms_rel``, ``err_floor`` and
    ``final_degenerate`` (module docstring) of outputs ``Y`` against reference
    rows ``R`` (times x error components; the last row the final time), with
    the floor ``scale`` of each component; None each without a component."""
    if Y.shape[1] == 0:
        return dict.fromkeys(("err_rms", "err_max_rel", "err_rms_rel", "err_floor",
                              "final_degenerate"))
    diff = np.abs(Y - R)
    mixed = diff / (scale + np.abs(R))
    rel = diff / np.maximum(np.max(np.abs(R), axis=0), _TINY)
    return {"err_rms": float(np.sqrt(np.mean(mixed ** 2))),
            "err_max_rel": float(np.max(rel)), "err_rms_rel": float(np.sqrt(np.mean(rel ** 2))),
            "err_floor": float(np.min(scale)), "final_degenerate": int(at_rest(R))}


def at_rest(R: np.ndarray) -> bool:
    """Whether reference rows ``R`` (times x components) end near zero or at rest
    on every component (module docstring, ``final_degenerate``)."""
    m = R.shape[0]
    if m < 3 or R.shape[1] == 0:
        return False
    size, span = np.max(np.abs(R), axis=0), np.ptp(R, axis=0)
    tail = R[-max(2, m // 10):]
    near_zero = np.abs(R[-1]) <= REST * size
    still = np.max(np.abs(tail - R[-1]), axis=0) <= REST * span
    return bool(np.all((near_zero | still) & (span > 0)))


def monitor_error(P: np.ndarray, P_ref: np.ndarray, t: np.ndarray, t_start: float) -> float:
    """Orlov's error of a monitored history (a pin force) over ``t >= t_start``.

    ``E = max_t |P - P_ref| / max_t |P_ref|`` over the output times from
    ``t_start`` (the transient before it left out); E > 0.05 is what Orlov
    calls unacceptable (seed 004, "Numerical experiments").

    Parameters
    ----------
    P, P_ref : ndarray, shape (m,)
        The computed and the reference history at the output times ``t``.
    t_start : float
        The first time that counts; NaN when no output time is that late.
    """
    window = np.asarray(t) >= t_start
    if not window.any():            # a span ending before t*: no error to measure
        return math.nan
    diff = np.abs(np.asarray(P, float) - np.asarray(P_ref, float))[window]
    size = np.max(np.abs(np.asarray(P_ref, float)[window]))
    return float(np.max(diff) / max(size, _TINY))


def energy_variation(problem, t: np.ndarray, Y: np.ndarray) -> float | None:
    """The largest variation of the mechanical energy from its initial value,
    ``max_t |E(t) - E(t0)|`` over the output times ``t`` of the canonical rows
    ``Y``, for a problem that conserves it (its ``invariants()`` has
    ``"energy"``); None otherwise, or when it is not finite.

    The IFToMM benchmark library's accuracy measure of its conservative
    problems (A01, A02, A04: "the energy variation from the initial
    condition", in J; Gonzalez, Dopico, Lugris and Cuadrado, Multibody Syst.
    Dyn. 16 (2006) 179-190).
    """
    energy = problem.invariants().get("energy")
    if energy is None or not len(t):
        return None
    E = np.asarray(energy(t, Y), float)
    value = float(np.max(np.abs(E - E[0])))
    return value if math.isfinite(value) else None


def agreement_digits(A: np.ndarray, B: np.ndarray, scale: np.ndarray | None = None) -> np.ndarray:
    """Per-component digits to which two solutions agree over a whole run.

    ``-log10(max_t |a - b| / max(max_t |b|, scale))``: the difference relative
    to the component's magnitude over the run (robust to zero crossings), or to
    its absolute-tolerance scale when the component stays smaller than that.
    """
    diff = np.max(np.abs(A - B), axis=0)
    mag = np.max(np.abs(B), axis=0)
    if scale is not None:
        mag = np.maximum(mag, scale)
    return np.array([digits(d) for d in diff / np.maximum(mag, _TINY)])


def match_events(run: list, ref: list) -> list[tuple[int, int]]:
    """Pairs ``(i, j)`` of run event ``i`` matched with reference event ``j``.

    Matched by kind and order: the k-th event of each kind (name) in ``run``
    goes with the k-th of that kind in ``ref``. Pairs are sorted by ``i``.
    A run that misses an event in the middle of a sequence thus has its later
    events of that kind matched one place off, which shows as a large
    event-time error besides the missed count.

    Parameters
    ----------
    run, ref : list of (t, name, ...)
        Event sequences in time order; only the first two entries are read.
    """
    positions: dict[str, list[int]] = {}
    for j, ev in enumerate(ref):
        positions.setdefault(ev[1], []).append(j)
    seen: dict[str, int] = {}
    pairs = []
    for i, ev in enumerate(run):
        k = seen.get(ev[1], 0)
        seen[ev[1]] = k + 1
        refs = positions.get(ev[1], [])
        if k < len(refs):
            pairs.append((i, refs[k]))
    return pairs


def event_measures(run: list, ref: list, scale: np.ndarray, err: np.ndarray) -> dict:
    """The event fields of the record (harness/matrix/record.py) of a run against a reference.

    Parameters
    ----------
    run, ref : list of (t, name, y_after)
        The run's events acted on and the reference's, in time order, each
        with the canonical state right after it (after the reset).
    scale : ndarray
        Absolute-tolerance scale of each canonical component.
    err : ndarray of int
        The error components (positions).

    Returns
    -------
    dict
        ``events_by_kind`` ({name: count} of the run, JSON text),
        ``events_matched`` (run events matched with a reference event),
        ``event_time_err`` (largest ``|t - t_ref|`` over matched events, None
        when none matched), ``events_missed`` (reference events left without a
        match), ``events_spurious`` (run events left without one) and
        ``event_state_err`` (the mixed error ``|y - y_ref| / (scale + |y_ref|)``,
        max over the error components, of the state right after the last
        matched event; None when none matched).
    """
    pairs = match_events(run, ref)
    kinds: dict[str, int] = {}
    for ev in run:
        kinds[ev[1]] = kinds.get(ev[1], 0) + 1
    out = {"events_by_kind": json.dumps(dict(sorted(kinds.items()))),
           "events_matched": len(pairs),
           "events_missed": len(ref) - len(pairs), "events_spurious": len(run) - len(pairs),
           "event_time_err": None, "event_state_err": None}
    if pairs:
        out["event_time_err"] = float(max(abs(run[i][0] - ref[j][0]) for i, j in pairs))
        i, j = pairs[-1]
        y, r = np.asarray(run[i][2], float)[err], np.asarray(ref[j][2], float)[err]
        out["event_state_err"] = mixed_max(y[None, :], r[None, :], scale[err])
    return out


def event_time_digits(a: list, b: list, span: float) -> float:
    """Digits to which two event sequences agree in time: ``-log10(max |t_a - t_b| /
    span)`` over events matched by kind and order (16 when both are empty).

    Raises
    ------
    ValueError
        When the sequences differ in length or in the kind at any place, naming
        the first difference.
    """
    if len(a) != len(b):
        raise ValueError(f"the event sequences differ in count: {len(a)} against {len(b)}")
    for k, (ea, eb) in enumerate(zip(a, b)):
        if ea[1] != eb[1]:
            raise ValueError(f"event {k + 1} differs in kind: {ea[1]!r} against {eb[1]!r} "
                             f"(t = {ea[0]:.10g}, {eb[0]:.10g})")
    worst = max((abs(ea[0] - eb[0]) for ea, eb in zip(a, b)), default=0.0)
    return digits(worst / span)
