"""The source documents' numbers, row by row, beside the project's closest runs.

Every table of the seed documents that reports run statistics (steps NS,
f-evaluations NF, Jacobians NJ, ...) becomes a list of :class:`SourceRow`: the
published numbers, the project's closest configuration (problem and parameters,
formulation, integrator with settings, a tolerance or step) and one line saying
what differs between the two, each statement about the source checked against
its text. The ``seeds`` preset (:data:`integrator_bench.harness.matrix.cases.PRESETS`)
runs exactly these configurations (:func:`preset_cases`), and the report's part
"The sources, number by number" (:func:`compare`) sets each row beside the
matching record of the store, the ratio ours / published of every number the row
gives, and one of six verdicts (:data:`VERDICTS`), from evidence only, by the one
rule the page states (:data:`RULE`; a claim's parts combine by :data:`COMBINE`,
:func:`combine`):

``agrees``
    steps and f-evaluations (those the row gives) within :data:`AGREE` (10 %);
``differs, cause measured``
    a number differs by more, the row names one configuration difference
    (:class:`Cause`) and a run that changes it (the cause's configuration, in the
    preset too) brings every judged number within :data:`AGREE`; the page shows
    both runs (Sudarsan and Keerthi's TP rows: the paper's tangent
    parametrization, the ``tangent`` formulation, against coordinate
    partitioning; their ICS rows: Baumgarte's alpha tuned by the paper's
    indicators, :func:`tune_alpha`, against the project's default);
``differs, cause explains part``
    the cause's run moves every judged number toward the source's but stays
    outside :data:`AGREE`; both figures shown;
``differs, unexplained``
    a number differs by more and no run shows why (a named difference alone, or
    one whose run is missing, diverged or does not move the number, gives this);
``contradicts``
    the source's claim is reversed here on the quantity it speaks of (used by the
    claims, seed 000's ratios and Orlov's cells,
    :mod:`~integrator_bench.harness.sources.page`);
``cannot test``
    the store holds no usable record (not run, or failed before the end of its
    span; the reason is shown), the configuration the source names was not run
    (:attr:`SourceRow.not_run`), the counts cannot agree by construction
    (:attr:`SourceRow.ratios_only`: the ratios between codes are judged instead,
    :func:`within_table_ratios`), or the source's figure has no counterpart here
    (:data:`UNTESTED`).

Sources: Sudarsan and Keerthi, Appl. Math. Comput. 92 (1998) 195-218, Tables 1,
2 and 4 (seed 003; read from a column-scrambled OCR; their NJ counts evaluations
of the constraint Jacobian, which the project does not count apart, so it is
shown and not compared); the Lund FMNN05 student report, Tables 1, 2, 3 and 5
(seed 002); S. G. Orlov, "Application of numerical integration methods to
continuously variable transmission dynamics models" (seed 004) and the slides of
S. G. Orlov, A. K. Kuzin and N. N. Shabrov, "Two approaches to speeding up
dynamics simulation for a low dimension mechanical system", Russian
Supercomputing Days 2017 (public repository deadmorous/rsd-2017,
``docs/speedup.html``), each figure attributed to the one it comes from
(:data:`ORLOV_SPEEDUPS`, :data:`ORLOV_CELLS`); the ADAMS/Solver seminar's CPU
ratios (seed 000) and the ADAMS course's stiffness criterion (seed 001) are run
by :mod:`~integrator_bench.harness.sources.runs`.

A run that reached the end of its span with a final error over the divergence
bound (recorded ``failed``, reason ``diverged``, its errors kept) is compared by
its counts like a successful one, and its row says so: the sources report the
counts of their runs at a tolerance, whatever the accuracy reached. It is no
evidence for a cause, though: a row whose own run or whose cause's run diverged
measures no cause.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from integrator_bench.harness.matrix.cases import PRESETS
from integrator_bench.harness.matrix.line import parse_spec
from integrator_bench.harness.sources.runs import LADDERS, TRAPEZOIDAL, WOODPECKER, stiffness_ladders

AGREE = 0.10
#: the problem options that change a formulation, not the problem
#: (:attr:`~integrator_bench.problems.base.Problem.form_options`)
FORM_OPTIONS = frozenset(("baumgarte_alpha", "baumgarte_beta"))
#: the six verdicts of a row, in the order the summary counts them
VERDICTS = ("agrees", "differs, cause measured", "differs, cause explains part",
            "differs, unexplained", "contradicts", "cannot test")
#: the one rule of the page, as it states it (:data:`RULE_TEXT`): what each verdict
#: requires of a row, a ratio or a cell (:func:`compare` and the report's functions
#: apply it, and ``tests/harness/sources/test_seed_doc.py`` checks every row of the page against it)
RULE = {
    "agrees": "every judged number (a table's NS and NF; a ratio or speed-up itself) "
              "within 10% of the source's, bounds not taken for values",
    "differs, cause measured": "a judged number outside 10%, and the run that changes the "
                               "row's named cause (it and the row's own run ending ok) brings "
                               "every judged number within 10%; both runs shown",
    "differs, cause explains part": "as above, but the cause's run only moves every judged "
                                    "number toward the source's and stays outside 10%; both "
                                    "figures shown",
    "differs, unexplained": "a judged number outside 10% and no cause measured (none named, "
                            "its run missing, diverged or not moving the numbers toward "
                            "the source's): the cause is unknown",
    "contradicts": "the claim is reversed here on the quantity it speaks of (for seed 000 "
                   "CPU; a count or a cell the source states), whatever other figures say; "
                   "figures a code does not count alike are shown, not voted",
    "cannot test": "no usable run (not run, failed, or the configuration the source names "
                   "was not run here), no figure to judge (an empty set of counts judges "
                   "nothing), or only a bound where a value is needed",
}
#: how the parts of one claim (rows, ratios, cells) make its headline verdict
COMBINE = ("a claim's parts combine by one rule: cannot test when no part is tested; "
           "contradicts when any tested part contradicts; agrees when every tested part "
           "agrees; differs, cause measured when every tested part agrees or is explained "
           "so; differs, cause explains part when every tested part agrees or is at least "
           "partly explained; differs, unexplained otherwise")


def combine(verdicts) -> str:
    """The headline verdict of a claim's parts, by :data:`COMBINE`."""
    tested = [v for v in verdicts if v != "cannot test"]
    if not tested:
        return "cannot test"
    if "contradicts" in tested:
        return "contradicts"
    for v, allowed in (("agrees", {"agrees"}),
                       ("differs, cause measured", {"agrees", "differs, cause measured"}),
                       ("differs, cause explains part", {"agrees", "differs, cause measured",
                                                         "differs, cause explains part"})):
        if set(tested) <= allowed:
            return v
    return "differs, unexplained"


