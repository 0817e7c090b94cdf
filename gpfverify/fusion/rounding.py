r"""The rounding bounds of a fusion step, in prior standard deviations (docs/fusion-definitions.md,
"Rounding bound"), vectorised over a leading step axis (B steps at once; one step is B = 1).

Coordinates. The fused state is measured in the central prior's standard deviations, ξ = L_p⁻¹ x
(L_p = diag(d_p) L_c the equilibrated Cholesky factor of the central C_p), sensor m's innovation
in its own, z_m = L_y^m⁻¹ (y^m ⊖ μ_y^m) (C_y^m = L_y^m L_y^mᵀ), so w_m = L_y^m⁻ᵀ z_m.

Why the bound does not depend on units. A floating-point operation rounds relative to its
operands: fl(a ∘ b) = (a ∘ b)(1 + δ), |δ| ≤ eps. Rescaling the components (x → S_x x, y → S_y y,
S diagonal) rescales every operand and every result of the step component by component, so the
rounding errors, bounded componentwise by eps times magnitudes |·| of the operands, move with
them: a magnitude vector m of a state quantity becomes S_x m, and its whitened size
‖ |L_p⁻¹| m ‖₂ (|·| entrywise) stays the same, because |L_p⁻¹| becomes |L_p⁻¹| S_x⁻¹. Every
term below is such a whitened componentwise magnitude, or a norm of a whitened matrix
(L_p⁻¹ G_m L_y^m, canonical correlations, condition numbers of equilibrated factors), which do
not change either. Under the canonical rule the reconstruction's operands are the whitened
inverse's (:func:`gpfverify.fusion.exactness.sensor_terms`); under the SVD rank rules, which depend
on units, numpy's SVD's own condition σ_1/σ_r enters and changes with units, as those rules do.

Gap bound (:func:`gap_bound`), when DMF is exact, on ‖L_p⁻¹(μ_DMF − μ_CMF)‖: G = C_xy C_y⁻¹ is
shared by both rules, so its rounding cancels to first order; what rounds independently is,
componentwise in state units,

* CMF, μ_p + G (y ⊖ μ_y):                       |μ_p| + |G| (|y| + |μ_y|);
* DMF, μ_p + G v with v_m = (μ_y^m ⊖ μ_y(m)) + C_y^m r_m, r_m = A_m (μ_e^m − μ_p^m):
                                                |μ_p| + Σ_m |G_m| (|μ_y^m| + |μ_y(m)| + |C_y^m| |r_m|);
* the report: μ_e^m − μ_p^m equals C_xy^m w_m only to the sensor's own rounding of its update,
  eps (|μ_e^m| + |μ_p^m| + κ(C_y^m) |C_xy^m| |r_m|) (a Cholesky solve with C_y^m, κ the condition
  of its correlation matrix), which eq. 35 carries into the state by |G_m C_y^m A_m|;

and the reconstruction r_m itself, computed with an error of whitened size ‖L_y^mᵀ δr_m‖ ≤ e_m eps
(e_m depends on the route that computed A_m: :func:`left_inverse_error`, :func:`svd_inverse_error`,
:func:`gpfverify.fusion.exactness.sensor_terms`), which G_m C_y^m = (G_m L_y^m) L_y^mᵀ maps into
the state: ‖L_p⁻¹ G_m L_y^m‖₂ e_m. The sum is multiplied by (D + L) eps
(:func:`~gpfverify.tolerances.rounding_bound`: D + L operations in sequence). A sensor that lost
rank is judged exact when its gap gain R_m is within its exactness bound τ_m (below), not only
when it is zero; the gap such a sensor may still leave, τ_m ‖z_m‖, is added.

Exactness bound (:func:`exactness_bound`), on sensor m's gap gain R_m (the gap per unit whitened
innovation through the kernel its rank rule dropped): the fused estimate's own rounding, which a
gap gain cannot be told from — its size ‖ |L_p⁻¹| |μ_p| ‖ and its update per unit whitened
innovation ‖ |L_p⁻¹| |G| |L_y| ‖₂ (L_y the central C_y's factor); the computed G (a Cholesky solve
with the central C_y, relative error κ(C_y) eps componentwise) seen through the kernel projector,
whose whitened norm is ω_m (1 when the rule projects in whitened coordinates);
and the computed kernel, whose angle to the exact one is θ_m eps, seen through
‖L_p⁻¹ G_m L_y^m‖₂. Same factor (D + L) eps.

:class:`SensorTerms` carries a sensor's operands; the callers (the per-case audit in
:mod:`gpfverify.fusion.exactness` and the batched block audit in :mod:`gpfverify.audit.block`)
compute the route-dependent numbers e_m, ω_m, θ_m with the route that computed the reconstruction.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gpfverify.tolerances import rounding_bound


def _abs_times(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a| b over the step axis: (B, n, k) × (B, k) → (B, n)."""
    return np.einsum("bij,bj->bi", np.abs(a), b)


