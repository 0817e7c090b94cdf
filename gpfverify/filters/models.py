"""State-space models with known equations, for the reference filters (KF, EKF, UKF) and the
particle filters.

    x_k = f(x_{k−1}, k) + w_k,  w_k ~ N(0, Q)
    y_k = h(x_k, k) + v_k,      v_k ~ N(0, R)

``f`` and ``h`` are vectorised over a leading axis: (N, D) -> (N, D) and (N, D) -> (N, L).
Jacobians (for the EKF) take one state (D,) and return (D, D) / (L, D).
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
