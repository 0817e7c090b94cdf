"""The default (canonical) rank rule does not depend on units, on drawn fusion cases.

Rescaling state components (x → S_x x) and measurement components (y → S_y y) by positive
diagonal factors — metres → km, radians → microradians, anything in [1e-6, 1e6] — changes

* no rank verdict (rank, full column rank, Proposition 1's condition),
* no exactness verdict (per sensor, wherever both frames' arithmetic resolves it),
* the DMF − CMF gap only by rounding when no sensor lost rank (with a rank loss eq. 35's
  Moore–Penrose inverse depends on units; the unit-free variant's gap never does): it is a state
  difference, so S_x⁻¹ · gap' = gap, compared component by component against a rounding bound
  that transforms the same way,
* the canonical correlations only by rounding,

while numpy's σ_max rule (on the same cases) is allowed to change its mind: its σ_min/σ_max ratios
move with the units (checked to make sure the scalings are not trivial).

Oracle: the unscaled case's own audit; the rounding bound is algebra_rtol(κ) times the
componentwise sizes of eq. 35's and eq. 36's operands (|μ_p| + |G| (|…| stacked)), κ from the
correlation matrices (invariant under the scaling).
"""

import numpy as np
from hypothesis import event, example, given
from hypothesis import strategies as st

from gpfverify.audit.case import audit_case
from gpfverify.fusion.case import CentralPrediction, FusionCase, LocalReport
from gpfverify.fusion.centralized import fusion_gain
from gpfverify.fusion.distributed import dmf_update
from gpfverify.fusion.exactness import repair_message, rescaled_case
from gpfverify.strategies import fusion_cases
from gpfverify.strategies.matrices import log_uniform
from gpfverify.tolerances import RESOLVABLE_GAP, algebra_rtol


def _range_condition(split) -> float:
    """σ_1/σ_r over the singular values of C_xy^m the split keeps (1 when it keeps none)."""
    s = split.rank.singular_values[: split.rank.rank]
    return float(s[0] / s[-1]) if s.size else 1.0


def _correlation_condition(cov: np.ndarray) -> float:
    d = np.sqrt(np.diag(cov))
    eig = np.linalg.eigvalsh(cov / np.outer(d, d))
    return float(eig[-1] / eig[0])


def gap_rounding_bound(case, dmf) -> np.ndarray:
    """Componentwise rounding bound (state units) on the computed DMF − CMF of ``case``:
    algebra_rtol(κ) · (|μ_p| + |G| v), v stacking per sensor |μ_y^m| + |μ_y(m)| + |y^m| +
    |C_y^m| |A_m| (|μ_e^m| + |μ_p^m|); every term scales with S_x (and κ, built from correlation
    matrices and the canonical split's own condition, does not change)."""
    c = case.central
    gain = np.abs(dmf.gain)
    parts, kappa = [], _correlation_condition(c.C_y)
    for s, block, local in zip(dmf.sensors, c.blocks, case.locals):
        kappa = max(kappa, _range_condition(s.split) * _correlation_condition(local.C_y))
        parts.append(np.abs(local.mu_y) + np.abs(c.mu_y[block]) + np.abs(case.local_measurement(s.index))
                     + np.abs(local.C_y) @ np.abs(s.split.pinv) @ (np.abs(local.mu_e) + np.abs(local.mu_p)))
    return algebra_rtol(kappa) * (np.abs(c.mu_p) + gain @ np.concatenate(parts))


@st.composite
def scaled_cases(draw, **options):
    """(case, S_x, S_y): a drawn case and positive diagonal scalings in [1e-6, 1e6]."""
    case = draw(fusion_cases(**options)).case
    s_x = np.array([draw(log_uniform(1e-6, 1e6)) for _ in range(case.state_dim)])
    s_y = np.array([draw(log_uniform(1e-6, 1e6)) for _ in range(case.central.mu_y.shape[0])])
    return case, s_x, s_y


