"""Resampling, particle densities and the bootstrap PF against exact references: the systematic
scheme's floor/ceil property (to N and to another size) and unbiasedness, scipy's log-sum-exp and
Gaussian density, wrapped angle residuals. The PF against the Kalman filter and across the bearing
cut is in the shared oracle suite (``test_filter_oracles.py``)."""


import numpy as np
import pytest
from scipy.special import logsumexp
from scipy.stats import multivariate_normal

from gpfverify.errors import InputError
from gpfverify.filters.likelihoods import SUBSTITUTION_MAX_DIM, gaussian_logpdf, measurement_loglik
from gpfverify.filters.pf import pf_step
from gpfverify.filters.resampling import (Particles, effective_sample_size, log_sum_exp, needs_resampling,
                                          normalize_log_weights, systematic_resample)
from gpfverify.filters.upf import upf_step
from gpfverify.models import Sensor, StateSpaceModel, linear_model
from gpfverify.tolerances import algebra_rtol, monte_carlo_atol


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("size", [None, 10, 37, 90])
def test_systematic_counts_are_floor_or_ceil_of_n_w(seed, size):
    """n draws from M = 37 particles: each index ⌊n w_i⌋ or ⌈n w_i⌉ times (n = M by default)."""
    rng = np.random.default_rng(seed)
    log_w = rng.normal(scale=2.0, size=37)
    w = np.exp(normalize_log_weights(log_w))
    n = 37 if size is None else size
    counts = np.bincount(systematic_resample(log_w, rng, size=size), minlength=37)
    assert counts.size == 37 and counts.sum() == n
    assert np.all((counts == np.floor(n * w)) | (counts == np.ceil(n * w)))


def test_systematic_resample_guards_rounding_at_the_end():
    """Cumulative weights that round below 1 must not send the last position past the end."""
    class LastPosition:
        def uniform(self):
            return np.nextafter(1.0, 0.0)

    log_w = np.log(np.full(10, 0.1))  # Σ of ten 0.1 rounds to 0.9999999999999999
    for size in (None, 3, 25):
        idx = systematic_resample(log_w, LastPosition(), size=size)
        assert idx.max() == 9


def test_log_sum_exp_matches_scipy():
    rng = np.random.default_rng(8)
    for values in (rng.normal(scale=30.0, size=500), np.full(7, -3.2), np.array([-np.inf, 2.0, 2.0, -1.0]),
                   np.array([1e-300, -800.0])):
        assert log_sum_exp(values) == pytest.approx(float(logsumexp(values)), rel=algebra_rtol())
    assert log_sum_exp(np.full(3, -np.inf)) == -np.inf


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


@pytest.mark.parametrize("dim", [1, 3, SUBSTITUTION_MAX_DIM, SUBSTITUTION_MAX_DIM + 2])
def test_gaussian_logpdf_matches_scipy(dim):
    """Both whitening routes (forward substitution over a few components, numpy's solve beyond),
    with leading axes, against scipy's density."""
    rng = np.random.default_rng(2)
    a = rng.normal(size=(dim, dim))
    cov = a @ a.T + 0.5 * np.eye(dim)
    r = rng.normal(size=(2, 7, dim))
    expected = multivariate_normal(np.zeros(dim), cov).logpdf(r.reshape(-1, dim)).reshape(2, 7)
    np.testing.assert_allclose(gaussian_logpdf(r, cov), expected, rtol=algebra_rtol(np.linalg.cond(cov)))


def test_measurement_loglik_wraps_angle_outputs():
    model = StateSpaceModel(lambda x: x, np.eye(1), [Sensor(lambda x: x, [[0.1]], circular=(0,))], [0.0], [[1.0]])
    near_cut = measurement_loglik(model, np.array([np.pi - 0.01]), np.array([[-np.pi + 0.01]]), 1)
    direct = gaussian_logpdf(np.array([[-0.02]]), model.R)
    np.testing.assert_allclose(near_cut, direct, rtol=algebra_rtol())


def test_bad_input_raises_input_error():
    model = linear_model(np.eye(2), np.eye(2)[:1], np.eye(2), np.eye(1))
    rng = np.random.default_rng(0)
    belief = Particles.equally_weighted(np.zeros((5, 2)))
    with pytest.raises(InputError, match="y"):
        pf_step(belief, model, np.zeros(2), k=1, rng=rng)
    with pytest.raises(InputError, match="particles"):
        pf_step(Particles.equally_weighted(np.zeros((5, 3))), model, np.zeros(1), k=1, rng=rng)
    with pytest.raises(InputError, match="y"):
        pf_step(belief, model, np.array([np.nan]), k=1, rng=rng)
    with pytest.raises(InputError, match="StateSpaceModel"):
        pf_step(belief, object(), np.zeros(1), k=1, rng=rng)
    with pytest.raises(InputError, match="sqrt_covs"):
        upf_step(belief, model, np.zeros(1), k=1, rng=rng)
