"""The source documents' numbers, row by row, beside the project's closest runs.

Every table of the seed documents that reports run statistics (steps NS,
f-evaluations NF, Jacobians NJ, ...) becomes a list of :class:`SourceRow`: the
published numbers, the project's closest configuration (problem and parameters,
formulation, integrator with settings, the seed's tolerance or step) and one
line saying what differs between the two (code, formulation, error norm,
machine); ``""`` when nothing does. The ``seeds`` preset
(:data:`integrator_bench.harness.model.cases.PRESETS`) runs exactly these
configurations (:func:`preset_cases`), and the report's part "The sources,
number by number" (:func:`compare`) sets each row beside the matching record
of the store: the ratio ours / published of every number the row gives and a
verdict:

``agrees``
    steps and f-evaluations (those the row gives) within :data:`AGREE` (10 %);
``explained``
    a number differs by more, and the row names what differs in configuration;
``unexplained``
    a number differs by more although the row claims the same configuration;
``failed here``
    the store's record of the configuration did not succeed (its status and reason
    are shown);
``not run``
    the store holds no record of the configuration.

Sources: Sudarsan and Keerthi, Appl. Math. Comput. 92 (1998) 195-218, Tables 1,
2 and 4 (seed 003; read from a column-scrambled OCR, Tables 1 and 4 with medium
confidence; their NJ counts evaluations of the constraint Jacobian, which the
project does not count apart, so it is shown and not compared); the Lund FMNN05
student report, Tables 1, 2, 3 and 5 (seed 002);
Orlov, Kuzin and Shabrov, Russian Supercomputing Days 2017 (seed 004's
slides: DUMKA3 over RK4); the ADAMS/Solver seminar's CPU ratios (seed 000) and
the ADAMS course's stiffness criterion (seed 001) are run by
:mod:`~integrator_bench.harness.model.seed_runs`.

A run that reached the end of its span with a final error over the divergence
bound (recorded ``failed``, reason ``diverged``, its errors kept) is compared by
its counts like a successful one, and its row says so: the sources report the
counts of their runs at a tolerance, whatever the accuracy reached.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

from integrator_bench.harness.model import seed_runs

AGREE = 0.10
#: the numbers compared, in the order shown, with their headings
KEYS = (("nsteps", "NS"), ("nfev", "NF"), ("njev", "NJ"), ("nnfail", "NCF"))
JUDGED = ("nsteps", "nfev")


@dataclass(frozen=True)
class SourceRow:
    """One row of a seed's table and the project's closest configuration."""

    seed: str
    table: str
    row: str
    published: dict            # {"nsteps": 36, "nfev": 68, ...}
    problem: str               # a problem spec, ``spring_pendulum:k=1000,t_end=8``
    formulation: str
    integrator: str            # an integrator spec, ``dumka3:polynomial=P5``
    rtol: float | None = None
    h: float | None = None
    differs: str = ""          # what differs in configuration; "" when nothing
    own_f: bool = False        # f without difference-quotient Jacobian calls (Assimulo's)
    uncounted: tuple = ()      # published numbers with no counterpart here (shown only)


def _sk(table: str, problem: str, ns: dict, nf: dict, nj: dict) -> list[SourceRow]:
    """Sudarsan and Keerthi's approaches for one problem, TOL 1e-2, 1e-4, 1e-6."""
    mapping = {
        "PA": ("ode", "cvode-adams", "PA projects an Adams predictor-corrector's step onto "
               "the constraints; here CVODE-Adams (variable order) on the index-1 ODE without "
               "projection (the projection formulation takes one-step methods only)"),
        "TP": ("partitioning", "scipy-RK23", "TP integrates tangent coordinates with an Adams "
               "code; here coordinate partitioning with RK23 (3 f per step, one-step)"),
        "ECS": ("ggl", "ida", "ECS is a DASSL-type BDF on the stabilized index 2 (GGL) "
                "form; here IDA (BDF, variable order) on GGL: same family, another code and "
                "error norm"),
        "ICS": ("baumgarte", "cvode-adams", "ICS is Baumgarte with a tuned alpha and an "
                "Adams predictor-corrector; here CVODE-Adams on Baumgarte at the problem's "
                "alpha"),
    }
    rows = []
    for approach, (form, integrator, differs) in mapping.items():
        for i, tol in enumerate((1e-2, 1e-4, 1e-6)):
            pub = {"nsteps": ns[approach][i], "njev": nj[approach][i]}
            if nf.get(approach):
                pub["nfev"] = nf[approach][i]
            rows.append(SourceRow("003", table, f"{approach}, TOL {tol:g}", pub, problem, form,
                                  integrator, rtol=tol, differs=differs, uncounted=("njev",)))
    return rows


