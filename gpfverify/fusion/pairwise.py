"""Two-estimate rules in the basis that diagonalises both covariances at once.

The generalised symmetric eigenproblem P_2 v = μ P_1 v gives V with Vᵀ P_1 V = I and
Vᵀ P_2 V = diag(μ). In coordinates u = Vᵀ x the two estimates have covariances I and diag(μ),
and every rule of the CI family whose fused information is a combination of P_1⁻¹ = V Vᵀ,
P_2⁻¹ = V diag(1/μ) Vᵀ and (ωP_1 + (1 − ω)P_2)⁻¹ = V diag(1/(ω + (1 − ω)μ)) Vᵀ is diagonal too:
fused information V diag(q) Vᵀ, fused covariance B diag(1/q) Bᵀ with B = V⁻ᵀ = P_1 V, and fused
mean B diag(1/q)(a₁ ⊙ u₁ + a₂ ⊙ u₂). Trace and log-determinant of the fused covariance are then
scalar functions of ω: tr = Σ_i c_i / q_i (c_i = ‖B e_i‖²), log det = log det P_1 − Σ_i log q_i.
No inverse is formed.
"""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Callable

import numpy as np
import scipy.linalg as sla

from gpfverify.filters.records import Gaussian
from gpfverify.fusion.estimates import FusedEstimate
from gpfverify.linalg import symmetrize


@dataclass(frozen=True)
class JointDiagonalisation:
    """``ratios`` μ (D,), ``back`` B = P_1 V (D, D), ``u1`` = Vᵀx_1, ``u2`` = Vᵀx_2."""

    ratios: np.ndarray
    back: np.ndarray
    u1: np.ndarray
    u2: np.ndarray

    @property
    def column_norms(self) -> np.ndarray:
        """c_i = ‖B e_i‖², the trace weights."""
        return np.sum(self.back**2, axis=0)

    def fuse(self, q: np.ndarray, a1: np.ndarray, a2: np.ndarray, weights=None) -> FusedEstimate:
        """Fused estimate with information V diag(q) Vᵀ and mean B diag(1/q)(a₁u₁ + a₂u₂)."""
        mean = self.back @ ((a1 * self.u1 + a2 * self.u2) / q)
        cov = symmetrize((self.back / q) @ self.back.T)
        return FusedEstimate(mean, cov, None if weights is None else np.asarray(weights, dtype=float))


def joint_diagonalise(first: Gaussian, second: Gaussian) -> JointDiagonalisation:
    """Simultaneous diagonalisation of two positive definite covariances (see module docstring)."""
    ratios, v = sla.eigh(second.cov, first.cov)
    return JointDiagonalisation(ratios, first.cov @ v, v.T @ first.mean, v.T @ second.mean)


def criterion_derivative(criterion: str, column_norms: np.ndarray, q, dq) -> Callable[[float], float]:
    """d/dω of tr P (= −Σ c_i q_i'/q_i²) or log det P (= −Σ q_i'/q_i) for P = B diag(1/q(ω)) Bᵀ."""
    if criterion == "trace":
        return lambda w: float(-np.sum(column_norms * dq(w) / q(w) ** 2))
    return lambda w: float(-np.sum(dq(w) / q(w)))


def minimise_convex_on_unit_interval(derivative: Callable[[float], float]) -> float:
    """argmin over [0, 1] of a convex differentiable function given its (non-decreasing)
    derivative: an endpoint exactly when the derivative does not change sign, else the root of the
    derivative by Brent's method; a flat objective (zero derivative at both ends) gives ½."""
    d0, d1 = derivative(0.0), derivative(1.0)
    if d0 >= 0.0 and d1 <= 0.0:
        return 0.5
    if d0 >= 0.0:
        return 0.0
    if d1 <= 0.0:
        return 1.0
    from scipy.optimize import brentq  # 0.3 s to import; only CI-type weights need it

    return float(brentq(derivative, 0.0, 1.0))
