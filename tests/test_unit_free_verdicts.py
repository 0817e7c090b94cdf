"""Every verdict of the audit is the same in any units (docs/fusion-definitions.md, "Rounding
bound"): a user's planar robot (tests/fixtures/robot/unicycle.py) run in metres, millimetres,
micrometres, ×1e5 and ×1e8, and logged steps of it and random steps under random rescalings of
every state and output component by 1e-8…1e8 (angles keep radians) get the same ranks, exactness
and "reproduced" verdicts; a DMF error planted at 1e-8 prior standard deviations is beyond rounding
in every unit; the rounding bound holds against the same step recomputed in 50 digits and stays
within a stated factor of that real rounding; a saturated sensor whose gap is at the fused
estimate's rounding is exact; where the 8-output sensor lost rank, DMF in other units is within
the two units' distances to the unit-free variant, which the distance in one unit does not bound."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from gpfverify.angles import difference
from gpfverify.audit.case import audit_case
from gpfverify.audit.block import block_audits
from gpfverify.fusion.exactness import gap_size, rescaled_case
from gpfverify.model_fusion import run_fusion
from gpfverify.audit.runfile import open_run, write_run
from gpfverify.fusion.synthetic import random_case
from gpfverify.rng import generator
from gpfverify.tolerances import ALGEBRA_RTOL, EPS, SOLVER_TOL

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))                       # the suite imports in importlib mode: helpers beside it
sys.path.insert(0, str(HERE / "fixtures" / "robot"))
from high_precision import fused_means  # noqa: E402
from unicycle import NAMES, unicycle  # noqa: E402

STEPS = 8
#: (metre, radian per second) in the units tried: m, mm, µm, km, ×1e5 and ×1e8 for every length,
#: and every non-angle component ×1e5 and ×1e8
UNITS = [(1.0, 1.0), (1e3, 1.0), (1e6, 1.0), (1e-3, 1.0), (1e5, 1.0), (1e8, 1.0), (1e5, 1e5), (1e8, 1e8)]
#: the stated factor: a first-order worst-case bound sums (D + L) eps times the magnitude of every
#: operand, while the rounding a step actually makes is a sum of errors of either sign, each at most
#: eps/2 of one operand; on well-conditioned steps the two differ by the number of terms and
#: operations, 10²–10³ (the median), and never by more than 10⁵ (a step whose rounding happens to
#: cancel)
MEDIAN_FACTOR, LARGEST_FACTOR = 1e3, 1e5


def _robot_run(length: float, rate: float, sensors=NAMES[:5], steps: int = STEPS):
    model = unicycle(length, rate, sensors)
    _, ys = model.simulate(steps, generator(np.random.SeedSequence(7)))
    return run_fusion(model, ys, methods=("cmf", "dmf"))


def _verdicts(audits) -> list:
    return [([s.rank for s in a.sensors], [s.exact for s in a.sensors], a.exact, a.condition_holds, a.reproduced)
            for a in audits]


@pytest.fixture(scope="module")
def metres():
    return _robot_run(1.0, 1.0)


@pytest.mark.parametrize("length, rate", UNITS[1:])
def test_the_robot_gets_the_same_verdicts_in_every_unit(metres, length, rate):
    """The robot as a user would rescale it (lengths, and every non-angle component): every rank,
    exactness and reproduced verdict of every step and sensor as in metres; no step reproduced (the
    8-output sensor is not exact), none exact."""
    other = _robot_run(length, rate)
    expected = _verdicts(metres.audit.steps)
    assert _verdicts(other.audit.steps) == expected
    assert not any(a.reproduced or a.exact for a in other.audit.steps)
    # the gap in prior standard deviations is the same where the Moore–Penrose inverse of the rank-deficient
    # sensor does not depend on the change (its outputs all rescaled alike)
    if length == rate:
        for a, b in zip(metres.audit.steps, other.audit.steps):
            assert b.gap_size == pytest.approx(a.gap_size, rel=1e-6)


@pytest.mark.parametrize("length, rate", UNITS)
def test_a_robot_whose_only_rank_loss_is_exact_reproduces_cmf_in_every_unit(length, rate):
    """Without the 8-output sensor the only rank loss is compass 2's temperature channel, which no
    state moves: DMF is exact (in exact arithmetic it equals CMF), so every step is reproduced, in
    every unit."""
    run = _robot_run(length, rate, sensors=NAMES[:4])
    for a in run.audit.steps:
        assert not a.condition_holds and a.exact and a.reproduced, (a.gap_size, a.gap_bound)


def _random_scales(case, rng) -> tuple[np.ndarray, np.ndarray]:
    """(state, output) scales: every component ×10^U(−8, 8), angle outputs and angle state
    components ×1."""
    states = 10.0 ** rng.uniform(-8, 8, case.state_dim)
    states[list(case.circular_state)] = 1.0
    outputs = 10.0 ** rng.uniform(-8, 8, case.central.mu_y.size)
    outputs[list(case.central.circular)] = 1.0
    return states, outputs


def _random_rescaling(case, rng):
    return rescaled_case(case, *_random_scales(case, rng))


def _logged_steps(metres) -> list:
    rng = np.random.default_rng(11)
    robot = [s.dmf.case for s in metres.steps]
    full = [random_case(rng, 4, (2, 1, 3)) for _ in range(6)]
    decoupled = [random_case(rng, 3, (2, 2), decoupled=(3,)) for _ in range(4)]   # rank lost, exact
    lost = [random_case(rng, 3, (4, 2)) for _ in range(4)]                          # l > D, not exact
    return robot + full + decoupled + lost


def test_random_rescalings_keep_every_verdict(metres):
    """Logged steps (the robot's, random full-rank ones, random ones with a decoupled output —
    rank lost yet exact — and random ones with l > D — not exact), each under five random
    rescalings: the same verdicts; and the batched audit of the rescaled full-rank steps agrees."""
    rng = np.random.default_rng(12)
    for case in _logged_steps(metres):
        expected = _verdicts([audit_case(case)])
        for _ in range(5):
            other = _random_rescaling(case, rng)
            assert _verdicts([audit_case(other)]) == expected


def test_the_batched_audit_gives_the_same_verdicts_in_any_units(tmp_path):
    """Random full-rank steps and their random rescalings audited as one block: every step
    reproduced, and each rescaled step's bound the unscaled one's (in exact arithmetic the bound is
    the same number; the two computations differ by rounding of well-conditioned whitenings), small
    enough that a 1e-8 prior-SD error is beyond it."""
    rng = np.random.default_rng(13)
    cases = [random_case(rng, 4, (2, 2, 1)) for _ in range(6)]
    scaled = [_random_rescaling(c, rng) for c in cases]
    with open_run(write_run(tmp_path / "run.jsonl", cases + scaled)) as reader:
        [block] = list(reader.blocks())
    batched = block_audits(block.block, audit_case(cases[0]).rank_rule)
    assert all(b is not None and b.exact and b.reproduced for b in batched), [b and b.gap_size for b in batched]
    for plain, other in zip(batched[:6], batched[6:]):
        assert other.gap_bound == pytest.approx(plain.gap_bound, rel=ALGEBRA_RTOL)
        assert plain.gap_bound < 1e-8 / 10


def _planted(case, size: float) -> tuple[float, float, float]:
    """(clean gap size, gap size with a DMF error of ``size`` prior standard deviations, bound)."""
    audit = audit_case(case)
    factor = np.linalg.cholesky(case.central.C_p)
    direction = factor @ np.ones(case.state_dim) / np.sqrt(case.state_dim)   # one prior standard deviation
    planted = difference(audit.dmf_mean + size * direction, audit.cmf_mean, case.circular_state)
    return audit.gap_size, gap_size(case, planted), audit.gap_bound


def test_a_planted_dmf_error_of_1e_8_prior_sd_is_beyond_rounding_in_every_unit(metres):
    rng = np.random.default_rng(14)
    exact = [s.dmf.case for s in _robot_run(1.0, 1.0, sensors=NAMES[:4]).steps]
    exact += [random_case(rng, 4, (2, 1, 3)) for _ in range(4)] + [random_case(rng, 3, (2, 2), decoupled=(3,))]
    for case in exact:
        for other in [case] + [_random_rescaling(case, rng) for _ in range(4)]:
            clean, planted, bound = _planted(other, 1e-8)
            assert clean <= bound < 1e-8 / 10 and planted > bound


def _rounding_cases():
    rng = np.random.default_rng(15)
    out = []
    for _ in range(12):
        dim = int(rng.integers(2, 6))
        case = random_case(rng, dim, tuple(int(rng.integers(1, dim + 1)) for _ in range(int(rng.integers(1, 4)))))
        out += [case, _random_rescaling(case, rng)]
    robot = [s.dmf.case for s in _robot_run(1.0, 1.0, sensors=NAMES[:4], steps=4).steps]
    return out + robot + [_random_rescaling(c, rng) for c in robot]


def test_the_bound_holds_against_50_digits_and_stays_within_the_stated_factor():
    """The real rounding of a step: its DMF and CMF against the same step in 50 digits, and the gap
    the 50-digit step still has (the reports' own rounding: eq. 32 holds for the logged numbers
    only to rounding). The observed gap never exceeds the bound, and the bound exceeds the largest
    of those by at most the stated factor."""
    factors = []
    for case in _rounding_cases():
        audit = audit_case(case)
        assert audit.exact
        dmf, cmf = fused_means(case, [s.rank for s in audit.sensors])
        angles = case.circular_state
        real = max(gap_size(case, difference(audit.dmf_mean, dmf, angles)),
                   gap_size(case, difference(audit.cmf_mean, cmf, angles)),
                   gap_size(case, difference(dmf, cmf, angles)))
        assert audit.gap_size <= audit.gap_bound
        assert real <= audit.gap_bound
        if real > 0:
            factors.append(audit.gap_bound / real)
    assert len(factors) >= 30
    assert np.median(factors) <= MEDIAN_FACTOR and max(factors) <= LARGEST_FACTOR, np.percentile(factors, [50, 100])


@pytest.mark.parametrize("length, rate", [(1.0, 1.0), (1e-3, 1.0), (1e5, 1e5)])
def test_a_saturated_sensor_is_exact_in_every_unit(length, rate):
    """The saturated copy of the 8-output sensor (noise 10¹⁴ times larger): its gap per unit
    whitened innovation is below the fused estimate's own rounding, (D + L) eps ‖L_p⁻¹ μ_p‖,
    computed here with numpy's Cholesky: exact at every step, in every unit; the 8-output sensor
    itself is not exact at any."""
    run = _robot_run(length, rate, sensors=NAMES, steps=10)
    for step in run.steps:
        case, audit = step.dmf.case, step.audit
        saturated, eight = audit.sensors[5], audit.sensors[4]
        estimate = np.linalg.solve(np.linalg.cholesky(case.central.C_p), case.central.mu_p)
        floor = (case.state_dim + case.central.mu_y.size) * EPS * np.linalg.norm(estimate)
        assert saturated.gap_gain_norm <= floor
        assert saturated.exact and not saturated.full_column_rank
        assert not eight.exact and eight.gap_gain_norm > 1e6 * eight.exactness_tol


def _ci_means(length: float, criterion: str) -> np.ndarray:
    """CI's fused means of the robot (without the 8-output sensor) in units where a metre is
    ``length``, back in metres."""
    model = unicycle(length, 1.0, NAMES[:4])
    _, ys = model.simulate(5, generator(np.random.SeedSequence(8)))
    run = run_fusion(model, ys, methods=("cmf", "dmf", "ci"), audit=False, ci_criterion=criterion)
    units = np.array([length, length, 1.0, length, 1.0])
    return run.means("ci") / units


def test_the_determinant_criterion_makes_ci_unit_free_and_the_trace_criterion_does_not():
    """The same robot in metres and in kilometres: CI with the determinant criterion gives the same
    estimate (to the solver's accuracy, in prior standard deviations of the metre run), the trace
    criterion a different one — the dependence the check page states."""
    prior_sd = np.sqrt(np.diag(unicycle().prior_cov))
    det = np.abs(_ci_means(1.0, "det") - _ci_means(1e-3, "det")) / prior_sd
    trace = np.abs(_ci_means(1.0, "trace") - _ci_means(1e-3, "trace")) / prior_sd
    assert det.max() <= SOLVER_TOL
    assert trace.max() > 1e3 * SOLVER_TOL


def test_the_unit_dependence_bounds_how_far_a_change_of_units_moves_dmf_only_with_the_other_units_own(metres):
    """What the check page and the docs say of the Moore–Penrose DMF where the 8-output sensor lost
    rank: rescaled back, DMF in other units is within the sum of the two units' distances to the
    unit-free variant (the triangle inequality through the estimate no change of units moves), and
    the distance in metres alone does not bound the move (some rescaling moves DMF further)."""
    rng = np.random.default_rng(16)
    moved_beyond = 0
    for step in metres.steps[:4]:
        case, audit = step.dmf.case, step.audit
        assert audit.unit_dependence is not None and audit.unit_dependence < 1e-5
        for _ in range(10):
            states, outputs = _random_scales(case, rng)
            other = audit_case(rescaled_case(case, states, outputs))
            move = gap_size(case, difference(other.dmf_mean / states, audit.dmf_mean, case.circular_state))
            sides = audit.unit_dependence + other.unit_dependence
            assert move <= sides + audit.gap_bound + other.gap_bound
            moved_beyond += move > 1.0
    assert moved_beyond
