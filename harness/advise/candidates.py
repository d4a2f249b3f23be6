"""The candidates of an advice, and those the evidence rules out before any run.

A candidate is one adaptive line: an integrator with its settings on one
formulation of the model. Every registered integrator is tried (built-in,
Assimulo, plugins, a plugin's declared settings at their defaults), beside the
setting variants the seeds advise (:data:`integrator_bench.harness.matrix.cases.SEED_VARIANTS`:
CVODE's and IDA's maximum order 2, HHT's alpha at both ends of its range) of
every integrator tried. A candidate is ruled out, and listed with the reason,
when it cannot take the formulation's kind or index
(:func:`integrator_bench.harness.matrix.cases.unsupported_reason`; the reason given
first, whatever its step), when it runs at a fixed step only (the search
calibrates a tolerance), or when it is an
explicit method whose real stability interval at the model's spectral radius
needs more right-hand sides than the per-case budget allows
(:class:`integrator_bench.harness.run.schedule.StiffnessBound`, the bound ``ibench
stiffness`` computes).

Each candidate belongs to the family of the report's panel for its line
(:attr:`~integrator_bench.harness.matrix.line.Line.family`), as the advice names it
(:data:`~integrator_bench.harness.matrix.line.FAMILY_WORDS`): ``DAE/mechanical`` when
its formulation is a DAE or a mechanical system or the integrator takes neither an
ODE nor an FMU, otherwise ``implicit`` or ``explicit`` by the integrator's declaration.
"""

from __future__ import annotations

from dataclasses import dataclass

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.line import FAMILY_WORDS, Line, ProblemSpec, spec_name
from integrator_bench.harness.matrix.cases import (SEED_VARIANTS, Case, formulated,
                                                  parse_integrator_spec, unsupported_reason)
from integrator_bench.harness.errors import BadInput
from integrator_bench.harness.run.schedule import StiffnessBound
from integrator_bench.integrators.settings import variant_name

#: the tolerance at which a candidate's kind and mode are checked
PROBE_RTOL = 1e-3
#: why a code that takes the formulation is ruled out when it has no error estimate
FIXED_ONLY = "fixed step only (no error estimate); the advice calibrates a tolerance"


@dataclass(frozen=True)
class Candidate:
    """One line of the search: integrator with settings on a formulation."""

    formulation: str
    integrator: str
    settings: tuple = ()
    family: str = "explicit"

    @property
    def label(self) -> str:
        """``cvode-bdf (max_order=2)``: the integrator with its changed settings
        (:attr:`Line.label`)."""
        return variant_name(self.integrator, dict(self.settings))

    @property
    def key(self) -> tuple:
        """``(label, formulation)``: what tells the search's lines apart, all of one
        problem and adaptive (:func:`~integrator_bench.harness.advise.search.by_line`
        reads the same from each record's ``label``)."""
        return (self.label, self.formulation)

    def case(self, problem, rtol: float) -> Case:
        """This line's case for ``problem`` (an instance) at ``rtol``."""
        spec = ProblemSpec.of_problem(problem)
        return Case(spec.name, spec.params, self.formulation, self.integrator, rtol=rtol,
                    settings=self.settings)


@dataclass(frozen=True)
class RuledOut:
    """A candidate not run, with the evidence against it."""

    label: str
    formulation: str
    reason: str


def integrator_entries(names=None) -> list[tuple[str, type, tuple]]:
    """``(name, class, settings)`` of each integrator spec of ``names`` (None:
    every registered one), with the seed variants of every bare name tried."""
    registered = registry.integrators()
    specs = list(names or registered)
    bare = {s for s in specs if ":" not in s}
    specs += [v for v in SEED_VARIANTS if spec_name(v) in bare & set(registered)]
    out = []
    for spec in specs:
        for entry in parse_integrator_spec(spec):
            if entry not in out:
                out.append(entry)
    return out


def candidates(problem, integrators=None, formulations=None, case_timeout=60.0,
               reference_dir=None) -> tuple[list[Candidate], list[RuledOut]]:
    """The candidates of ``problem`` (an instance) and those ruled out.

    Parameters
    ----------
    problem : Problem
    integrators : list of str, optional
        Integrator specs (``-i``; None: every registered one).
    formulations : list of str, optional
        Formulations (``-f``; None: every one the problem offers).
    case_timeout : float or callable or None
        The per-case budget the stiffness bound is held against, or a function of
        the number of candidates that can run the problem giving it (the search's
        first round shares its time among them); None: no stiffness bound (only
        the selection and its checks: :func:`stiffness_ruled` does the rest).
    reference_dir : path, optional
        Where the reference the stiffness bound reads is.

    Raises
    ------
    BadInput
        A formulation the problem does not offer, or a selection of which no
        candidate can run the problem (naming why for each).
    """
    forms = list(formulations or problem.formulations)
    for f in forms:
        if f not in problem.formulations:
            raise BadInput(f"problem {problem.name} offers no formulation {f!r}; valid: "
                           f"{', '.join(problem.formulations)}")
    entries = integrator_entries(integrators)
    runnable, out = [], []
    for form in forms:
        system = formulated(problem, form, problem.label())
        for name, icls, settings in entries:
            why = unsupported_reason(system, icls, form, rtol=PROBE_RTOL)
            if icls.mode_unsupported(PROBE_RTOL, None):
                # a fixed-step code: first whether it takes the formulation at all (at a
                # step), the reason for gen-alpha on an ODE as for hht
                why = (unsupported_reason(system, icls, form, h=system.t_end - system.t0)
                       or FIXED_ONLY)
            if why is None:
                line = Line(ProblemSpec.of_problem(problem), form, name, settings, "rtol",
                            system.kind)
                runnable.append(Candidate(form, name, settings, FAMILY_WORDS[line.family]))
            else:
                out.append(RuledOut(variant_name(name, dict(settings)), form, why))
    if not runnable:
        reasons = "; ".join(f"{r.label}/{r.formulation}: {r.reason}" for r in out[:3])
        raise BadInput(f"no candidate can run {problem.label()} ({reasons}"
                       f"{'; ...' if len(out) > 3 else ''}); valid integrators: "
                       f"{', '.join(registry.integrators())}")
    if case_timeout is None:
        return runnable, out
    kept, stiff = stiffness_ruled(problem, runnable, case_timeout, reference_dir)
    return kept, out + stiff


def stiffness_ruled(problem, runnable: list, case_timeout, reference_dir=None
                    ) -> tuple[list[Candidate], list[RuledOut]]:
    """``runnable`` split into those kept and those the stiffness bound rules out
    (:func:`candidates`' ``case_timeout`` and ``reference_dir``). It reads the
    problem's reference (computed when missing, without a limit: the advice has it
    checked, within its budget, first)."""
    out = []
    bound = StiffnessBound(case_timeout if not callable(case_timeout)
                           else case_timeout(len(runnable)), reference_dir)  # reads the reference
    if callable(case_timeout):
        # the first round's share grows as candidates are ruled out: held against the
        # share of those that pass at the smallest, a candidate still ruled out cannot
        # finish in the round it would have run in
        bound.budget_s = case_timeout(sum(bound(c.case(problem, PROBE_RTOL)) is None
                                         for c in runnable))
    kept = []
    for cand in runnable:
        why = bound(cand.case(problem, PROBE_RTOL))
        if why is None:
            kept.append(cand)
        else:
            out.append(RuledOut(cand.label, cand.formulation, why.removeprefix("skipped: ")))
    return kept, out