#: Sudarsan and Keerthi (1998), Tables 1, 2 and 4: NS, NF, NJ per approach and TOL
S_AND_K = tuple(
    _sk("Table 1 (slider-crank)", "slider_crank",
        ns={"PA": (36, 83, 145), "TP": (28, 61, 100), "ECS": (186, 398, 580),
            "ICS": (36, 83, 135)},
        nf={"PA": (68, 162, 286), "TP": (55, 121, 200), "ICS": (68, 166, 266)},
        nj={"PA": (73, 167, 291), "TP": (143, 275, 455), "ECS": (172, 386, 468),
            "ICS": (73, 171, 271)})
    + _sk("Table 2 (manipulator)", "manipulator",
          ns={"PA": (43, 95, 151), "TP": (55, 105, 183), "ECS": (105, 256, 340),
              "ICS": (45, 90, 150)},
          nf={"PA": (85, 190, 302), "TP": (110, 210, 378), "ICS": (88, 178, 298)},
          nj={"PA": (91, 195, 308), "TP": (245, 460, 1034), "ECS": (98, 240, 328),
              "ICS": (93, 183, 303)})
    + _sk("Table 4 (quick-return)", "quick_return",
          ns={"PA": (356, 686, 1080), "TP": (506, 938, 1556), "ECS": (1208, 1932, 3574),
              "ICS": (346, 599, 1044)},
          nf={"PA": (712, 1272, 2160), "TP": (1012, 1876, 3112), "ICS": (676, 1191, 2082)},
          nj={"PA": (682, 1173, 2060), "TP": (3814, 5724, 9512), "ECS": (1194, 1860, 3787),
              "ICS": (681, 1196, 2087)})
)

_FIXED_BDF = ("the report's Assimulo fixed-step BDF solves each step by Newton with a "
              "difference-quotient Jacobian; here the project's BDF (analytic Jacobian, its "
              "own Newton stopping rule)")
_DYMOLA = ("Dymola's {code}, here {ours}; over 1 s of the report's 30 s (the reference "
           "over 30 s, Radau and DOP853 at 1e-13 through some 10^7 steps, is beyond the "
           "preset's time): compare the ratios between the codes, not the counts")
_K6 = "spring_pendulum:k=1000000,t_end=1"

