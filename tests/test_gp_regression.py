"""GaussianProcess.predict / log_marginal_likelihood / fit against scikit-learn."""

import numpy as np
import pytest
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

from gpfverify.errors import InputError
from gpfverify.gp import GaussianProcess
from gpfverify.tolerances import algebra_rtol


def _data(seed, n=40, d=2, e=3):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-3, 3, size=(n, d))
    y = np.stack([np.sin(x @ rng.normal(size=d)) + 0.1 * rng.normal(size=n) for _ in range(e)], 1)
    ell = rng.uniform(0.5, 2.0, size=(e, d))
    return x, y, ell, rng.uniform(0.5, 2.0, size=e), rng.uniform(0.01, 0.2, size=e)


def _sklearn(x, y, ell, s2, n2):
    kernel = ConstantKernel(s2, "fixed") * RBF(ell, "fixed") + WhiteKernel(n2, "fixed")
    return GaussianProcessRegressor(kernel, optimizer=None, alpha=0.0).fit(x, y)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_predict_and_evidence_equal_sklearn(seed):
    x, y, ell, s2, n2 = _data(seed)
    gp = GaussianProcess(x, y, lengthscales=ell, signal_var=s2, noise_var=n2)
    xs = np.random.default_rng(seed + 10).uniform(-4, 4, size=(25, x.shape[1]))
    mean, var = gp.predict(xs)
    cond = max(np.linalg.cond(k) for k in np.linalg.inv(gp.K_inv))
    tol = algebra_rtol(cond)
    lml = 0.0
    for a in range(y.shape[1]):
        sk = _sklearn(x, y[:, a], ell[a], s2[a], n2[a])
        m_sk, sd_sk = sk.predict(xs, return_std=True)
        # sklearn's std includes the white-noise kernel at test points: remove it
        np.testing.assert_allclose(mean[:, a], m_sk, rtol=tol, atol=tol * np.abs(y).max())
        np.testing.assert_allclose(var[:, a] + n2[a], sd_sk**2, rtol=tol, atol=tol * s2[a])
        lml += sk.log_marginal_likelihood_value_
    assert gp.log_marginal_likelihood() == pytest.approx(lml, rel=tol)


def test_one_dimensional_targets_and_shapes():
    x, y, ell, s2, n2 = _data(3, e=1)
    gp = GaussianProcess(x, y[:, 0], lengthscales=ell[0], signal_var=s2[0], noise_var=n2[0])
    mean, var = gp.predict(x[:4])
    assert mean.shape == (4, 1) and var.shape == (4, 1)
    assert gp.lengthscales.shape == (1, 2)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_fit_at_least_as_good_as_sklearn(seed):
    x, y, *_ = _data(seed, n=60, d=2, e=1)
    gp = GaussianProcess.fit(x, y[:, 0], restarts=3, seed=seed)
    kernel = ConstantKernel(1.0, (1e-5, 1e5)) * RBF([1.0, 1.0], (1e-5, 1e5)) + WhiteKernel(0.1, (1e-8, 1e5))
    sk = GaussianProcessRegressor(kernel, n_restarts_optimizer=3, random_state=seed).fit(x, y[:, 0])
    # our optimum may only be better, up to the optimiser's stopping accuracy
    assert gp.log_marginal_likelihood() >= sk.log_marginal_likelihood_value_ - 1e-3 * abs(
        sk.log_marginal_likelihood_value_)


def test_fit_is_deterministic_for_a_seed():
    x, y, *_ = _data(5, n=30, d=2, e=2)
    a = GaussianProcess.fit(x, y, restarts=2, seed=7)
    b = GaussianProcess.fit(x, y, restarts=2, seed=7)
    np.testing.assert_array_equal(a.lengthscales, b.lengthscales)
    np.testing.assert_array_equal(a.noise_var, b.noise_var)


def test_evidence_gradient_matches_finite_differences():
    from gpfverify.gp.regression import _neg_log_evidence

    x, y, *_ = _data(6, n=25, d=2, e=1)
    sq = (x[:, None, :] - x[None, :, :]) ** 2
    theta = np.log(np.array([0.8, 1.3, 1.1, 0.05]))
    _, grad = _neg_log_evidence(theta, x, y[:, 0], sq)
    h = 1e-6
    fd = np.array([(_neg_log_evidence(theta + h * e_i, x, y[:, 0], sq)[0]
                    - _neg_log_evidence(theta - h * e_i, x, y[:, 0], sq)[0]) / (2 * h)
                   for e_i in np.eye(theta.size)])
    # central differences: truncation O(h²) and rounding O(eps·f/h) ~ 1e-8 relative
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-6)


