"""Scaled unscented transform (Julier & Uhlmann; Wan & van der Merwe), batched.

λ = α²(D + κ) − D; points χ_0 = μ, χ_{±i} = μ ± (√((D + λ) C))_i (columns of the lower Cholesky
factor); weights w_m0 = λ/(D + λ), w_c0 = w_m0 + 1 − α² + β, w_i = 1/(2(D + λ)).
Seed 000 eq. 21–23 with the default α = 1, β = 0, κ = 2.

The weighted mean of angle-valued points is :func:`gpfverify.angles.weighted_mean` with the
parameters' ``angle_mean`` (gpfverify's "reference", Stone Soup's "atan2", filterpy's "linear").
A filter's prediction and its measurement update may use different points
(:class:`SigmaSettings`: Stone Soup's predictor and updater each carry their own α, β, κ).
"""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Sequence

import numpy as np

from gpfverify.angles import ANGLE_MEANS, difference, weighted_mean
from gpfverify.errors import InputError
from gpfverify.linalg import cholesky_batched


@dataclass(frozen=True)
class SigmaParams:
    """α, β, κ of the scaled unscented transform (module docstring) and ``angle_mean``, how the
    transformed points' angle components are averaged (:data:`gpfverify.angles.ANGLE_MEANS`)."""

    alpha: float = 1.0
    beta: float = 0.0
    kappa: float = 2.0
    angle_mean: str = "reference"

    def __post_init__(self):
        if self.angle_mean not in ANGLE_MEANS:
            raise InputError(f"angle_mean must be one of {', '.join(ANGLE_MEANS)}, got {self.angle_mean!r}")
        for name in ("alpha", "beta", "kappa"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)) \
                    or not np.isfinite(value):
                raise InputError(f"sigma-point {name} must be a finite number, got {value!r}")
            object.__setattr__(self, name, float(value))
        if self.alpha == 0.0:
            raise InputError("sigma-point alpha must not be 0 (the points would collapse onto the mean)")

    def to_json(self) -> dict:
        return {"alpha": self.alpha, "beta": self.beta, "kappa": self.kappa, "angle_mean": self.angle_mean}

    def lam(self, dim: int) -> float:
        return self.alpha**2 * (dim + self.kappa) - dim

    def weights(self, dim: int) -> tuple[np.ndarray, np.ndarray]:
        """(w_m, w_c), each (2D + 1,)."""
        lam = self.lam(dim)
        if dim + lam <= 0:
            raise InputError(f"sigma-point parameters give D + λ = {dim + lam:.3g} ≤ 0 "
                             f"(alpha={self.alpha}, kappa={self.kappa}, D={dim})")
        wm = np.full(2 * dim + 1, 0.5 / (dim + lam))
        wc = wm.copy()
        wm[0] = lam / (dim + lam)
        wc[0] = wm[0] + 1.0 - self.alpha**2 + self.beta
        return wm, wc


@dataclass(frozen=True)
class SigmaSettings:
    """The sigma points of a filter's prediction and of its measurement update, each a
    :class:`SigmaParams` (the prediction's angle mean averages the predicted states', the update's
    the predicted measurements' angle components)."""

    predict: SigmaParams = SigmaParams()
    update: SigmaParams = SigmaParams()

    @classmethod
    def of(cls, params: SigmaParams | SigmaSettings) -> SigmaSettings:
        """``params`` as settings: one :class:`SigmaParams` serves the prediction and the update."""
        if isinstance(params, SigmaSettings):
            return params
        if not isinstance(params, SigmaParams):
            raise InputError(f"sigma-point parameters must be SigmaParams or SigmaSettings, got "
                             f"{type(params).__name__}")
        return cls(params, params)

    def to_json(self) -> dict:
        return {"predict": self.predict.to_json(), "update": self.update.to_json()}


def sigma_points(mean: np.ndarray, cov: np.ndarray, params: SigmaParams = SigmaParams()) -> np.ndarray:
    """Sigma points (..., 2D + 1, D) for means (..., D) and covariances (..., D, D)."""
    dim = mean.shape[-1]
    scale = dim + params.lam(dim)
    root = cholesky_batched(scale * cov, "sigma-point covariance")  # (..., D, D), columns are the directions
    offsets = np.swapaxes(root, -1, -2)  # (..., D, D): row i = column i of the factor
    return np.concatenate([mean[..., None, :], mean[..., None, :] + offsets,
                           mean[..., None, :] - offsets], axis=-2)


def weighted_moments(points_x: np.ndarray, points_y: np.ndarray, wm: np.ndarray, wc: np.ndarray,
                     circular_x: Sequence[int] = (), circular_y: Sequence[int] = (), angle_mean: str = "reference"):
    """Mean of y, covariance of y and cross covariance of (x, y) from transformed sigma points:
    points_x (..., S, D), points_y (..., S, L). Returns (..., L), (..., L, L), (..., D, L).

    Components listed in ``circular_x`` / ``circular_y`` are angles: their means are taken on the
    circle (:func:`gpfverify.angles.weighted_mean` with ``angle_mean``, for y; x's points are
    symmetric about the central one, whose angle every convention returns) and their deviations
    wrapped to (−π, π]. The points are made C-ordered first: numpy's weighted sums may add in
    another order over a strided layout, and a run's numbers must not depend on the layout its
    batch came in."""
    points_x, points_y = np.ascontiguousarray(points_x), np.ascontiguousarray(points_y)
    mean_x = weighted_mean(points_x, wm, circular_x)
    mean_y = weighted_mean(points_y, wm, circular_y, angle_mean)
    dx = difference(points_x, mean_x[..., None, :], circular_x)
    dy = difference(points_y, mean_y[..., None, :], circular_y)
    cov_y = weighted_outer(wc, dy, dy)
    return mean_y, 0.5 * (cov_y + np.swapaxes(cov_y, -1, -2)), weighted_outer(wc, dx, dy)


def weighted_outer(weights: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Σ_s w_s a_s b_sᵀ for points a (..., S, D) and b (..., S, L): (..., D, L), one (batched)
    matrix product (a three-operand einsum takes numpy's slow unoptimised path)."""
    return np.swapaxes(a * weights[:, None], -1, -2) @ b
