"""An advice shown: the terminal text (its table and per-line notes at most
:data:`COLUMNS` wide, its last line the answer) and the offline HTML page (one file, the work-precision diagram of every
line explored embedded, the target marked, the winner and runner-up
highlighted, and the certificate)."""

from __future__ import annotations

import base64
import html
import io
import json
from pathlib import Path

from integrator_bench.harness.ranking.cost import SHORT
from integrator_bench.harness.advise.answer import Advice
from integrator_bench.harness.advise.evidence import LineEntry, Perturbed, Reproduction
from integrator_bench.harness.advise.certificate import PERTURBATION, START_RULE, STARTS
from integrator_bench.harness.paths import write_atomically
from integrator_bench.harness.ranking import reach
from integrator_bench.harness.ranking.margin import BAND

COLUMNS = 128
#: a robustness check's outcome (its ``holds``)
CHECK_WORDS = {True: "holds", False: "FAILS", None: "unfinished (the budget spent)"}
#: the runner-up's margin in words: clearly slower, a tie (its interval reaches 1),
#: or a tie because its interval was not measured (too few paired samples)
TIE_WORDS = {"clear": "clearly slower: its interval above 1",
             "tie": "a tie: its interval reaches 1",
             "unmeasured": "a tie: its interval not measured, so the noise may reverse "
                           "the order"}
#: the runner-up's margin in words when it is out of contention
OUT_OF_CONTENTION = f"beyond {BAND:g}x: out of contention, not timed again"
#: the least widths of the table's integrator and formulation columns (a longer name
#: widens its column: a name is never cut)
NAME_WIDTH, FORMULATION_WIDTH = 26, 11


def _head(wn: int = NAME_WIDTH, wf: int = FORMULATION_WIDTH) -> str:
    return (f"{'rank':>4} {'integrator (settings)':<{wn}} {'formulation':<{wf}} {'rtol':>7} "
            f"{'error':>7} {'CPU s':>8} {'to E s':>8} {'nfev':>6} {'njev':>5} {'nlu':>5} "
            f"{'nsteps':>6} {'nrej':>4} verdict")


#: under the table: what ranks it
RANKED_BY = ("rank: by the CPU to the target (to E s: the report's crossing, interpolated; "
             "≤ an upper bound); CPU s: the advised run's")


def _n(v) -> str:
    return "-" if v is None else str(int(v))


def _verdict(e: LineEntry, answer: Advice) -> str:
    if answer.is_winner(e):
        return "tie, advised" if answer.verdict == "tie" else "winner"
    if answer.is_tied(e):
        return "tie"
    if answer.is_runner_up(e):
        return "runner-up"
    if e.robustness == "failed":
        return "failed robustness"
    return "reached" if e.run is not None else "missed" if e.points else "no run"


def table(answer: Advice) -> list[str]:
    """One line per line explored, best first: at most :data:`COLUMNS` wide, the
    verdict cut where it would not fit; an integrator or formulation name longer
    than its column widens the column (and the table) rather than being cut."""
    entries = answer.lines
    wn = max([NAME_WIDTH, *(len(e.label) for e in entries)])
    wf = max([FORMULATION_WIDTH, *(len(e.formulation) for e in entries)])
    width = COLUMNS + wn - NAME_WIDTH + wf - FORMULATION_WIDTH
    lines = [_head(wn, wf)]
    for e in entries:
        r = e.run
        name, form = e.label, e.formulation
        if r is None:
            best = "-" if e.best_error is None else f"{e.best_error:.2g}"
            row = (f"{'-':>4} {name:<{wn}} {form:<{wf}} {'-':>7} {best:>7} "
                   f"{'-':>8} {'-':>8} {'-':>6} {'-':>5} {'-':>5} {'-':>6} {'-':>4}")
        else:
            to = "-" if e.to_target is None else (
                f"{'≤' if e.how == 'at most' else ''}{e.to_target:.3g}")
            row = (f"{e.rank:>4} {name:<{wn}} {form:<{wf}} {r.rtol:>7.2g} "
                   f"{r.error:>7.2g} {r.cpu_s:>8.3g} {to:>8} {_n(r.nfev):>6} "
                   f"{_n(r.njev):>5} {_n(r.nlu):>5} {_n(r.nsteps):>6} "
                   f"{_n(r.nreject):>4}")
        lines.append((row + " " + _verdict(e, answer))[:width])
    return lines


#: the words for an integrator's settings when none is changed (or it has none)
DEFAULT_SETTINGS = "default settings"


