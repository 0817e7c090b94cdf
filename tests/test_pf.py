"""Resampling, particle densities and the bootstrap PF against exact references: the systematic
scheme's floor/ceil property and unbiasedness, scipy's Gaussian density, the Kalman filter."""

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from gpfverify.errors import InputError
from gpfverify.filters.kalman import kf_step
from gpfverify.filters.likelihoods import gaussian_logpdf, measurement_loglik
from gpfverify.filters.models import NonlinearModel, linear_model
from gpfverify.filters.pf import pf_step
from gpfverify.filters.records import Gaussian
from gpfverify.filters.resampling import (ParticleSet, effective_sample_size, needs_resampling,
                                          normalize_log_weights, systematic_resample)
from gpfverify.scenarios.simulate import simulate
from gpfverify.tolerances import algebra_rtol, monte_carlo_atol


@pytest.mark.parametrize("seed", range(5))
def test_systematic_counts_are_floor_or_ceil_of_n_w(seed):
    rng = np.random.default_rng(seed)
    log_w = rng.normal(scale=2.0, size=37)
    w = np.exp(normalize_log_weights(log_w))
    counts = np.bincount(systematic_resample(log_w, rng), minlength=37)
    assert counts.sum() == 37
    assert np.all((counts == np.floor(37 * w)) | (counts == np.ceil(37 * w)))


def test_systematic_resampling_is_unbiased():
    rng = np.random.default_rng(1)
    log_w = rng.normal(size=20)
    w = np.exp(normalize_log_weights(log_w))
    draws = 4000
    counts = np.array([np.bincount(systematic_resample(log_w, rng), minlength=20) for _ in range(draws)])
    np.testing.assert_array_less(np.abs(counts.mean(0) - 20 * w),
                                 monte_carlo_atol(counts.std(0), draws) + algebra_rtol())


def test_effective_sample_size_extremes_and_threshold():
    assert effective_sample_size(np.zeros(10)) == pytest.approx(10.0, rel=algebra_rtol())
    one_hot = np.full(10, -np.inf)
    one_hot[3] = 0.0
    assert effective_sample_size(one_hot) == pytest.approx(1.0, rel=algebra_rtol())
    assert needs_resampling(np.zeros(10), 1.0) and not needs_resampling(np.zeros(10), 0.5)
    assert needs_resampling(one_hot, 0.5)
    with pytest.raises(InputError):
        normalize_log_weights(np.full(4, -np.inf))


def test_gaussian_logpdf_matches_scipy():
    rng = np.random.default_rng(2)
    a = rng.normal(size=(3, 3))
    cov = a @ a.T + 0.5 * np.eye(3)
    r = rng.normal(size=(7, 3))
    expected = multivariate_normal(np.zeros(3), cov).logpdf(r)
    np.testing.assert_allclose(gaussian_logpdf(r, cov), expected, rtol=algebra_rtol(np.linalg.cond(cov)))


def test_measurement_loglik_uses_the_model_residual():
    wrap = lambda y, yp: np.mod(y - yp + np.pi, 2 * np.pi) - np.pi  # noqa: E731
    model = NonlinearModel(f=lambda x, k: x, h=lambda x, k: x, Q=np.eye(1), R=np.array([[0.1]]),
                           measurement_residual=wrap)
    near_cut = measurement_loglik(model, np.array([np.pi - 0.01]), np.array([[-np.pi + 0.01]]), 0)
    direct = gaussian_logpdf(np.array([[0.02]]), model.R)
    np.testing.assert_allclose(near_cut, direct, rtol=algebra_rtol())


def _linear_problem():
    F = np.array([[1.0, 1.0], [0.0, 0.9]])
    H = np.array([[1.0, 0.0]])
    Q, R = np.diag([0.3, 0.2]), np.array([[0.5]])
    _, ys = simulate(linear_model(F, H, Q, R), np.array([0.5, -0.5]), 4, np.random.default_rng(3))
    return F, H, Q, R, ys


def test_bootstrap_pf_agrees_with_the_kalman_filter_within_monte_carlo_error():
    """Independent PF runs: the spread of (PF mean − KF mean) over runs is the Monte Carlo error;
    the average error must be within 5 standard errors of zero, for mean and covariance."""
    F, H, Q, R, ys = _linear_problem()
    model = linear_model(F, H, Q, R)
    prior = Gaussian(np.array([0.5, -0.5]), np.eye(2))
    kalman = prior
    for k, y in enumerate(ys, 1):
        kalman = kf_step(kalman, F, H, Q, R, y).posterior
    runs, count = 24, 4000
    mean_err, cov_err = [], []
    for seed in range(runs):
        rng = np.random.default_rng(100 + seed)
        belief = ParticleSet.equally_weighted(rng.multivariate_normal(prior.mean, prior.cov, count))
        for k, y in enumerate(ys, 1):
            belief, info = pf_step(belief, model, y, k, rng)
        mean_err.append(info.mean - kalman.mean)
        cov_err.append(info.cov - kalman.cov)
    for err in (np.array(mean_err), np.array(cov_err)):
        np.testing.assert_array_less(np.abs(err.mean(0)), monte_carlo_atol(err.std(0, ddof=1), runs))
    # and the Monte Carlo error itself is of order posterior std / sqrt(N)
    assert np.all(np.array(mean_err).std(0) < 10 * np.sqrt(np.diag(kalman.cov) / count))


def test_bad_input_raises_input_error():
    model = linear_model(np.eye(2), np.eye(2)[:1], np.eye(2), np.eye(1))
    rng = np.random.default_rng(0)
    belief = ParticleSet.equally_weighted(np.zeros((5, 2)))
    with pytest.raises(InputError, match="y"):
        pf_step(belief, model, np.zeros(2), 1, rng)
    with pytest.raises(InputError, match="particles"):
        pf_step(ParticleSet.equally_weighted(np.zeros((5, 3))), model, np.zeros(1), 1, rng)
    with pytest.raises(InputError, match="y"):
        pf_step(belief, model, np.array([np.nan]), 1, rng)
