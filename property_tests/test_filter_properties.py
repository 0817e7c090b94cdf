"""Gaussian filters on drawn models.

* UKF = KF on linear-Gaussian models for every valid (α, β, κ): the unscented transform of an
  affine map is exact whatever the weights, as long as Σ w_m = 1 and Σ w_c (χ − μ)(χ − μ)ᵀ = C.
  The weights can be large (w_m0 = 1 − D/(α²(D + κ)) ≈ −1e6 at α = 1e-3), and the sums then lose
  eps · Σ|w_m| of the points' size, so the tolerance is algebra_rtol(cond · Σ|w_m|);
* GP-ADF: the predicted and updated covariances C_p, C_e and the measurement covariance C_y stay
  symmetric positive semidefinite (C_y definite) for drawn GPs and beliefs.
"""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gpfverify.filters.ekf import ekf_step
from gpfverify.filters.gp_adf import gp_adf_step
from gpfverify.filters.kalman import kf_step
from gpfverify.filters.ukf import ukf_step
from gpfverify.models import GPModel, linear_model
from gpfverify.strategies import gaussian_inputs, gaussian_processes, linear_gaussian_models, sigma_params
from gpfverify.tolerances import algebra_rtol


@given(model=linear_gaussian_models(), data=st.data())
def test_ukf_equals_kf_on_linear_models(model, data):
    params = data.draw(sigma_params(model.F.shape[0]), label="sigma params")
    system = linear_model(model.F, model.H, model.Q, model.R)
    kf = kf_step(model.prior, system, model.y, k=1)
    ukf = ukf_step(model.prior, system, model.y, k=1, params=params)
    wm, _ = params.weights(model.F.shape[0])
    cond = max(np.linalg.cond(kf.C_p), np.linalg.cond(kf.C_y))
    tol = algebra_rtol(cond * np.abs(wm).sum())
    for name in ("mu_p", "C_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e"):
        want, got = getattr(kf, name), getattr(ukf, name)
        scale = max(np.abs(want).max(), np.sqrt(np.abs(kf.C_p).max() * np.abs(kf.C_y).max()),
                    np.abs(model.prior.mean).max(), np.abs(model.y).max())
        np.testing.assert_allclose(got, want, rtol=0, atol=tol * scale, err_msg=name)


@given(transition=gaussian_processes(input_dim=st.integers(1, 2), output_dim=None), data=st.data())
def test_gp_adf_covariances_stay_psd(transition, data):
    d = transition.input_dim
    measurement = data.draw(gaussian_processes(input_dim=d, output_dim=st.integers(1, 3)), label="h GP")
    prior = data.draw(gaussian_inputs(d, max_variance=4.0), label="belief")
    y = data.draw(st.lists(st.floats(-3, 3), min_size=measurement.output_dim,
                           max_size=measurement.output_dim), label="y")
    record = gp_adf_step(prior, GPModel(transition, [measurement]), np.array(y), k=1)
    for name in ("C_p", "C_y", "C_e"):
        cov = getattr(record, name)
        np.testing.assert_array_equal(cov, cov.T, err_msg=name)
        assert np.linalg.eigvalsh(cov)[0] >= -algebra_rtol(np.linalg.cond(record.C_y)) * np.abs(cov).max(), name
    assert np.linalg.eigvalsh(record.C_y)[0] > 0


@pytest.mark.parametrize("step", [kf_step, ekf_step, ukf_step], ids=["KF", "EKF", "UKF"])
@given(model=linear_gaussian_models())
def test_gaussian_filters_equal_the_information_form_on_linear_models(step, model):
    """KF, EKF and UKF (default sigma points) on a linear-Gaussian model against the information
    form of the exact posterior, written here independently of the shared Gaussian update:
    C_p = F C Fᵀ + Q, C_e = (C_p⁻¹ + HᵀR⁻¹H)⁻¹, μ_e = C_e (C_p⁻¹ F μ + HᵀR⁻¹ y)."""
    system = linear_model(model.F, model.H, model.Q, model.R)
    kf = step(model.prior, system, model.y, k=1)
    np.testing.assert_allclose(kf.C_p, model.F @ model.prior.cov @ model.F.T + model.Q, rtol=0,
                               atol=algebra_rtol(np.linalg.cond(model.prior.cov)) * np.abs(kf.C_p).max())
    h, r_inv, p_inv = model.H, np.linalg.inv(model.R), np.linalg.inv(kf.C_p)
    info = p_inv + h.T @ r_inv @ h
    cov = np.linalg.inv(info)
    mean = cov @ (p_inv @ (model.F @ model.prior.mean) + h.T @ r_inv @ model.y)
    cond = np.linalg.cond(kf.C_p) * np.linalg.cond(model.R) * np.linalg.cond(info)
    tol = algebra_rtol(cond)
    scale = max(np.abs(kf.mu_p).max(), np.abs(model.y).max(), np.abs(mean).max(), 1.0)
    np.testing.assert_allclose(kf.mu_e, mean, rtol=0, atol=tol * scale * np.linalg.cond(kf.C_y))
    np.testing.assert_allclose(kf.C_e, cov, rtol=0, atol=tol * np.abs(kf.C_p).max())


class _FixedUniform:
    """An rng whose uniform() returns a given value (systematic resampling draws one uniform)."""

    def __init__(self, value: float):
        self.value = value

    def uniform(self, *args, **kwargs):
        return self.value


@given(counts=st.lists(st.integers(0, 4), min_size=1, max_size=12).filter(lambda c: sum(c) > 0),
       u=st.one_of(st.just(0.0), st.floats(0.0, 1.0, exclude_max=True)), size=st.integers(1, 40))
def test_systematic_resampling_counts_are_floor_or_ceil(counts, u, size):
    """Systematic resampling with offset u: particle i is drawn between ⌊n w_i⌋ and ⌈n w_i⌉ times
    (each stratum [(u + j)/n, (u + j + 1)/n) holds one draw), and never when w_i = 0 — also at
    the stratum boundaries (u = 0, weights that are multiples of 1/n). Counts of n·w_i within
    n·(number of particles)·eps of an integer may round either way."""
    from gpfverify.filters.resampling import systematic_resample

    weights = np.array(counts, dtype=float) / sum(counts)
    with np.errstate(divide="ignore"):
        log_w = np.log(weights)
    idx = systematic_resample(log_w, _FixedUniform(u), size)
    drawn = np.bincount(idx, minlength=len(weights))
    expected = size * weights
    slack = size * len(weights) * np.finfo(float).eps
    assert np.all(drawn >= np.floor(expected - slack)) and np.all(drawn <= np.ceil(expected + slack)), (drawn, expected)
    assert not np.any(drawn[weights == 0]), (drawn, weights)
