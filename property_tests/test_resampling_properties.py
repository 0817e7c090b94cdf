"""Systematic resampling as a randomised algorithm: over the generator's draws its counts are
unbiased, E[count_i] = n w_i (Kitagawa 1996), and every draw gives ⌊n w_i⌋ or ⌈n w_i⌉; and the
adaptive rule of every particle filter's step at any threshold (resample when N_eff < t N).

Each count lies in an interval of length 1 (checked on every draw), so the mean of R draws is
within Hoeffding's :func:`~gpfverify.tolerances.bounded_mean_atol` of n w_i — no estimate of the
variance, which a sample may put at 0 when the fractional part of n w_i is small. The fixed-offset
variant (one u for every call) satisfies floor/ceil on every call but is biased; a variant with
one uniform per particle is unbiased but leaves floor/ceil.
"""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import logsumexp

from gpfverify.filters.resampling import (effective_sample_size, needs_resampling, reweight_and_resample,
                                          systematic_resample)
from gpfverify.strategies import scaled_examples, weights_with_ess
from gpfverify.tolerances import EPS, bounded_mean_atol

DRAWS = 2000


@given(counts=st.lists(st.integers(0, 6), min_size=1, max_size=12).filter(lambda c: sum(c) > 0),
       size=st.integers(1, 40), seed=st.integers(0, 2**32 - 1))
def test_systematic_resampling_counts_are_unbiased_over_the_generators_draws(counts, size, seed):
    weights = np.array(counts, dtype=float) / sum(counts)
    with np.errstate(divide="ignore"):
        log_w = np.log(weights)
    rng = np.random.default_rng(seed)
    drawn = np.stack([np.bincount(systematic_resample(log_w, rng, size), minlength=weights.size)
                      for _ in range(DRAWS)])
    expected = size * weights
    slack = size * weights.size * EPS
    assert np.all(drawn >= np.floor(expected - slack)) and np.all(drawn <= np.ceil(expected + slack))
    bias = np.abs(drawn.mean(axis=0) - expected)
    assert np.all(bias <= bounded_mean_atol(1.0, DRAWS) + slack), (bias, expected)


@settings(max_examples=scaled_examples(0.2))
@given(counts=st.lists(st.integers(1, 6), min_size=2, max_size=8), seed=st.integers(0, 2**32 - 1))
def test_a_resampling_step_keeps_every_particle_in_expectation(counts, seed):
    """reweight_and_resample at threshold 1 (resample every step): each particle's number of copies
    has mean N w_i over the generator's draws, and the resampled set is equally weighted."""
    weights = np.array(counts, dtype=float) / sum(counts)
    particles = np.arange(weights.size, dtype=float)[:, None]
    rng = np.random.default_rng(seed)
    copies = []
    for _ in range(DRAWS):
        step = reweight_and_resample(particles, np.log(weights), rng, 1.0)
        copies.append(np.bincount(step.posterior.particles[:, 0].astype(int), minlength=weights.size))
    assert step.resampled
    np.testing.assert_allclose(np.exp(step.posterior.log_weights), 1.0 / weights.size, rtol=4 * EPS)
    bias = np.abs(np.mean(copies, axis=0) - weights.size * weights)
    assert np.all(bias <= bounded_mean_atol(1.0, DRAWS) + weights.size**2 * EPS), bias


@given(log_w=st.lists(st.one_of(st.just(-np.inf), st.floats(-30.0, 5.0)), min_size=1, max_size=20)
       .filter(lambda v: max(v) > -np.inf),
       threshold=st.one_of(st.floats(0.0, 1.5), st.just(1.0)), seed=st.integers(0, 2**32 - 1))
def test_reweight_and_resample_resamples_exactly_below_the_effective_sample_size_threshold(log_w, threshold, seed):
    """At any threshold t: N_eff = (Σ w)² / Σ w² (computed here with scipy's logsumexp) decides —
    resample when t ≥ 1 or N_eff < t N; a resampled set is equally weighted and every particle is
    one of the weighted set carrying its own covariance factor; otherwise the weighted set is kept.
    The weighted set's log weights are normalised and the estimate is its weighted moments, taken
    before resampling. Thresholds within rounding of N_eff/N may go either way."""
    log_w = np.array(log_w)
    n = log_w.size
    particles = np.column_stack([np.arange(n, dtype=float), np.arange(n, dtype=float) ** 2])
    factors = np.arange(n, dtype=float)[:, None, None] * np.eye(2) + np.eye(2)
    step = reweight_and_resample(particles, log_w, np.random.default_rng(seed), threshold, factors)
    # exp and the sums lose n eps relative to the log weights' size
    rounding = 8 * n * EPS * (1.0 + np.abs(log_w[np.isfinite(log_w)]).max())
    normalised = log_w - logsumexp(log_w)
    np.testing.assert_allclose(step.weighted.log_weights, normalised, rtol=0, atol=rounding)
    ess = float(np.exp(2.0 * logsumexp(log_w) - logsumexp(2.0 * log_w)))
    assert abs(step.ess - ess) <= rounding * ess
    w = np.exp(normalised)
    mean = w @ particles
    scale = float(n * n)  # the particles' largest entry
    np.testing.assert_allclose(step.mean, mean, rtol=0, atol=rounding * scale)
    np.testing.assert_allclose(step.cov, (particles - mean).T @ ((particles - mean) * w[:, None]), rtol=0,
                               atol=rounding * scale**2)
    if abs(ess - threshold * n) > rounding * n:  # else the comparison may go either way
        assert step.resampled == (threshold >= 1.0 or ess < threshold * n), (ess, threshold, n)
    if step.resampled:
        idx = step.posterior.particles[:, 0].astype(int)
        np.testing.assert_array_equal(step.posterior.particles, particles[idx])
        np.testing.assert_array_equal(step.posterior.sqrt_covs, factors[idx])
        np.testing.assert_array_equal(step.posterior.log_weights, np.full(n, -np.log(n)))
        assert np.all(w[idx] > 0)
    else:
        assert step.posterior is step.weighted


@given(designed=weights_with_ess(), side=st.sampled_from([-1.0, 0.0, 1.0]), margin=st.floats(1e-6, 0.5))
def test_resampling_decision_follows_a_designed_effective_sample_size(designed, side, margin):
    """Weights whose N_eff is known in closed form (k particles sharing a mass s, the rest 1 − s,
    shuffled, shifted, zeros allowed): effective_sample_size is that N_eff, and needs_resampling
    decides on the threshold t = (N_eff / N)(1 + side · margin) exactly as N_eff < t N says — just
    above, just below, and t ≥ 1 (every step)."""
    n = designed.log_weights.size
    assert abs(effective_sample_size(designed.log_weights) - designed.ess) <= n * 8 * EPS * designed.ess
    threshold = designed.ess / n * (1.0 + side * margin)
    if side:  # off the boundary by more than N_eff's rounding: the side is decided
        assert needs_resampling(designed.log_weights, threshold) == (side > 0 or threshold >= 1.0)
    assert needs_resampling(designed.log_weights, 1.0)
    assert not needs_resampling(designed.log_weights, 0.0)
