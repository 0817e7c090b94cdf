"""The unscented particle filter against independent references: the bootstrap weights when the
proposal is the prior (exact cancellation) and 1-D quadrature of the one-step posterior under
gamma process noise. The UPF against the Kalman filter and across the bearing cut is in the shared
oracle suite (``test_filter_oracles.py``)."""

from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import quad

from gpfverify.errors import InputError
from gpfverify.filters.likelihoods import measurement_loglik
from gpfverify.filters.resampling import Particles, normalize_log_weights
from gpfverify.filters.upf import upf_step
from gpfverify.linalg import cholesky
from gpfverify.models import linear_model
from gpfverify.papers.particle_flow.pff1d_scenario import gamma_benchmark_model
from gpfverify.tolerances import QUADRATURE_RTOL, algebra_rtol, monte_carlo_atol


def test_prior_proposal_gives_the_bootstrap_weights():
    """q = p(x_k | x_{k−1}) cancels the transition density: w ∝ p(y | x) exactly."""
    gaussian = replace(gamma_benchmark_model(R=0.1), transition_logpdf=None, transition_sampler=None)
    rng = np.random.default_rng(4)
    q_factor = cholesky(gaussian.Q).factor

    def prior_proposal(belief, model_, y, *, k):
        return model_.f(belief.particles, k), np.broadcast_to(q_factor, belief.sqrt_covs.shape)

    belief = Particles.from_gaussian(np.ones(1), np.eye(1), 50, rng)
    y = np.array([1.3])
    out = upf_step(belief, gaussian, y, k=1, rng=rng, proposal=prior_proposal, resample_threshold=0.0).posterior
    expected = normalize_log_weights(belief.log_weights + measurement_loglik(gaussian, y, out.particles, 1))
    np.testing.assert_allclose(out.log_weights, expected, rtol=algebra_rtol(), atol=algebra_rtol())


def test_upf_weights_gamma_process_noise_exactly():
    """One UPF step from a single previous state x₀ under Γ(3, 2) noise: the self-normalised
    estimate of E[x₁ | y₁] agrees with 1-D quadrature of p(x₁ | x₀) p(y₁ | x₁)."""
    model = gamma_benchmark_model(R=0.5)
    x0, y, k = np.array([1.0]), np.array([1.2]), 1
    drift = model.f(x0[None, :], k)[0, 0] - 1.5  # f includes the noise mean 3/2

    def unnormalised(x):
        w = x - drift
        if w <= 0:
            return 0.0
        return w**2 * np.exp(-2.0 * w) * np.exp(-0.5 * (y[0] - 0.2 * x * x) ** 2 / 0.5)

    lo, hi = drift, drift + 30.0
    z = quad(unnormalised, lo, hi, epsabs=0, epsrel=QUADRATURE_RTOL, limit=200)[0]
    exact = quad(lambda x: x * unnormalised(x), lo, hi, epsabs=0, epsrel=QUADRATURE_RTOL, limit=200)[0] / z
    count = 200_000
    rng = np.random.default_rng(5)
    belief = Particles(np.repeat(x0[None, :], count, 0), np.zeros(count), np.full((count, 1, 1), 0.3))
    record = upf_step(belief, model, y, k=k, rng=rng, resample_threshold=0.0)
    out = record.posterior
    w = np.exp(out.log_weights)
    # delta-method standard error of a self-normalised importance-sampling mean
    se = np.sqrt(np.sum(w**2 * (out.particles[:, 0] - record.mean[0]) ** 2))
    assert abs(record.mean[0] - exact) < monte_carlo_atol(se, 1)


def test_upf_rejects_bad_input():
    model = linear_model(np.eye(2), np.eye(2)[:1], np.eye(2), np.eye(1))
    rng = np.random.default_rng(0)
    belief = Particles.from_gaussian(np.zeros(2), np.eye(2), 5, rng)
    with pytest.raises(InputError, match="y"):
        upf_step(belief, model, np.zeros(2), k=1, rng=rng)
