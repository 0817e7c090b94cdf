"""CC/CW, CI, ICI and EI against independent routes: explicit-inverse formulas, a brute-force
grid over ω, the cvxpy formulation against the closed form, and the consistency of CI for every
admissible cross-correlation."""

import numpy as np
import pytest

from gpfverify.errors import InputError
from gpfverify.filters.records import Gaussian
from gpfverify.fusion.ci import (covariance_intersection, criterion_value,
                                 inverse_covariance_intersection)
from gpfverify.fusion.convex import convex_combination
from gpfverify.fusion.ellipsoidal import ellipsoidal_intersection
from gpfverify.fusion.estimates import information_form, weighted_information_fusion
from gpfverify.fusion.synthetic import random_spd
from gpfverify.tolerances import SOLVER_TOL, algebra_rtol

GRID = np.linspace(0.0, 1.0, 401)


def _elongated(rng, d, ratio):
    """A covariance with eigenvalues spread by ``ratio`` in a random orientation: pairs of these
    have interior CI optima."""
    q, _ = np.linalg.qr(rng.normal(size=(d, d)))
    return (q * np.geomspace(1.0, ratio, d)) @ q.T


def _pair(seed, d):
    rng = np.random.default_rng(seed)
    return [Gaussian(rng.normal(size=d), _elongated(rng, d, 30.0)) for _ in range(2)]


def _cond(*covs):
    return max(np.linalg.cond(c) for c in covs)


def _inv(a):
    return np.linalg.inv(a)


def _ci_direct(ests, w):
    info = sum(wm * _inv(e.cov) for wm, e in zip(w, ests))
    p = _inv(info)
    return p @ sum(wm * _inv(e.cov) @ e.mean for wm, e in zip(w, ests)), p


def _psd_slack(a):
    return np.linalg.eigvalsh(0.5 * (a + a.T))[0]


@pytest.mark.parametrize("d", [1, 2, 3, 6])
def test_convex_combination_matches_explicit_formula(d):
    rng = np.random.default_rng(d)
    ests = [Gaussian(rng.normal(size=d), random_spd(rng, d)) for _ in range(3)]
    mean, cov = _ci_direct(ests, np.ones(3))
    fused = convex_combination(ests)
    tol = algebra_rtol(_cond(*[e.cov for e in ests]))
    np.testing.assert_allclose(fused.cov, cov, rtol=tol, atol=tol * np.abs(cov).max())
    np.testing.assert_allclose(fused.mean, mean, rtol=tol, atol=tol * np.abs(mean).max())


@pytest.mark.parametrize("criterion", ["trace", "det"])
@pytest.mark.parametrize("seed, d", [(0, 2), (1, 2), (2, 3), (3, 4), (4, 6)])
def test_two_sensor_ci_closed_form_is_optimal_and_matches_cvxpy(criterion, seed, d):
    ests = _pair(seed, d)
    fused = covariance_intersection(ests, criterion)
    w = fused.weights
    assert w.shape == (2,) and w.sum() == pytest.approx(1.0, abs=1e-15)
    mean, cov = _ci_direct(ests, w)
    tol = algebra_rtol(_cond(*[e.cov for e in ests]))
    np.testing.assert_allclose(fused.cov, cov, rtol=tol, atol=tol * np.abs(cov).max())
    np.testing.assert_allclose(fused.mean, mean, rtol=tol, atol=tol * np.abs(mean).max())
    best = criterion_value(fused.cov, criterion)
    grid = [criterion_value(_ci_direct(ests, [g, 1 - g])[1], criterion) for g in GRID]
    assert best <= min(grid) + tol * abs(min(grid))
    via_sdp = covariance_intersection(ests, criterion, solver="cvxpy")
    # at a smooth minimum the argmin is only as accurate as the square root of the objective
    np.testing.assert_allclose(via_sdp.weights, w, atol=np.sqrt(SOLVER_TOL))
    assert criterion_value(via_sdp.cov, criterion) == pytest.approx(best, rel=SOLVER_TOL, abs=SOLVER_TOL)


def test_some_pairs_have_interior_optima():
    """Guards the tests above against only ever seeing endpoints."""
    inner = [covariance_intersection(_pair(s, 2), c).weights[0] for s in range(5) for c in ("trace", "det")]
    assert sum(0.0 < w < 1.0 for w in inner) >= 5


@pytest.mark.parametrize("criterion", ["trace", "det"])
def test_dominated_estimate_gives_the_exact_endpoint(criterion):
    rng = np.random.default_rng(3)
    p = random_spd(rng, 3)
    good, bad = Gaussian(rng.normal(size=3), p), Gaussian(rng.normal(size=3), 2.0 * p + random_spd(rng, 3))
    for ests, want in (([good, bad], [1.0, 0.0]), ([bad, good], [0.0, 1.0])):
        fused = covariance_intersection(ests, criterion)
        assert list(fused.weights) == want
        winner = ests[int(np.argmax(want))]
        np.testing.assert_allclose(fused.cov, winner.cov, rtol=algebra_rtol(np.linalg.cond(p)))
    three = covariance_intersection([bad, good, bad], criterion)
    assert list(three.weights) == [0.0, 1.0, 0.0]


