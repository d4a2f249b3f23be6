"""Error and drift measures, as the IVP Test Set defines them.

For a computed solution ``y`` and a reference ``r`` at the final time, over the
problem's declared error components ``I``:

* ``scd = -log10(max_{i in I} |y_i - r_i| / |r_i|)`` (significant correct digits);
* ``mescd = -log10(max_{i in I} |y_i - r_i| / (atol/rtol + |r_i|))`` (mixed), where
  ``atol/rtol`` is the problem's absolute-tolerance scale;
* ``err_max``: the largest mixed error ``|y_i - r_i| / (scale_i + |r_i|)`` over all
  output times and error components; ``err_vel`` and ``err_lambda`` the same over
  velocity and multiplier components.

A run whose mixed error at the final time exceeds :data:`DIVERGENCE_BOUND` (1:
its positions are off by more than their own size plus the absolute scale,
``mescd < 0``) has diverged (:func:`divergence`): the harness records it as
``failed`` with reason ``diverged`` and keeps these measures, so a report can
still show how far off it was.

Reference: Mazzia and Magherini, "Test Set for Initial Value Problem Solvers",
release 2.4 (2008), University of Bari, sect. II ("scd" and "mescd").
"""

from __future__ import annotations

import math

import numpy as np

_TINY = 1e-300

#: the largest final-time mixed error (``10**-mescd``) of a run that has not diverged
DIVERGENCE_BOUND = 1.0


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
    }
    for key, name in (("err_vel", "velocity"), ("err_lambda", "lambda")):
        idx = groups.get(name, [])
        out[key] = mixed_max(Y[:, idx], R[:, idx], scale[idx]) if len(idx) else None
    return out


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
