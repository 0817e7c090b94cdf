"""Extended Kalman filter with a known model, batched over leading axes.

Linearise at the current mean: with J_f = ∂f/∂x (μ_e) and J_h = ∂h/∂x (μ_p),

    μ_p = f(μ_e, k),  C_p = J_f C_e J_fᵀ + Q;
    μ_y = h(μ_p, k),  C_y = J_h C_p J_hᵀ + R,  C_xy = C_p J_hᵀ;

then :func:`~gpfverify.filters.update.gaussian_update` (angle outputs: y − μ_y wrapped; angle state
components of μ_p and μ_e wrapped). On a linear model this is the KF exactly. The Jacobians are
the model's (:meth:`~gpfverify.models.StateSpaceModel.f_jacobian`): exact for matrices, casadi
and sympy models and user-supplied Jacobians, central differences otherwise.
"""

from __future__ import annotations

import numpy as np

from gpfverify.angles import wrap_components
from gpfverify.filters.records import Gaussian, MeasurementMoments, StepRecord
from gpfverify.filters.ukf import map_points
from gpfverify.filters.update import check_belief, gaussian_update
from gpfverify.linalg import symmetrize
from gpfverify.models.system import StateSpaceModel, require_model
from gpfverify.runtime import one_blas_thread


def ekf_predict(belief: Gaussian, model, *, k: int = 1) -> Gaussian:
    """N(f(μ_e), J_f C_e J_fᵀ + Q)."""
    require_model(model, StateSpaceModel, "the EKF")
    belief = check_belief(belief, model.state_dim)
    J = model.f_jacobian(belief.mean, k)
    mean = wrap_components(map_points(lambda x: model.f(x, k), belief.mean), model.circular_state)
    return Gaussian(mean, symmetrize(J @ belief.cov @ np.swapaxes(J, -1, -2) + model.Q))


def ekf_measurement(prediction: Gaussian, model, *, k: int = 1) -> MeasurementMoments:
    """(h(μ_p), J_h C_p J_hᵀ + R, C_p J_hᵀ)."""
    require_model(model, StateSpaceModel, "the EKF")
    prediction = check_belief(prediction, model.state_dim, "prediction")
    J = model.h_jacobian(prediction.mean, k)
    C_xy = prediction.cov @ np.swapaxes(J, -1, -2)
    mu_y = map_points(lambda x: model.h(x, k), prediction.mean)
    return MeasurementMoments(mu_y, symmetrize(J @ C_xy + model.R), C_xy)


@one_blas_thread
def ekf_step(belief: Gaussian, model, y, *, k: int = 1) -> StepRecord:
    """One EKF predict–update cycle on a :class:`~gpfverify.models.StateSpaceModel`; ``k`` is
    the time index of ``y``."""
    prediction = ekf_predict(belief, model, k=k)
    return gaussian_update(prediction, ekf_measurement(prediction, model, k=k), y,
                           model.circular, model.circular_state)
