"""IFToMM A04 (Bricard's mechanism) and A05 (the stiff flyball governor): the
redundant constraint at every instant, what every formulation does with it, the
energy variation in the record, and the flyball's physics against its invariants."""

import numpy as np
import pytest

from integrator_bench.harness.measure import references
from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.harness.run.execution import execute
from integrator_bench.problems.models.bricard import Bricard
from integrator_bench.problems.models.flyball import Flyball
from integrator_bench.problems.formulations import FULL_RANK
from integrator_bench.problems.system import Unsupported, convert

#: one cheap run of each formulation that takes a rank-deficient Jacobian
RUNS = {"ode": ("scipy-DOP853", {"rtols": [1e-5]}),
        "baumgarte": ("scipy-DOP853", {"rtols": [1e-5]}),
        "projection": ("scipy-DOP853", {"rtols": [1e-5]}),
        "al3": ("al-trapezoidal", {"hs": [0.01]})}


def test_bricards_jacobian_has_one_redundant_row_along_the_whole_motion():
    """Gruebler's count (nq = nc = 24) says rigid; the Jacobian has rank 23 at every
    output time of the reference, which holds the constraints and the energy."""
    p = Bricard()
    ref = references.load(p, compute_missing=False)
    nq = p.nq
    assert p.nq == p.nc == 24
    for row in ref.Y[::20]:
        s = np.linalg.svd(p.constraint_jac(row[:nq]), compute_uv=False)
        assert s[-1] < 1e-12 * s[0] and s[-2] > 1e-3 * s[0]
    pos, vel = p.constraint_residuals(ref.t, ref.Y)
    assert pos.max() < 1e-9 and vel.max() < 1e-8
    energy = p.energy(ref.t, ref.Y)
    assert np.ptp(energy) < 1e-8 * abs(energy[0])
    # P3 starts at (1, -1, 0) at rest and moves under gravity
    np.testing.assert_allclose(ref.Y[0, 3:6], [1.0, -1.0, 0.0], atol=1e-14)
    assert np.ptp(ref.Y[:, 3]) > 1.0


@pytest.mark.parametrize("form", registry.formulations())
def test_every_formulation_runs_bricard_or_is_refused_with_the_reason(form):
    """Over the formulation registry: a form that needs a full-rank Jacobian gives
    every integrator an ``unsupported`` case naming the rank deficiency; the others
    run to an ok record within IFToMM's high precision level (1e-3 on P3) with the
    energy variation recorded: never a traceback or a NaN."""
    problem = Bricard()
    if form not in problem.formulations:
        pytest.skip(f"bricard offers no {form}")
    if form in FULL_RANK:
        cases = expand(problems=["bricard"], formulations=[form])
        assert cases and all(c.unsupported for c in cases)
        assert all("full row rank" in c.unsupported and "rank 23 < 24" in c.unsupported
                   for c in cases)
        with pytest.raises(Unsupported, match="redundant constraint"):
            convert(problem.formulate(form), registry.get_integrator("scipy-Radau"))
        return
    integrator, tol = RUNS[form]
    (case,) = expand(problems=["bricard"], formulations=[form], integrators=[integrator], **tol)
    record = execute(case)
    assert record["status"] == CaseStatus.OK, record["message"]
    assert record["err_max"] < 1e-3
    assert 0 <= record["energy_var"] < 1e-2 and record["err_lambda"] is None


def test_the_energy_variation_is_recorded_for_a02_and_none_for_the_dissipative_flyball():
    from integrator_bench.harness.measure.metrics import energy_variation
    p = Flyball()
    ref = references.load(p, compute_missing=False)
    assert energy_variation(p, ref.t, ref.Y) is None
    (case,) = expand(problems=["n_four_bar:n=2"], formulations=["projection"],
                     integrators=["scipy-DOP853"], rtols=[1e-6])
    record = execute(case)
    assert record["status"] == CaseStatus.OK, record["message"]
    assert 0 < record["energy_var"] < 1e-2


