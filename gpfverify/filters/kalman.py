"""Kalman filter for the linear-Gaussian model (Kalman 1960), batched over leading axes:

    x_k = F x_{k−1} + w_k, w_k ~ N(0, Q);   y_k = H x_k + v_k, v_k ~ N(0, R).

Prediction μ_p = F μ_e, C_p = F C_e Fᵀ + Q; measurement moments μ_y = H μ_p,
C_y = H C_p Hᵀ + R, C_xy = C_p Hᵀ (angle state components of μ_p and angle outputs of μ_y wrapped
to (−π, π], as every filter records them); update by :func:`~gpfverify.filters.update.gaussian_update`
(seed 000 eq. 15–16 are exactly these formulas with the moments computed exactly). The exact
oracle of every other Gaussian filter on linear models. The model is a
:class:`~gpfverify.models.StateSpaceModel` whose functions are matrices
(:func:`~gpfverify.models.linear_model`); F, H, Q and R were validated when it was built and are
not checked again here. A step checks what it is given: the belief and y (shape, NaN or inf),
with an :class:`~gpfverify.errors.InputError` naming it.

:func:`kf_step` forms the predicted joint of (x_k, y_k) in one product instead of prediction then
moments: with A = [F; H F] and B = [[Q, Q Hᵀ], [H Q, H Q Hᵀ + R]] it is

    N(A μ_e, A C_e Aᵀ + B),   blocks μ_p, μ_y and C_p, C_xy, C_y,

the same numbers to rounding. The covariance is symmetrised, (M + Mᵀ)/2, as G + Gᵀ with
G = A C_e (Aᵀ/2) + B/2: halving is exact in binary floating point (barring subnormals), so this is
exactly (M + Mᵀ)/2 with one operation fewer. A, Aᵀ/2 and B/2 are formed once per model
(:class:`PredictedJoint`).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from gpfverify.angles import wrap_components
from gpfverify.filters.records import Gaussian, MeasurementMoments, StepRecord
from gpfverify.filters.update import check_belief, condition
from gpfverify.linalg import matmul_for, rows_times, symmetrize
from gpfverify.models.system import StateSpaceModel, require_model
from gpfverify.runtime import one_blas_thread


def _predict(belief: Gaussian, F: np.ndarray, Q: np.ndarray, circular_state=()) -> Gaussian:
    return Gaussian(wrap_components(rows_times(belief.mean, F.T), circular_state), symmetrize(F @ belief.cov @ F.T + Q))


def _measurement(prediction: Gaussian, H: np.ndarray, R: np.ndarray, circular=()) -> MeasurementMoments:
    C_xy = prediction.cov @ H.T
    return MeasurementMoments(wrap_components(rows_times(prediction.mean, H.T), circular), symmetrize(H @ C_xy + R),
                              C_xy)


def kf_predict(belief: Gaussian, model, *, k: int = 1) -> Gaussian:
    """N(F μ_e, F C_e Fᵀ + Q)."""
    require_model(model, StateSpaceModel, "the Kalman filter")
    F, _ = model.linear_matrices()
    return _predict(check_belief(belief, model.state_dim), F, model.Q, model.circular_state)


def kf_measurement(prediction: Gaussian, model, *, k: int = 1) -> MeasurementMoments:
    """(H μ_p, H C_p Hᵀ + R, C_p Hᵀ)."""
    require_model(model, StateSpaceModel, "the Kalman filter")
    _, H = model.linear_matrices()
    return _measurement(check_belief(prediction, model.state_dim, "prediction"), H, model.R, model.circular)


@dataclass(frozen=True)
class PredictedJoint:
    """The predicted joint of (x_k, y_k) as a map of the belief (module docstring): A (D + L, D),
    Aᵀ, Aᵀ/2 (views), B/2 (D + L, D + L); ``state_dim`` D splits the blocks."""

    A: np.ndarray
    A_T: np.ndarray
    half_A_T: np.ndarray
    half_B: np.ndarray
    state_dim: int

    @classmethod
    def of(cls, F: np.ndarray, H: np.ndarray, Q: np.ndarray, R: np.ndarray) -> PredictedJoint:
        A = np.concatenate([F, H @ F])
        QH_T = Q @ H.T
        B = symmetrize(np.block([[Q, QH_T], [QH_T.T, H @ QH_T + R]]))
        return cls(A, A.T, (0.5 * A).T, 0.5 * B, F.shape[0])


# formed once per model (a model is immutable once built); entries go with their models
_JOINTS: weakref.WeakKeyDictionary[StateSpaceModel, PredictedJoint] = weakref.WeakKeyDictionary()


def _joint(model) -> PredictedJoint:
    """The :class:`PredictedJoint` of ``model``; InputError unless it is a linear StateSpaceModel."""
    found = _JOINTS.get(model) if isinstance(model, StateSpaceModel) else None
    if found is None:
        require_model(model, StateSpaceModel, "the Kalman filter")
        F, H = model.linear_matrices()
        found = _JOINTS[model] = PredictedJoint.of(F, H, model.Q, model.R)
    return found


@one_blas_thread
def kf_step(belief: Gaussian, model, y, *, k: int = 1) -> StepRecord:
    """One Kalman predict–update cycle: the predicted joint (module docstring), then the update of
    :func:`~gpfverify.filters.update.gaussian_update`; the belief and y are checked once and no
    intermediate record is built. Equals :func:`kf_predict`, :func:`kf_measurement` and
    ``gaussian_update`` in turn to rounding."""
    joint = _joint(model)
    belief = check_belief(belief, joint.state_dim)
    mul = matmul_for(belief.cov)
    half = mul(mul(joint.A, belief.cov), joint.half_A_T) + joint.half_B
    cov = half + half.swapaxes(-1, -2)
    mean = rows_times(belief.mean, joint.A_T)
    d = joint.state_dim
    mu_p, mu_y = mean[..., :d], mean[..., d:]
    if model.circular_state:
        mu_p = wrap_components(mu_p, model.circular_state)
    if model.circular:
        mu_y = wrap_components(mu_y, model.circular)
    return condition(mu_p, cov[..., :d, :d], mu_y, cov[..., d:, d:], cov[..., :d, d:], y,
                     model.circular, model.circular_state)