def vector_norms(a: np.ndarray) -> np.ndarray:
    """‖a_b‖₂ of every row of (B, n), scaled by the row's largest entry first (as BLAS's nrm2), so
    that entries of 1e-200 do not underflow when squared."""
    largest = np.max(np.abs(a), axis=1, initial=0.0)
    scale = np.where(largest > 0, largest, 1.0)
    return largest * np.sqrt(np.sum((a / scale[:, None]) ** 2, axis=1))


def whitened_sizes(factor_y: np.ndarray, r: np.ndarray) -> np.ndarray:
    """‖L_yᵀ r‖ (B,) of (B, l, l) factors and (B, l) vectors: a w-space vector's whitened size."""
    return vector_norms(np.einsum("bji,bj->bi", factor_y, r))


def left_inverse_error(condition: np.ndarray, factor_y: np.ndarray, r: np.ndarray) -> np.ndarray:
    """e_m of the whitened left inverse (canonical rule, full column rank), (B,): two triangular
    solves with the equilibrated factors and the canonical SVD, whose inverse on its range amplifies
    by ρ_1/ρ_r, so ``condition`` = (κ(L_p,c) + κ(L_y,c)) (1 + ρ_1/ρ_r) relative to ‖L_yᵀ r‖."""
    return condition * whitened_sizes(factor_y, r)


def svd_inverse_error(singular_values: np.ndarray, rank: int, factor_y: np.ndarray, r: np.ndarray) -> np.ndarray:
    """e_m of numpy's SVD (numpy and absolute rules), (B,): a relative error σ_1/σ_r in the
    Euclidean size of r_m, at most κ₂(L_y^m) times more in its whitened size (both depend on units,
    as these rules do)."""
    condition = singular_values[:, 0] / singular_values[:, rank - 1] * np.linalg.cond(factor_y)
    return condition * whitened_sizes(factor_y, r)


def spectral_norms(a: np.ndarray) -> np.ndarray:
    """‖a_b‖₂ of every matrix of a stack (B, n, k) → (B,) (0 for an empty matrix)."""
    if not a.shape[1] or not a.shape[2]:
        return np.zeros(a.shape[0])
    return np.linalg.norm(a, 2, axis=(1, 2))


@dataclass(frozen=True)
class FusedRounding:
    """The centre's side of B steps: ``inverse`` L_p⁻¹ (B, D, D), ``gain`` G (B, D, L), the prior
    mean ``mu_p`` (B, D) and the predicted measurement ``mu_y`` (B, L)."""

    inverse: np.ndarray
    gain: np.ndarray
    mu_p: np.ndarray
    mu_y: np.ndarray

    @property
    def operations(self) -> int:
        """D + L: the longest chain of roundings in a fused mean."""
        return self.gain.shape[1] + self.gain.shape[2]

    def whitened_size(self, magnitudes: np.ndarray) -> np.ndarray:
        """‖ |L_p⁻¹| m ‖₂ of entrywise magnitudes m ≥ 0 (B, D) → (B,): the largest whitened size of
        a state error whose entries are at most m."""
        return vector_norms(_abs_times(self.inverse, magnitudes))

    def whitened_gain(self, block: slice, factor_y: np.ndarray) -> np.ndarray:
        """‖L_p⁻¹ G_m L_y^m‖₂ (B,): how many prior standard deviations the fused mean moves per unit
        of sensor m's whitened innovation (``factor_y`` L_y^m (B, l, l))."""
        return spectral_norms(self.inverse @ self.gain[:, :, block] @ factor_y)

    def componentwise_gain(self, block: slice, factor_y: np.ndarray) -> np.ndarray:
        """‖ |L_p⁻¹| |G_m| |L_y^m| ‖₂ (B,): the same for errors bounded componentwise (entrywise
        products of magnitudes, unit-free as the whitened gain is)."""
        return spectral_norms(np.abs(self.inverse) @ np.abs(self.gain[:, :, block]) @ np.abs(factor_y))


