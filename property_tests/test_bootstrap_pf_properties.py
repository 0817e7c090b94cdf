"""The bootstrap particle filter's step against the closed-form Gaussian posterior of linear models.

* one step's weights: on a linear-Gaussian model, Bayes' rule gives, for every x,
  p(y | x) ∝ N(x; μ_e, C_e) / N(x; μ_p, C_p) with (μ_e, C_e) the Kalman posterior of any Gaussian
  prior N(μ_p, C_p) — so the normalised log weights of the propagated particles minus
  log N(x_i; μ_e, C_e) − log N(x_i; μ_p, C_p) (both evaluated here with scipy) are the same number
  for every particle, whatever the particles;
* weights across steps, without resampling: w_{i,k} ∝ w_{i,k−1} p(y_k | x_{i,k}), the previous
  weights carried, not reset; the estimate is the weighted mean and covariance of the set;
* one step from particles drawn from N(μ, C): the weighted mean is the Kalman posterior mean within
  Monte Carlo error (delta-method standard error of a self-normalised importance-sampling mean);
* the densities the weights are made of, absolutely (normalising hides a constant): log p(y | x_i),
  log p(x_i | x_prev,i) and the per-row batched Gaussian log density are scipy's multivariate normal
  log densities.
"""

import numpy as np
import scipy.stats
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import logsumexp

from gpfverify.filters.likelihoods import batched_gaussian_logpdf, measurement_loglik, transition_logpdf
from gpfverify.filters.pf import pf_step
from gpfverify.filters.resampling import Particles
from gpfverify.models import linear_model
from gpfverify.strategies import linear_gaussian_models, scaled_examples, spd_matrices
from gpfverify.strategies.matrices import float_arrays
from gpfverify.tolerances import algebra_rtol, monte_carlo_atol


def kalman_update(mu_p, C_p, H, R, y):
    """Posterior of N(mu_p, C_p) given y = H x + v, v ~ N(0, R), in information form."""
    r_inv = np.linalg.inv(R)
    C_e = np.linalg.inv(np.linalg.inv(C_p) + H.T @ r_inv @ H)
    return C_e @ (np.linalg.solve(C_p, mu_p) + H.T @ r_inv @ y), C_e


def _magnitude(x, mean, cov):
    """Size of the quadratic form (x − m)ᵀC⁻¹(x − m) as the rounding sees it: (|x| + |m|)² / λ_min."""
    size = np.abs(x) + np.abs(mean)
    return np.einsum("ni,ni->n", size, size) / np.linalg.eigvalsh(cov)[0]


def _logpdf_tol(x, mean, cov):
    """Rounding of log N(x; m, C): the quadratic form's size and |log|C|| + L log 2π, through cond(C)."""
    size = _magnitude(x, mean, cov) + abs(np.linalg.slogdet(cov)[1]) + cov.shape[0] * np.log(2 * np.pi)
    return algebra_rtol(np.linalg.cond(cov)) * (size + 1.0)


@given(model=linear_gaussian_models(max_condition=1e2), count=st.integers(1, 12), data=st.data())
def test_the_filters_log_densities_are_scipys_gaussian_log_densities(model, count, data):
    dim, size = model.F.shape[0], model.H.shape[0]
    x_prev = data.draw(float_arrays((count, dim), -3.0, 3.0), label="previous particles")
    x = data.draw(float_arrays((count, dim), -3.0, 3.0), label="particles")
    system = linear_model(model.F, model.H, model.Q, model.R)
    want = np.array([scipy.stats.multivariate_normal(model.H @ xi, model.R).logpdf(model.y) for xi in x])
    got = measurement_loglik(system, model.y, x, 1)
    tol = _logpdf_tol(np.broadcast_to(model.y, (count, size)), x @ model.H.T, model.R)
    assert np.all(np.abs(got - want) <= tol), (got, want, tol)
    want = np.array([scipy.stats.multivariate_normal(model.F @ xp, model.Q).logpdf(xi) for xp, xi in zip(x_prev, x)])
    got = transition_logpdf(system, x, x_prev, 1)
    tol = _logpdf_tol(x, x_prev @ model.F.T, model.Q)
    assert np.all(np.abs(got - want) <= tol), (got, want, tol)
    covs = [data.draw(spd_matrices(size, 1e2), label=f"C_{i}") for i in range(count)]
    residuals = data.draw(float_arrays((count, size), -3.0, 3.0), label="residuals")
    want = np.array([scipy.stats.multivariate_normal(np.zeros(size), c).logpdf(r) for r, c in zip(residuals, covs)])
    got = batched_gaussian_logpdf(residuals, np.array(covs), "C")
    tol = np.array([_logpdf_tol(r[None], np.zeros((1, size)), c)[0] for r, c in zip(residuals, covs)])
    assert np.all(np.abs(got - want) <= tol), (got, want, tol)


@given(model=linear_gaussian_models(max_condition=1e2), count=st.integers(2, 30), seed=st.integers(0, 2**32 - 1),
       data=st.data())