#: The student report (seed 002): Tables 1, 2, 3 and 5
STUDENT = (
    *(SourceRow("002", "Table 1 (spring pendulum k = 1000, t = 8, h = 0.01)", f"BDF{p}",
                {"nfev": f}, "spring_pendulum:k=1000,t_end=8", "ode", f"bdf{p}", h=0.01,
                differs=_FIXED_BDF)
      for p, f in ((2, 16214), (3, 16112), (4, 16061))),
    SourceRow("002", "Table 2 (Dymola, k = 1e6, t = 30, tol 1e-8; here t = 1)", "Lsodar",
              {"nsteps": 391591, "nfev": 809798, "njev": 3706},
              _K6, "ode", "assimulo-lsodar", rtol=1e-8,
              differs=_DYMOLA.format(code="Lsodar", ours="ODEPACK's LSODAR through Assimulo"),
              own_f=True),
    SourceRow("002", "Table 2 (Dymola, k = 1e6, t = 30, tol 1e-8; here t = 1)", "Dassl",
              {"nsteps": 698252, "nfev": 1422260, "njev": 7651},
              _K6, "ode", "ida", rtol=1e-8,
              differs=_DYMOLA.format(code="DASSL", ours="IDA, DASSL's successor")),
    SourceRow("002", "Table 2 (Dymola, k = 1e6, t = 30, tol 1e-8; here t = 1)", "Dopri45",
              {"nsteps": 314896, "nfev": 1894983},
              _K6, "ode", "assimulo-dopri5", rtol=1e-8,
              differs=_DYMOLA.format(code="Dopri45", ours="Hairer's DOPRI5 through Assimulo")),
    SourceRow("002", "Table 2 (Dymola, k = 1e6, t = 30, tol 1e-8; here t = 1)", "Sdirk34",
              {"nsteps": 603762, "nfev": 6215245, "njev": 74847},
              _K6, "ode", "scipy-Radau", rtol=1e-8,
              differs=_DYMOLA.format(code="Sdirk34", ours="scipy's Radau IIA (order 5, 3 "
                                     "stages), the closest implicit Runge-Kutta code (no "
                                     "adaptive SDIRK here)")),
    *(SourceRow("002", "Table 3 (spring pendulum k = 100, t = 10, tol 1e-8)", f"BDF{p}",
                {"nsteps": 1001, "nfev": f}, "spring_pendulum:k=100,t_end=10", "ode",
                f"bdf{p}", h=0.01, differs=_FIXED_BDF)
      for p, f in ((2, 8469), (3, 8390), (4, 8349))),
    SourceRow("002", "Table 3 (spring pendulum k = 100, t = 10, tol 1e-8)", "CVODE (Adams)",
              {"nsteps": 1007, "nfev": 1227}, "spring_pendulum:k=100,t_end=10", "ode",
              "assimulo-cvode-adams", rtol=1e-8, own_f=True),
    SourceRow("002", "Table 3 (spring pendulum k = 100, t = 10, tol 1e-8)", "Lsodar",
              {"nsteps": 1106, "nfev": 2309}, "spring_pendulum:k=100,t_end=10", "ode",
              "assimulo-lsodar", rtol=1e-8, own_f=True,
              differs="the report's row is Dymola's Lsodar beside Assimulo's runs; here "
                      "LSODAR through Assimulo"),
    SourceRow("002", "Table 5 (squeezer, IDA, 0.03 s)", "index 2, algvar",
              {"nsteps": 617, "nfev": 1613, "njev": 120, "nnfail": 0}, "squeezer", "i2",
              "assimulo-ida", rtol=1e-6, own_f=True,
              differs="analytic Jacobian here; the report's difference quotients give "
                      "617/1613/120/0 exactly (studies/seed002_assimulo.py)"),
    SourceRow("002", "Table 5 (squeezer, IDA, 0.03 s)", "index 2, high ATOL on lambda",
              {"nsteps": 910, "nfev": 1511, "njev": 75, "nnfail": 0}, "squeezer", "i2",
              "assimulo-ida", rtol=1e-6, own_f=True,
              differs="the report's ATOL on lambda is not stated; here lambda is left out of "
                      "the error test (suppress_alg), analytic Jacobian"),
    SourceRow("002", "Table 5 (squeezer, IDA, 0.03 s)", "index 3, high ATOL on v, lambda",
              {"nsteps": 707, "nfev": 1496, "njev": 784, "nnfail": 120}, "squeezer", "i3",
              "assimulo-ida", rtol=1e-6, own_f=True,
              differs="the report's ATOL values are not stated; its authors' code (atol 1e5 "
                      "on v and lambda) gives 792/1764/734/229 (studies/seed002_assimulo.py); "
                      "here v and lambda are left out of the error test, analytic Jacobian"),
)

_ORLOV = ("Orlov's 3600-state chain against the project's 298-state cvt_chain (same rho "
          "1e8, max |Im| 7e5 against 1e6); speed-up as RK4's f-evaluations over the cell's "
          "(Orlov's is CPU), RK4 at Orlov's 5e-8 s (h rho = 5 is beyond RK4's real interval "
          "2.79; it runs because the friction saturates, E about 0.06)")

#: Orlov's DUMKA3 speed-ups over RK4 (seed 004's slides): (polynomial, h, speed-up)
ORLOV = ((5, 2e-6, 5.9), (7, 3e-6, 4.7), (8, 4e-6, 4.4))
RK4_H = 5e-8        # Orlov's RK4 step (his speed-ups are over RK4 at 5e-8 s)

def orlov_rows() -> tuple:
    return tuple(SourceRow("004", "DUMKA3 over RK4 (slides, Russian Supercomputing Days 2017)",
                           f"P{k} at h = {h:g}", {"speedup": s}, "cvt_chain:friction=1",
                           "ode", f"dumka3:polynomial=P{k}", h=h, differs=_ORLOV)
                 for k, h, s in ORLOV)