@dataclass(frozen=True)
class SensorTerms:
    """Sensor m's operands over B steps: its columns ``block`` of G; its report ``mu_y`` (B, l),
    ``mu_p``, ``mu_e`` (B, D), ``cov_y`` C_y^m (B, l, l), ``cross_cov`` C_xy^m (B, D, l); the
    ``reconstruction`` A_m (B, l, D) eq. 35 applied and what it gave, ``recovered``
    r_m = A_m (μ_e^m − μ_p^m) (B, l); ``factor_y`` L_y^m (B, l, l); ``cov_y_condition`` κ(C_y^m)
    (B,), the condition of its correlation matrix; ``reconstruction_error`` e_m (B,), the whitened
    size of r_m's computed error per eps (module docstring); ``accepted_gap`` (B,) the gap a sensor
    with a kernel may leave while judged exact, its exactness bound times its whitened innovation's
    size ‖z_m‖ (None: no kernel)."""

    block: slice
    mu_y: np.ndarray
    mu_p: np.ndarray
    mu_e: np.ndarray
    cov_y: np.ndarray
    cross_cov: np.ndarray
    reconstruction: np.ndarray
    recovered: np.ndarray
    factor_y: np.ndarray
    cov_y_condition: np.ndarray
    reconstruction_error: np.ndarray
    accepted_gap: np.ndarray | None = None


def gap_bound(fused: FusedRounding, y: np.ndarray, sensors: Sequence[SensorTerms]) -> np.ndarray:
    """First-order rounding bound on ‖L_p⁻¹(μ_DMF − μ_CMF)‖₂ when DMF is exact, (B,) in prior
    standard deviations (module docstring); ``y`` (B, L) the stacked measurements."""
    gain = fused.gain
    magnitudes = 2.0 * np.abs(fused.mu_p) + _abs_times(gain, np.abs(y) + np.abs(fused.mu_y))
    reconstruction = np.zeros(gain.shape[0])
    accepted = np.zeros(gain.shape[0])
    for s in sensors:
        g_m = gain[:, :, s.block]
        r = s.recovered
        carried = g_m @ s.cov_y @ s.reconstruction                                   # G_m C_y^m A_m
        own = (np.abs(s.mu_e) + np.abs(s.mu_p)
               + s.cov_y_condition[:, None] * _abs_times(s.cross_cov, np.abs(r)))    # the report's rounding
        innovation = np.abs(s.mu_y) + np.abs(fused.mu_y[:, s.block]) + _abs_times(s.cov_y, np.abs(r))
        magnitudes = magnitudes + _abs_times(g_m, innovation) + _abs_times(carried, own)
        reconstruction = reconstruction + fused.whitened_gain(s.block, s.factor_y) * s.reconstruction_error
        if s.accepted_gap is not None:
            accepted = accepted + s.accepted_gap
    return rounding_bound(fused.whitened_size(magnitudes) + reconstruction, fused.operations) + accepted


def estimate_floor(fused: FusedRounding, central_factor_y: np.ndarray) -> np.ndarray:
    """The fused estimate's own rounding, (B,) prior standard deviations: ‖ |L_p⁻¹| |μ_p| ‖ plus its
    update per unit whitened innovation ‖ |L_p⁻¹| |G| |L_y| ‖₂ (``central_factor_y`` L_y (B, L, L)
    of the central C_y), before the factor (D + L) eps."""
    update = spectral_norms(np.abs(fused.inverse) @ np.abs(fused.gain) @ np.abs(central_factor_y))
    return fused.whitened_size(np.abs(fused.mu_p)) + update


def exactness_bound(fused: FusedRounding, floor: np.ndarray, gain_condition: np.ndarray, block: slice,
                    factor_y: np.ndarray, obliqueness: np.ndarray, kernel_angle: np.ndarray) -> np.ndarray:
    """First-order rounding bound on sensor m's gap gain R_m when it is zero (module docstring), (B,):
    ``floor`` from :func:`estimate_floor`, ``gain_condition`` κ(C_y) of the central C_y's
    correlation matrix (B,), ``factor_y`` L_y^m, ``obliqueness`` ω_m and ``kernel_angle`` θ_m (B,)."""
    gain_term = fused.componentwise_gain(block, factor_y) * gain_condition * obliqueness
    kernel_term = fused.whitened_gain(block, factor_y) * kernel_angle
    return rounding_bound(floor + gain_term + kernel_term, fused.operations)