def within(ratio: float) -> bool:
    """Whether a ratio ours / published is within :data:`AGREE` of 1."""
    return abs(ratio - 1) <= AGREE
#: the numbers compared, in the order shown, with their headings
KEYS = (("nsteps", "NS"), ("nfev", "NF"), ("njev", "NJ"), ("nnfail", "NCF"),
        ("nevents", "NP"))
JUDGED = ("nsteps", "nfev")


@dataclass(frozen=True)
class Cause:
    """A configuration difference between a row and the source, and the run that
    changes it (``problem``, ``formulation``, ``integrator``, ``rtol``, ``h``: the
    row's configuration with that one difference changed)."""

    what: str
    problem: str
    formulation: str
    integrator: str
    rtol: float | None = None
    h: float | None = None
    #: the problem's Baumgarte alpha is the one :func:`tune_alpha` chooses from the
    #: records (the spec's problem name without it); the case is then known only
    #: with the records (:func:`cause_case`)
    tuned_alpha: bool = False

    @property
    def case(self) -> tuple:
        return (self.problem, self.formulation, self.integrator, self.rtol, self.h)


def cause_case(cause: Cause, df) -> tuple | None:
    """The case of ``cause``'s run in ``df``: its own, or with the tuned alpha
    (:func:`tune_alpha`; None when no alpha of the sweep is admissible)."""
    if not cause.tuned_alpha:
        return cause.case
    alpha = tune_alpha(df, cause.problem).chosen
    return None if alpha is None else ics_case(cause.problem, alpha, cause.rtol)


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
    cause: Cause | None = None  # a run that changes one named difference
    flag: str = ""             # where the source contradicts itself on this row
    #: the configuration the source names was not run here (why): the row cannot be
    #: tested and borrows no other run
    not_run: str = ""
    #: why the row's counts cannot agree by construction: shown, not judged; the row
    #: is judged by its ratios to the table's first code (:func:`within_table_ratios`)
    ratios_only: str = ""

    @property
    def case(self) -> tuple:
        return (self.problem, self.formulation, self.integrator, self.rtol, self.h)


#: what the paper does not give for the slider-crank, and the project chose
_SLIDER = ("; slider-crank: the torque T = 10 N m is the paper's ('A constant torque T - - 10 "
           "N m is applied to body-1' in the OCR of Example 5.2); the span [0, 2] s is the "
           "project's choice (the paper's reads '!0.2]' in the OCR)")
_PAPER_PA_BEST = ("the paper's observation (1), 'in terms of all the performance indicators, "
                  "PA is the best', against its own Table 1: TP takes fewer steps and "
                  "f-evaluations than PA at every TOL (NS 28/36, 61/83, 100/145; NF 55/68, "
                  "121/162, 200/286)")