def test_pf_weights_are_the_ratio_of_the_gaussian_posterior_to_the_prior(model, count, seed, data):
    dim = model.F.shape[0]
    particles = data.draw(float_arrays((count, dim), -3.0, 3.0), label="particles")
    system = linear_model(model.F, model.H, model.Q, model.R)
    step = pf_step(Particles.equally_weighted(particles), system, model.y, rng=np.random.default_rng(seed),
                   resample_threshold=0.0)
    x = step.weighted.particles
    mu_e, C_e = kalman_update(model.prior.mean, model.prior.cov, model.H, model.R, model.y)
    ratio = (scipy.stats.multivariate_normal(mu_e, C_e).logpdf(x)
             - scipy.stats.multivariate_normal(model.prior.mean, model.prior.cov).logpdf(x))
    offset = step.weighted.log_weights - np.atleast_1d(ratio)
    cond = np.linalg.cond(model.prior.cov) * np.linalg.cond(C_e) * np.linalg.cond(model.R)
    magnitude = (_magnitude(x, mu_e[None], C_e) + _magnitude(x, model.prior.mean[None], model.prior.cov)
                 + _magnitude(np.broadcast_to(model.y, (count, model.y.size)), x @ model.H.T, model.R))
    tol = algebra_rtol(cond) * (magnitude + 1.0)
    assert np.ptp(offset) <= 2 * tol.max(), (offset, tol)


@given(model=linear_gaussian_models(max_condition=1e2), count=st.integers(2, 20), steps=st.integers(1, 4),
       seed=st.integers(0, 2**32 - 1), data=st.data())
def test_pf_weights_across_steps_are_the_accumulated_likelihoods(model, count, steps, seed, data):
    dim, size = model.F.shape[0], model.y.size
    particles = data.draw(float_arrays((count, dim), -3.0, 3.0), label="particles")
    log_w = data.draw(float_arrays((count,), -3.0, 0.0), label="log weights")
    ys = data.draw(float_arrays((steps, size), -5.0, 5.0), label="measurements")
    system = linear_model(model.F, model.H, model.Q, model.R)
    rng = np.random.default_rng(seed)
    belief = Particles(particles, log_w)
    want = log_w - logsumexp(log_w)
    likelihood = scipy.stats.multivariate_normal(np.zeros(size), model.R)
    for k, y in enumerate(ys, start=1):
        step = pf_step(belief, system, y, k=k, rng=rng, resample_threshold=0.0)
        assert not step.resampled
        x = step.weighted.particles
        loglik = np.atleast_1d(likelihood.logpdf(y - x @ model.H.T))
        want = want + loglik
        want -= logsumexp(want)
        magnitude = _magnitude(np.broadcast_to(y, (count, size)), x @ model.H.T, model.R)
        tol = algebra_rtol(np.linalg.cond(model.R)) * (np.abs(want).max() + magnitude.max() + 1.0) * k
        np.testing.assert_allclose(step.weighted.log_weights, want, rtol=0, atol=2 * tol, err_msg=f"step {k}")
        w = np.exp(want)
        mean = w @ x
        cov = (x - mean).T @ ((x - mean) * w[:, None])
        scale = np.abs(x).max() + 1.0
        np.testing.assert_allclose(step.mean, mean, rtol=0, atol=tol * scale)
        np.testing.assert_allclose(step.cov, cov, rtol=0, atol=tol * scale**2)
        belief = step.posterior


@settings(max_examples=scaled_examples(0.25))
@given(model=linear_gaussian_models(max_condition=1e2), seed=st.integers(0, 2**32 - 1), data=st.data())
def test_pf_estimate_is_the_kalman_posterior_mean_within_monte_carlo_error(model, seed, data):
    """The particles are draws of N(μ, C) propagated, so the target is the posterior of the prior
    predictive N(F μ, F C Fᵀ + Q). The likelihood is made no sharper than that predictive (R ⪰ H C_p Hᵀ)
    and y lies within two of its standard deviations per whitened axis, so the effective sample size
    stays a fair fraction of the 4000 particles and the delta-method standard error holds."""
    count = 4000
    rng = np.random.default_rng(seed)
    mu_p = model.F @ model.prior.mean
    C_p = model.F @ model.prior.cov @ model.F.T + model.Q
    R = model.R + model.H @ C_p @ model.H.T
    S = model.H @ C_p @ model.H.T + R
    y = model.H @ mu_p + np.linalg.cholesky(S) @ data.draw(float_arrays((model.y.size,), -2.0, 2.0), label="z")
    system = linear_model(model.F, model.H, model.Q, R)
    belief = Particles.from_gaussian(model.prior.mean, model.prior.cov, count, rng)
    step = pf_step(belief, system, y, rng=rng, resample_threshold=0.0)
    exact, _ = kalman_update(mu_p, C_p, model.H, R, y)
    w = np.exp(step.weighted.log_weights)
    se = np.sqrt(np.einsum("n,ni->i", w**2, (step.weighted.particles - step.mean) ** 2))
    assert np.all(np.abs(step.mean - exact) <= monte_carlo_atol(se, 1)), (step.mean, exact, se)
