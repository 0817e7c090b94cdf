"""Densities and samplers a particle filter needs from a :class:`~gpfverify.filters.models.NonlinearModel`,
with the model's optional non-Gaussian fields taking precedence over the Gaussian defaults:

* transition: x_k ~ p(x_k | x_{k−1}) — default N(f(x_{k−1}, k), Q);
* measurement: log p(y_k | x_k) = log N(r; 0, R), r = residual(y_k, h(x_k, k)) — default r = y − h;
* :func:`unwrapped_measurement`: h(x) moved to the branch nearest y (y − r), so that flows and
  moment computations see a continuous measurement function (bearings near ±π).
"""

from __future__ import annotations

import numpy as np

from gpfverify.filters.models import NonlinearModel
from gpfverify.linalg import cholesky

LOG_2PI = float(np.log(2.0 * np.pi))


def gaussian_logpdf(residuals: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """log N(r; 0, C) for residuals (..., L): −½ rᵀC⁻¹r − ½ log|C| − (L/2) log 2π."""
    chol = cholesky(cov, "covariance")
    flat = residuals.reshape(-1, residuals.shape[-1])
    # L⁻¹ r; numpy's small dense solve (scipy's solve_triangular is orders of magnitude slower
    # for an L × N right-hand side when threaded BLAS competes for the cores)
    white = np.linalg.solve(chol.factor, flat.T)
    quad = np.sum(white * white, axis=0).reshape(residuals.shape[:-1])
    return -0.5 * (quad + chol.logdet() + residuals.shape[-1] * LOG_2PI)


def sample_transition(model: NonlinearModel, x_prev: np.ndarray, k: int,
                      rng: np.random.Generator) -> np.ndarray:
    """Draws x_k ~ p(x_k | x_{k−1}) for particles x_prev (N, D)."""
    if model.transition_sampler is not None:
        return model.transition_sampler(x_prev, k, rng)
    noise = rng.multivariate_normal(np.zeros(model.state_dim), model.Q, size=x_prev.shape[0],
                                    method="cholesky")
    return model.f(x_prev, k) + noise


def transition_logpdf(model: NonlinearModel, x_new: np.ndarray, x_prev: np.ndarray, k: int) -> np.ndarray:
    """log p(x_new | x_prev) per particle (N,)."""
    if model.transition_logpdf is not None:
        return model.transition_logpdf(x_new, x_prev, k)
    return gaussian_logpdf(x_new - model.f(x_prev, k), model.Q)


def measurement_residual(model: NonlinearModel, y: np.ndarray, y_pred: np.ndarray) -> np.ndarray:
    """y − y_pred, or the model's own residual (e.g. wrapped to (−π, π] for bearings)."""
    if model.measurement_residual is not None:
        return model.measurement_residual(y, y_pred)
    return y - y_pred


def measurement_loglik(model: NonlinearModel, y: np.ndarray, x: np.ndarray, k: int) -> np.ndarray:
    """log p(y | x_i) for particles x (N, D) under Gaussian measurement noise R."""
    return gaussian_logpdf(measurement_residual(model, y, model.h(x, k)), model.R)


def unwrapped_measurement(model: NonlinearModel, y: np.ndarray, x: np.ndarray, k: int) -> np.ndarray:
    """h(x_i, k) on the branch nearest y: y − residual(y, h(x_i)); equals h(x_i) without a custom
    residual."""
    return y - measurement_residual(model, y, model.h(x, k))