def _sk(table: str, problem: str, ns: dict, nf: dict, nj: dict, np_tp: tuple) -> list[SourceRow]:
    """Sudarsan and Keerthi's approaches for one problem, TOL 1e-2, 1e-4, 1e-6; PA
    twice: as CVODE-Adams on the unprojected ODE (an Adams code, as the tables' NF
    about 2 NS suggests) and projected, with RK23 as TP here ("PA projected")."""
    mapping = {
        "PA": ("ode", "cvode-adams", "the paper's PA integrates the index-1 ODE with local "
               "error control and projects every step onto the constraints (Procedure PA, "
               "algorithm C*) in its FORTRAN code DAMES, the integration method not named "
               "(the paper names Adams predictor-corrector and Runge-Kutta methods as usable "
               "on the index-1 form); here CVODE-Adams (variable order) on the index-1 ODE "
               "without projection (the project's projection formulation takes one-step "
               "methods only)"),
        "PA projected": ("projection", "scipy-RK23", "the paper's PA integrates the index-1 "
                         "ODE with local error control and projects every step onto the "
                         "constraints (Procedure PA, algorithm C*), the integration method "
                         "not named; here the projection formulation (the index-1 ODE "
                         "projected onto the position and velocity constraints after every "
                         "step) with RK23, the one-step method TP runs with here, so that "
                         "PA and TP differ here by the approach alone"),
        "TP": ("partitioning", "scipy-RK23", "the paper's TP integrates the coordinates of a "
               "local tangent parametrization (QR of the constraint Jacobian's transpose), "
               "with a new parametrization when ||y'|| / ||v|| falls below p = 0.5 (its NP), "
               "error weights transformed from (q, v), the integration method not named; "
               "here coordinate partitioning with RK23 (3 f per step, one-step), and, as the "
               "cause's run, the paper's TP (the tangent formulation, its weights those of "
               "the positions and velocities) with the same RK23"),
        "ECS": ("ggl", "ida", "the paper's ECS is its own variable-order fixed-leading-"
                "coefficient BDF (as DASSL) on the stabilized index-2 form, one corrector "
                "iteration per step; here IDA (variable-order BDF) on GGL: same family, "
                "another code and error norm"),
        "ICS": ("baumgarte", "cvode-adams", "the paper's ICS is Baumgarte stabilization with "
                "alpha chosen per problem by raising it from 0 and looking at the solution "
                "plots (Remark 5.1), the constraint violation and the failed steps "
                "(Section 5.1), the value not given, the integration method not named; "
                "here CVODE-Adams on Baumgarte at the project's default alpha = beta = 10, "
                "and, as the cause's run, at the alpha tuned from the sweep (see 'Baumgarte's "
                "alpha for ICS')"),
    }
    slider = problem == "slider_crank"
    rows = []
    for approach, (form, integrator, differs) in mapping.items():
        paper = approach.split()[0]          # "PA projected" has PA's published numbers
        for i, tol in enumerate((1e-2, 1e-4, 1e-6)):
            pub = {"nsteps": ns[paper][i], "njev": nj[paper][i]}
            if nf.get(paper):
                pub["nfev"] = nf[paper][i]
            if paper == "TP":        # new parametrizations: the tangent run's events
                pub["nevents"] = np_tp[i]
            cause = (Cause("the alpha tuned as the paper tunes it", problem, form,
                           integrator, rtol=tol, tuned_alpha=True) if approach == "ICS" else
                     Cause("the paper's tangent parametrization", problem, "tangent",
                           integrator, rtol=tol) if approach == "TP" else None)
            rows.append(SourceRow(
                "003", table, f"{approach}, TOL {tol:g}", pub, problem, form, integrator,
                rtol=tol, differs=differs + (_SLIDER if slider else ""), uncounted=("njev",),
                flag=_PAPER_PA_BEST if slider and approach == "TP" else "", cause=cause))
    return rows


#: Sudarsan and Keerthi (1998), Tables 1, 2 and 4: NS, NF, NJ per approach and TOL
S_AND_K = tuple(
    _sk("Table 1 (slider-crank)", "slider_crank",
        ns={"PA": (36, 83, 145), "TP": (28, 61, 100), "ECS": (186, 398, 580),
            "ICS": (36, 83, 135)},
        nf={"PA": (68, 162, 286), "TP": (55, 121, 200), "ICS": (68, 166, 266)},
        nj={"PA": (73, 167, 291), "TP": (143, 275, 455), "ECS": (172, 386, 468),
            "ICS": (73, 171, 271)}, np_tp=(2, 2, 4))
    + _sk("Table 2 (manipulator)", "manipulator",
          ns={"PA": (43, 95, 151), "TP": (55, 105, 183), "ECS": (105, 256, 340),
              "ICS": (45, 90, 150)},
          nf={"PA": (85, 190, 302), "TP": (110, 210, 378), "ICS": (88, 178, 298)},
          nj={"PA": (91, 195, 308), "TP": (245, 460, 1034), "ECS": (98, 240, 328),
              "ICS": (93, 183, 303)}, np_tp=(8, 6, 4))
    + _sk("Table 4 (quick-return)", "quick_return",
          ns={"PA": (356, 686, 1080), "TP": (506, 938, 1556), "ECS": (1208, 1932, 3574),
              "ICS": (346, 599, 1044)},
          nf={"PA": (712, 1272, 2160), "TP": (1012, 1876, 3112), "ICS": (676, 1191, 2082)},
          nj={"PA": (682, 1173, 2060), "TP": (3814, 5724, 9512), "ECS": (1194, 1860, 3787),
              "ICS": (681, 1196, 2087)}, np_tp=(10, 16, 14))
)

_FIXED_BDF = ("the report's own constant-step BDF run through Assimulo's simulate (it does "
              "not say how a step's implicit equation is solved); here the project's BDF "
              "(Newton, analytic Jacobian)")
_DYMOLA = ("Dymola's {code}, here {ours}; the report states no tolerance for Table 2 (its "
           "Figure 9 runs at tol 1e-8, the project's choice here) and runs 30 s, here 1 s "
           "(the reference over 30 s is beyond the preset's time): compare the ratios "
           "between the codes, not the counts")
