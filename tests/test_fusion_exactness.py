"""DMF (eq. 35) against CMF on random joint Gaussians: equal to rounding under full column rank,
the observed gap equals the closed-form gap otherwise, the repaired DMF equals CMF, and the
exactness verdict matches what happens for many measurements.

Oracle: CMF computed from the central joint Gaussian (an independent route to the same mean);
the tolerance propagates eps · condition through every factor of eq. 35.
"""

from dataclasses import replace

import numpy as np
import pytest

from gpfverify.fusion.centralized import cmf_update, fusion_gain
from gpfverify.fusion.distributed import dmf_update
from gpfverify.fusion.exactness import (analyse_sensors, canonical_split, equivalence_tolerance, kernel_split,
                                        local_consistency_residual, predicted_gap,
                                        repair_message)
from gpfverify.fusion.synthetic import random_case
from gpfverify.tolerances import algebra_rtol

FULL_RANK = [(1, (1, 1)), (2, (1, 2)), (2, (2, 2)), (3, (1, 2, 3)), (4, (4, 2)), (6, (6, 6, 6, 6)),
             (6, (2, 2, 2, 2, 2, 2, 2, 2)), (9, (3, 9))]
DEFICIENT = [(1, (2, 1), None), (2, (3, 2), None), (3, (3, 3), (2, 3)), (3, (5, 1), None),
             (4, (4, 4, 2), (1, 4, 2)), (2, (6, 6), None), (6, (8, 3), (5, 3))]


def _range_condition(split) -> float:
    """σ_1/σ_r over the singular values of C_xy^m the split keeps (1 when it keeps none)."""
    s = split.rank.singular_values[: split.rank.rank]
    return float(s[0] / s[-1]) if s.size else 1.0



def _cond(a):
    """Condition number on the numerical range (singular values above numpy's rank rule)."""
    return _range_condition(kernel_split(a))


def _atol(case):
    """eps·cond error bound of eq. 35 against the CMF mean, with the sizes of its terms."""
    gain = fusion_gain(case.central)
    return equivalence_tolerance(case, gain, analyse_sensors(case, gain))


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("d, sizes", FULL_RANK)
def test_dmf_equals_cmf_under_full_column_rank(d, sizes, seed):
    case = random_case(np.random.default_rng([seed, d, *sizes]), d, sizes)
    dmf, cmf = dmf_update(case), cmf_update(case.central, case.y)
    assert dmf.condition_holds and dmf.exact
    assert all(s.repair_dim == 0 for s in dmf.sensors)
    np.testing.assert_allclose(dmf.mean, cmf.mean, rtol=0, atol=_atol(case))
    c = case.central  # C_e = C_p − C_xy C_y⁻¹ C_xyᵀ formed here with an explicit inverse (another route)
    direct = c.C_p - c.C_xy @ np.linalg.inv(c.C_y) @ c.C_xy.T
    np.testing.assert_allclose(dmf.cov, direct, rtol=0,
                               atol=algebra_rtol(np.linalg.cond(c.C_y)) * np.abs(c.C_p).max())


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("d, sizes, ranks", DEFICIENT)
def test_observed_gap_equals_closed_form_and_repair_restores_cmf(d, sizes, ranks, seed):
    case = random_case(np.random.default_rng([seed, d, *sizes, 7]), d, sizes, ranks)
    dmf, cmf = dmf_update(case), cmf_update(case.central, case.y)
    atol = _atol(case)
    assert not dmf.condition_holds
    want_ranks = ranks or [min(d, s) for s in sizes]
    assert [s.split.rank.rank for s in dmf.sensors] == list(want_ranks)
    assert [s.repair_dim for s in dmf.sensors] == [s - r for s, r in zip(sizes, want_ranks)]
    gap = dmf.mean - cmf.mean
    assert np.linalg.norm(gap) > 1e3 * atol  # the random case really has a gap
    np.testing.assert_allclose(gap, predicted_gap(case, dmf.sensors), rtol=0, atol=atol)
    messages = [repair_message(local, case.local_measurement(m)) for m, local in enumerate(case.locals)]
    # the message is the kernel component (I − P_m) w_m: an l_m-vector in ker C_xy^m (repair_dim dims)
    assert [r.shape[0] for r in messages] == list(sizes)
    for s, local, k in zip(dmf.sensors, case.locals, messages):
        np.testing.assert_allclose(s.split.kernel_component(k), k, rtol=0, atol=atol * np.linalg.norm(k))
        np.testing.assert_allclose(local.C_xy @ k, 0.0, rtol=0,
                                   atol=algebra_rtol(_cond(local.C_y)) * np.linalg.norm(local.C_xy) * np.linalg.norm(k))
    repaired = dmf_update(case, messages)
    assert repaired.repaired
    np.testing.assert_allclose(repaired.mean, cmf.mean, rtol=0, atol=atol)


