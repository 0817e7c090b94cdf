"""predict_uncertain against three oracles: Gauss–Hermite quadrature (tight), Monte Carlo
(statistical) and the deterministic prediction as Σ → 0."""

import numpy as np
import pytest

from gpfverify.gp import GaussianProcess
from gpfverify.gp.reference import monte_carlo_moments, quadrature_moments
from gpfverify.tolerances import QUADRATURE_RTOL, algebra_rtol, monte_carlo_atol

#: every test here runs on the fused kernel (numba) and on the numpy reference path
pytestmark = pytest.mark.usefixtures("moment_path")

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


def test_near_linear_regime_with_large_outputs_matches_quadrature():
    """A GP fitted to a rotation of states far from the origin (the constant-turn experiment):
    lengthscales of thousands, signal variance of millions, outputs ~100. Q's entries are ~α⁴ =
    2e13 while the covariance is ~3; the formula evaluated without centring gave an eigenvalue of
    −2 here (quadrature: all positive)."""
    rng = np.random.default_rng(126)
    x = rng.uniform(-50, 150, size=(300, 2))
    turn = np.array([[np.cos(0.5), -np.sin(0.5)], [np.sin(0.5), np.cos(0.5)]])
    y = x @ turn.T + np.sqrt(5.0) * rng.standard_normal((300, 2))
    gp = GaussianProcess(x, y, lengthscales=[[3728.0, 5590.0], [3643.0, 2912.0]],
                         signal_var=[4.5e6, 2.4e6], noise_var=[4.3, 5.2])
    mu, sigma = np.array([23.2, 108.5]), np.array([[2.0, 1.9], [1.9, 4.2]])
    mm = gp.predict_uncertain(mu, sigma)
    ref = quadrature_moments(gp, mu, sigma, order=40)
    scale = np.abs(ref.cov).max()
    np.testing.assert_allclose(mm.cov, ref.cov, rtol=QUADRATURE_RTOL, atol=QUADRATURE_RTOL * scale)
    np.testing.assert_allclose(mm.mean, ref.mean, rtol=QUADRATURE_RTOL)
    assert np.linalg.eigvalsh(mm.cov).min() > 0


def test_input_far_wider_than_the_lengthscales_matches_monte_carlo(monkeypatch):
    """Σ ≫ ℓ² with training points far in the input's tail (ν²/2Σ > 700): exp(d_ii) overflows
    where q_a q_b underflows; the log-space branch must be taken and agree with Monte Carlo."""
    import gpfverify.gp.moments as moments

    rng = np.random.default_rng(9)
    x = np.concatenate([rng.uniform(-10, 10, size=(30, 1)), rng.uniform(250, 400, size=(30, 1))])
    gp = GaussianProcess(x, np.sin(3 * x[:, 0]), lengthscales=[[0.5]], signal_var=[1.0], noise_var=[0.01])
    mu, sigma = np.array([0.5]), np.array([[30.0]])
    calls = []
    original = moments._log_space_centred

    def spy(*args):
        calls.append(args)
        return original(*args)

    monkeypatch.setattr(moments, "_log_space_centred", spy)
    mm = gp.predict_uncertain(mu, sigma)
    assert len(calls) == 1
    est, se = monte_carlo_moments(gp, mu, sigma, 200_000, np.random.default_rng(2))
    for name in ("mean", "cov", "cross_cov"):
        diff = np.abs(getattr(mm, name) - getattr(est, name))
        assert np.all(diff <= monte_carlo_atol(getattr(se, name) * np.sqrt(200_000), 200_000) + 1e-12), name
    assert mm.cov[0, 0] > 0