_K6 = "spring_pendulum:k=1000000,t_end=1"
_T1 = "Table 1 (spring pendulum; Figure 4's k = 1000, t = 8, h = 0.01)"
_T2 = "Table 2 (Dymola, k = 1e6, t = 30, no tolerance stated; here rtol 1e-8, t = 1)"
_T3 = "Table 3 (spring pendulum k = 100, t = 10, tol 1e-8)"
_T5 = "Table 5 (squeezer, IDA; no tolerance or span stated; here rtol 1e-6, 0.03 s)"
_T1_CAPTION = ("the report's Table 1 sits under Figure 5's caption (k = 150, t = 10, h = "
               "0.005) while Figure 4's (k = 1000, t = 8, h = 0.01) calls its plots those "
               "'for the function evaluation comparison table': the project takes Figure 4's")
_T1_DELTA = ("the report's ΔF row gives 0, 102, 133, but 16214 - 16061 = 153")
_LSODAR_FEWEST = ("the report says 'Lsodar uses the lowest number of steps and function "
                  "calls', but Dopri45 takes fewer steps in its own table (314896 against "
                  "391591)")


_SPAN = ("the report runs 30 s, here 1 s: the counts cannot agree by construction; the "
         "ratios between the codes are judged instead (below)")


def _table2(code: str, integrator: str, ours: str, published: dict, **extra) -> SourceRow:
    return SourceRow("002", _T2, code, published, _K6, "ode", integrator, rtol=1e-8,
                     differs=_DYMOLA.format(code=code, ours=ours), ratios_only=_SPAN, **extra)


#: The student report (seed 002): Tables 1, 2, 3 and 5
STUDENT = (
    *(SourceRow("002", _T1, f"BDF{p}", {"nfev": f}, "spring_pendulum:k=1000,t_end=8", "ode",
                f"bdf{p}", h=0.01, differs=_FIXED_BDF, flag=flag)
      for p, f, flag in ((2, 16214, _T1_CAPTION), (3, 16112, ""), (4, 16061, _T1_DELTA))),
    _table2("Lsodar", "assimulo-lsodar", "ODEPACK's LSODAR through Assimulo",
            {"nsteps": 391591, "nfev": 809798, "njev": 3706}, own_f=True, flag=_LSODAR_FEWEST),
    _table2("Dassl", "ida", "IDA, DASSL's successor",
            {"nsteps": 698252, "nfev": 1422260, "njev": 7651}),
    _table2("Dopri45", "assimulo-dopri5", "Hairer's DOPRI5 through Assimulo",
            {"nsteps": 314896, "nfev": 1894983}, own_f=True),
    SourceRow("002", _T2, "Sdirk34", {"nsteps": 603762, "nfev": 6215245, "njev": 74847},
              _K6, "ode", "scipy-Radau", rtol=1e-8,
              differs=_DYMOLA.format(code="Sdirk34", ours="scipy's Radau IIA (order 5, 3 "
                                     "stages), the closest implicit Runge-Kutta code (no "
                                     "adaptive SDIRK here)"), ratios_only=_SPAN),
    *(SourceRow("002", _T3, f"BDF{p}", {"nsteps": 1001, "nfev": f},
                "spring_pendulum:k=100,t_end=10", "ode", f"bdf{p}", h=0.01, differs=_FIXED_BDF)
      for p, f in ((2, 8469), (3, 8390), (4, 8349))),
    SourceRow("002", _T3, "CVODE (Adams)", {"nsteps": 1007, "nfev": 1227},
              "spring_pendulum:k=100,t_end=10", "ode", "assimulo-cvode-adams", rtol=1e-8,
              own_f=True, differs="the report's atol for Table 3 is not stated; here the "
                                  "project's"),
    SourceRow("002", _T3, "Lsodar", {"nsteps": 1106, "nfev": 2309},
              "spring_pendulum:k=100,t_end=10", "ode", "assimulo-lsodar", rtol=1e-8,
              own_f=True, differs="the report's discussion calls this Dymola's Lsodar; here "
                                  "LSODAR through Assimulo"),
    SourceRow("002", _T5, "index 2, algvar", {"nsteps": 617, "nfev": 1613, "njev": 120,
                                             "nnfail": 0}, "squeezer", "i2", "assimulo-ida",
              rtol=1e-6, own_f=True,
              differs="the report's IDA with suppress_alg (the multipliers out of the error "
                      "test) on the index-2 form, its tolerances and Jacobian not stated; "
                      "here lambda out of the error test, the analytic Jacobian"),
    SourceRow("002", _T5, "index 2, high ATOL on lambda",
              {"nsteps": 910, "nfev": 1511, "njev": 75, "nnfail": 0}, "squeezer", "i2",
              "assimulo-ida", rtol=1e-6, own_f=True,
              differs="the report sets the multipliers' ATOL 'very high', the value not "
                      "stated",
              not_run="not run here: the report's ATOL on lambda is not stated, and no run "
                      "here sets one (the algvar row's run is another configuration)"),
    SourceRow("002", _T5, "index 3, high ATOL on v, lambda",
              {"nsteps": 707, "nfev": 1496, "njev": 784, "nnfail": 120}, "squeezer", "i3",
              "assimulo-ida", rtol=1e-6, own_f=True,
              differs="the report suppresses every multiplier and velocity by a 'very high' "
                      "ATOL, the value not stated; here v and lambda are left out of the "
                      "error test, analytic Jacobian; no variant run here reproduces "
                      "707/1496/784/120"),
)

ROWS: tuple = S_AND_K + STUDENT

