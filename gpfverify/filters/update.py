"""The Gaussian measurement update shared by every Gaussian filter (seed 000 eq. 15–16, 30–31).

Given the predicted state N(μ_p, C_p) and the predicted measurement moments (μ_y, C_y, C_xy):

    μ_e = μ_p + C_xy C_y⁻¹ (y ⊖ μ_y),        C_e = C_p − C_xy C_y⁻¹ C_xyᵀ,

where ⊖ is the difference with the angle outputs wrapped to (−π, π] (``circular``); angle state
components (``circular_state``) of μ_e are wrapped too. With the Cholesky factor C_y = L Lᵀ and
W = L⁻¹ C_xyᵀ (a triangular solve, never an inverse), C_xy C_y⁻¹ C_xyᵀ = Wᵀ W and
C_xy C_y⁻¹ (y ⊖ μ_y) = Wᵀ L⁻¹ (y ⊖ μ_y); C_e is symmetrised. Every array may carry the same
leading batch axes (one update per particle, per test point, …).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gpfverify.angles import difference, wrap_components
from gpfverify.errors import InputError
from gpfverify.filters.records import Gaussian, MeasurementMoments, StepRecord
from gpfverify.linalg import all_finite, cholesky_batched, solve_lower, symmetrize
from gpfverify.validate import as_array


def gaussian_update(prediction: Gaussian, moments: MeasurementMoments, y,
                    circular: Sequence[int] = (), circular_state: Sequence[int] = ()) -> StepRecord:
    """Condition the joint Gaussian of (x_k, y_k) on the measurement ``y`` (eq. 15–16).

    Shapes: prediction.mean (..., D), prediction.cov (..., D, D), moments.mu_y (..., L),
    moments.C_y (..., L, L), moments.C_xy (..., D, L), y (..., L) (broadcast against mu_y).
    No jitter is added (the record's ``jitter`` stays 0): a C_y that is not positive definite
    raises :class:`NumericalError` naming C_y instead of producing NaN or a silently changed gain.
    """
    mu_y = np.asarray(moments.mu_y, dtype=float)
    y = np.asarray(y, dtype=float)
    if y.shape[-1:] != mu_y.shape[-1:]:
        raise InputError(f"y must have {mu_y.shape[-1]} entries in its last axis, got shape {y.shape}")
    if not all_finite(y):
        raise InputError("y contains NaN or inf")
    chol = cholesky_batched(np.asarray(moments.C_y, dtype=float), "C_y")
    innovation = difference(y, mu_y, circular)
    cross_t = np.swapaxes(moments.C_xy, -1, -2)
    if innovation.shape == chol.shape[:-1] and cross_t.shape[:-2] == chol.shape[:-2]:
        # one solve for both right-hand sides [C_xyᵀ | y ⊖ μ_y] (each column is solved on its own)
        solved = solve_lower(chol, np.concatenate([cross_t, innovation[..., None]], axis=-1))
        w, white = solved[..., :-1], solved[..., -1]
    else:  # y carries more batch axes than the moments: broadcast the solves
        w = np.linalg.solve(chol, cross_t)  # L⁻¹ C_xyᵀ, (..., L, D)
        white = np.linalg.solve(chol, innovation[..., None])[..., 0]  # L⁻¹ (y ⊖ μ_y)
    mu_e = prediction.mean + np.einsum("...ld,...l->...d", w, white)
    if len(circular_state):
        mu_e = wrap_components(mu_e, circular_state)
    C_e = symmetrize(prediction.cov - np.swapaxes(w, -1, -2) @ w)
    return StepRecord(mu_p=prediction.mean, C_p=prediction.cov, mu_y=mu_y, C_y=moments.C_y,
                      C_xy=moments.C_xy, mu_e=mu_e, C_e=C_e)


def check_belief(belief: Gaussian, dim: int, name: str = "belief") -> Gaussian:
    """``belief`` as float arrays with mean (..., dim) and cov (..., dim, dim), finite;
    :class:`InputError` naming ``name`` otherwise."""
    mean, cov = belief.mean, belief.cov
    if not (type(mean) is np.ndarray and mean.dtype == np.float64 and type(cov) is np.ndarray
            and cov.dtype == np.float64):
        mean, cov = as_array(mean, f"{name}.mean"), as_array(cov, f"{name}.cov")
    if mean.shape[-1:] != (dim,) or cov.shape != mean.shape + (dim,):
        raise InputError(f"{name} must have mean (..., {dim}) and cov (..., {dim}, {dim}), "
                         f"got {mean.shape} and {cov.shape}")
    if not (all_finite(mean) and all_finite(cov)):
        raise InputError(f"{name}.{'mean' if not all_finite(mean) else 'cov'} contains NaN or inf")
    return belief if mean is belief.mean and cov is belief.cov else Gaussian(mean, cov)