def _plain_neg_log_evidence(theta, x, y, sq_diff):
    """The evidence and its gradient as the formulas read (a full K⁻¹ from the factor), for the
    bit-for-bit comparison below."""
    from gpfverify.linalg import cholesky

    d = x.shape[1]
    ell2 = np.exp(2.0 * theta[:d])
    signal, noise = np.exp(theta[d]), np.exp(theta[d + 1])
    kf = signal * np.exp(-0.5 * sq_diff @ (1.0 / ell2))
    try:
        chol = cholesky(kf + noise * np.eye(len(y)), "K", allow_jitter=False)
    except Exception:
        return 1e25, np.zeros_like(theta)
    beta = chol.solve(y)
    nll = 0.5 * float(y @ beta) + 0.5 * chol.logdet() + 0.5 * len(y) * np.log(2.0 * np.pi)
    w = np.outer(beta, beta) - chol.inverse()
    wk = w * kf
    grad = np.empty_like(theta)
    grad[:d] = -0.5 * np.einsum("ij,ijd->d", wk, sq_diff) / ell2
    grad[d] = -0.5 * float(np.sum(wk))
    grad[d + 1] = -0.5 * noise * float(np.trace(w))
    return nll, grad


@pytest.mark.parametrize("n, d", [(2, 1), (30, 1), (200, 1), (25, 2), (30, 3)])
def test_evidence_is_the_plain_formulas_to_the_bit(n, d):
    """The in-place evaluation the optimiser calls returns the bits of the plain formulas (so every
    fit takes the same L-BFGS path), at random log parameters, including ones where K is not
    positive definite in floating point (the 1e25 wall)."""
    from gpfverify.gp.regression import _neg_log_evidence

    rng = np.random.default_rng(n + d)
    x = rng.uniform(-3, 3, size=(n, d))
    y = np.sin(x.sum(axis=1)) + 0.1 * rng.normal(size=n)
    sq = (x[:, None, :] - x[None, :, :]) ** 2
    thetas = [rng.normal(size=d + 2) * 2.0 for _ in range(40)] + [np.r_[np.full(d, 20.0), 0.0, -60.0]]
    walls = 0
    for theta in thetas:
        value, grad = _neg_log_evidence(theta, x, y, sq)
        ref_value, ref_grad = _plain_neg_log_evidence(theta, x, y, sq)
        assert value == ref_value
        np.testing.assert_array_equal(grad, ref_grad)
        walls += value == 1e25
    assert walls  # the wall is among the cases


def test_fit_keeps_noise_away_from_zero_on_noise_free_data():
    x = np.linspace(-3, 3, 30)[:, None]
    gp = GaussianProcess.fit(x, np.sin(x[:, 0]), restarts=2, seed=0)
    power = np.mean(np.sin(x[:, 0]) ** 2)
    assert gp.noise_var[0] >= 1e-8 * power * (1 - 1e-12)
    assert gp.lengthscales[0, 0] <= 100 * np.ptp(x) * (1 + 1e-12)


@pytest.mark.parametrize("kwargs, match", [
    (dict(X=np.ones((3, 2)), Y=np.ones(4)), "Y"),
    (dict(X=np.array([[np.nan, 1.0]]), Y=np.ones(1)), "X"),
    (dict(X=np.ones((3, 2)), Y=np.ones(3), lengthscales=[[1.0, -1.0]]), "lengthscales"),
    (dict(X=np.ones((3, 2)), Y=np.ones(3), lengthscales=[[1.0, 1.0, 1.0]]), "lengthscales"),
    (dict(X=np.ones((3, 2)), Y=np.ones(3), signal_var=[0.0]), "signal_var"),
    (dict(X=np.ones((3, 2)), Y=np.ones(3), noise_var=[np.inf]), "noise_var"),
])
def test_bad_input_raises_input_error_naming_the_argument(kwargs, match):
    args = dict(lengthscales=[[1.0, 1.0]], signal_var=[1.0], noise_var=[0.1]) | kwargs
    with pytest.raises(InputError, match=match):
        GaussianProcess(**args)


def test_predict_uncertain_rejects_bad_mu_and_sigma():
    x, y, ell, s2, n2 = _data(0)
    gp = GaussianProcess(x, y, lengthscales=ell, signal_var=s2, noise_var=n2)
    with pytest.raises(InputError, match="mu"):
        gp.predict_uncertain(np.zeros(3), np.eye(2))
    with pytest.raises(InputError, match="Sigma"):
        gp.predict_uncertain(np.zeros(2), np.array([[1.0, 0.5], [0.0, 1.0]]))
    with pytest.raises(InputError, match="Sigma"):
        gp.predict_uncertain(np.zeros(2), np.array([[1.0, 2.0], [2.0, 1.0]]))
    with pytest.raises(InputError, match="Sigma"):
        gp.predict_uncertain(np.zeros(2), np.array([[np.nan, 0.0], [0.0, 1.0]]))