def test_the_flyball_keeps_its_angular_momentum_and_loses_energy_in_its_dampers():
    """An independent check of the Lagrange equations sympy derived: no torque acts
    about the shaft, so ``dT/d phi'`` is constant along the reference; the dampers
    only dissipate, so the energy (kinetic, and the potentials of gravity and the
    springs computed here from the module's constants) never rises; the springs
    start at rest length."""
    p = Flyball()
    ref = references.load(p, compute_missing=False)
    nq = p.nq
    momentum = [(p.mass(y[:nq]) @ y[nq:2 * nq])[0] for y in ref.Y]
    assert np.ptp(momentum) < 1e-8 * abs(momentum[0])
    q0, v0 = ref.Y[0, :nq], ref.Y[0, nq:2 * nq]
    assert v0[0] == pytest.approx(2 * np.pi) and q0[1] == pytest.approx(0.5)
    midpoint = (np.array([0.05, 1.0]) + q0[2:4]) / 2
    assert np.hypot(*(midpoint - [0.05, 0.5])) == pytest.approx(0.5)   # rest length
    from integrator_bench.problems.models import flyball as fb
    kinetic = np.array([y[nq:2 * nq] @ p.mass(y[:nq]) @ y[nq:2 * nq] / 2 for y in ref.Y])
    s, x1, y1, x2, y2 = (ref.Y[:, k] for k in range(1, 6))
    potential = fb.GRAVITY * (fb.SLIDER_MASS * s + fb.ROD_MASS * (2 + y1 + y2) / 2
                              + fb.POINT_MASS * (y1 + y2))
    for x, y, hinge in ((x1, y1, fb.OFFSET), (x2, y2, -fb.OFFSET)):
        length = np.hypot((x - hinge) / 2, (fb.HINGE_HEIGHT + y) / 2 - s)
        potential = potential + fb.STIFFNESS * (length - fb.REST) ** 2 / 2
    energy = kinetic + potential
    assert np.all(np.diff(energy) <= 1e-9 * abs(energy[0]))    # the dampers only take
    assert energy[-1] < energy[0] - 1e-3   # and they do take: 3.1e-3 J of 237 J in 10 s


def test_a_stiff_integrator_reaches_the_high_level_on_the_flyball():
    (case,) = expand(problems=["flyball"], formulations=["ode"], integrators=["scipy-Radau"],
                     rtols=[1e-6])
    record = execute(case)
    assert record["status"] == CaseStatus.OK, record["message"]
    assert record["err_max"] < 1e-3 and record["energy_var"] is None


def test_the_report_tables_a_problem_at_its_declared_precision_levels():
    """A02's page of ``ibench report`` takes IFToMM's levels (1e-1, 1e-3) as its targets;
    a problem declaring none (A04, A05: their levels were not found) the default ones."""
    from integrator_bench.harness.report.write import problem_targets
    assert problem_targets("n_four_bar", (1e-3, 1e-5)) == (1e-1, 1e-3)
    assert problem_targets("bricard", (1e-3, 1e-5)) == (1e-3, 1e-5)
    assert problem_targets("flyball", (1e-3, 1e-5)) == (1e-3, 1e-5)


@pytest.fixture(scope="module")
def iftomm_cases():
    """The ``iftomm`` preset's matrix (expanded once: about 3.5 s of CPU)."""
    return expand(preset="iftomm")


@pytest.mark.parametrize("form", registry.formulations())
def test_the_iftomm_preset_runs_every_formulation_on_each_problem_or_names_why_not(
        iftomm_cases, form):
    """Whatever the preset's budget and ladders leave out, every formulation of the
    registry stays in it on each of A01-A05: some case of it runs, or (a form that
    needs a full-rank Jacobian, on Bricard's redundant mechanism) every case of it
    is ``unsupported`` naming the rank deficiency. On the stiff flyball both an
    implicit and an explicit integrator run the underlying ODE: the stiff/explicit
    comparison the issue asks for."""
    for problem in {c.problem for c in iftomm_cases}:
        cases = [c for c in iftomm_cases if c.problem == problem and c.formulation == form]
        if form not in registry.problems()[problem].formulations:
            assert not cases
            continue
        assert cases, f"the iftomm preset has no {form} case of {problem}"
        if problem == "bricard" and form in FULL_RANK:
            assert all(c.unsupported and "full row rank" in c.unsupported for c in cases)
        else:
            assert any(not c.unsupported for c in cases), (problem, form)
    if form == "ode":
        families = {c.identity()["family"] for c in iftomm_cases
                    if c.problem == "flyball" and c.formulation == "ode" and not c.unsupported}
        assert {"implicit", "explicit"} <= families
