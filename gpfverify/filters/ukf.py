"""Unscented Kalman filter with a known model (Julier & Uhlmann 2004), batched over leading axes.

Prediction (seed 000 eq. 21–24 with f in place of the GP mean): sigma points χ_i of
N(μ_e, C_e), μ_p = Σ w_m,i f(χ_i), C_p = Σ w_c,i (f(χ_i) − μ_p)(f(χ_i) − μ_p)ᵀ + Q.
Measurement (eq. 25–29): sigma points χ̂_i of N(μ_p, C_p) redrawn, μ_y = Σ w_m,i h(χ̂_i),
C_y = Σ w_c,i (h(χ̂_i) − μ_y)(…)ᵀ + R, C_xy = Σ w_c,i (χ̂_i − μ_p)(h(χ̂_i) − μ_y)ᵀ; then
:func:`~gpfverify.filters.update.gaussian_update` (eq. 30–31).

Every function accepts beliefs with leading batch axes: mean (..., D), cov (..., D, D), y (..., L)
(the unscented particle filter runs one UKF step per particle in one call).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from gpfverify.filters.models import NonlinearModel
from gpfverify.filters.records import Gaussian, MeasurementMoments, StepRecord
from gpfverify.filters.sigma_points import SigmaParams, sigma_points, weighted_moments
from gpfverify.filters.update import check_belief, gaussian_update
from gpfverify.linalg import symmetrize


def map_points(fn: Callable[[np.ndarray], np.ndarray], points: np.ndarray) -> np.ndarray:
    """Apply ``fn`` (vectorised over one leading axis, (N, D) -> (N, E)) to points (..., D)."""
    flat = fn(points.reshape(-1, points.shape[-1]))
    return flat.reshape(points.shape[:-1] + (flat.shape[-1],))


def unscented_transform(belief: Gaussian, fn: Callable[[np.ndarray], np.ndarray],
                        params: SigmaParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mean, cov, cross_cov) of fn(x), x ~ belief, by the scaled unscented transform (no noise)."""
    dim = belief.mean.shape[-1]
    wm, wc = params.weights(dim)  # first: raises InputError for invalid parameters (D + λ ≤ 0)
    points = sigma_points(belief.mean, belief.cov, params)
    return weighted_moments(points, map_points(fn, points), wm, wc)


def ukf_predict(belief: Gaussian, model: NonlinearModel, k: int = 0,
                params: SigmaParams = SigmaParams()) -> Gaussian:
    """N(μ_p, C_p) of x_k = f(x_{k−1}, k) + w_k from the posterior N(μ_e, C_e) at k − 1."""
    belief = check_belief(belief, model.state_dim)
    mean, cov, _ = unscented_transform(belief, lambda x: model.f(x, k), params)
    return Gaussian(mean, symmetrize(cov + model.Q))


def ukf_measurement(prediction: Gaussian, model: NonlinearModel, k: int = 0,
                    params: SigmaParams = SigmaParams()) -> MeasurementMoments:
    """(μ_y, C_y, C_xy) of y_k = h(x_k, k) + v_k with sigma points redrawn from N(μ_p, C_p)."""
    prediction = check_belief(prediction, model.state_dim, "prediction")
    mu_y, C_y, C_xy = unscented_transform(prediction, lambda x: model.h(x, k), params)
    return MeasurementMoments(mu_y, symmetrize(C_y + model.R), C_xy)


def ukf_step(belief: Gaussian, model: NonlinearModel, y, k: int = 0,
             params: SigmaParams = SigmaParams()) -> StepRecord:
    """One UKF predict–update cycle; ``k`` is the time index of ``y``."""
    prediction = ukf_predict(belief, model, k, params)
    return gaussian_update(prediction, ukf_measurement(prediction, model, k, params), y)