#: Baumgarte's alpha (beta = alpha) swept for Sudarsan and Keerthi's ICS, from 0 (the
#: underlying ODE) upward, as the paper raises it (Remark 5.1)
ICS_ALPHAS = (0.0, 1.0, 3.0, 10.0, 30.0, 100.0)
ICS_PROBLEMS = ("slider_crank", "manipulator", "quick_return")
ICS_TOLS = (1e-2, 1e-4, 1e-6)
ICS_FORM, ICS_INTEGRATOR = "baumgarte", "cvode-adams"


def ics_case(problem: str, alpha: float, tol: float) -> tuple:
    """The ICS configuration of ``problem`` at Baumgarte's ``alpha`` (beta = alpha)."""
    return (f"{problem}:baumgarte_alpha={alpha:g}", ICS_FORM, ICS_INTEGRATOR, tol, None)


@dataclass
class Tuning:
    """The alpha sweep of one problem: per alpha, per TOL, the record's counts
    (``runs[alpha][tol]``: None when not usable), whether every TOL ran
    (``admissible``), its rank sum and the chosen alpha."""

    problem: str
    runs: dict
    violation: dict            # alpha -> sum over the TOLs of log10(drift_pos)
    failed: dict               # alpha -> sum over the TOLs of nreject + nnfail
    rank_sum: dict
    chosen: float | None


def tune_alpha(df, problem: str) -> Tuning:
    """Baumgarte's alpha for ``problem`` by the paper's criterion (Section 5.1: "by
    looking at the amount of constraint violation and the number of failed
    integration steps a proper (optimal) alpha is chosen"), made a rule: among the
    alphas of :data:`ICS_ALPHAS` whose runs at every TOL of :data:`ICS_TOLS` succeed,
    rank the constraint violation (sum over the TOLs of log10 of the largest
    position residual, ``drift_pos``) and the failed steps (sum of rejected steps and
    Newton failures) each, both counting equally; the least rank sum wins, a tie
    going to the smaller alpha (the paper raises alpha from 0)."""

    runs, violation, failed = {}, {}, {}
    for alpha in ICS_ALPHAS:
        runs[alpha] = {}
        for tol in ICS_TOLS:
            rec = match(df, *ics_case(problem, alpha, tol))
            ok = rec is not None and rec["status"] == "ok" and _finite(rec.get("drift_pos"))
            runs[alpha][tol] = None if not ok else {
                k: float(rec.get(k) or 0.0) for k in ("nsteps", "nfev", "nreject", "nnfail",
                                                      "drift_pos")}
        if all(runs[alpha].values()):
            violation[alpha] = sum(math.log10(max(r["drift_pos"], 1e-300))
                                   for r in runs[alpha].values())
            failed[alpha] = sum(r["nreject"] + r["nnfail"] for r in runs[alpha].values())
    if not violation:
        return Tuning(problem, runs, {}, {}, {}, None)
    ranks = (pd.Series(violation).rank(method="min") + pd.Series(failed).rank(method="min"))
    rank_sum = {float(a): float(r) for a, r in ranks.items()}
    chosen = min(rank_sum, key=lambda a: (rank_sum[a], a))
    return Tuning(problem, runs, violation, failed, rank_sum, chosen)


def _finite(x) -> bool:
    try:
        return math.isfinite(float(x))
    except (TypeError, ValueError):
        return False

#: Orlov's error criterion (seed 004, eq. (3) and Section 3.4: a solution with a
#: relative pin-force error E > 0.05 is "inacceptable"); the records' ``monitor_err``
ORLOV_E = 0.05
#: the slides' DUMKA3 speed-ups over RK4 at 5e-8 s, (polynomial, h, speed-up): "5.9x
#: practical speedup (DUMKA-p5 @2e-6 vs RK4 @5e-8)" and the grid's cells 4.7 and 4.4.
#: Seed 004's Table 1 ("Performance of DUMKA3 schemes compared against RK4": scheme,
#: n_RHS, speedup against RK4) survives in its text as headings only.
ORLOV_SPEEDUPS = ((5, 2e-6, 5.9), (7, 3e-6, 4.7), (8, 4e-6, 4.4))
ORLOV_PROBLEM = "cvt_chain:friction=1"
#: RK4's steps here: the slides' 5e-8 s ("RK4 @5e-8"), then smaller ones until one
#: meets :data:`ORLOV_E` (0.95 of RK4's stable step, 2.5e-8 s, does, E about 4e-10)
RK4_HS = (5e-8, 4e-8, 2.5e-8)
#: seed 004's own verdicts on P4-P9 (Section 3.6): "schemes DUMKA3-P5 - DUMKA3-P8
#: give sufficiently accurate solution at step 2 10[^-6], and at step 4 10[^-6] only
#: the scheme DUMKA3-P8 does so" (the exponents are lost in the text; the slides'
#: 2e-6 and 4e-6), "Polynomials 4 and 9 have shown poor performance" (no step given)
SEED004_ACCURATE = {2e-6: (5, 6, 7, 8), 4e-6: (8,)}
ORLOV_POLYNOMIALS = (4, 5, 6, 7, 8, 9)
#: the slides' grid on the same cells (good, bad, failed, untested)
SLIDES_GRID = {(4, 2e-6): "bad", (5, 2e-6): "good", (6, 2e-6): "good", (7, 2e-6): "good",
               (8, 2e-6): "good", (9, 2e-6): "bad", (4, 4e-6): "untested",
               (5, 4e-6): "untested", (6, 4e-6): "untested", (7, 4e-6): "bad",
               (8, 4e-6): "good", (9, 4e-6): "failed"}