@pytest.mark.parametrize("criterion", ["trace", "det"])
@pytest.mark.parametrize("n, d", [(3, 2), (4, 3)])
def test_n_sensor_ci_beats_a_simplex_sample(criterion, n, d):
    rng = np.random.default_rng(n * d)
    ests = [Gaussian(rng.normal(size=d), _elongated(rng, d, 20.0)) for _ in range(n)]
    fused = covariance_intersection(ests, criterion)
    assert np.all(fused.weights >= 0) and fused.weights.sum() == pytest.approx(1.0)
    best = criterion_value(fused.cov, criterion)
    info = information_form(ests)
    for w in rng.dirichlet(np.ones(n), size=300):
        other = criterion_value(weighted_information_fusion(info, w).cov, criterion)
        assert best <= other + SOLVER_TOL * abs(other)


@pytest.mark.parametrize("criterion", ["trace", "det"])
def test_n_sensor_ci_is_bitwise_independent_of_earlier_solves(criterion):
    """The same CI problem gives the same bits whatever the process solved before (a warm-started
    solver changed the last bits, so results depended on workers and resume)."""
    rng = np.random.default_rng(7)
    first, other = ([Gaussian(rng.normal(size=3), _elongated(rng, 3, 20.0)) for _ in range(3)] for _ in range(2))
    before = covariance_intersection(first, criterion)
    covariance_intersection(other, criterion)
    after = covariance_intersection(first, criterion)
    np.testing.assert_array_equal(after.weights, before.weights)
    np.testing.assert_array_equal(after.cov, before.cov)


def _admissible_joint(rng, p1, p2, correlation):
    """[[P1, P12], [P21, P2]] ⪰ 0 with P12 = L1 C L2ᵀ, ‖C‖₂ = correlation ≤ 1."""
    l1, l2 = np.linalg.cholesky(p1), np.linalg.cholesky(p2)
    u, _, vt = np.linalg.svd(rng.normal(size=p1.shape))
    return l1 @ (correlation * u @ vt) @ l2.T


@pytest.mark.parametrize("seed", range(4))
def test_ci_is_consistent_for_every_admissible_cross_correlation(seed):
    rng = np.random.default_rng(seed)
    ests = _pair(seed + 10, 3)
    p1, p2 = ests[0].cov, ests[1].cov
    for w in (covariance_intersection(ests).weights, covariance_intersection(ests, "det").weights,
              np.array([0.3, 0.7])):
        _, p = _ci_direct(ests, w)
        k1 = p @ (w[0] * _inv(p1))
        k2 = p @ (w[1] * _inv(p2))
        for corr in (0.0, 0.5, 0.99, 1.0):
            p12 = _admissible_joint(rng, p1, p2, corr)
            actual = k1 @ p1 @ k1.T + k1 @ p12 @ k2.T + k2 @ p12.T @ k1.T + k2 @ p2 @ k2.T
            assert _psd_slack(p - actual) >= -algebra_rtol(_cond(p1, p2)) * np.abs(p).max()


@pytest.mark.parametrize("seed", range(3))
def test_convex_combination_is_below_every_ci_bound(seed):
    rng = np.random.default_rng(seed)
    ests = [Gaussian(rng.normal(size=3), random_spd(rng, 3)) for _ in range(3)]
    cc = convex_combination(ests).cov
    info = information_form(ests)
    for w in rng.dirichlet(np.ones(3), size=20):
        p = weighted_information_fusion(info, w).cov
        assert _psd_slack(p - cc) >= -algebra_rtol(np.linalg.cond(p)) * np.abs(p).max()


def _ici_direct(e1, e2, w):
    p1i, p2i = _inv(e1.cov), _inv(e2.cov)
    mix = _inv(w * e1.cov + (1 - w) * e2.cov)
    p = _inv(p1i + p2i - mix)
    return p @ ((p1i - w * mix) @ e1.mean + (p2i - (1 - w) * mix) @ e2.mean), p


@pytest.mark.parametrize("criterion", ["trace", "det"])
@pytest.mark.parametrize("seed, d", [(0, 2), (1, 3), (2, 4)])
def test_ici_matches_direct_formula_and_grid(criterion, seed, d):
    ests = _pair(seed + 20, d)
    fused = inverse_covariance_intersection(ests, criterion)
    (w,) = fused.weights
    mean, cov = _ici_direct(*ests, w)
    tol = algebra_rtol(_cond(*[e.cov for e in ests]))
    np.testing.assert_allclose(fused.cov, cov, rtol=tol, atol=tol * np.abs(cov).max())
    np.testing.assert_allclose(fused.mean, mean, rtol=tol, atol=tol * np.abs(mean).max())
    grid = min(criterion_value(_ici_direct(*ests, g)[1], criterion) for g in GRID)
    assert criterion_value(fused.cov, criterion) <= grid + tol * abs(grid)


