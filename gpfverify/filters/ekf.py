"""Extended Kalman filter with a known model, batched over leading axes.

Linearise at the current mean: with J_f = ∂f/∂x (μ_e) and J_h = ∂h/∂x (μ_p),

    μ_p = f(μ_e, k),  C_p = J_f C_e J_fᵀ + Q;
    μ_y = h(μ_p, k),  C_y = J_h C_p J_hᵀ + R,  C_xy = C_p J_hᵀ;

then :func:`~gpfverify.filters.update.gaussian_update`. On a linear model this is the KF exactly.
"""

from __future__ import annotations

import numpy as np

from gpfverify.errors import InputError
from gpfverify.filters.models import Jacobian, NonlinearModel
from gpfverify.filters.records import Gaussian, MeasurementMoments, StepRecord
from gpfverify.filters.ukf import map_points
from gpfverify.filters.update import check_belief, gaussian_update
from gpfverify.linalg import symmetrize


def _jacobians(jacobian: Jacobian | None, name: str, means: np.ndarray, k: int) -> np.ndarray:
    """The Jacobian at every mean (..., D) -> (..., out, D); the model's Jacobians take one state."""
    if jacobian is None:
        raise InputError(f"the EKF needs the model's {name}")
    flat = means.reshape(-1, means.shape[-1])
    stacked = np.stack([np.atleast_2d(np.asarray(jacobian(x, k), dtype=float)) for x in flat])
    return stacked.reshape(means.shape[:-1] + stacked.shape[1:])


def ekf_predict(belief: Gaussian, model: NonlinearModel, k: int = 0) -> Gaussian:
    """N(f(μ_e), J_f C_e J_fᵀ + Q)."""
    belief = check_belief(belief, model.state_dim)
    J = _jacobians(model.f_jacobian, "f_jacobian", belief.mean, k)
    mean = map_points(lambda x: model.f(x, k), belief.mean)
    return Gaussian(mean, symmetrize(J @ belief.cov @ np.swapaxes(J, -1, -2) + model.Q))


def ekf_measurement(prediction: Gaussian, model: NonlinearModel, k: int = 0) -> MeasurementMoments:
    """(h(μ_p), J_h C_p J_hᵀ + R, C_p J_hᵀ)."""
    prediction = check_belief(prediction, model.state_dim, "prediction")
    J = _jacobians(model.h_jacobian, "h_jacobian", prediction.mean, k)
    C_xy = prediction.cov @ np.swapaxes(J, -1, -2)
    mu_y = map_points(lambda x: model.h(x, k), prediction.mean)
    return MeasurementMoments(mu_y, symmetrize(J @ C_xy + model.R), C_xy)


def ekf_step(belief: Gaussian, model: NonlinearModel, y, k: int = 0) -> StepRecord:
    """One EKF predict–update cycle; ``k`` is the time index of ``y``."""
    prediction = ekf_predict(belief, model, k)
    return gaussian_update(prediction, ekf_measurement(prediction, model, k), y)