def orlov_cell(k: int, h: float) -> tuple:
    """The case of DUMKA3's polynomial ``k`` at the fixed step ``h`` on Orlov's chain."""
    return (ORLOV_PROBLEM, "ode", f"dumka3:polynomial=P{k}", None, h)


def rk4_case(h: float) -> tuple:
    return (ORLOV_PROBLEM, "ode", "rk4", None, h)


#: figures of the sources with no counterpart here: (seed, where, figures, why)
UNTESTED = (
    ("000", "conclusions", "HHT and Newmark 'typically two times faster compared with "
     "fastest ADAMS integrator'; 'sped-up engine simulations by 5-10x factor'",
     "no model, tolerance or measurement given; the engine models are not available"),
    ("000", "linear solvers", "CALAHAN 'about 30% faster than HARWELL'",
     "neither sparse solver is available here"),
    ("000", "MODIFIED CORRECTOR", "'Contact 200% faster'",
     "ADAMS's corrector option and contact models are not available here"),
    ("001", "SI2 formulation", "'Can generally loosen ERROR by /10 or /100 when switching "
     "from I3 to SI2'", "no model or measurement given to reproduce"),
    ("002", "Table 1", "CPU 2.340264, 2.471802, 2.609666 s; ΔF 0, 102, 133",
     "CPU of another machine; ΔF contradicts the table's own F row (16214 - 16061 = 153)"),
    ("002", "Table 2", "CPU 3.17, 7.34, 14.97, 41.28 s; rejected steps -, -, 935, 14570",
     "CPU of Dymola on another machine; the rejected steps over 30 s, here 1 s"),
    ("002", "Table 5", "time 1.379, 1.793, 8.537 s", "CPU of another machine"),
    ("003", "Tables 1, 2, 4", "CPU (MicroVAX), NΦ, NI, NT, NFK columns",
     "CPU of a MicroVAX; constraint evaluations, iterations, triangular solves and LU "
     "factorizations of TP are not counted apart here (TP's NP, its new "
     "parametrizations, is: the tangent runs' events, in the TP rows)"),
    ("004", "Table 1", "n_RHS of each scheme", "the table survives in the text as headings "
     "only (its figures are lost)"),
)
def preset_cases() -> tuple:
    """The configurations of :data:`ROWS` and of their causes' runs, Orlov's DUMKA3
    cells (:data:`ORLOV_POLYNOMIALS` at 2e-6 and 4e-6 s and the slides' speed-up
    cells) and RK4 at :data:`RK4_HS`, seed 000's CPU ratios and seed 001's criterion
    (:mod:`~integrator_bench.harness.sources.runs`), each once: ``(problem spec,
    formulation, integrator spec, rtol, h)``."""
    out = dict.fromkeys(r.case for r in ROWS)
    out.update(dict.fromkeys(r.cause.case for r in ROWS
                             if r.cause is not None and not r.cause.tuned_alpha))
    out.update(dict.fromkeys(ics_case(p, a, tol) for p in ICS_PROBLEMS for a in ICS_ALPHAS
                             for tol in ICS_TOLS))
    out.update(dict.fromkeys(orlov_cell(k, h) for k, h, _ in ORLOV_SPEEDUPS))
    out.update(dict.fromkeys(orlov_cell(k, h) for h in SEED004_ACCURATE
                             for k in ORLOV_POLYNOMIALS))
    out.update(dict.fromkeys(rk4_case(h) for h in RK4_HS))
    out[WOODPECKER] = out[TRAPEZOIDAL] = None
    for ladder in (*LADDERS, *stiffness_ladders()):
        out.update(dict.fromkeys(ladder.cases()))
    return tuple(out)


def listed_cases(preset: str) -> tuple | None:
    """The cases ``preset`` lists, which
    :func:`~integrator_bench.harness.matrix.cases.expand` is handed (``listed``):
    the seeds preset's :func:`preset_cases`; None for a preset that lists none
    (:attr:`~integrator_bench.harness.matrix.cases.Preset.listed`)."""
    return preset_cases() if PRESETS[preset].listed else None


def _params(spec: str) -> tuple[str, dict]:
    name, sets = parse_spec(spec)
    return name, {k: float(v) for k, v in (sets or [{}])[0].items()}


def match(df, problem, formulation, integrator, rtol, h):
    """The record of one configuration in ``df`` (the last successful one, else the
    last), or None."""

    name, params = _params(problem)
    base, sets = parse_spec(integrator, "setting")
    settings = (sets or [{}])[0]

    def equal(column, value):   # on the plain values: several times cheaper than pandas'
        return df[column].to_numpy(dtype=object, na_value=None) == value

    mask = equal("problem", name)
    if mask.any():
        mask &= equal("formulation", formulation) & equal("integrator", base)
    if not mask.any():         # most configurations: not run (no copy of the records made)
        return None
    g = df[mask]

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

    # a record with a form option (Baumgarte's alpha) is another configuration than
    # a spec that names none (one that names alpha is matched on it, beta following)
    form = set() if FORM_OPTIONS & set(params) else FORM_OPTIONS
    hits = [r for _, r in g.iterrows() if same(r)
            and not form & set(json.loads(r["params"]) if isinstance(r["params"], str)
                               else {})]
    ok = [r for r in hits if r["status"] == "ok"]
    return (ok or hits or [None])[-1]