def _ei_direct(e1, e2, eta):
    """Sijs & Lazar (2012) eq. 9-11, written from the paper with eigendecompositions."""
    d1, s1 = np.linalg.eigh(e1.cov)
    half = s1 * np.sqrt(d1)
    inv_half = s1 / np.sqrt(d1)
    d2, s2 = np.linalg.eigh(inv_half.T @ e2.cov @ inv_half)
    t = half @ s2
    gamma = t @ np.diag(np.maximum(1.0, d2)) @ t.T
    p1i, p2i, gi = _inv(e1.cov), _inv(e2.cov), _inv(gamma)
    e = eta * np.eye(len(d1))
    mutual = _inv(p1i + p2i - 2 * gi + 2 * e) @ ((p2i - gi + e) @ e1.mean + (p1i - gi + e) @ e2.mean)
    p = _inv(p1i + p2i - gi)
    return p @ (p1i @ e1.mean + p2i @ e2.mean - gi @ mutual), p


@pytest.mark.parametrize("seed, d", [(0, 2), (1, 3), (2, 5)])
def test_ellipsoidal_intersection_matches_sijs_lazar(seed, d):
    ests = _pair(seed + 30, d)
    fused = ellipsoidal_intersection(ests)
    mean, cov = _ei_direct(*ests, eta=0.0)
    tol = algebra_rtol(_cond(*[e.cov for e in ests]))
    np.testing.assert_allclose(fused.cov, cov, rtol=tol, atol=tol * np.abs(cov).max())
    np.testing.assert_allclose(fused.mean, mean, rtol=0, atol=tol * np.abs(mean).max())
    for e in ests:  # EI is below both inputs
        assert _psd_slack(e.cov - fused.cov) >= -tol * np.abs(e.cov).max()


def test_ellipsoidal_intersection_of_equal_covariances_averages():
    rng = np.random.default_rng(4)
    p = random_spd(rng, 3)
    ests = [Gaussian(rng.normal(size=3), p), Gaussian(rng.normal(size=3), p)]
    fused = ellipsoidal_intersection(ests)
    mean, cov = _ei_direct(*ests, eta=1.0)  # Sijs & Lazar's regularised case
    np.testing.assert_allclose(fused.mean, 0.5 * (ests[0].mean + ests[1].mean), rtol=algebra_rtol(np.linalg.cond(p)))
    np.testing.assert_allclose(fused.mean, mean, rtol=algebra_rtol(np.linalg.cond(p)))
    np.testing.assert_allclose(fused.cov, p, rtol=algebra_rtol(np.linalg.cond(p)))


def test_bad_inputs_are_input_errors():
    ests = _pair(0, 2)
    with pytest.raises(InputError, match="criterion"):
        covariance_intersection(ests, "volume")
    with pytest.raises(InputError, match="two estimates"):
        covariance_intersection(ests * 2, solver="closed-form")
    with pytest.raises(InputError, match=r"estimates\[1\].cov"):
        convex_combination([ests[0], Gaussian(ests[1].mean, -ests[1].cov)])
    with pytest.raises(InputError, match=r"estimates\[1\].mean"):
        convex_combination([ests[0], Gaussian(np.zeros(3), ests[1].cov)])
    with pytest.raises(InputError, match="at least"):
        convex_combination([])


def test_det_ci_for_three_sensors_survives_a_solver_failure_at_a_vertex_optimum():
    """Found by the property suite: Clarabel fails on this case, whose det-optimal weights are the
    vertex (1, 0, 0); the result must be that vertex, certified by the KKT condition."""
    from gpfverify.filters.records import Gaussian
    from gpfverify.fusion.ci import kkt_violation
    from gpfverify.fusion.estimates import information_form

    estimates = [Gaussian(np.zeros(3), np.eye(3)), Gaussian(np.zeros(3), np.diag([1.0, 1.24093776, 1.0])),
                 Gaussian(np.zeros(3), np.diag([177.827941, 1.0, 1.0]))]
    fused = covariance_intersection(estimates, "det")
    np.testing.assert_array_equal(fused.weights, [1.0, 0.0, 0.0])
    info = information_form(estimates)
    assert kkt_violation(info, fused.weights, "det") <= 0.0
    # a non-optimal vertex is rejected: at (0, 1, 0), g = tr(S⁻¹ I_0) = 3.24 > D = 3
    from gpfverify.tolerances import KKT_REJECT_TOL

    assert kkt_violation(info, np.array([0.0, 1.0, 0.0]), "det") == pytest.approx(3.24093776 / 3 - 1)
    assert kkt_violation(info, np.array([0.0, 1.0, 0.0]), "det") > KKT_REJECT_TOL