def _settings(label: str) -> str:
    name, _, rest = label.partition(" (")
    return f"{name} ({rest}" if rest else f"{name} ({DEFAULT_SETTINGS})"


def final_line(answer: Advice) -> str:
    """``use X (settings) on formulation F at rtol R: error E <= target at CPU C;
    V; verified on N perturbed sets`` (or why there is no answer), ``V`` the
    verdict (:func:`verdict_words`)."""
    w = answer.winner
    if w is None:
        return f"no advice: {answer.why}"
    r = w.run
    mark = "PARTIAL: " if answer.status == "partial" else ""
    return (f"{mark}use {_settings(w.label)} on formulation {w.formulation} at rtol "
            f"{r.rtol:.2g}: error {r.error:.2g} <= target {answer.asked.target:g} at CPU "
            f"{r.cpu_s:.3g} s; {verdict_words(answer)}; {_checked_words(w, answer)}")


def verdict_words(answer: Advice) -> str:
    """The verdict as the report words its answer
    (:func:`~integrator_bench.harness.ranking.reach.answer_parts`): ``tie: A (ode),
    B (ode) (margin 1.04, 95 % 0.91-1.19)``, then which tied lines run one library
    code (``; A (ode) and B (ode) are one code, SUNDIALS CVODE (Adams)``); ``the
    winner (margin 1.3 over B (ode), 95 % 1.2-1.4)``; ``the winner (runner-up B
    (ode) at 3.1x)`` beyond the band; ``the only line verified on the perturbed
    sets`` (or ``that reached the target``, without a check)."""
    m = answer.margin
    if answer.verdict == "tie":
        same = "".join(f"; {' and '.join(reach.line_name(t) for t in lines)} are one code, "
                       f"{code}" for code, lines in answer.same_code.items())
        return f"tie: {', '.join(answer.tied)} ({m.text()}){same}"
    if m is None:
        return "the only line " + ("verified on the perturbed sets"
                                   if answer.winner.robustness == "holds"
                                   else "that reached the target")
    return f"the winner ({m.text(over=True)})"


def _checked_words(entry: LineEntry, answer: Advice) -> str:
    """How ``entry`` (the winner or the runner-up) fared on the perturbed sets."""
    got = entry.robustness
    n = len(answer.robustness.sets) if answer.robustness else 0
    sets = f"{n} perturbed set{'s' * (n != 1)}"
    return {"holds": f"verified on {sets}", "failed": f"FAILED on {sets}",
            "unfinished": f"its check on {sets} unfinished (the budget spent)"}.get(
        got, "not checked on perturbed sets")


def perturbed_lines(moved: Perturbed | None, sets) -> list[str]:
    """What the robustness check perturbed, by how much, and each set's values."""
    names = ", ".join(sorted({k for s in sets for k in s}))
    if moved is not None and moved.what == STARTS:
        out = [f"  perturbed initial states (the model has no parameter to perturb): {names}",
               f"  ({moved.rule or START_RULE}; seeded)"]
    else:
        out = [f"  perturbed parameters: {names} (up to {PERTURBATION:.0%}, seeded)"]
    out += [f"  set {i}: " + ", ".join(f"{k}={v:.6g}" for k, v in sorted(s.items()))
            for i, s in enumerate(sets, 1)]
    return [line[:COLUMNS] for line in out]


