"""Gaussian filters on drawn models.

* UKF = KF on linear-Gaussian models for every valid (α, β, κ): the unscented transform of an
  affine map is exact whatever the weights, as long as Σ w_m = 1 and Σ w_c (χ − μ)(χ − μ)ᵀ = C.
  The weights can be large (w_m0 = 1 − D/(α²(D + κ)) ≈ −1e6 at α = 1e-3), and the sums then lose
  eps · Σ|w_m| of the points' size, so the tolerance is algebra_rtol(cond · Σ|w_m|);
* GP-ADF: the predicted and updated covariances C_p, C_e and the measurement covariance C_y stay
  symmetric positive semidefinite (C_y definite) for drawn GPs and beliefs.
"""

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from gpfverify.filters.gp_adf import gp_adf_step
from gpfverify.filters.kalman import kf_step
from gpfverify.filters.records import Gaussian
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