ROWS: tuple = S_AND_K + STUDENT + orlov_rows()


def preset_cases() -> tuple:
    """The configurations of :data:`ROWS` (and RK4 on ``cvt_chain`` for Orlov's
    ratios), of seed 000's CPU ratios and of seed 001's criterion
    (:mod:`~integrator_bench.harness.model.seed_runs`), each once: ``(problem spec,
    formulation, integrator spec, rtol, h)``."""
    out = dict.fromkeys((r.problem, r.formulation, r.integrator, r.rtol, r.h) for r in ROWS)
    out[("cvt_chain:friction=1", "ode", "rk4", None, RK4_H)] = None
    for line in (*seed_runs.LINES, *seed_runs.stiffness_lines()):
        out.update(dict.fromkeys(line.cases()))
    return tuple(out)


def _params(spec: str) -> tuple[str, dict]:
    name, _, rest = spec.partition(":")
    return name, {k: float(v) for k, v in (kv.split("=") for kv in rest.split(",") if kv)}


def match(df, problem, formulation, integrator, rtol, h):
    """The record of one configuration in ``df`` (the last successful one, else the
    last), or None."""
    import numpy as np

    from integrator_bench.integrators.settings import base_name

    name, params = _params(problem)
    base, _, sets = integrator.partition(":")
    settings = dict(kv.split("=") for kv in sets.split(",") if kv)
    # the report's records name a variant "dumka3 (polynomial=P5)"; the store's "dumka3"
    g = df[(df["problem"] == name) & (df["formulation"] == formulation)
           & (df["integrator"].map(base_name) == base)]
    if g.empty:
        return None

    def same(row) -> bool:
        p = json.loads(row["params"]) if isinstance(row["params"], str) else {}
        if any(not math.isclose(float(p.get(k, math.nan)), v) for k, v in params.items()):
            return False
        s = json.loads(row["settings"]) if isinstance(row.get("settings"), str) else {}
        if {k: str(v) for k, v in s.items()} != settings:
            return False
        for key, want in (("rtol", rtol), ("h", h)):
            got = row.get(key)
            got = None if got is None or (isinstance(got, float) and np.isnan(got)) else got
            if (want is None) != (got is None) or (want is not None
                                                   and not math.isclose(got, want, rel_tol=1e-9)):
                return False
        return True

    hits = [r for _, r in g.iterrows() if same(r)]
    ok = [r for r in hits if r["status"] == "ok"]
    return (ok or hits or [None])[-1]


def _own(record, key, own_f: bool):
    value = record.get(key)
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return None
    if key == "nfev" and own_f:
        counts = record.get("solver_counts")
        counts = json.loads(counts) if isinstance(counts, str) else (counts or {})
        value -= (counts or {}).get("nfev_jac", 0) or 0
    return float(value)


@dataclass
class Compared:
    row: SourceRow
    ours: dict = field(default_factory=dict)
    ratios: dict = field(default_factory=dict)
    verdict: str = "not run"
    status: str = ""           # the record's status and reason when it did not succeed


def ran_through(record) -> bool:
    """Whether a record that did not succeed reached the end of its span: failed
    as ``diverged`` with its final error kept (the errors of a run that stopped
    early are not computed)."""
    mescd = record.get("mescd")
    return (record["status"] != "ok" and record.get("reason") == "diverged"
            and mescd is not None and math.isfinite(float(mescd)))


def compare(df) -> list[Compared]:
    """Every row of :data:`ROWS` beside its record in ``df`` (the store's records)."""
    out = []
    rk4 = match(df, "cvt_chain:friction=1", "ode", "rk4", None, RK4_H)
    rk4 = rk4 if rk4 is not None and rk4["status"] == "ok" else None
    for row in ROWS:
        c = Compared(row)
        rec = match(df, row.problem, row.formulation, row.integrator, row.rtol, row.h)
        if rec is not None and ran_through(rec):
            c.status = (f"ran to the end, final error {10 ** -float(rec['mescd']):.2g} over "
                        f"the divergence bound (recorded {rec['status']}, {rec['reason']})")
        if rec is not None and rec["status"] != "ok" and not c.status:
            c.verdict, c.status = "failed here", f"{rec['status']} ({rec.get('reason')})"
        elif rec is not None and "speedup" in row.published:
            if rk4 is not None and _own(rec, "nfev", False):
                c.ours["speedup"] = _own(rk4, "nfev", False) / _own(rec, "nfev", False)
        elif rec is not None:
            c.ours = {k: v for k, _ in KEYS if k in row.published and k not in row.uncounted
                      for v in [_own(rec, k, row.own_f)] if v is not None}
        if c.ours:
            c.ratios = {k: c.ours[k] / row.published[k] for k in c.ours
                        if row.published.get(k)}
            judged = [abs(c.ratios[k] - 1) <= AGREE for k in c.ratios
                      if k in JUDGED or k == "speedup"]
            c.verdict = ("agrees" if judged and all(judged) else
                         "explained" if row.differs else "unexplained")
        out.append(c)
    return out


