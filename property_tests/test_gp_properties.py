"""Gaussian-process moments on drawn GPs (hyperparameters in the boxes of
:mod:`gpfverify.strategies.models`, so every K_a is well conditioned by construction).

* Σ = 0: predict_uncertain equals the deterministic prediction (mean, latent variance, zero cross
  covariance) to exact-algebra rounding;
* Σ ≠ 0: the mean moves by at most the curvature bound ½ tr Σ · α_a² Σ_i|β_ai| / ℓ_a,min²
  (Taylor's theorem with ‖∇²k_a‖₂ ≤ α_a²/ℓ_a,min²), so it tends to the Σ = 0 value;
* the joint covariance of (x, f(x)), [[Σ, C_xf], [C_xfᵀ, Cov f]], is positive semidefinite;
* exact moments equal self-converged Gauss–Hermite quadrature (its own error estimate added);
* predictions do not depend on the order of the training points.
"""

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from gpfverify.gp import GaussianProcess
from gpfverify.gp.reference import converged_quadrature_moments
from gpfverify.strategies import gaussian_inputs, gaussian_processes
from gpfverify.strategies.matrices import float_arrays
from gpfverify.strategies.profiles import scaled_examples
from gpfverify.tolerances import QUADRATURE_RTOL, algebra_rtol

#: every test here runs on the fused kernel (numba) and on the numpy reference path
pytestmark = pytest.mark.usefixtures("moment_path")

REGRESSIONS = Path(__file__).parent / "regressions"


def _k_condition(gp) -> float:
    """Largest condition number of the K_a (from the cached inverses)."""
    return max(np.linalg.cond(k) for k in gp.K_inv)


def saved_gp_example(name: str):
    """``@example(gp=..., mu=...)`` from ``regressions/<name>.gp.json`` (training data,
    hyperparameters and the input mean of a shrunk counterexample)."""
    data = json.loads((REGRESSIONS / f"{name}.gp.json").read_text())
    gp = GaussianProcess(data["X"], data["Y"], data["lengthscales"], data["signal_var"], data["noise_var"])
    return example(gp=gp, mu=data["mu"] + [0.0] * (2 - len(data["mu"])))


@saved_gp_example("gp-zero-input-covariance--explicit-inverse")
@given(gp=gaussian_processes(), mu=float_arrays((2,), -3.0, 3.0))
def test_zero_input_covariance_is_the_deterministic_prediction(gp, mu):
    """Σ = 0: the exact moments are the deterministic prediction, to algebra_rtol(cond K_a)
    relative to α² (the variance is k** − kᵀK⁻¹k, a cancellation of O(α²) terms). The saved
    example (found by the ``thorough`` profile) exceeds it by 27 %: the moment-matching variance
    goes through the cached explicit inverse K⁻¹, ``predict`` through a triangular solve."""
    mu = np.asarray(mu, dtype=float)[:gp.input_dim]
    mean, var = gp.predict(mu[None, :])
    exact = gp.predict_uncertain(mu, np.zeros((gp.input_dim, gp.input_dim)))
    tol = algebra_rtol(_k_condition(gp))
    scale = gp.signal_var.max()
    np.testing.assert_allclose(exact.mean, mean[0], rtol=0, atol=tol * (np.abs(gp.Y).max() + scale))
    np.testing.assert_allclose(exact.cov, np.diag(var[0]), rtol=0, atol=tol * scale)
    np.testing.assert_array_equal(exact.cross_cov, 0.0)


@given(gp=gaussian_processes(), data=st.data())
def test_mean_moves_at_most_by_the_curvature_bound(gp, data):
    """|E[m_a(x)] − m_a(μ)| ≤ ½ tr Σ · max‖∇²m_a‖₂ ≤ ½ tr Σ · α_a² Σ_i|β_ai| / min_d ℓ_ad²."""
    x = data.draw(gaussian_inputs(gp.input_dim), label="input")
    moved = gp.predict_uncertain(x.mean, x.cov).mean
    at_mean = gp.predict(x.mean[None, :])[0][0]
    curvature = gp.signal_var * np.abs(gp.beta).sum(axis=1) / gp.lengthscales.min(axis=1) ** 2
    rounding = algebra_rtol(_k_condition(gp)) * (np.abs(gp.Y).max() + gp.signal_var.max())
    assert np.all(np.abs(moved - at_mean) <= 0.5 * np.trace(x.cov) * curvature + rounding)


@given(gp=gaussian_processes(), data=st.data())
def test_joint_covariance_of_input_and_output_is_psd(gp, data):
    x = data.draw(gaussian_inputs(gp.input_dim, max_variance=4.0), label="input")
    mm = gp.predict_uncertain(x.mean, x.cov)
    joint = np.block([[x.cov, mm.cross_cov], [mm.cross_cov.T, mm.cov]])
    np.testing.assert_array_equal(mm.cov, mm.cov.T)
    scale = max(np.abs(joint).max(), np.finfo(float).tiny)
    assert np.linalg.eigvalsh(joint)[0] >= -algebra_rtol(_k_condition(gp)) * scale


@given(gp=gaussian_processes(input_dim=st.integers(1, 2), output_dim=st.integers(1, 2)), data=st.data())
@settings(max_examples=scaled_examples(0.3))
def test_moments_equal_converged_quadrature(gp, data):
    """Closed-form moments against Gauss–Hermite raised until self-converged; the tolerance is
    QUADRATURE_RTOL plus the rule's own last change, relative to the output scale. Input variances
    are ≥ 0.05 (or exactly 0) so that the moments differ clearly from the Σ = 0 prediction."""
    x = data.draw(gaussian_inputs(gp.input_dim, max_variance=1.0, min_variance=0.05), label="input")
    mm = gp.predict_uncertain(x.mean, x.cov)
    ref, change, _ = converged_quadrature_moments(gp, x.mean, x.cov, max_nodes=40_000)
    scale = max(np.abs(ref.cov).max(), gp.signal_var.max())
    atol = (QUADRATURE_RTOL + change) * scale
    np.testing.assert_allclose(mm.mean, ref.mean, rtol=0, atol=atol * (1 + np.abs(gp.Y).max()))
    np.testing.assert_allclose(mm.cov, ref.cov, rtol=0, atol=atol)
    np.testing.assert_allclose(mm.cross_cov, ref.cross_cov,
                               rtol=0, atol=atol * np.sqrt(max(np.abs(x.cov).max(), np.finfo(float).tiny) / scale) + atol)


@given(gp=gaussian_processes(train_size=st.integers(2, 12)), data=st.data())
def test_predictions_do_not_depend_on_training_order(gp, data):
    order = np.array(data.draw(st.permutations(range(gp.X.shape[0])), label="order"))
    other = GaussianProcess(gp.X[order], gp.Y[order], gp.lengthscales, gp.signal_var, gp.noise_var)
    x = data.draw(gaussian_inputs(gp.input_dim), label="input")
    tol = algebra_rtol(_k_condition(gp))
    scale = np.abs(gp.Y).max() + gp.signal_var.max()
    for a, b in zip(gp.predict(x.mean[None, :]), other.predict(x.mean[None, :])):
        np.testing.assert_allclose(b, a, rtol=0, atol=tol * scale)
    first, second = gp.predict_uncertain(x.mean, x.cov), other.predict_uncertain(x.mean, x.cov)
    for name in ("mean", "cov", "cross_cov"):
        np.testing.assert_allclose(getattr(second, name), getattr(first, name), rtol=0, atol=tol * scale,
                                   err_msg=name)