@pytest.mark.parametrize("d, sizes, decoupled", [(2, (3, 2), (2,)), (3, (4, 1), (0,)),
                                                 (2, (2, 3), (1, 4)), (1, (2, 2), (1, 3))])
def test_exact_although_rank_condition_fails(d, sizes, decoupled):
    """A measurement component uncorrelated with everything: C_xy^m loses column rank, but the
    kernel lies in ker G_m C_y^m, so DMF = CMF for every measurement."""
    rng = np.random.default_rng([d, *sizes, *decoupled])
    case = random_case(rng, d, sizes, decoupled=decoupled)
    dmf = dmf_update(case)
    assert not dmf.condition_holds and dmf.exact
    for _ in range(5):  # many measurements: redraw y, keeping locals consistent with it
        case = random_case(rng, d, sizes, decoupled=decoupled)
        np.testing.assert_allclose(dmf_update(case).mean, cmf_update(case.central, case.y).mean,
                                   rtol=0, atol=_atol(case))


def _with_measurement(case, y):
    """The same case with the stacked measurement ``y`` and the local posteriors that the local
    updates (eq. 32) give for it."""
    reports = tuple(replace(r, mu_e=r.mu_p + r.C_xy @ np.linalg.solve(r.C_y, y[b] - r.mu_y))
                    for r, b in zip(case.locals, case.central.blocks))
    return replace(case, locals=reports, y=np.asarray(y, dtype=float))


@pytest.mark.parametrize("seed", range(4))
def test_inexact_verdict_means_some_measurement_shows_a_gap(seed):
    """The verdict is about the case's matrices: with other measurements of the same case, DMF
    and CMF (computed independently) differ by more than the rounding bound."""
    rng = np.random.default_rng(seed)
    case = random_case(rng, 2, (3, 2))
    sensors = dmf_update(case).sensors
    assert not sensors[0].exact and sensors[1].exact
    for _ in range(3):
        other = _with_measurement(case, case.y + rng.normal(size=case.y.shape))
        gap = np.linalg.norm(dmf_update(other).mean - cmf_update(other.central, other.y).mean)
        assert gap > _atol(other)


@pytest.mark.parametrize("d, l", [(1, 2), (2, 3), (3, 7)])
def test_full_column_rank_needs_l_at_most_d(d, l):
    rng = np.random.default_rng([d, l])
    case = random_case(rng, d, (l,))
    (sensor,) = dmf_update(case).sensors
    assert sensor.split.rank.rank <= d < l and not sensor.full_column_rank


@pytest.mark.parametrize("rows, cols, rank", [(3, 2, 2), (3, 5, 3), (4, 4, 2), (2, 6, 1)])
def test_kernel_split_against_numpy(rows, cols, rank):
    from gpfverify.fusion.synthetic import random_rank_matrix

    a = random_rank_matrix(np.random.default_rng(rows * cols), rows, cols, rank)
    split = kernel_split(a)
    assert split.rank.rank == np.linalg.matrix_rank(a) == rank
    n = split.kernel_basis
    tol = algebra_rtol(_cond(a))
    np.testing.assert_allclose(split.pinv, np.linalg.pinv(a, rcond=split.rank.tol / split.rank.singular_values[0]),
                               rtol=0, atol=tol * np.linalg.norm(np.linalg.pinv(a), 2))
    np.testing.assert_allclose(n.T @ n, np.eye(cols - rank), atol=tol)
    np.testing.assert_allclose(a @ n, 0.0, atol=tol * np.linalg.norm(a, 2))
    np.testing.assert_allclose(split.pinv @ a + n @ n.T, np.eye(cols), atol=tol)


