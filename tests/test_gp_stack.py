"""GaussianProcessStack: joint moments of sensors' GPs with separate training sets."""

import numpy as np
import pytest

from gpfverify.errors import InputError
from gpfverify.gp import GaussianProcess, GaussianProcessStack
from gpfverify.gp.reference import monte_carlo_moments, quadrature_moments
from gpfverify.tolerances import QUADRATURE_RTOL, algebra_rtol, monte_carlo_atol


def _gp(rng, n, d, e):
    x = rng.uniform(-2, 2, size=(n, d))
    y = np.stack([np.sin(x @ rng.normal(size=d)) + 0.3 * x[:, 0] for _ in range(e)], 1)
    return GaussianProcess(x, y, lengthscales=rng.uniform(0.7, 2.0, size=(e, d)),
                           signal_var=rng.uniform(0.5, 2.0, size=e), noise_var=rng.uniform(0.01, 0.1, size=e))


@pytest.mark.parametrize("d, sizes", [(1, (1, 1)), (2, (2, 1)), (2, (1, 2, 2)), (3, (2, 2))])
def test_stack_matches_quadrature_with_cross_sensor_blocks(d, sizes):
    rng = np.random.default_rng(d * 10 + len(sizes))
    stack = GaussianProcessStack([_gp(rng, 20 + 5 * i, d, e) for i, e in enumerate(sizes)])
    # correlated Σ with eigenvalues in [0.05, 0.4]: narrow enough against ℓ ≥ 0.7 for the
    # tensor rule to converge to ~1e-9 (wider inputs need far more nodes in 3-D)
    rotation, _ = np.linalg.qr(rng.normal(size=(d, d)))
    mu, sigma = rng.uniform(-1, 1, size=d), rotation @ np.diag(rng.uniform(0.05, 0.4, d)) @ rotation.T
    mm = stack.predict_uncertain(mu, sigma)
    ref = quadrature_moments(stack, mu, sigma, order={1: 80, 2: 40, 3: 30}[d])
    scale = np.abs(ref.cov).max()
    assert mm.cov.shape == (sum(sizes), sum(sizes)) and mm.cross_cov.shape == (d, sum(sizes))
    np.testing.assert_allclose(mm.mean, ref.mean, rtol=QUADRATURE_RTOL, atol=QUADRATURE_RTOL * scale)
    np.testing.assert_allclose(mm.cov, ref.cov, rtol=QUADRATURE_RTOL, atol=QUADRATURE_RTOL * scale)
    np.testing.assert_allclose(mm.cross_cov, ref.cross_cov, rtol=QUADRATURE_RTOL, atol=QUADRATURE_RTOL * scale)
    # the cross-sensor block is really there (not zero) at an uncertain input
    assert np.abs(mm.cov[: sizes[0], sizes[0]:]).max() > 1e3 * QUADRATURE_RTOL * scale


def test_stack_matches_monte_carlo():
    rng = np.random.default_rng(5)
    stack = GaussianProcessStack([_gp(rng, 25, 2, 1), _gp(rng, 30, 2, 2)])
    mu, sigma = np.array([0.2, -0.3]), np.array([[0.5, 0.2], [0.2, 0.4]])
    mm = stack.predict_uncertain(mu, sigma)
    est, se = monte_carlo_moments(stack, mu, sigma, 100_000, np.random.default_rng(1))
    for name in ("mean", "cov", "cross_cov"):
        diff = np.abs(getattr(mm, name) - getattr(est, name))
        assert np.all(diff <= monte_carlo_atol(getattr(se, name) * np.sqrt(100_000), 100_000) + 1e-12), name


def test_stack_on_shared_training_data_equals_one_multi_output_gp():
    rng = np.random.default_rng(2)
    x = rng.uniform(-2, 2, size=(30, 2))
    y = np.stack([np.sin(x[:, 0]), np.cos(x[:, 1]), x[:, 0] * x[:, 1]], 1)
    ell, s2, n2 = rng.uniform(0.7, 2, size=(3, 2)), rng.uniform(0.5, 2, 3), rng.uniform(0.01, 0.1, 3)
    joint = GaussianProcess(x, y, lengthscales=ell, signal_var=s2, noise_var=n2)
    stack = GaussianProcessStack([GaussianProcess(x, y[:, :1], ell[:1], s2[:1], n2[:1]),
                                  GaussianProcess(x, y[:, 1:], ell[1:], s2[1:], n2[1:])])
    mu, sigma = np.array([0.3, 0.1]), np.array([[0.4, 0.1], [0.1, 0.3]])
    a, b = joint.predict_uncertain(mu, sigma), stack.predict_uncertain(mu, sigma)
    tol = algebra_rtol(max(np.linalg.cond(k) for k in np.linalg.inv(joint.K_inv)))
    for name in ("mean", "cov", "cross_cov"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), rtol=tol, atol=tol)
    np.testing.assert_allclose(stack.predict(x[:5])[1], joint.predict(x[:5])[1], rtol=tol, atol=tol)
    np.testing.assert_array_equal(stack.noise_var, n2)
    assert stack.sizes == [1, 2] and stack.output_dim == 3


def test_stack_rejects_mismatched_input_dimensions():
    rng = np.random.default_rng(0)
    with pytest.raises(InputError, match="input dimension"):
        GaussianProcessStack([_gp(rng, 10, 2, 1), _gp(rng, 10, 3, 1)])
    with pytest.raises(InputError, match="at least one"):
        GaussianProcessStack([])
