"""SR-UKF against the covariance-form UKF (same sigma points, redrawn after the prediction), the
exact KF on a linear model, and the rank-one factor updates against explicit Cholesky factors."""

import numpy as np
import pytest

from gpfverify.errors import NumericalError
from gpfverify.filters.kalman import kf_step
from gpfverify.filters.records import Gaussian
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.filters import sr_ukf
from gpfverify.filters.sr_ukf import (SqrtGaussian, cholupdate, noise_sqrt, qr_factor, rank_one_series,
                                      sr_ukf_step)
from gpfverify.filters.ukf import ukf_step
from gpfverify.models import Sensor, StateSpaceModel, linear_model
from gpfverify.tolerances import algebra_rtol


def _spd(rng, dim, batch=()):
    a = rng.normal(size=batch + (dim, dim))
    return a @ np.swapaxes(a, -1, -2) / dim + 0.3 * np.eye(dim)


def _close(a, b, cond):
    tol = algebra_rtol(cond)
    np.testing.assert_allclose(a, b, rtol=tol, atol=tol * max(1.0, float(np.abs(b).max())))


def test_qr_factor_is_the_cholesky_factor_of_a_at():
    rng = np.random.default_rng(0)
    cols = rng.normal(size=(5, 4, 9))
    s = qr_factor(cols)
    expected = np.linalg.cholesky(cols @ np.swapaxes(cols, -1, -2))
    _close(s, expected, np.linalg.cond(expected).max() ** 2)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_cholupdate_matches_explicit_factor_batched(sign):
    rng = np.random.default_rng(1)
    cov = _spd(rng, 6, (7,))
    lower = np.linalg.cholesky(cov)
    x = 0.15 * rng.normal(size=(7, 6))
    target = cov + sign * x[:, :, None] * x[:, None, :]
    assert np.all(np.linalg.eigvalsh(target)[:, 0] > 0)
    new, failed = cholupdate(lower, x, sign)
    assert not failed.any()
    _close(new, np.linalg.cholesky(target), np.linalg.cond(target).max())


@pytest.mark.skipif(not sr_ukf.compiled, reason="the compiled loop needs numba (the fast extra)")
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_compiled_cholupdate_agrees_with_the_numpy_loop(sign, monkeypatch):
    """The compiled loop against the numpy loop, for a batch, a single factor and a Fortran-ordered
    one: the same factors to the rounding of the update (a compiler may contract or reorder the
    floating-point operations, so not to the bit) and the same failed downdates flagged."""
    rng = np.random.default_rng(4)
    lower = np.linalg.cholesky(_spd(rng, 6, (9,)))
    x = 0.4 * rng.normal(size=(9, 6))
    x[3] = 3.0 * lower[3] @ np.ones(6)  # a downdate of this one fails
    for args in ((lower, x), (lower[0], x[0]), (np.asfortranarray(lower[1]), x[1])):
        monkeypatch.setattr(sr_ukf, "compiled", True)
        fast = cholupdate(*args, sign)
        monkeypatch.setattr(sr_ukf, "compiled", False)
        reference = cholupdate(*args, sign)
        np.testing.assert_array_equal(fast[1], reference[1])
        kept = ~np.asarray(reference[1])  # a failed downdate's entries are not meaningful
        _close(np.asarray(fast[0])[kept], np.asarray(reference[0])[kept], np.linalg.cond(args[0]).max())


def test_failed_downdate_is_flagged_not_kept():
    rng = np.random.default_rng(2)
    lower = np.linalg.cholesky(_spd(rng, 4, (3,)))
    x = np.zeros((3, 4))
    x[1] = 3.0 * lower[1] @ np.ones(4)  # entry 1: LLᵀ − xxᵀ is indefinite
    _, failed = cholupdate(lower, x, -1.0)
    assert failed.tolist() == [False, True, False]
    with pytest.raises(NumericalError, match="test downdate"):
        rank_one_series(lower, x[..., None], -1.0, "test downdate")


def test_downdate_to_a_singular_matrix_is_recomputed_with_reported_jitter():
    rng = np.random.default_rng(3)
    cov = _spd(rng, 4)
    lower = np.linalg.cholesky(cov)
    x = lower[:, 0].copy()  # LLᵀ − xxᵀ is PSD of rank 3: the first pivot is exactly 0
    new, jitter = rank_one_series(lower, x[:, None], -1.0, "singular downdate")
    assert jitter > 0
    target = cov - np.outer(x, x)
    # a Cholesky factor reproduces its matrix to O(eps ‖A‖) whatever the conditioning (backward stability)
    np.testing.assert_allclose(new @ new.T, target + jitter * np.eye(4), atol=algebra_rtol() * np.abs(cov).max())


