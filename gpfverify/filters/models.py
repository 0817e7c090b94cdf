"""State-space models with known equations, for the reference filters (KF, EKF, UKF) and the
particle filters.

    x_k = f(x_{k−1}, k) + w_k,  w_k ~ N(0, Q)
    y_k = h(x_k, k) + v_k,      v_k ~ N(0, R)

``f`` and ``h`` are vectorised over a leading axis: (N, D) -> (N, D) and (N, D) -> (N, L).
Jacobians (for the EKF) take one state (D,) and return (D, D) / (L, D).

Particle filters may need more than the Gaussian summary: the optional fields
``transition_sampler(x_prev (N, D), k, rng) -> (N, D)`` and
``transition_logpdf(x_new (N, D), x_prev (N, D), k) -> (N,)`` describe non-Gaussian process noise
(then ``f`` and ``Q`` are the noise-mean-shifted transition and the noise covariance, the Gaussian
approximation a Gaussian filter uses); ``measurement_residual(y, y_pred) -> y − y_pred`` (batched
over leading axes) handles measurements on a circle (bearings). ``None`` means the Gaussian /
plain-difference default; :mod:`gpfverify.filters.likelihoods` applies the defaults.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

Vectorised = Callable[[np.ndarray, int], np.ndarray]
Jacobian = Callable[[np.ndarray, int], np.ndarray]


@dataclass(frozen=True)
class NonlinearModel:
    f: Vectorised
    h: Vectorised
    Q: np.ndarray
    R: np.ndarray
    f_jacobian: Jacobian | None = None
    h_jacobian: Jacobian | None = None
    transition_sampler: Callable[[np.ndarray, int, np.random.Generator], np.ndarray] | None = None
    transition_logpdf: Callable[[np.ndarray, np.ndarray, int], np.ndarray] | None = None
    measurement_residual: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None

    @property
    def state_dim(self) -> int:
        return self.Q.shape[0]

    @property
    def measurement_dim(self) -> int:
        return self.R.shape[0]


def linear_model(F: np.ndarray, H: np.ndarray, Q: np.ndarray, R: np.ndarray) -> NonlinearModel:
    """x_k = F x_{k−1} + w, y_k = H x_k + v as a :class:`NonlinearModel` (for oracle tests)."""
    F, H = np.asarray(F, float), np.asarray(H, float)
    return NonlinearModel(f=lambda x, k: x @ F.T, h=lambda x, k: x @ H.T,
                          Q=np.asarray(Q, float), R=np.asarray(R, float),
                          f_jacobian=lambda x, k: F, h_jacobian=lambda x, k: H)