def summary(compared: list[Compared]) -> dict:
    """How many rows agree, differ with an explanation, differ unexplained, did not run."""
    counts = {"agrees": 0, "explained": 0, "unexplained": 0, "failed here": 0, "not run": 0}
    for c in compared:
        counts[c.verdict] += 1
    return counts


def _num(x) -> str:
    if x is None:
        return "–"
    return f"{x:.3g}" if isinstance(x, float) and not float(x).is_integer() else f"{int(x)}"


TABLE_HEADER = ("row", "configuration here", "published", "ours", "ours / published",
                "verdict", "what differs")


def tables(compared: list[Compared]) -> list[tuple[str, list]]:
    """``(seed and table title, rows of TABLE_HEADER cells)`` per table, in order."""
    out: dict = {}
    for c in compared:
        r = c.row
        keys = [k for k in ("speedup", *dict(KEYS)) if k in r.published]
        names = dict(KEYS, speedup="speed-up")
        pub = ", ".join(f"{names[k]} {_num(r.published[k])}" for k in keys)
        ours = ", ".join(f"{names[k]} {_num(c.ours[k])}" for k in keys if k in c.ours) or "–"
        ratio = ", ".join(f"{c.ratios[k]:.2f}" for k in keys if k in c.ratios) or "–"
        tol = f"rtol {r.rtol:g}" if r.rtol is not None else f"h {r.h:g}"
        config = f"{r.problem} {r.formulation} {r.integrator} {tol}"
        verdict = f"{c.verdict}: {c.status}" if c.status else c.verdict
        out.setdefault(f"seed {r.seed}, {r.table}", []).append(
            (r.row, config, pub, ours, ratio, verdict, r.differs or "same configuration"))
    return list(out.items())


def within_table_ratios(compared: list[Compared]) -> list[tuple]:
    """Ratios between the methods of one table, the source's beside ours: each row's
    steps (or f-evaluations when the row gives no steps) over those of the table's
    first row at the same tolerance (seed 003: each approach over PA at each TOL;
    seed 002: each code over the table's first). ``(table, row, ratio, source, ours)``."""
    first: dict = {}
    out = []
    for c in compared:
        if "speedup" in c.row.published:
            continue
        _, _, tol = c.row.row.partition(", ")
        key = (c.row.seed, c.row.table, tol)
        base = first.setdefault(key, c)
        if base is c:
            continue
        name = c.row.row.partition(", ")[0]
        what = "nsteps" if "nsteps" in c.row.published and "nsteps" in base.row.published \
            else "nfev"
        if what not in c.row.published or what not in base.row.published:
            continue
        paper = c.row.published[what] / base.row.published[what]
        ours = (c.ours[what] / base.ours[what]
                if what in c.ours and base.ours.get(what) else None)
        label = dict(KEYS)[what]
        out.append((f"seed {c.row.seed}, {c.row.table}", c.row.row,
                    f"{label} {name} / {base.row.row.partition(', ')[0]}", f"{paper:.2f}",
                    "–" if ours is None else f"{ours:.2f}"))
    return out


def summary_line(counts: dict) -> str:
    """One line: the rows that agree within 10 %, differ explained, unexplained, not run."""
    total = sum(counts.values())
    return (f"{total} rows: {counts['agrees']} agree within {AGREE:.0%} (steps and "
            f"f-evaluations, or the speed-up), {counts['explained']} differ with the "
            f"difference in configuration named, {counts['unexplained']} differ unexplained, "
            f"{counts['failed here']} failed here, {counts['not run']} not in the store.")
