"""Kalman filter for the linear-Gaussian model (Kalman 1960), batched over leading axes:

    x_k = F x_{k−1} + w_k, w_k ~ N(0, Q);   y_k = H x_k + v_k, v_k ~ N(0, R).

Prediction μ_p = F μ_e, C_p = F C_e Fᵀ + Q; measurement moments μ_y = H μ_p,
C_y = H C_p Hᵀ + R, C_xy = C_p Hᵀ; update by :func:`~gpfverify.filters.update.gaussian_update`
(seed 000 eq. 15–16 are exactly these formulas with the moments computed exactly). The exact
oracle of every other Gaussian filter on linear models.
"""

from __future__ import annotations

from gpfverify.errors import InputError
from gpfverify.filters.records import Gaussian, MeasurementMoments, StepRecord
from gpfverify.filters.update import check_belief, gaussian_update
from gpfverify.linalg import symmetrize
from gpfverify.validate import as_covariance, as_matrix


def kf_predict(belief: Gaussian, F, Q) -> Gaussian:
    """N(F μ_e, F C_e Fᵀ + Q); F (D, D), Q (D, D)."""
    F = as_matrix(F, "F")
    if F.shape[0] != F.shape[1]:
        raise InputError(f"F must be square, got shape {F.shape}")
    Q = as_covariance(Q, "Q", F.shape[0])
    belief = check_belief(belief, F.shape[1])
    return Gaussian(belief.mean @ F.T, symmetrize(F @ belief.cov @ F.T + Q))


def kf_measurement(prediction: Gaussian, H, R) -> MeasurementMoments:
    """(H μ_p, H C_p Hᵀ + R, C_p Hᵀ); H (L, D), R (L, L)."""
    H = as_matrix(H, "H")
    R = as_covariance(R, "R", H.shape[0])
    prediction = check_belief(prediction, H.shape[1], "prediction")
    C_xy = prediction.cov @ H.T
    return MeasurementMoments(prediction.mean @ H.T, symmetrize(H @ C_xy + R), C_xy)


def kf_step(belief: Gaussian, F, H, Q, R, y) -> StepRecord:
    """One Kalman predict–update cycle."""
    prediction = kf_predict(belief, F, Q)
    return gaussian_update(prediction, kf_measurement(prediction, H, R), y)
