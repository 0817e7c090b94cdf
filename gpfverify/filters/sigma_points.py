"""Scaled unscented transform (Julier & Uhlmann; Wan & van der Merwe), batched.

λ = α²(D + κ) − D; points χ_0 = μ, χ_{±i} = μ ± (√((D + λ) C))_i (columns of the lower Cholesky
factor); weights w_m0 = λ/(D + λ), w_c0 = w_m0 + 1 − α² + β, w_i = 1/(2(D + λ)).
Seed 000 eq. 21–23 with the default α = 1, β = 0, κ = 2.
"""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Sequence

import numpy as np

from gpfverify.angles import difference, weighted_mean
from gpfverify.errors import InputError
from gpfverify.linalg import cholesky_batched


@dataclass(frozen=True)
class SigmaParams:
    alpha: float = 1.0
    beta: float = 0.0
    kappa: float = 2.0

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


def sigma_points(mean: np.ndarray, cov: np.ndarray, params: SigmaParams = SigmaParams()) -> np.ndarray:
    """Sigma points (..., 2D + 1, D) for means (..., D) and covariances (..., D, D)."""
    dim = mean.shape[-1]
    scale = dim + params.lam(dim)
    root = cholesky_batched(scale * cov, "sigma-point covariance")  # (..., D, D), columns are the directions
    offsets = np.swapaxes(root, -1, -2)  # (..., D, D): row i = column i of the factor
    return np.concatenate([mean[..., None, :], mean[..., None, :] + offsets,
                           mean[..., None, :] - offsets], axis=-2)


def weighted_moments(points_x: np.ndarray, points_y: np.ndarray, wm: np.ndarray, wc: np.ndarray,
                     circular_x: Sequence[int] = (), circular_y: Sequence[int] = ()):
    """Mean of y, covariance of y and cross covariance of (x, y) from transformed sigma points:
    points_x (..., S, D), points_y (..., S, L). Returns (..., L), (..., L, L), (..., D, L).

    Components listed in ``circular_x`` / ``circular_y`` are angles: their means are taken on the
    circle and their deviations wrapped to (−π, π] (:func:`gpfverify.angles.weighted_mean`).
    The points are made C-ordered first: numpy's weighted sums may add in another order over a
    strided layout, and a run's numbers must not depend on the layout its batch came in."""
    points_x, points_y = np.ascontiguousarray(points_x), np.ascontiguousarray(points_y)
    mean_x = weighted_mean(points_x, wm, circular_x)
    mean_y = weighted_mean(points_y, wm, circular_y)
    dx = difference(points_x, mean_x[..., None, :], circular_x)
    dy = difference(points_y, mean_y[..., None, :], circular_y)
    cov_y = weighted_outer(wc, dy, dy)
    return mean_y, 0.5 * (cov_y + np.swapaxes(cov_y, -1, -2)), weighted_outer(wc, dx, dy)


def weighted_outer(weights: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Σ_s w_s a_s b_sᵀ for points a (..., S, D) and b (..., S, L): (..., D, L), one (batched)
    matrix product (a three-operand einsum takes numpy's slow unoptimised path)."""
    return np.swapaxes(a * weights[:, None], -1, -2) @ b
