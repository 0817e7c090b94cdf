"""Local posteriors as the covariance-based baselines see them, and their common result record.

The baselines (CC/CW, CI, ICI, EI, RCC-CI) use only each sensor's (μ_e^m, C_e^m); every fused
result is a :class:`FusedEstimate`. Information matrices I_m = P_m⁻¹ are formed by Cholesky solves.

Angle state components (``circular_state``): every rule is a weighted mean of the local means
(CC/CI/ICI/RCC-CI: x = P Σ_m W_m x_m with P Σ_m W_m = I; EI picks and averages components in a
joint eigenbasis), so an angle is averaged on the circle by putting the local angles on one branch
first. The reference is the circular mean of the local angles, r = atan2(Σ_m sin x_m, Σ_m cos x_m)
(independent of the sensors' order); each local angle is replaced by its representative within π
of r,

    x_m ← r + wrap(x_m − r),

the linear rule is applied, and the fused angle is wrapped to (−π, π]. Every rule here is
equivariant under a common translation of the local means, so the result is a weighted circular
mean: rotating every local angle by φ rotates the fused angle by φ, wherever the ±π cut falls.
Covariances are used as given (the small-angle linearisation of the angle errors).
"""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Sequence

import numpy as np

from gpfverify.angles import wrap, wrap_components
from gpfverify.errors import InputError
from gpfverify.filters.records import Gaussian
from gpfverify.linalg import cholesky, solve_spd, symmetrize
from gpfverify.validate import as_covariance, as_indices, as_vector


@dataclass(frozen=True)
class FusedEstimate:
    """Fused ``mean`` (D,), ``cov`` (D, D) and, for weighted rules, the weights ω (N,)."""

    mean: np.ndarray
    cov: np.ndarray
    weights: np.ndarray | None = None


def checked_estimates(estimates: Sequence, minimum: int = 1,
                      circular_state: Sequence[int] = ()) -> list[Gaussian]:
    """Validated local estimates — objects with ``mean`` (D,) and positive definite ``cov`` — with
    their ``circular_state`` components (validated indices) on one branch (:func:`on_one_branch`)."""
    if len(estimates) < minimum:
        raise InputError(f"fusion needs at least {minimum} estimate(s), got {len(estimates)}")
    out: list[Gaussian] = []
    for m, e in enumerate(estimates):
        mean = as_vector(e.mean, f"estimates[{m}].mean", None if not out else out[0].mean.shape[0])
        out.append(Gaussian(mean, as_covariance(e.cov, f"estimates[{m}].cov", mean.shape[0], definite=True)))
    angles = as_indices(circular_state, out[0].mean.shape[0], "circular_state") if out else ()
    return on_one_branch(out, angles)


def on_one_branch(estimates: Sequence[Gaussian], circular_state: Sequence[int]) -> list[Gaussian]:
    """The estimates with each angle component replaced by its representative within π of the
    circular mean r of the local angles: x_m ← r + wrap(x_m − r) (module docstring)."""
    if not circular_state or not estimates:
        return list(estimates)
    means = on_one_branch_arrays(np.array([e.mean for e in estimates]), circular_state)
    return [Gaussian(mean, e.cov) for mean, e in zip(means, estimates)]


def on_one_branch_arrays(means: np.ndarray, circular_state: Sequence[int]) -> np.ndarray:
    """:func:`on_one_branch` on the means alone, (..., N, D) for N estimates (with any leading axes,
    e.g. Monte Carlo runs): a new array, the angle components moved within π of their circular mean."""
    if not circular_state:
        return means
    idx = list(circular_state)
    angles = means[..., idx]
    reference = np.arctan2(np.sin(angles).sum(axis=-2), np.cos(angles).sum(axis=-2))[..., None, :]
    out = means.copy()
    out[..., idx] = reference + wrap(angles - reference)
    return out


def wrapped(fused: FusedEstimate, circular_state: Sequence[int]) -> FusedEstimate:
    """``fused`` with its angle components (indices checked by :func:`checked_estimates`) wrapped
    to (−π, π]."""
    if not circular_state:
        return fused
    return FusedEstimate(wrap_components(fused.mean, circular_state), fused.cov, fused.weights)


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
