"""Local posteriors as the covariance-based baselines see them, and their common result record.

The baselines (CC/CW, CI, ICI, EI, RCC-CI) use only each sensor's (μ_e^m, C_e^m); every fused
result is a :class:`FusedEstimate`. Information matrices I_m = P_m⁻¹ are formed by Cholesky solves.
"""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Sequence

import numpy as np

from gpfverify.errors import InputError
from gpfverify.filters.records import Gaussian
from gpfverify.linalg import cholesky, solve_spd, symmetrize
from gpfverify.validate import as_covariance, as_vector


@dataclass(frozen=True)
class FusedEstimate:
    """Fused ``mean`` (D,), ``cov`` (D, D) and, for weighted rules, the weights ω (N,)."""

    mean: np.ndarray
    cov: np.ndarray
    weights: np.ndarray | None = None


def checked_estimates(estimates: Sequence, minimum: int = 1) -> list[Gaussian]:
    """Validated local estimates: objects with ``mean`` (D,) and positive definite ``cov``."""
    if len(estimates) < minimum:
        raise InputError(f"fusion needs at least {minimum} estimate(s), got {len(estimates)}")
    out: list[Gaussian] = []
    for m, e in enumerate(estimates):
        mean = as_vector(e.mean, f"estimates[{m}].mean", None if not out else out[0].mean.shape[0])
        out.append(Gaussian(mean, as_covariance(e.cov, f"estimates[{m}].cov", mean.shape[0], definite=True)))
    return out


@dataclass(frozen=True)
class Information:
    """Information form of each estimate: matrices I_m = P_m⁻¹ (N, D, D), vectors I_m x_m (N, D)."""

    matrices: np.ndarray
    vectors: np.ndarray


def information_form(estimates: Sequence[Gaussian]) -> Information:
    """I_m and I_m x_m by one Cholesky factorisation of each P_m."""
    mats, vecs = [], []
    for m, e in enumerate(estimates):
        chol = cholesky(e.cov, f"estimates[{m}].cov", allow_jitter=False)
        mats.append(symmetrize(chol.solve(np.eye(e.mean.shape[0]))))
        vecs.append(chol.solve(e.mean))
    return Information(np.array(mats), np.array(vecs))


def weighted_information_fusion(info: Information, weights: np.ndarray) -> FusedEstimate:
    """P = (Σ ω_m I_m)⁻¹, x = P Σ ω_m I_m x_m — the CI family's fused estimate for given weights."""
    total = symmetrize(np.tensordot(weights, info.matrices, axes=1))
    rhs = np.column_stack([weights @ info.vectors, np.eye(total.shape[0])])
    sol = solve_spd(total, rhs, "weighted information")
    return FusedEstimate(sol[:, 0], symmetrize(sol[:, 1:]), np.asarray(weights, dtype=float))