def text(answer: Advice) -> str:
    """The terminal output: header, reference, table, certificate, answer."""
    asked = answer.asked
    out = [f"advice for {asked.problem}",
           f"target {asked.target:g}: {reach.ERRORS[asked.measure].words}"
           + (f" on {', '.join(asked.scored)}" if asked.scored else ""),
           f"ranked by {asked.ranked_by}: " + SHORT[asked.ranked_by]
           + ("; every CPU figure below is that work, in seconds"
              if asked.ranked_by == "work" else "")]
    if answer.status == "partial":
        out.append(f"PARTIAL ANSWER: {answer.why}")
    ref = answer.reference
    if ref is not None:
        methods = " vs ".join(m.name + ("" if m.rtol is None else f" rtol {m.rtol:g}")
                              + f" ({m.family})" for m in ref.methods)
        out.append(f"reference: {methods}: agree to {ref.claimed_digits} digits "
                   f"({ref.needed_digits} needed)"
                   + (f"; computed tighter than the stored one (its methods' rtols "
                      f"x{ref.tightened:g})" if ref.tightened else ""))
    if answer.lines:  # then why each line left the search
        out += [""] + table(answer) + [RANKED_BY, ""]
        out += [f"  {e.label} ({e.formulation}): {e.note}"[:COLUMNS]
                for e in answer.lines if e.note]
    run = answer.winner.run if answer.winner else None
    drift = [] if run is None else [f"{k} {v:.2g}" for k, v in (
        ("drift_pos", run.drift_pos), ("drift_vel", run.drift_vel)) if v is not None]
    if drift:
        out.append(f"winner's constraint drift: {', '.join(drift)}")
    if answer.margin:
        m, up = answer.margin, answer.runner_up
        words = TIE_WORDS["clear" if not m.tie else "tie" if m.low is not None
                          else "unmeasured"]
        how = (f": {m.text()} ({words})" if m.contended else
               f" at {m.ratio:.2g}x ({OUT_OF_CONTENTION})" if m.ratio is not None else
               f", an upper bound too ({OUT_OF_CONTENTION})")
        out.append(f"runner-up: {up.name}{how}; {_checked_words(up, answer)}")
    if answer.contenders is not None:
        out.append(contenders_line(answer.contenders))
    if answer.families:
        out.append("best of each family:")
        out += [f"  {f}: {b.label} ({b.formulation}) at rtol {b.rtol:.2g}, "
                f"{b.cpu_s:.3g} s" for f, b in answer.families.items()]
    rob = answer.robustness
    if rob is not None:
        if rob.why:
            out.append(f"robustness: not checked: {rob.why}")
        kind = "start" if rob.perturbed and rob.perturbed.what == STARTS else "parameter"
        for c in rob.checked:
            errs = ", ".join("-" if g.error is None else f"{g.error:.2g}"
                             if g.status == "ok" else g.status for g in c.runs)
            out.append(f"robustness: {c.label} ({c.formulation}) at rtol "
                       f"{c.rtol:.2g} on {len(c.runs)} perturbed {kind} sets: errors "
                       f"{errs}: {CHECK_WORDS[c.holds]}")
        if rob.sets:
            out += perturbed_lines(rob.perturbed, rob.sets)
    ruled = answer.ruled_out
    if ruled:
        out.append(f"ruled out before running ({len(ruled)}):")
        out += [f"  {r.label} ({r.formulation}): {r.reason}"[:COLUMNS] for r in ruled]
    if answer.reproduce:
        out += reproduce_lines(answer.reproduce)
    cost = answer.cost
    out.append(f"cost: {cost.cases} cases ({cost.search_cases} in {cost.rounds} "
               f"rounds of the search, {cost.robustness_cases} of the robustness check), "
               f"wall {cost.wall_s:.3g} s, CPU {cost.cpu_s:.3g} s (the search "
               f"{cost.search_wall_s:.3g} s and {cost.search_cpu_s:.3g} s); budget "
               f"{asked.budget_s:g} s")
    return "\n".join(out + [final_line(answer)])


def contenders_line(c) -> str:
    """What timing the contenders again did
    (:class:`~integrator_bench.harness.advise.answer.Contenders`), in one line."""
    if c.why:
        return f"contenders: {c.why}"
    if not c.contests:
        return (f"contenders: nothing timed again (no line within {BAND:g}x of the "
                "cheapest, or every one's margin decided by the search's own samples)")
    return (f"contenders: the lines within {BAND:g}x of the cheapest timed again: "
            f"{c.retimed} records in {c.blocks} block{'s' * (c.blocks != 1)}, CPU "
            f"{c.cpu_s:.2g} s "
            f"(cap {c.cap_s:.2g} s); {c.stopped}"
            + (", the contest left open" if c.left_open else ""))


def reproduce_lines(rep: Reproduction) -> list[str]:
    """The recipe (:func:`~integrator_bench.harness.advise.certificate.reproduction`)
    as text."""
    settings = ", ".join(f"{k}={v}" for k, v in rep.settings.items() if v is not None)
    t = rep.output_times
    return [f"to reproduce: {rep.integrator} ({settings or DEFAULT_SETTINGS})",
            f"  formulation {rep.formulation} ({rep.system_kind}, {rep.states} "
            f"states: {', '.join(rep.variables)}; scored {', '.join(rep.scored)})",
            f"  rtol {rep.rtol:.2g}, atol = rtol * scale per state (scale "
            f"{rep.atol_scale_min:g} ... {rep.atol_scale_max:g})",
            f"  Jacobian: {rep.jacobian}",
            f"  output times: {t.count} {t.spacing} in [{t.first:g}, {t.last:g}]",
            *call_lines(rep.library_call, rep.loop)]


