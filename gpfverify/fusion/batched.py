"""Fusion of many Monte Carlo runs at one step, the runs stacked along a leading axis (B).

The per-run rules (:mod:`gpfverify.fusion.centralized`, :mod:`gpfverify.fusion.distributed`,
:mod:`gpfverify.fusion.convex`, …) fuse one step of one run; here the same rules take B runs' steps
at once, as arrays, so that a Monte Carlo study's runs advance together:

* :func:`case_block` — the B fusion cases of one step (the centre's prediction and moments, the
  sensors' step records, y) as a :class:`~gpfverify.fusion.caseblock.CaseBlock`, not validated
  again (they come from the filters, whose outputs are symmetric and checked where they are made);
* eq. 35 with every sensor's rank decision and exactness evidence and the per-step audit are the
  block route's (:func:`gpfverify.blockaudit.block_dmf`, :func:`gpfverify.blockaudit.block_audits`),
  which the run-file audit uses over a log's steps;
* :func:`cmf_update_block` — CMF's update μ_p + G (y ⊖ μ_y), C_p − G C_xyᵀ from the same central
  prediction, with G formed as the block route forms it;
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

from gpfverify.angles import difference, wrap_components
from gpfverify.filters.records import Gaussian, StepRecord
from gpfverify.fusion.blockexactness import apply, equilibrated, right_solve_factored, symmetric, transposed
from gpfverify.fusion.case import CentralPrediction
from gpfverify.fusion.caseblock import CaseBlock, LocalBlock
from gpfverify.fusion.estimates import on_one_branch_arrays


def case_block(central: StepRecord | CentralPrediction, local_records: Sequence[StepRecord], y: np.ndarray | None,
               sizes: Sequence[int], circular: Sequence[int] = (), circular_state: Sequence[int] = ()) -> CaseBlock:
    """The fusion cases of B runs at one step: ``central`` holds the centre's μ_p (B, D), C_p, μ_y,
    C_y, C_xy (e.g. a batched CMF record or prediction), ``local_records[m]`` sensor m's batched
    step record (what it sends: μ_p^m, μ_y^m, C_y^m, C_xy^m, μ_e^m, C_e^m), ``y`` the stacked
    measurements (B, L) or None; ``sizes``, ``circular`` and ``circular_state`` as in a case."""
    runs = central.mu_p.shape[0]
    locals_ = tuple(LocalBlock(r.mu_p, r.mu_y, r.C_y, r.C_xy, r.mu_e, r.C_e, np.ones(runs, dtype=bool))
                    for r in local_records)
    return CaseBlock(tuple(int(s) for s in sizes), tuple(circular), central.mu_p, central.C_p, central.mu_y,
                     central.C_y, central.C_xy, locals_, None if y is None else np.asarray(y, dtype=float),
                     np.full(runs, np.nan), tuple(circular_state))


def cmf_update_block(block: CaseBlock) -> Gaussian:
    """CMF's posterior from the block's central predictions and y (seed 000 eq. 15–16):
    G = C_xy C_y⁻¹ by the equilibrated Cholesky factor of C_y (as :func:`gpfverify.blockaudit.block_dmf`
    forms it, so the one-step gap is the audit's to the bit), μ_e = μ_p + G (y ⊖ μ_y) with the angle
    outputs wrapped and the angle state components of μ_e wrapped, C_e = C_p − G C_xyᵀ."""
    gain = right_solve_factored(block.C_xy, *equilibrated(block.C_y))
    mean = wrap_components(block.mu_p + apply(gain, difference(block.y, block.mu_y, block.circular)),
                           block.circular_state)
    return Gaussian(mean, symmetric(symmetric(block.C_p) - gain @ transposed(block.C_xy)))


def information_batch(means: np.ndarray, covs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(I_m = P_m⁻¹ (B, N, D, D), I_m x_m (B, N, D)) of N estimates in each of B runs, by one
    Cholesky factorisation of each P_m and two solves (no inverse is formed)."""
    dim = means.shape[-1]
    factor = np.linalg.cholesky(covs)
    rhs = np.concatenate([np.broadcast_to(np.eye(dim), covs.shape), means[..., :, None]], axis=-1)
    solved = np.linalg.solve(transposed(factor), np.linalg.solve(factor, rhs))
    return symmetric(solved[..., :dim]), solved[..., dim]


def weighted_information_batch(matrices: np.ndarray, vectors: np.ndarray, weights: np.ndarray) -> Gaussian:
    """P = (Σ ω_m I_m)⁻¹, x = P Σ ω_m I_m x_m in every run: matrices (B, N, D, D), vectors (B, N, D),
    weights (B, N); the sums over the estimates in their order."""
    total = symmetric(np.sum(weights[..., None, None] * matrices, axis=-3))
    vector = np.sum(weights[..., None] * vectors, axis=-2)
    dim = vector.shape[-1]
    factor = np.linalg.cholesky(total)
    rhs = np.concatenate([vector[..., :, None], np.broadcast_to(np.eye(dim), total.shape)], axis=-1)
    solved = np.linalg.solve(transposed(factor), np.linalg.solve(factor, rhs))
    return Gaussian(solved[..., 0], symmetric(solved[..., 1:]))


def convex_combination_batch(means: np.ndarray, covs: np.ndarray, circular_state: Sequence[int] = ()) -> Gaussian:
    """CC/CW (:func:`gpfverify.fusion.convex.convex_combination`) of N local estimates in each of B
    runs: means (B, N, D), covs (B, N, D, D) positive definite; angle state components averaged on
    the circle (:func:`gpfverify.fusion.estimates.on_one_branch_arrays`) and wrapped."""
    means = on_one_branch_arrays(means, circular_state)
    fused = weighted_information_batch(*information_batch(means, covs), np.ones(means.shape[:-1]))
    return Gaussian(wrap_components(fused.mean, circular_state), fused.cov)


def squared_mahalanobis_batch(truth: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """(x − x̂)ᵀ C⁻¹ (x − x̂) per run (B,): ‖L⁻¹(x − x̂)‖² with C = L Lᵀ (seed 000 eq. 44 as written)."""
    white = np.linalg.solve(np.linalg.cholesky(cov), (truth - mean)[..., None])[..., 0]
    return np.sum(white * white, axis=-1)
