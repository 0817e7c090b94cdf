"""Kalman filter for the linear-Gaussian model (Kalman 1960), batched over leading axes:

    x_k = F x_{k−1} + w_k, w_k ~ N(0, Q);   y_k = H x_k + v_k, v_k ~ N(0, R).

Prediction μ_p = F μ_e, C_p = F C_e Fᵀ + Q; measurement moments μ_y = H μ_p,
C_y = H C_p Hᵀ + R, C_xy = C_p Hᵀ; update by :func:`~gpfverify.filters.update.gaussian_update`
(seed 000 eq. 15–16 are exactly these formulas with the moments computed exactly). The exact
oracle of every other Gaussian filter on linear models. The model is a
:class:`~gpfverify.models.StateSpaceModel` whose functions are matrices
(:func:`~gpfverify.models.linear_model`); Q and R were validated when it was built.
"""

from __future__ import annotations

import numpy as np

from gpfverify.filters.records import Gaussian, MeasurementMoments, StepRecord
from gpfverify.filters.update import check_belief, gaussian_update
from gpfverify.linalg import symmetrize
from gpfverify.models.system import StateSpaceModel, require_model


def _predict(belief: Gaussian, F: np.ndarray, Q: np.ndarray) -> Gaussian:
    return Gaussian(belief.mean @ F.T, symmetrize(F @ belief.cov @ F.T + Q))


def _measurement(prediction: Gaussian, H: np.ndarray, R: np.ndarray) -> MeasurementMoments:
    C_xy = prediction.cov @ H.T
    return MeasurementMoments(prediction.mean @ H.T, symmetrize(H @ C_xy + R), C_xy)


def kf_predict(belief: Gaussian, model, *, k: int = 1) -> Gaussian:
    """N(F μ_e, F C_e Fᵀ + Q)."""
    require_model(model, StateSpaceModel, "the Kalman filter")
    F, _ = model.linear_matrices()
    return _predict(check_belief(belief, model.state_dim), F, model.Q)


def kf_measurement(prediction: Gaussian, model, *, k: int = 1) -> MeasurementMoments:
    """(H μ_p, H C_p Hᵀ + R, C_p Hᵀ)."""
    require_model(model, StateSpaceModel, "the Kalman filter")
    _, H = model.linear_matrices()
    return _measurement(check_belief(prediction, model.state_dim, "prediction"), H, model.R)


def kf_step(belief: Gaussian, model, y, *, k: int = 1) -> StepRecord:
    """One Kalman predict–update cycle (the belief is checked once; the prediction made here is
    not checked again)."""
    require_model(model, StateSpaceModel, "the Kalman filter")
    F, H = model.linear_matrices()
    prediction = _predict(check_belief(belief, model.state_dim), F, model.Q)
    return gaussian_update(prediction, _measurement(prediction, H, model.R), y, model.circular,
                           model.circular_state)
