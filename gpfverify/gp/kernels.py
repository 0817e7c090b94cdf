"""Squared-exponential ARD kernel, vectorised over outputs (seed 000 eq. 3).

k_a(x, x') = α_a² exp(−½ (x − x')ᵀ Λ_a⁻¹ (x − x')),  Λ_a = diag(ℓ_a²).
"""

from __future__ import annotations

import numpy as np


def scaled_sq_dist(x1: np.ndarray, x2: np.ndarray, lengthscales: np.ndarray) -> np.ndarray:
    """(x1_i − x2_j)ᵀ Λ_a⁻¹ (x1_i − x2_j) for every output a: shape (E, n1, n2).

    ``lengthscales`` is (E, D). Computed from differences (not the |a|²+|b|²−2ab expansion) so it
    is exact to rounding and never negative.
    """
    diff = x1[:, None, :] - x2[None, :, :]  # (n1, n2, D)
    inv_l2 = 1.0 / lengthscales**2  # (E, D)
    return np.einsum("ijd,ed->eij", diff * diff, inv_l2, optimize=True)


def se_ard(x1: np.ndarray, x2: np.ndarray, lengthscales: np.ndarray,
           signal_var: np.ndarray) -> np.ndarray:
    """Kernel matrices k_a(x1_i, x2_j), shape (E, n1, n2)."""
    return signal_var[:, None, None] * np.exp(-0.5 * scaled_sq_dist(x1, x2, lengthscales))