def check_unit_invariance(case, s_x, s_y) -> None:
    moved = rescaled_case(case, s_x, s_y)
    base, other = audit_case(case), audit_case(moved)
    assert base.rank_rule.name == other.rank_rule.name == "canonical"
    assert [s.rank for s in base.sensors] == [s.rank for s in other.sensors]
    for s, t in zip(base.sensors, other.sensors):
        # the kernel-inclusion verdict does not depend on units wherever both frames resolve it: both
        # bounds at most RESOLVABLE_GAP (else "not exact" by design) and neither residual between the
        # two frames' rounding bounds (a gap one frame's arithmetic resolves and the other's cannot)
        low, high = sorted((s.exactness_tol, t.exactness_tol))
        between = any(low < r <= high for r in (s.gap_gain_norm, t.gap_gain_norm))
        if high <= RESOLVABLE_GAP and not between:
            assert s.exact == t.exact, (s.gap_gain_norm, s.exactness_tol, t.gap_gain_norm, t.exactness_tol)
    assert base.condition_holds == other.condition_holds
    dmf, dmf_moved = dmf_update(case), dmf_update(moved)
    for s, t, split in zip(base.sensors, other.sensors, dmf.sensors):
        # ρ are singular values of a matrix with entries ≤ 1: absolute rounding ≈ eps · whitening condition
        np.testing.assert_allclose(t.canonical_correlations, s.canonical_correlations, rtol=0,
                                   atol=algebra_rtol(split.split.whitening.whitening_condition ** 2))
    # DMF (eq. 35, Moore–Penrose) transforms as states do when no sensor lost rank; the unit-free
    # variant always does
    pairs = [(dmf_update(case, unit_free=True), dmf_update(moved, unit_free=True))]
    if base.condition_holds:
        pairs.append((dmf, dmf_moved))
    for one, two in pairs:
        bound = gap_rounding_bound(case, one) + gap_rounding_bound(moved, two) / s_x
        gap, gap_moved = one.mean - base.cmf_mean, two.mean - other.cmf_mean
        assert np.all(np.abs(gap_moved / s_x - gap) <= bound), (gap_moved / s_x, gap, bound)
    # repair messages restore CMF in any units (the unit-free variant's split; eq. 35's Moore–Penrose
    # reconstruction is itself ill-conditioned in badly mixed units)
    variant_moved = pairs[0][1]
    messages = [repair_message(local, moved.local_measurement(m), split=s.split)
                for m, (local, s) in enumerate(zip(moved.locals, variant_moved.sensors))]
    repaired = dmf_update(moved, messages, unit_free=True).mean
    np.testing.assert_array_less(np.abs(repaired - other.cmf_mean) / s_x,
                                 gap_rounding_bound(moved, variant_moved) / s_x + np.finfo(float).tiny)
    # numpy's rule does see the units: its σ_min/σ_max moves (reported, not asserted per case)
    numpy_base, numpy_moved = audit_case(case, rank_rule="numpy"), audit_case(moved, rank_rule="numpy")
    event("numpy rule changed a rank verdict" if [s.rank for s in numpy_base.sensors]
          != [s.rank for s in numpy_moved.sensors] else "numpy rule kept its rank verdicts")


def _found_case() -> tuple[FusionCase, np.ndarray, np.ndarray]:
    """A case the property found: three 1-D sensors (one with C_xy = 1e-7), rescaled so that the
    central C_y spans 1e-14 … 1e11 and its computed smallest eigenvalue is 0 — a condition number
    formed as λ_max/λ_min divided by zero there (now ∞, or the unit-free correlation condition)."""
    def local(c_y, c_xy, c_e):
        return LocalReport(np.zeros(1), np.zeros(1), np.array([[c_y]]), np.array([[c_xy]]), np.zeros(1),
                           np.array([[c_e]]))

    c_y = np.array([[0.11, 1e-7, 0.1], [1e-7, 0.01, 1e-7], [0.1, 1e-7, 0.11]])
    central = CentralPrediction(np.zeros(1), np.array([[0.1]]), np.zeros(3), c_y, np.array([[0.1, 1e-7, 0.1]]),
                                (1, 1, 1))
    case = FusionCase(central, (local(0.11, 0.1, 0.1 / 11), local(0.01, 1e-7, 0.1), local(0.11, 0.1, 0.1 / 11)),
                      np.zeros(3))
    return case, np.array([1e-6]), np.array([1e-6, 1e-6, 1e6])


@example(scaled=_found_case())
@given(scaled=scaled_cases())
def test_canonical_rank_exactness_and_gap_do_not_depend_on_units(scaled):
    check_unit_invariance(*scaled)


@given(scaled=scaled_cases(kinds="nearly", sigma_min=log_uniform(1e-12, 1e-2), sensors=st.integers(1, 2)))
def test_nearly_rank_deficient_cross_terms_too(scaled):
    """Near the threshold of the rule (small designed σ_min, so ρ from 1e-13 to 1e-2)."""
    check_unit_invariance(*scaled)


@given(case=fusion_cases(kinds=st.sampled_from(("full", "deficient", "decoupled"))).map(lambda d: d.case),
       component=st.data())
def test_radians_to_microradians_on_one_output(case, component):
    """One measurement component multiplied by 1e6 (e.g. a bearing in microradians): same verdicts,
    same gap; numpy's singular-value ratio of that sensor moves."""
    j = component.draw(st.integers(0, case.central.mu_y.shape[0] - 1), label="output")
    s_y = np.ones(case.central.mu_y.shape[0])
    s_y[j] = 1e6
    check_unit_invariance(case, np.ones(case.state_dim), s_y)


def test_the_gap_bound_is_not_vacuous():
    """On a rank-deficient case the gap is far above the bound used to compare it."""
    from gpfverify.fusion.synthetic import random_case

    case = random_case(np.random.default_rng(3), 2, (3, 2))
    dmf = dmf_update(case)
    gap = dmf.mean - (case.central.mu_p + fusion_gain(case.central) @ (case.y - case.central.mu_y))
    assert np.all(np.abs(gap) > 1e3 * gap_rounding_bound(case, dmf))
