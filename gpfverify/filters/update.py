"""The Gaussian measurement update shared by every Gaussian filter (seed 000 eq. 15–16, 30–31).

Given the predicted state N(μ_p, C_p) and the predicted measurement moments (μ_y, C_y, C_xy):

    μ_e = μ_p + C_xy C_y⁻¹ (y ⊖ μ_y),        C_e = C_p − C_xy C_y⁻¹ C_xyᵀ,

where ⊖ is the difference with the angle outputs wrapped to (−π, π] (``circular``); angle state
components (``circular_state``) of μ_e are wrapped too.

A measurement may be missing: a NaN entry of y is an output that did not report. The update is then
the one on the outputs that did (the Gaussian conditioned on them alone): the missing outputs'
rows and columns of C_y are replaced by those of the identity, their columns of C_xy and their
innovations by zeros, so that C_y is block diagonal between reported and missing outputs, its
Cholesky factor too, and the gain of every missing output is exactly zero. With every output of y
missing the posterior is the prediction. The record keeps the predicted moments of every output.

With the Cholesky factor C_y = L Lᵀ and W = L⁻¹ C_xyᵀ (a solve, never an inverse), C_xy C_y⁻¹ C_xyᵀ = Wᵀ W and
C_xy C_y⁻¹ (y ⊖ μ_y) = Wᵀ L⁻¹ (y ⊖ μ_y); C_e is exactly symmetric.
Every array may carry the same leading batch axes (one update per particle, per test point, …).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gpfverify.angles import difference, wrap_components
from gpfverify.errors import InputError, NumericalError
from gpfverify.filters.records import Gaussian, MeasurementMoments, StepRecord
from gpfverify.linalg import all_finite, cholesky_symmetric, matmul_for, solve_lower, symmetrize
from gpfverify.validate import as_array

_FLOAT = np.dtype(np.float64)


def gaussian_update(prediction: Gaussian, moments: MeasurementMoments, y,
                    circular: Sequence[int] = (), circular_state: Sequence[int] = ()) -> StepRecord:
    """Condition the joint Gaussian of (x_k, y_k) on the measurement ``y`` (eq. 15–16).

    Shapes: prediction.mean (..., D), prediction.cov (..., D, D), moments.mu_y (..., L),
    moments.C_y (..., L, L), moments.C_xy (..., D, L), y (..., L) (broadcast against mu_y).
    C_p and C_y are symmetrised, (C + Cᵀ)/2, before they are used and recorded. A NaN in ``y`` is
    an output that did not report (module docstring); ``y`` gets an :class:`InputError` when its
    last axis is not L or it holds inf. No jitter is added (the
    record's ``jitter`` stays 0): a C_y that is not finite or not positive definite raises
    :class:`NumericalError` naming C_y instead of producing NaN or a silently changed gain.
    """
    return condition(prediction.mean, symmetrize(prediction.cov), moments.mu_y, symmetrize(moments.C_y),
                     np.asarray(moments.C_xy, dtype=float), y, circular, circular_state)


def condition(mu_p: np.ndarray, C_p: np.ndarray, mu_y, C_y: np.ndarray, C_xy: np.ndarray, y,
              circular: Sequence[int] = (), circular_state: Sequence[int] = ()) -> StepRecord:
    """:func:`gaussian_update` on the fields of its two records, for a step that computed them as
    arrays with C_p and C_y already exactly symmetric (float arrays; not symmetrised again).

    With S = L⁻¹ [C_xyᵀ | y ⊖ μ_y] = [W | v] (one solve for both right-hand sides), the Gram
    matrix SᵀS holds WᵀW and Wᵀ v: one product gives the covariance and the mean correction.
    numpy forms a product XᵀX by a symmetric rank-k update (BLAS syrk, one triangle mirrored), so
    WᵀW and C_e = C_p − WᵀW are exactly symmetric without a further symmetrisation."""
    mu_y = np.asarray(mu_y, dtype=float)
    y = np.asarray(y, dtype=float)
    if y.shape[-1:] != mu_y.shape[-1:]:
        raise InputError(f"y must have {mu_y.shape[-1]} entries in its last axis, got shape {y.shape}")
    gain_C_y, gain_C_xy, reported = C_y, C_xy, None  # the moments the gain is made of
    if not all_finite(y):
        if np.isinf(y).any():
            raise InputError("y contains inf")
        reported = ~np.isnan(y)  # NaN: an output that did not report
        gain_C_y, gain_C_xy = _without_missing(C_y, C_xy, reported)
    chol = cholesky_symmetric(gain_C_y, "C_y")
    if not all_finite(chol):
        raise NumericalError("C_y contains NaN or inf")
    innovation = difference(y, mu_y, circular) if len(circular) else y - mu_y
    if reported is not None:
        innovation = np.where(reported, innovation, 0.0)
    if innovation.shape == chol.shape[:-1] and gain_C_xy.shape[:-2] == chol.shape[:-2]:
        # [C_xy; (y ⊖ μ_y)ᵀ] stacked as rows and transposed: Fortran order, what LAPACK takes
        solved = solve_lower(chol, np.concatenate((gain_C_xy, innovation[..., None, :]), axis=-2)
                             .swapaxes(-1, -2))
        gram = matmul_for(solved)(solved.swapaxes(-1, -2), solved)
        shift, spread = gram[..., :-1, -1], gram[..., :-1, :-1]
    else:  # y carries more batch axes than the moments: broadcast the solves
        w = np.linalg.solve(chol, np.swapaxes(gain_C_xy, -1, -2))  # L⁻¹ C_xyᵀ, (..., L, D)
        white = np.linalg.solve(chol, innovation[..., None])  # L⁻¹ (y ⊖ μ_y), (..., L, 1)
        shift, spread = (w.swapaxes(-1, -2) @ white)[..., 0], w.swapaxes(-1, -2) @ w
    mu_e = mu_p + shift
    if len(circular_state):
        mu_e = wrap_components(mu_e, circular_state)
    return StepRecord(mu_p, C_p, mu_y, C_y, C_xy, mu_e, C_p - spread)


def _without_missing(C_y: np.ndarray, C_xy: np.ndarray, reported: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """C_y with the missing outputs' rows and columns those of the identity, and C_xy with their
    columns zero (module docstring); ``reported`` (..., L) broadcast against both."""
    both = reported[..., :, None] & reported[..., None, :]
    eye = np.eye(C_y.shape[-1], dtype=bool)
    return (np.where(both, C_y, np.where(eye, 1.0, 0.0)),
            np.where(reported[..., None, :], C_xy, 0.0))


def check_belief(belief: Gaussian, dim: int, name: str = "belief") -> Gaussian:
    """``belief`` as float arrays with mean (..., dim) and cov (..., dim, dim), finite;
    :class:`InputError` naming ``name`` otherwise."""
    mean, cov = belief.mean, belief.cov
    if not (type(mean) is np.ndarray and mean.dtype == _FLOAT and type(cov) is np.ndarray
            and cov.dtype == _FLOAT):
        mean, cov = as_array(mean, f"{name}.mean"), as_array(cov, f"{name}.cov")
    if mean.shape[-1:] != (dim,) or cov.shape != mean.shape + (dim,):
        raise InputError(f"{name} must have mean (..., {dim}) and cov (..., {dim}, {dim}), "
                         f"got {mean.shape} and {cov.shape}")
    if not all_finite(mean, cov):
        raise InputError(f"{name}.{'mean' if not all_finite(mean) else 'cov'} contains NaN or inf")
    return belief if mean is belief.mean and cov is belief.cov else Gaussian(mean, cov)