def _own(record, key, own_f: bool):

    value = record.get(key)
    if value is None or pd.isna(value):      # NaN, or a nullable column's NA
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
    verdict: str = "cannot test"
    status: str = ""           # why it cannot be tested, or how the run ended
    measured: dict = field(default_factory=dict)   # the cause's run: its numbers
    measured_ratios: dict = field(default_factory=dict)
    cause_case: tuple | None = None   # the cause's run (:func:`cause_case`)
    cause_note: str = ""               # how the cause's run ended, when not ok
    ran_ok: bool = False               # the row's own run ended ok (not diverged)

    @property
    def evidence(self) -> dict:
        """The row's own numbers when its run ended ok, else none: a diverged run is
        no evidence for a claim."""
        return self.ours if self.ran_ok else {}

    @property
    def cause_evidence(self) -> dict:
        """The cause's run's numbers when it ended ok, else none."""
        return self.measured if self.measured and not self.cause_note else {}


def ran_through(record) -> bool:
    """Whether a record that did not succeed reached the end of its span: failed
    as ``diverged`` with its final error kept (the errors of a run that stopped
    early are not computed)."""
    mescd = record.get("mescd")
    return (record["status"] != "ok" and record.get("reason") == "diverged"
            and mescd is not None and math.isfinite(float(mescd)))


def usable(record) -> bool:
    """Whether a record's counts can be compared: it succeeded or ran through."""
    return record is not None and (record["status"] == "ok" or ran_through(record))


def _numbers(record, row: SourceRow) -> dict:
    return {k: v for k, _ in KEYS if k in row.published and k not in row.uncounted
            for v in [_own(record, k, row.own_f)] if v is not None}


def _closer(moved: dict, ours: dict, published: dict) -> bool:
    """Whether every judged number of ``moved`` is nearer (in ratio) the published one
    than ``ours`` is."""
    keys = [k for k in JUDGED if k in moved and k in ours and published.get(k)]
    return bool(keys) and all(abs(math.log(moved[k] / published[k]))
                              < abs(math.log(ours[k] / published[k])) for k in keys)


def compare(df) -> list[Compared]:
    """Every row of :data:`ROWS` beside its record in ``df`` (the store's records),
    with its verdict (:data:`VERDICTS`) from the records alone."""
    out = []
    for row in ROWS:
        c = Compared(row)
        rec = None if row.not_run else match(df, *row.case)
        if row.not_run:
            c.status = row.not_run
        elif rec is None:
            c.status = "not in the store"
        elif not usable(rec):
            c.status = f"failed here: {rec['status']} ({rec.get('reason')})"
        else:
            if rec["status"] != "ok":
                c.status = (f"ran to the end, final error {10 ** -float(rec['mescd']):.2g} "
                            f"over the divergence bound (recorded {rec['status']}, "
                            f"{rec['reason']})")
            c.ours = _numbers(rec, row)
            c.ran_ok = rec["status"] == "ok"
            c.ratios = {k: c.ours[k] / row.published[k] for k in c.ours
                        if row.published.get(k)}
            judged = [within(c.ratios[k]) for k in c.ratios if k in JUDGED]
            if row.ratios_only:
                c.status = _and(c.status, row.ratios_only)
            elif not judged:
                c.status = "no number of the row is counted here"
            elif all(judged):
                c.verdict = "agrees"
            else:
                c.verdict = "differs, unexplained"
                _measure_cause(c, df, rec["status"] == "ok")
        if row.cause is not None and not c.verdict.startswith("differs"):
            _show_cause(c, df)       # shown beside the row; the verdict does not rest on it
        out.append(c)
    return out


def _measure_cause(c: Compared, df, own_ok: bool) -> None:
    """A differing row whose cause's run is in ``df`` (:data:`RULE`): "differs, cause
    measured" when that run brings every judged number within :data:`AGREE`,
    "differs, cause explains part" when it only moves every one toward the
    source's; a run that diverged (the row's own or the cause's) is no evidence.
    The finding either way goes to the row's status."""
    cause = c.row.cause
    if cause is None:
        return
    if not _show_cause(c, df):
        c.status = _and(c.status,
                        f"{cause.what}: its run is not in the store or did not succeed")
        return
    if not own_ok or c.cause_note:
        c.status = _and(c.status, f"{cause.what}: no evidence, a run diverged")
        return
    keys = [k for k in JUDGED if k in c.measured_ratios and k in c.ratios]
    figures = ", ".join(f"{dict(KEYS)[k]} {c.ratios[k]:.2f} -> {c.measured_ratios[k]:.2f}"
                        for k in keys)
    if keys and all(within(c.measured_ratios[k]) for k in keys):
        c.verdict = "differs, cause measured"
        c.status = _and(c.status, f"{cause.what} brings the numbers within {AGREE:.0%} "
                                  f"(ours / published {figures})")
    elif _closer(c.measured, c.ours, c.row.published):
        c.verdict = "differs, cause explains part"
        c.status = _and(c.status, f"{cause.what} moves the numbers toward the source's but "
                                  f"not within {AGREE:.0%} (ours / published {figures})")
    else:
        c.status = _and(c.status, f"{cause.what} does not move the numbers toward the "
                                  f"source's (ours / published {figures}); cause unknown")


