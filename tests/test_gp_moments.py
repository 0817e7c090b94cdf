"""predict_uncertain against three oracles: Gauss–Hermite quadrature (tight), Monte Carlo
(statistical) and the deterministic prediction as Σ → 0."""

import numpy as np
import pytest

from gpfverify.gp import GaussianProcess
from gpfverify.gp.reference import monte_carlo_moments, quadrature_moments
from gpfverify.tolerances import QUADRATURE_RTOL, algebra_rtol, monte_carlo_atol

ORDER = {1: 80, 2: 40, 3: 24}


def _gp(seed, d, e, n=30):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-2, 2, size=(n, d))
    y = np.stack([np.cos(x @ rng.normal(size=d)) + x[:, 0] * (a + 1) / e for a in range(e)], 1)
    return GaussianProcess(x, y, lengthscales=rng.uniform(0.7, 2.0, size=(e, d)),
                           signal_var=rng.uniform(0.5, 2.0, size=e),
                           noise_var=rng.uniform(0.01, 0.1, size=e)), rng


def _correlated_sigma(rng, d, scale=0.3):
    a = rng.normal(size=(d, d))
    return scale * (a @ a.T / d + 0.2 * np.eye(d))


@pytest.mark.parametrize("d", [1, 2, 3])
@pytest.mark.parametrize("e", [1, 2, 3, 4])
def test_matches_gauss_hermite_quadrature(d, e):
    gp, rng = _gp(10 * d + e, d, e)
    mu, sigma = rng.uniform(-1, 1, size=d), _correlated_sigma(rng, d)
    mm = gp.predict_uncertain(mu, sigma)
    ref = quadrature_moments(gp, mu, sigma, order=ORDER[d])
    scale = np.abs(ref.cov).max()
    np.testing.assert_allclose(mm.mean, ref.mean, rtol=QUADRATURE_RTOL, atol=QUADRATURE_RTOL * scale)
    np.testing.assert_allclose(mm.cov, ref.cov, rtol=QUADRATURE_RTOL, atol=QUADRATURE_RTOL * scale)
    np.testing.assert_allclose(mm.cross_cov, ref.cross_cov, rtol=QUADRATURE_RTOL,
                               atol=QUADRATURE_RTOL * np.sqrt(scale * np.abs(sigma).max()))


def test_model_uncertainty_term_is_included():
    """Far from the data the latent variance returns to α²: an RBF network would give ~0."""
    gp, rng = _gp(1, 1, 1)
    mm = gp.predict_uncertain(np.array([40.0]), np.array([[0.1]]))
    assert mm.cov[0, 0] == pytest.approx(gp.signal_var[0], rel=1e-9)


@pytest.mark.parametrize("d, e", [(2, 3), (3, 2)])
def test_matches_monte_carlo(d, e):
    gp, rng = _gp(d * 7 + e, d, e)
    mu, sigma = rng.uniform(-1, 1, size=d), _correlated_sigma(rng, d, 0.5)
    mm = gp.predict_uncertain(mu, sigma)
    est, se = monte_carlo_moments(gp, mu, sigma, 100_000, np.random.default_rng(3))
    for name in ("mean", "cov", "cross_cov"):
        diff = np.abs(getattr(mm, name) - getattr(est, name))
        # k standard errors, computed from the sample (plus rounding for exact-zero entries)
        assert np.all(diff <= monte_carlo_atol(getattr(se, name) * np.sqrt(100_000), 100_000) + 1e-12), name


@pytest.mark.parametrize("d, e", [(1, 1), (2, 4), (3, 2)])
def test_tends_to_deterministic_prediction(d, e):
    gp, rng = _gp(d + e, d, e)
    mu = rng.uniform(-1, 1, size=d)
    mean, var = gp.predict(mu[None, :])
    exact = gp.predict_uncertain(mu, np.zeros((d, d)))
    tol = algebra_rtol(np.linalg.cond(np.linalg.inv(gp.K_inv[0])))
    np.testing.assert_allclose(exact.mean, mean[0], rtol=tol, atol=tol)
    np.testing.assert_allclose(exact.cov, np.diag(var[0]), rtol=tol, atol=tol * gp.signal_var.max())
    np.testing.assert_array_equal(exact.cross_cov, 0.0)
    small = gp.predict_uncertain(mu, 1e-8 * np.eye(d))
    np.testing.assert_allclose(small.mean, mean[0], atol=1e-6)
    np.testing.assert_allclose(small.cov, np.diag(var[0]), atol=1e-6)


def test_singular_sigma_matches_quadrature():
    gp, rng = _gp(4, 2, 2)
    v = np.array([1.0, 0.5])
    sigma = 0.4 * np.outer(v, v)  # rank one
    mm = gp.predict_uncertain(np.zeros(2), sigma)
    ref = quadrature_moments(gp, np.zeros(2), sigma, order=40)
    np.testing.assert_allclose(mm.cov, ref.cov, rtol=QUADRATURE_RTOL, atol=QUADRATURE_RTOL)
    np.testing.assert_allclose(mm.mean, ref.mean, rtol=QUADRATURE_RTOL, atol=QUADRATURE_RTOL)


@pytest.mark.parametrize("seed", range(5))
def test_covariance_is_symmetric_psd(seed):
    gp, rng = _gp(seed, 2, 4)
    mm = gp.predict_uncertain(rng.uniform(-3, 3, size=2), _correlated_sigma(rng, 2, 2.0))
    np.testing.assert_array_equal(mm.cov, mm.cov.T)
    assert np.linalg.eigvalsh(mm.cov).min() >= -algebra_rtol() * np.abs(mm.cov).max()
