"""RCC-CI's Newton route (the dual over the weights by a barrier method) against the conic route
(Clarabel on the semidefinite primal) on drawn cases, its invariances, closed forms, the empty
intersection and its batch.

Tolerances. Clarabel stops at a relative duality gap of about 1e-8 (SOLVER_TOL allows for that
with a margin); the weights and the centre maximise a strongly concave relaxation, so their accuracy
is the square root of the objective's, ARGMAX_TOL = √SOLVER_TOL, as test_fusion_rcc_ci.py compares
Clarabel's primal with its own dual. The Newton route stops at μ = 1e-11 on the central path, far
inside these; the measured differences are Clarabel's (about 1e-5 on the weights; against Clarabel
run to 1e-13 they fall to 1e-8 – 1e-10 in most cases)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gpfverify.errors import SolverError
from gpfverify.filters.records import Gaussian
from gpfverify.fusion import rcc_ci as rcc
from gpfverify.strategies.profiles import scaled_examples
from gpfverify.tolerances import SOLVER_TOL

ARGMAX_TOL = np.sqrt(SOLVER_TOL)


def _spd(rng, d, spread):
    q = np.linalg.qr(rng.normal(size=(d, d)))[0]
    return (q * np.geomspace(1.0, spread, d)) @ q.T


def _case(seed, n, d, kind):
    rng = np.random.default_rng(seed)
    spread = 1e6 if kind == "badly conditioned" else 10.0
    ests = [Gaussian(0.5 * rng.normal(size=d), _spd(rng, d, spread) * rng.uniform(0.5, 2.0)) for _ in range(n)]
    if kind == "nested":  # the first ellipsoid inside the second, far larger
        ests[1] = Gaussian(ests[0].mean.copy(), 100.0 * ests[0].cov)
    return ests


def _whitened_gap(got, want, cov):
    return float(np.abs(np.linalg.solve(np.linalg.cholesky(cov), got - want)).max())


def _agree(newton, conic, scale):
    assert newton.c == conic.c and newton.enlarged == conic.enlarged
    assert newton.primal_value == pytest.approx(conic.primal_value, rel=SOLVER_TOL, abs=SOLVER_TOL * scale ** 2)
    np.testing.assert_allclose(newton.weights, conic.weights, atol=ARGMAX_TOL)
    assert _whitened_gap(newton.mean, conic.mean, conic.cov) <= ARGMAX_TOL
    np.testing.assert_allclose(newton.cov, conic.cov, rtol=ARGMAX_TOL, atol=ARGMAX_TOL * np.abs(conic.cov).max())


@settings(max_examples=scaled_examples(0.5), deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 5), d=st.integers(1, 12),
       kind=st.sampled_from(["plain", "badly conditioned", "nested"]), metric=st.sampled_from(rcc.METRICS),
       size=st.sampled_from([None, 30.0]))
def test_the_newton_route_is_the_conic_routes(seed, n, d, kind, metric, size):
    ests = _case(seed, n, d, kind)
    conic = rcc.rcc_ci(ests, c=size, metric=metric, on_empty="enlarge", route="conic")
    newton = rcc.rcc_ci(ests, c=size, metric=metric, on_empty="enlarge", route="newton")
    scale = np.sqrt(newton.c * max(np.linalg.eigvalsh(e.cov)[-1] for e in ests))
    _agree(newton, conic, scale)


@settings(max_examples=scaled_examples(0.25), deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 4), d=st.integers(1, 6), closeness=st.sampled_from([1.05, 1.5]))
def test_nearly_disjoint_ellipsoids(seed, n, d, closeness):
    """The size just above the smallest at which the ellipsoids meet: a small intersection."""
    rng = np.random.default_rng(seed)
    ests = [Gaussian(3.0 * rng.normal(size=d), _spd(rng, d, 10.0)) for _ in range(n)]
    c = closeness * rcc.smallest_intersecting_size(ests)
    conic, newton = rcc.rcc_ci(ests, c=c, route="conic"), rcc.rcc_ci(ests, c=c, route="newton")
    _agree(newton, conic, np.sqrt(c * max(np.linalg.eigvalsh(e.cov)[-1] for e in ests)))


def test_the_empty_intersection_is_reported_as_by_the_conic_route():
    far = [Gaussian(np.zeros(2), np.eye(2)), Gaussian(np.array([10.0, 0.0]), np.eye(2))]
    for c in (None, 3.0):
        with pytest.raises(SolverError) as conic:
            rcc.rcc_ci(far, c=c, route="conic")
        with pytest.raises(SolverError) as newton:
            rcc.rcc_ci(far, c=c, route="newton")
        assert str(newton.value) == str(conic.value)
    res = rcc.rcc_ci(far, on_empty="enlarge", route="newton")
    assert res.enlarged and res.c == pytest.approx(rcc.EMPTY_GROWTH * 25.0, rel=SOLVER_TOL)
    np.testing.assert_allclose(res.mean, [5.0, 0.0], atol=1e-9)


@pytest.mark.parametrize("metric", rcc.METRICS)
def test_permuting_rotating_and_rescaling(metric):
    ests = _case(5, 4, 5, "plain")
    base = rcc.rcc_ci(ests, metric=metric, route="newton")
    order = [2, 0, 3, 1]
    permuted = rcc.rcc_ci([ests[i] for i in order], metric=metric, route="newton")
    np.testing.assert_allclose(permuted.weights, base.weights[order], atol=1e-9)
    np.testing.assert_allclose(permuted.mean, base.mean, atol=1e-9)
    s, shift = 7.0, np.arange(5.0)
    moved = rcc.rcc_ci([Gaussian(s * e.mean + shift, s**2 * e.cov) for e in ests], metric=metric, route="newton")
    np.testing.assert_allclose(moved.weights, base.weights, atol=1e-9)
    np.testing.assert_allclose(moved.mean, s * base.mean + shift, atol=1e-8 * s)
    if metric == "euclidean":  # the Euclidean norm is rotation invariant (the scaled one is not)
        q = np.linalg.qr(np.random.default_rng(0).normal(size=(5, 5)))[0]
        rotated = rcc.rcc_ci([Gaussian(q @ e.mean, q @ e.cov @ q.T) for e in ests], route="newton")
        np.testing.assert_allclose(rotated.weights, base.weights, atol=1e-9)
        np.testing.assert_allclose(rotated.mean, q @ base.mean, atol=1e-9)
        np.testing.assert_allclose(rotated.cov, q @ base.cov @ q.T, atol=1e-9 * np.abs(base.cov).max())


@pytest.mark.parametrize("d", [1, 3, 8])
def test_closed_forms_one_estimate_and_two_identical(d):
    est = _case(d, 1, d, "plain")[0]
    one = rcc.rcc_ci([est], route="newton")
    np.testing.assert_allclose(one.weights, [1.0])
    np.testing.assert_allclose(one.mean, est.mean, atol=1e-12)
    np.testing.assert_allclose(one.cov, est.cov, rtol=1e-10)
    two = rcc.rcc_ci([est, Gaussian(est.mean.copy(), est.cov.copy())], route="newton")
    np.testing.assert_allclose(two.weights, [0.5, 0.5], atol=1e-9)
    np.testing.assert_allclose(two.mean, est.mean, atol=1e-10)
    np.testing.assert_allclose(two.cov, est.cov, rtol=1e-9)


@pytest.mark.parametrize("spread", [0.5, 6.0])
def test_a_batch_by_newton_is_each_runs_own(spread):
    """Every split of the runs gives the same bits, and each run's weights are rcc_ci's alone."""
    rng = np.random.default_rng(11)
    means = rng.normal(size=(8, 3, 3)) * spread
    a = rng.normal(size=(8, 3, 3, 3))
    covs = a @ np.swapaxes(a, -1, -2) + 0.3 * np.eye(3)
    full = rcc.rcc_ci_batch(means, covs, route="newton")
    parts = [rcc.rcc_ci_batch(means[s:s + k], covs[s:s + k], route="newton") for s, k in ((0, 5), (5, 1), (6, 2))]
    for f in ("mean", "cov", "weights", "c", "enlarged"):
        np.testing.assert_array_equal(np.concatenate([getattr(p, f) for p in parts]), getattr(full, f), err_msg=f)
    conic = rcc.rcc_ci_batch(means, covs)
    np.testing.assert_array_equal(full.enlarged, conic.enlarged)
    np.testing.assert_allclose(full.weights, conic.weights, atol=ARGMAX_TOL)
    for b in range(8):
        alone = rcc.rcc_ci([Gaussian(m, c) for m, c in zip(means[b], covs[b])], on_empty="enlarge", route="newton")
        np.testing.assert_array_equal(full.weights[b], alone.weights)
