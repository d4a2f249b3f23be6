"""The spectrum of a problem along its reference: why it is hard (``ibench stiffness``).

At chosen times the state is taken from the stored reference (its canonical
components; for a mechanical problem the first ``2 nq`` of them, the positions
and velocities, are the state of its ``ode`` formulation) and the eigenvalues
of the ``ode`` formulation's Jacobian are computed: the system's analytic
``jac`` (dense or sparse) when it has one, else forward differences
(:func:`integrator_bench.integrators.newton.jacobian`, grouped on
``jac_sparsity`` when given). Up to :data:`DENSE_EIG_LIMIT` states every
eigenvalue (``numpy.linalg.eigvals``); above, only the extremes by ARPACK
(``scipy.sparse.linalg.eigs``: largest magnitude, most negative real part and
largest imaginary part; the stiffness ratio then compares the extremes found),
on the sparse Jacobian, or, for a system with neither ``jac`` nor
``jac_sparsity``, on products ``J v`` by forward differences along ``v``.
States are interpolated linearly between the reference's output times.

From the eigenvalues: the spectral radius ``rho``, the most negative real part,
the largest imaginary part, and the ADAMS stiffness ratio (MSC.ADAMS course
ADM703b, sect. 7, seed 001): the largest overdamped (real, negative) eigenvalue
over the largest underdamped (complex) eigenvalue in magnitude; above 200 the
system is stiff, below 20 non-stiff. An explicit method whose real stability
interval is ``[-beta, 0]`` (the integrators' ``stability_intervals``) is stable
at ``h <= beta / rho`` when the spectrum lies on the negative real axis. With
complex eigenvalues the real-interval prediction is not exact: the stable step
along an eigenvalue's direction depends on the shape of the stability region,
and is smaller for most explicit methods (explicit Euler and RKC, whose regions
are thin off the axis, are unstable at every step on the imaginary axis) but
can be larger (RK4 reaches ``2.83 / rho`` on the imaginary axis, against
``beta = 2.79``).

The spectrum's angle: for each eigenvalue with negative real part and a
magnitude above :data:`ANGLE_FLOOR` times ``rho`` (rigid-body and slow modes
left out), ``arg(-lambda)`` in degrees, 90 on the imaginary axis. The k-step
BDF is stable in the sector of half-angle ``alpha_k`` around the negative real
axis (:data:`~integrator_bench.integrators.bdf.A_ALPHA`: 90 for orders 1 and 2,
86.03, 73.35, 51.84 for 3, 4, 5; Hairer and Wanner II, Table V.2.3); an
eigenvalue outside that sector bounds the step of that order (its ``h
lambda`` must stay out of the instability region near the imaginary axis),
however loose the tolerance. ``outside`` counts them per order, and
``outside_size`` gives the largest of them in magnitude over ``rho``: small
eigenvalues near the imaginary axis are harmless (BDF is stable for small
``h |lambda|`` there), but when the stiffest modes themselves are lightly damped
(``outside_size`` near 1), every step an implicit code wants (``h rho`` well
above 1) puts them in the instability region of orders 3-5, which orders 1-2
do not have.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from integrator_bench.harness.measure import references

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.line import spec_name
from integrator_bench.harness.errors import BadInput
from integrator_bench.harness.paths import write_atomically
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.integrators.bdf import A_ALPHA
from integrator_bench.integrators.newton import jacobian as fd_jacobian
from integrator_bench.integrators.sparse import GroupedDifferences

DENSE_EIG_LIMIT = 2000   # states up to which every eigenvalue is computed
ARPACK_K = 6             # eigenvalues ARPACK finds at each end above it
ARPACK_NCV = 40          # its Lanczos/Arnoldi basis (scipy's default 2k+1 converges slowly)
ARPACK_SEED = 0          # of its starting vector: the same extremes in every run
STIFF, NON_STIFF = 200.0, 20.0   # ADAMS's thresholds on the stiffness ratio
ANGLE_FLOOR = 1e-3  # eigenvalues below this fraction of rho are left out of the angles
BDF_ORDERS = (3, 4, 5)  # the orders whose A(alpha) sector the spectrum is held against
REAL_TOL = 1e-8          # |Im| <= REAL_TOL |lambda|: a real (overdamped) eigenvalue


def ode_jacobian(system, t: float, y: np.ndarray):
    """``df/dy`` of an ``ode`` system at ``(t, y)``: dense or sparse as it comes.

    Parameters
    ----------
    system : OdeSystem
    t : float
    y : ndarray
    """
    if system.jac is None and system.jac_sparsity is None and system.n > DENSE_EIG_LIMIT:
        return difference_operator(system, t, y)
    grouped = (GroupedDifferences(system.jac_sparsity)
               if system.jac is None and system.jac_sparsity is not None else None)
    return fd_jacobian(system.fun, system.jac, system.atol_scale, t, y, {}, grouped)


def difference_operator(system, t: float, y: np.ndarray):
    """``v -> J v`` by one forward difference of ``fun`` along ``v``: the
    Jacobian of a large system with no ``jac`` and no ``jac_sparsity``, for
    ARPACK, without an ``n x n`` matrix."""
    from scipy.sparse.linalg import LinearOperator
    f0 = np.asarray(system.fun(t, y), float)
    size = math.sqrt(np.finfo(float).eps) * max(float(np.linalg.norm(y)), 1.0)

    def matvec(v):
        v = np.ravel(v)
        norm = float(np.linalg.norm(v))
        if norm == 0.0:
            return np.zeros_like(f0)
        step = size / norm
        return (np.asarray(system.fun(t, y + step * v), float) - f0) / step
    return LinearOperator((system.n, system.n), matvec=matvec, dtype=float)


def eigenvalues(J) -> tuple[np.ndarray, str]:
    """Every eigenvalue of ``J`` up to :data:`DENSE_EIG_LIMIT` states, else the
    extremes by ARPACK; returns them and how they were found (one line)."""
    n = J.shape[0]
    if n <= DENSE_EIG_LIMIT:
        return np.linalg.eigvals(J.toarray() if sp.issparse(J) else J), f"all {n} (dense)"
    from scipy.sparse.linalg import ArpackNoConvergence, eigs
    A = sp.csr_matrix(J) if sp.issparse(J) or isinstance(J, np.ndarray) else J
    # one fixed starting vector: ARPACK's own is random and its generator's state
    # persists between calls, so the extremes (to its tolerance) varied with what
    # the process had computed before
    v0 = np.random.default_rng(ARPACK_SEED).standard_normal(n)
    found, short = [], 0
    for which in ("LM", "SR", "LI"):
        try:
            found.append(eigs(A, k=ARPACK_K, which=which, ncv=min(n - 1, ARPACK_NCV),
                              maxiter=20 * n, v0=v0, return_eigenvectors=False))
        except ArpackNoConvergence as exc:   # keep the converged ones, and say so
            found.append(exc.eigenvalues)
            short += ARPACK_K - len(exc.eigenvalues)
    lam = np.unique(np.concatenate(found))
    return lam, (f"{lam.size} extremes of {n} by ARPACK (largest magnitude, most negative "
                 f"real part, largest imaginary part)"
                 + (f"; {short} did not converge" if short else ""))


def figures(lam: np.ndarray) -> dict:
    """Spectral radius, extremes and the ADAMS stiffness ratio with its verdict.

    Parameters
    ----------
    lam : ndarray of complex
        Eigenvalues.

    Returns
    -------
    dict
        ``rho``, ``min_real``, ``max_imag``, ``ratio`` (0 without an
        overdamped eigenvalue: numerically non-stiff, though it may be
        physically stiff; None without an underdamped one), ``verdict``
        (``stiff`` above 200, ``non-stiff`` below 20, else ``moderate``) and
        ``complex``, the number of non-real eigenvalues; ``max_angle``, the
        largest ``arg(-lambda)`` in degrees over the eigenvalues of negative real
        part above ``ANGLE_FLOOR rho`` (None without one), and ``outside``,
        per BDF order of :data:`BDF_ORDERS`, how many of them lie outside its
        A(alpha) sector, and ``outside_size``, per order, the largest magnitude
        among those over ``rho`` (0 when none).
    """
    mag = np.abs(lam)
    real = np.abs(lam.imag) <= REAL_TOL * np.maximum(mag, 1e-300)
    over = mag[real & (lam.real < 0)]
    under = mag[~real]
    ratio = None if not under.size else float(over.max() / under.max()) if over.size else 0.0
    verdict = classify(ratio)
    rho = float(mag.max())
    left = lam[(lam.real < 0) & (mag > ANGLE_FLOOR * rho)]
    angle = np.degrees(np.abs(np.angle(-left)))
    return {"rho": rho, "min_real": float(lam.real.min()),
            "max_imag": float(np.abs(lam.imag).max()), "ratio": ratio, "verdict": verdict,
            "complex": int((~real).sum()),
            "max_angle": float(angle.max()) if angle.size else None,
            "outside": {k: int((angle > A_ALPHA[k]).sum()) for k in BDF_ORDERS},
            "outside_size": {k: float(np.abs(left[angle > A_ALPHA[k]]).max(initial=0.0))
                             / rho if rho > 0 else 0.0 for k in BDF_ORDERS}}


def classify(ratio: float | None) -> str:
    """ADAMS's class of a stiffness ratio: ``stiff`` above :data:`STIFF`,
    ``non-stiff`` below :data:`NON_STIFF`, else ``moderate``; ``no underdamped
    mode`` for None."""
    if ratio is None:
        return "no underdamped mode"
    return "stiff" if ratio > STIFF else "non-stiff" if ratio < NON_STIFF else "moderate"


def predicted_steps(rho: float) -> dict:
    """``beta / rho`` for every registered integrator that declares
    ``stability_intervals``: ``{name: {label: h}}``."""
    return {name: {label: beta / rho if rho > 0 else math.inf for label, beta in
                   cls.stability_intervals.items()}
            for name, cls in registry.integrators().items() if cls.stability_intervals}


def achieved_steps(store, problem) -> dict:
    """The largest fixed step ``h`` at which each integrator succeeded (status
    ``ok``) on ``problem`` (its name and parameters) in the ``ode`` formulation,
    in the store at ``store``; empty when there is no store (or ``store`` is None)."""
    from integrator_bench.harness.matrix.store import load
    if store is None or not Path(store).exists():
        return {}
    df = load(store)
    if df.empty:
        return {}
    same = [json.loads(p) == problem.params for p in df.params]
    ok = df[np.array(same, bool) & (df.problem == problem.name) & (df.formulation == "ode")
            & (df.status == CaseStatus.OK) & df.h.notna()]
    return {k: float(v) for k, v in ok.groupby("integrator").h.max().items()}


def parse_times(problem, at) -> list[float]:
    """The times asked for (default: start, middle, end); one outside the span
    is :class:`BadInput`."""
    t0, t1 = problem.t_span
    times = list(at) if at else [t0, 0.5 * (t0 + t1), t1]
    for t in times:
        if not (math.isfinite(t) and t0 <= t <= t1):
            raise BadInput(f"--at {t:g} is outside the time span of {problem.label()}; "
                           f"valid: {t0:g} <= t <= {t1:g}")
    return times


def analyse(problem, times, store, reference_dir=None) -> dict:
    """The spectrum of ``problem``'s ``ode`` Jacobian at ``times`` along its reference
    (read from ``reference_dir``, computed there when missing: see
    :func:`integrator_bench.harness.measure.references.load`).

    Returns a dict with the label, the state count, per time the figures of
    :func:`figures`, the method and the eigenvalues, the predicted and achieved
    steps at the largest spectral radius.
    """
    out = spectrum(problem, times, reference_dir)
    rho = max(f["rho"] for f in out)
    return {"label": problem.label(), "n": problem.formulate("ode").n, "times": out,
            "rho": rho, "predicted": predicted_steps(rho),
            "achieved": achieved_steps(store, problem)}


def spectrum(problem, times, reference_dir=None) -> list[dict]:
    """Per time of ``times`` the figures of :func:`figures` of ``problem``'s ``ode``
    Jacobian along its reference, the method and the eigenvalues (what
    :func:`analyse` and the scheduler's stiffness bound take)."""
    system = problem.formulate("ode")
    ref = references.load(problem, reference_dir)
    out = []
    for t in times:
        y = np.array([np.interp(t, ref.t, ref.Y[:, j]) for j in range(system.n)])
        lam, method = eigenvalues(ode_jacobian(system, t, y))
        out.append({"t": t, "method": method, **figures(lam), "eigenvalues": lam})
    return out


def png_path(problem, out: Path) -> Path:
    """``<out>/<problem>/<parameters>.png``, named as the reference files are."""
    return references.paths(problem, out)[0].with_suffix(".png")


def plot(result: dict, path: Path) -> Path:
    """The eigenvalues at every time in the complex plane (symlog axes), as a PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 5))
    for f in result["times"]:
        lam = f["eigenvalues"]
        ax.plot(lam.real, lam.imag, "o", ms=4, mfc="none", label=f"t = {f['t']:g}")
    ax.set_xscale("symlog", linthresh=1.0)
    ax.set_yscale("symlog", linthresh=1.0)
    ax.axvline(0, color="0.7", lw=0.8)
    ax.set_xlabel("Re $\\lambda$ (1/s)")
    ax.set_ylabel("Im $\\lambda$ (1/s)")
    ax.set_title(f"{spec_name(result['label'])}, {result['n']} states: "
                 f"{result['times'][0]['method']}", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    try:   # a full disk or an interrupt leaves the old PNG or none, never half a one
        write_atomically(path, lambda part: fig.savefig(part, dpi=100, format="png"))
    finally:
        plt.close(fig)
    return path


def to_json(result: dict) -> dict:
    """``result`` with the eigenvalues as ``[re, im]`` pairs, ready for ``json``."""
    times = [{**{k: v for k, v in f.items() if k != "eigenvalues"},
              "eigenvalues": [[float(z.real), float(z.imag)] for z in f["eigenvalues"]]}
             for f in result["times"]]
    return {**result, "times": times}


def text(result: dict) -> str:
    """Markdown tables: the figures per time, then predicted vs achieved steps."""
    def g(x):
        return "-" if x is None else f"{x:.4g}"
    lines = [f"### {result['label']} ({result['n']} states)", "",
             "| t | eigenvalues | rho | min Re | max abs Im | stiffness ratio | verdict "
             "| max angle [deg] | outside BDF3 / 4 / 5 | their largest abs/rho |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for f in result["times"]:
        outside = " / ".join(str(f["outside"][k]) for k in BDF_ORDERS)
        size = " / ".join(f"{f['outside_size'][k]:.2g}" for k in BDF_ORDERS)
        lines.append(f"| {f['t']:g} | {f['method']} | {g(f['rho'])} | {g(f['min_real'])} | "
                     f"{g(f['max_imag'])} | {g(f['ratio'])} | {f['verdict']} | "
                     f"{g(f['max_angle'])} | {outside} | {size} |")
    lines += ["", "max angle: the largest arg(-lambda) of the eigenvalues with Re < 0 above "
              f"{ANGLE_FLOOR:g} rho (90: on the imaginary axis); outside: how many lie beyond "
              "the A(alpha) sector of BDF3, 4, 5 ("
              + ", ".join(f"{A_ALPHA[k]:g}" for k in BDF_ORDERS)
              + " degrees, Hairer and Wanner II, Table V.2.3), and the largest of those in magnitude "
              "over rho: near 1, the stiffest modes are lightly damped and bound the step of "
              "orders 3-5 (not of 1-2)"]
    complex_ = any(f["complex"] for f in result["times"])
    lines += ["", f"largest stable step h <= beta / rho, rho = {result['rho']:.4g}"
              + (" (complex eigenvalues present: the real-interval prediction is exact on the "
                 "real axis only; off it most explicit methods need less)"
                 if complex_ else " (real spectrum: exact)"), "",
              "| integrator | variant | beta | predicted h | largest h ok in store |",
              "|---|---|---|---|---|"]
    achieved = dict(result["achieved"])
    for name, steps in result["predicted"].items():
        cls = registry.integrators()[name]
        for label, h in steps.items():
            lines.append(f"| {name} | {label or '-'} | {cls.stability_intervals[label]:.4g} | "
                         f"{h:.3g} | {g(achieved.pop(name, None))} |")
    for name, h in achieved.items():
        lines.append(f"| {name} | (no interval declared) | - | - | {h:.3g} |")
    return "\n".join(lines)


def check_store(store) -> None:
    """Open the store at ``store`` when it exists: a foreign or unreadable file
    raises :class:`~integrator_bench.harness.errors.StoreError` before anything
    is computed or written."""
    from integrator_bench.harness.matrix.store import load
    if Path(store).exists():
        load(store)