def call_lines(call: dict | None, loop: str | None) -> list[str]:
    """The recipe's library call (:meth:`~integrator_bench.integrators.base.Integrator.
    library_call`) as text: the library, the call, the callbacks and every option (a
    list option, atol per state, by its values when short, else its length: the
    JSON holds them all)."""
    if call is None:
        return ["  library call: none (implemented in this project; its settings above)"]
    opts = ", ".join(f"{k}={_short(v)}" for k, v in call["options"].items())
    out = [f"  library: {call['library']}: {call['call']}",
           f"  callbacks: {call['callbacks']}", f"  options: {opts}"]
    out += [f"  beyond the options: {line}" for line in call.get("beyond_options", [])]
    if loop != "library":
        out.append(f"  (timed through the wrapper's loop ({loop}): the system's events or "
                   "projection need it; the call above is the library's part)")
    return out


def _short(v) -> str:
    if isinstance(v, list) and len(v) > 6:
        return f"[{len(v)} values: {min(v):g} ... {max(v):g}]" if all(
            isinstance(x, (int, float)) for x in v) else f"[{len(v)} values]"
    return str(v)


def figure_png(answer: Advice) -> bytes:
    """The work-precision diagram: every explored line's runs, error against CPU."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 5.5))
    for e in answer.lines:
        if not e.points:
            continue
        pts = sorted(e.points, key=lambda p: p[2])
        role, width = (("winner", 3.0) if answer.is_winner(e) else ("tie", 2.2)
                       if answer.is_tied(e) else ("runner-up", 2.2)
                       if answer.is_runner_up(e) else (None, 0.8))
        ax.loglog([p[2] for p in pts], [p[1] for p in pts], "o-", lw=width,
                  ms=3 + width, alpha=1.0 if role else 0.45,
                  label=f"{e.label} ({e.formulation})" + (f": {role}" if role else ""))
    asked = answer.asked
    ax.axhline(asked.target, color="k", ls="--", lw=1, label=f"target {asked.target:g}")
    ax.set_xlabel("CPU s (median of the timed solves)")
    ax.set_ylabel(f"error ({asked.measure})")
    ax.set_title(f"{asked.problem}: every line explored")
    ax.legend(fontsize=6, ncol=2)
    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


def default_dir(store, problem, target: float, measure: str, integrators=None,
                formulations=None) -> Path:
    """The folder of an advice's page when ``--out`` is not given: one of its own
    for each problem, parameter set, target, error measure and choice of
    candidates, in ``advice/`` beside ``store``:
    ``advice/two_mass/c1=1,...,target=1e-06,error=max`` (the parameters as a
    reference's file is named:
    :func:`~integrator_bench.harness.measure.references.file_stem`); an advice
    restricted by ``-i`` or ``-f`` adds ``,candidates=`` and a digest of the
    names given (the page names them), so that it does not overwrite the page
    of an advice over other candidates."""
    import hashlib

    from integrator_bench.harness.measure.references import file_stem
    from integrator_bench.harness.paths import file_name

    name = f"{file_stem(problem)},target={target:g},error={measure}"
    if integrators or formulations:
        given = json.dumps([sorted(integrators or []), sorted(formulations or [])])
        name += f",candidates={hashlib.sha256(given.encode()).hexdigest()[:10]}"
    return Path(store).resolve().parent / "advice" / file_name(problem.name) / name


def write_page(answer: Advice, out: Path) -> Path:
    """Write ``out/index.html`` (offline: the figure embedded) and ``out/advice.json``
    (:meth:`~.answer.Advice.to_dict`)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    png = base64.b64encode(figure_png(answer)).decode()
    body = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>advice: "
            f"{html.escape(answer.asked.problem)}</title><style>body{{font-family:sans-serif;"
            f"margin:2em}}pre{{font-size:12px}}</style></head><body>"
            f"<h1>Advice for {html.escape(answer.asked.problem)}</h1>"
            f"<p><b>{html.escape(final_line(answer))}</b></p>"
            f"<img alt='work-precision diagram' src='data:image/png;base64,{png}'>"
            f"<h2>Certificate</h2><pre>{html.escape(text(answer))}</pre></body></html>\n")
    page = out / "index.html"
    write_atomically(page, lambda part: part.write_text(body, encoding="utf-8"))
    write_atomically(out / "advice.json", lambda part: part.write_text(
        json.dumps(answer.to_dict(), indent=1, default=str) + "\n"))
    return page
