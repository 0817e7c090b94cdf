"""Fusion of many Monte Carlo runs at one step, the runs stacked along a leading axis (B).

The per-run rules (:mod:`gpfverify.fusion.centralized`, :mod:`gpfverify.fusion.distributed`,
:mod:`gpfverify.fusion.convex`, …) fuse one step of one run; here the same rules take B runs' steps
at once, as arrays, so that a Monte Carlo study's runs advance together:

* the B fusion cases of one step, eq. 35 with every sensor's rank decision and exactness evidence,
  CMF's update from the same central prediction and the per-step audit are the block route's, which
  the run-file audit uses over a log's steps (:mod:`gpfverify.audit.block`: ``case_block``,
  ``block_dmf``, ``cmf_update_block``, ``block_audits``);
* :func:`convex_combination_batch` — CC/CW, P = (Σ P_m⁻¹)⁻¹, x = P Σ P_m⁻¹ x_m;
* :func:`squared_mahalanobis_batch` — (x − x̂)ᵀ C⁻¹ (x − x̂) per run.

A run's numbers do not depend on the other runs or on B: every operation is elementwise, a
reduction along a trailing axis, an einsum over one run's matrices or a stacked LAPACK/BLAS call
(one per run; tests/test_batch_fusion.py checks batches of 1, 3, 8 and 5 + 3 bit for bit). They equal
the per-run rules to rounding (other factorisations of the same matrices: numpy's stacked Cholesky
and solves in place of the per-run route's direct LAPACK calls).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gpfverify.angles import wrap_components
from gpfverify.filters.records import Gaussian
from gpfverify.fusion.estimates import on_one_branch_arrays
from gpfverify.linalg import symmetrize


def transposed(a: np.ndarray) -> np.ndarray:
    """Every matrix of a stack transposed (a view)."""
    return np.swapaxes(a, -1, -2)


def information_batch(means: np.ndarray, covs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(I_m = P_m⁻¹ (B, N, D, D), I_m x_m (B, N, D)) of N estimates in each of B runs, by one
    Cholesky factorisation of each P_m and two solves (no inverse is formed)."""
    dim = means.shape[-1]
    factor = np.linalg.cholesky(covs)
    rhs = np.concatenate([np.broadcast_to(np.eye(dim), covs.shape), means[..., :, None]], axis=-1)
    solved = np.linalg.solve(transposed(factor), np.linalg.solve(factor, rhs))
    return symmetrize(solved[..., :dim]), solved[..., dim]


def weighted_information_batch(matrices: np.ndarray, vectors: np.ndarray, weights: np.ndarray) -> Gaussian:
    """P = (Σ ω_m I_m)⁻¹, x = P Σ ω_m I_m x_m in every run: matrices (B, N, D, D), vectors (B, N, D),
    weights (B, N); the sums over the estimates in their order."""
    total = symmetrize(np.sum(weights[..., None, None] * matrices, axis=-3))
    vector = np.sum(weights[..., None] * vectors, axis=-2)
    dim = vector.shape[-1]
    factor = np.linalg.cholesky(total)
    rhs = np.concatenate([vector[..., :, None], np.broadcast_to(np.eye(dim), total.shape)], axis=-1)
    solved = np.linalg.solve(transposed(factor), np.linalg.solve(factor, rhs))
    return Gaussian(solved[..., 0], symmetrize(solved[..., 1:]))


def convex_combination_batch(means: np.ndarray, covs: np.ndarray, circular_state: Sequence[int] = ()) -> Gaussian:
    """CC/CW (:func:`gpfverify.fusion.convex.convex_combination`) of N local estimates in each of B
    runs: means (B, N, D), covs (B, N, D, D) positive definite; angle state components averaged on
    the circle (:func:`gpfverify.fusion.estimates.on_one_branch_arrays`) and wrapped."""
    means = on_one_branch_arrays(means, circular_state)
    fused = weighted_information_batch(*information_batch(means, covs), np.ones(means.shape[:-1]))
    return Gaussian(wrap_components(fused.mean, circular_state), fused.cov)


def squared_mahalanobis_batch(truth: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """(x − x̂)ᵀ C⁻¹ (x − x̂) per run (B,): ‖L⁻¹(x − x̂)‖² with C = L Lᵀ (seed 000 eq. 44 as written).
    Estimates may carry further leading axes (mean (..., B, D), cov (..., B, D, D); ``truth`` (B, D)
    broadcast): every matrix is factored and solved on its own, so each result is the same bits in
    any stack."""
    white = np.linalg.solve(np.linalg.cholesky(cov), (truth - mean)[..., None])[..., 0]
    return np.sum(white * white, axis=-1)