def _and(status: str, more: str) -> str:
    """``more`` after what the row's status already says (how its own run ended)."""
    return f"{status}; {more}" if status else more


def _show_cause(c: Compared, df) -> bool:
    """Set the cause's run and its numbers on ``c`` (shown whatever the verdict);
    whether its record is usable."""
    case = c.cause_case = cause_case(c.row.cause, df)
    alt = None if case is None else match(df, *case)
    if not usable(alt):
        return False
    if alt["status"] != "ok":
        c.cause_note = (f" (ran to the end, final error {10 ** -float(alt['mescd']):.2g} over "
                        f"the divergence bound)")
    c.measured = _numbers(alt, c.row)
    c.measured_ratios = {k: c.measured[k] / c.row.published[k] for k in c.measured
                         if c.row.published.get(k)}
    return True


def summary(compared) -> dict:
    """How many rows (or claims) have each of the :data:`VERDICTS`."""
    counts = dict.fromkeys(VERDICTS, 0)
    for c in compared:
        counts[c.verdict] += 1
    return counts


def _num(x) -> str:
    if x is None:
        return "–"
    return f"{x:.3g}" if isinstance(x, float) and not float(x).is_integer() else f"{int(x)}"


TABLE_HEADER = ("row", "configuration here", "published", "ours", "ours / published",
                "verdict", "what differs", "the cause's run", "the source contradicts itself")


def _listed(numbers: dict, keys, names) -> str:
    return ", ".join(f"{names[k]} {_num(numbers[k])}" for k in keys if k in numbers) or "–"


def _config(case: tuple) -> str:
    problem, formulation, integrator, rtol, h = case
    tol = f"rtol {rtol:g}" if rtol is not None else f"h {h:g}"
    return f"{problem} {formulation} {integrator} {tol}"


def tables(compared: list[Compared]) -> list[tuple[str, list]]:
    """``(seed and table title, rows of TABLE_HEADER cells)`` per table, in order."""
    out: dict = {}
    names = dict(KEYS)
    for c in compared:
        r = c.row
        keys = [k for k in names if k in r.published]
        ratio = ", ".join(f"{c.ratios[k]:.2f}" for k in keys if k in c.ratios) or "–"
        verdict = f"{c.verdict}: {c.status}" if c.status else c.verdict
        cause = "–"
        if r.cause is not None:
            moved = ", ".join(f"{c.measured_ratios[k]:.2f}" for k in keys
                              if k in c.measured_ratios)
            run = c.cause_case or r.cause.case
            cause = (f"{r.cause.what}: {_config(run)}: "
                     f"{_listed(c.measured, keys, names)}"
                     + (f" (ours / published {moved})" if moved else "") + c.cause_note)
        out.setdefault(f"seed {r.seed}, {r.table}", []).append(
            (r.row, _config(r.case), _listed(r.published, keys, names),
             _listed(c.ours, keys, names), ratio, verdict, r.differs or "same configuration",
             cause, r.flag or "–"))
    return list(out.items())


def within_table_ratios(compared: list[Compared]) -> list[tuple]:
    """Ratios between the methods of one table, the source's beside ours: each row's
    steps (or f-evaluations when the row gives no steps) over those of the table's
    first row at the same tolerance (seed 003: each approach over PA at each TOL;
    seed 002: each code over the table's first). A row whose counts cannot agree by
    construction (:attr:`SourceRow.ratios_only`) is judged here instead, on its NS
    and NF ratios by :data:`RULE`; the others are shown ("–").
    ``(table, row, ratio, source, ours, verdict)``."""
    first: dict = {}
    out = []
    for c in compared:
        _, _, tol = c.row.row.partition(", ")
        key = (c.row.seed, c.row.table, tol)
        base = first.setdefault(key, c)
        if base is c:
            continue
        name = c.row.row.partition(", ")[0]
        if c.row.ratios_only:
            keys = [k for k in JUDGED if k in c.row.published and k in base.row.published]
        else:
            keys = ["nsteps" if "nsteps" in c.row.published
                    and "nsteps" in base.row.published else "nfev"]
            keys = [k for k in keys if k in c.row.published and k in base.row.published]
        if not keys:
            continue
        paper = [c.row.published[k] / base.row.published[k] for k in keys]
        ours = [c.ours[k] / base.ours[k] if k in c.ours and base.ours.get(k) else None
                for k in keys]
        verdict = "–"
        if c.row.ratios_only:
            verdict = ("cannot test" if None in ours else
                       "agrees" if all(within(o / p) for o, p in zip(ours, paper))
                       else "differs, unexplained")
        label = ", ".join(dict(KEYS)[k] for k in keys)
        out.append((f"seed {c.row.seed}, {c.row.table}", c.row.row,
                    f"{label} {name} / {base.row.row.partition(', ')[0]}",
                    ", ".join(f"{p:.2f}" for p in paper),
                    ", ".join("–" if o is None else f"{o:.2f}" for o in ours), verdict))
    return out


def summary_line(counts: dict, what: str = "rows") -> str:
    """One line: how many rows (or claims) have each verdict."""
    total = sum(counts.values())
    return f"{total} {what}: " + ", ".join(f"{counts[v]} {v}" for v in VERDICTS) + "."