def test_noise_sqrt_of_singular_covariance():
    q = np.diag([1.0, 0.0, 2.0])
    root = noise_sqrt(q)
    np.testing.assert_allclose(root @ root.T, q, atol=algebra_rtol())


def _nonlinear_model(rng, dim=3, meas=2):
    a = 0.9 * np.linalg.qr(rng.normal(size=(dim, dim)))[0]
    c = rng.normal(size=(meas, dim))

    def f(x, k):
        return x @ a.T + 0.2 * np.sin(x) + 0.05 * k

    def h(x, k):
        return np.tanh(x @ c.T) + 0.1 * x[:, :meas] ** 2

    return StateSpaceModel(f, 0.1 * _spd(rng, dim), [Sensor(h, 0.05 * _spd(rng, meas))], np.zeros(dim), np.eye(dim))


@pytest.mark.parametrize("params", [SigmaParams(), SigmaParams(1.0, 2.0, -1.0),
                                    SigmaParams(0.5, 2.0, 0.0), SigmaParams(1.0, 2.0, 0.5)],
                         ids=["default", "negative-wm0", "alpha0.5-negative-wm0-wc0", "beta2"])
def test_sr_ukf_equals_ukf_over_many_steps_batched(params):
    rng = np.random.default_rng(4)
    model = _nonlinear_model(rng)
    batch = 5
    mean = rng.normal(size=(batch, 3))
    cov = _spd(rng, 3, (batch,))
    ukf_belief = Gaussian(mean, cov)
    sr_belief = SqrtGaussian(mean, np.linalg.cholesky(cov))
    for k in range(12):
        y = rng.normal(size=(batch, 2))
        ref = ukf_step(ukf_belief, model, y, k=k, params=params)
        sr = sr_ukf_step(sr_belief, model, y, k=k, params=params)
        out = sr.to_record()
        cond = float(np.linalg.cond(ref.C_e).max() * np.linalg.cond(ref.C_y).max())
        for name in ("mu_p", "C_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e"):
            _close(getattr(out, name), getattr(ref, name), cond)
        assert sr.jitter == 0.0
        ukf_belief, sr_belief = ref.posterior, sr.posterior


def test_indefinite_ukf_covariance_raises_instead_of_a_wrong_factor():
    """With w_0 = −1/2 and w_c0 = −1/2 the UKF's own posterior covariance is indefinite on this model
    (checked through the UKF): the SR-UKF must refuse, not return a factor of something else."""
    rng = np.random.default_rng(4)
    model = _nonlinear_model(rng)
    params = SigmaParams(1.0, 0.0, -1.0)
    mean, cov = rng.normal(size=(5, 3)), _spd(rng, 3, (5,))
    y = rng.normal(size=(5, 2))
    ref = ukf_step(Gaussian(mean, cov), model, y, k=0, params=params)
    assert np.linalg.eigvalsh(ref.C_e)[:, 0].min() < 0
    with pytest.raises(NumericalError, match="posterior covariance"):
        sr_ukf_step(SqrtGaussian(mean, np.linalg.cholesky(cov)), model, y, k=0, params=params)


def test_sr_ukf_equals_kf_on_linear_model():
    rng = np.random.default_rng(5)
    F = 0.95 * np.linalg.qr(rng.normal(size=(4, 4)))[0]
    H = rng.normal(size=(2, 4))
    Q, R = 0.2 * _spd(rng, 4), 0.1 * _spd(rng, 2)
    model = linear_model(F, H, Q, R)
    mean, cov = rng.normal(size=4), _spd(rng, 4)
    kf = Gaussian(mean, cov)
    sr = SqrtGaussian(mean, np.linalg.cholesky(cov))
    for k in range(20):
        y = rng.normal(size=2)
        ref = kf_step(kf, model, y, k=k)
        rec = sr_ukf_step(sr, model, y, k=k)
        out = rec.to_record()
        _close(out.mu_e, ref.mu_e, np.linalg.cond(ref.C_e) * np.linalg.cond(ref.C_y))
        _close(out.C_e, ref.C_e, np.linalg.cond(ref.C_e) * np.linalg.cond(ref.C_y))
        kf, sr = ref.posterior, rec.posterior
