"""Unscented Kalman filter with a known model (Julier & Uhlmann 2004), batched over leading axes.

Prediction (seed 000 eq. 21–24 with f in place of the GP mean): sigma points χ_i of
N(μ_e, C_e), μ_p = Σ w_m,i f(χ_i), C_p = Σ w_c,i (f(χ_i) − μ_p)(f(χ_i) − μ_p)ᵀ + Q.
Measurement (eq. 25–29): sigma points χ̂_i of N(μ_p, C_p) redrawn, μ_y = Σ w_m,i h(χ̂_i),
C_y = Σ w_c,i (h(χ̂_i) − μ_y)(…)ᵀ + R, C_xy = Σ w_c,i (χ̂_i − μ_p)(h(χ̂_i) − μ_y)ᵀ; then
:func:`~gpfverify.filters.update.gaussian_update` (eq. 30–31).

Angles: for the model's circular outputs (``model.circular``) and state components
(``model.circular_state``) the weighted means are circular means relative to the central sigma
point and every deviation is wrapped to (−π, π] (:mod:`gpfverify.angles`), so a bearing whose
sigma points straddle ±π gets the right mean and spread; the update wraps y − μ_y.

Every function accepts beliefs with leading batch axes: mean (..., D), cov (..., D, D), y (..., L)
(the unscented particle filter runs one UKF step per particle in one call).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from gpfverify.filters.records import Gaussian, MeasurementMoments, StepRecord
from gpfverify.filters.sigma_points import SigmaParams, sigma_points, weighted_moments
from gpfverify.filters.update import check_belief, gaussian_update
from gpfverify.linalg import symmetrize
from gpfverify.models.system import StateSpaceModel, require_model
from gpfverify.runtime import one_blas_thread


def map_points(fn: Callable[[np.ndarray], np.ndarray], points: np.ndarray) -> np.ndarray:
    """Apply ``fn`` (vectorised over one leading axis, (N, D) -> (N, E)) to points (..., D)."""
    flat = fn(points.reshape(-1, points.shape[-1]))
    return flat.reshape(points.shape[:-1] + (flat.shape[-1],))


def unscented_transform(belief: Gaussian, fn: Callable[[np.ndarray], np.ndarray],
                        params: SigmaParams, circular_in: Sequence[int] = (),
                        circular_out: Sequence[int] = ()) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mean, cov, cross_cov) of fn(x), x ~ belief, by the scaled unscented transform (no noise);
    ``circular_in`` / ``circular_out`` are the angle components of x and of fn(x)."""
    dim = belief.mean.shape[-1]
    wm, wc = params.weights(dim)  # first: raises InputError for invalid parameters (D + λ ≤ 0)
    points = sigma_points(belief.mean, belief.cov, params)
    return weighted_moments(points, map_points(fn, points), wm, wc, circular_in, circular_out, params.angle_mean)


def ukf_predict(belief: Gaussian, model, *, k: int = 1, params: SigmaParams = SigmaParams()) -> Gaussian:
    """N(μ_p, C_p) of x_k = f(x_{k−1}, k) + w_k from the posterior N(μ_e, C_e) at k − 1."""
    require_model(model, StateSpaceModel, "the UKF")
    belief = check_belief(belief, model.state_dim)
    mean, cov, _ = unscented_transform(belief, lambda x: model.f(x, k), params,
                                       model.circular_state, model.circular_state)
    return Gaussian(mean, symmetrize(cov + model.Q))


def ukf_measurement(prediction: Gaussian, model, *, k: int = 1,
                    params: SigmaParams = SigmaParams()) -> MeasurementMoments:
    """(μ_y, C_y, C_xy) of y_k = h(x_k, k) + v_k with sigma points redrawn from N(μ_p, C_p)."""
    require_model(model, StateSpaceModel, "the UKF")
    prediction = check_belief(prediction, model.state_dim, "prediction")
    mu_y, C_y, C_xy = unscented_transform(prediction, lambda x: model.h(x, k), params,
                                          model.circular_state, model.circular)
    return MeasurementMoments(mu_y, symmetrize(C_y + model.R), C_xy)


@one_blas_thread
def ukf_step(belief: Gaussian, model, y, *, k: int = 1, params: SigmaParams = SigmaParams()) -> StepRecord:
    """One UKF predict–update cycle on a :class:`~gpfverify.models.StateSpaceModel`; ``k`` is
    the time index of ``y``."""
    prediction = ukf_predict(belief, model, k=k, params=params)
    return gaussian_update(prediction, ukf_measurement(prediction, model, k=k, params=params), y,
                           model.circular, model.circular_state)