def test_every_rule_records_the_same_singular_values():
    """σ(C_xy^m) recorded by the canonical split are the numpy/absolute split's bits: the rank rule
    changes the decision, never the reported singular values (LAPACK's route without singular
    vectors rounds differently, so the two splits must take the same one)."""
    rng = np.random.default_rng(11)
    for d, l in [(2, 2), (2, 3), (3, 2), (4, 4), (1, 3)] * 4:
        cross = rng.normal(size=(d, l)) * 10.0 ** rng.uniform(-3, 3)
        g = rng.normal(size=(d, 4 * d))
        prior = g @ g.T / (4 * d)
        cov_y = cross.T @ np.linalg.solve(prior, cross) + np.eye(l)  # ⪰ C_yx C_x⁻¹ C_xy: a valid joint
        canonical = canonical_split(cross, prior, cov_y).rank.singular_values
        np.testing.assert_array_equal(canonical, kernel_split(cross).rank.singular_values)


def test_logged_locals_are_consistent_with_y():
    case = random_case(np.random.default_rng(5), 3, (2, 4))
    for m, local in enumerate(case.locals):
        scale = np.linalg.norm(local.mu_e - local.mu_p)
        assert np.linalg.norm(local_consistency_residual(case, m)) <= algebra_rtol(_cond(local.C_y)) * scale


def test_explicit_rank_tolerance_changes_the_decision():
    """A singular value just above numpy's rule counts as rank; a larger tolerance drops it."""
    case = random_case(np.random.default_rng(11), 3, (2, 2))
    s_min = np.linalg.svd(case.locals[0].C_xy, compute_uv=False)[-1]
    assert dmf_update(case).sensors[0].full_column_rank
    assert dmf_update(case, rank_rule="numpy").sensors[0].full_column_rank
    loose = dmf_update(case, rank_tol=1.01 * s_min).sensors[0]
    assert not loose.full_column_rank and loose.split.rank.tol == 1.01 * s_min


@pytest.mark.parametrize("condition", [1e2, 1e5, 1e8, 1e11])
def test_reconstruction_error_stays_within_the_conditioning_bound(condition):
    """Full column rank but ill-conditioned C_xy^m: the pseudo-inverse reconstruction in eq. 35
    loses about eps·cond(C_xy^m)·cond(C_y^m); the observed DMF − CMF stays inside that bound.
    Under numpy's rule (this test is about its σ_max/σ_r condition; the default canonical rule
    calls the 1e-8 and 1e-11 directions uninformative, ρ < τ, and truncates them)."""
    rng = np.random.default_rng(int(np.log10(condition)))
    errors, bounds = [], []
    for _ in range(5):
        case = random_case(rng, 4, (3, 2), cross_condition=condition)
        dmf = dmf_update(case, rank_rule="numpy")
        assert dmf.condition_holds
        assert _range_condition(dmf.sensors[0].split) == pytest.approx(condition, rel=algebra_rtol(condition))
        errors.append(np.linalg.norm(dmf.mean - cmf_update(case.central, case.y).mean))
        bounds.append(equivalence_tolerance(case, dmf.gain, dmf.sensors))
    assert all(e <= b for e, b in zip(errors, bounds)), (errors, bounds)


@pytest.mark.parametrize("condition", [1e2, 1e5])
def test_canonical_reconstruction_stays_within_its_bound(condition):
    """The same cases under the default canonical rule (still full column rank at these
    conditions): DMF − CMF within the library bound built on the canonical split's condition."""
    rng = np.random.default_rng(int(np.log10(condition)))
    for _ in range(5):
        case = random_case(rng, 4, (3, 2), cross_condition=condition)
        dmf = dmf_update(case)
        assert dmf.rank_rule.name == "canonical" and dmf.condition_holds and dmf.exact
        error = np.linalg.norm(dmf.mean - cmf_update(case.central, case.y).mean)
        assert error <= equivalence_tolerance(case, dmf.gain, dmf.sensors)
