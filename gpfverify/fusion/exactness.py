r"""When the distributed rule (seed 000 eq. 35) reproduces centralized fusion, and how to repair it.

Notation. Sensor m's local update (eq. 32) is μ_e^m − μ_p^m = C_xy^m w_m with the *whitened local
innovation* w_m = (C_y^m)⁻¹ (y^m − μ_y^m) ∈ ℝ^{l_m}. With the thin SVD C_xy^m = U S Vᵀ at rank
r_m, let P_m = (C_xy^m)⁺ C_xy^m = V_r V_rᵀ (projector onto range(C_xy^mᵀ)) and N_m an orthonormal
basis of ker C_xy^m (l_m − r_m columns, I − P_m = N_m N_mᵀ). G = C_xy C_y⁻¹ (central) is split
into column blocks G_m.

Gap. Since (C_xy^m)⁺(μ_e^m − μ_p^m) = P_m w_m, the DMF mean (eq. 35) is
μ_p + Σ_m G_m (μ_y^m − μ_y(m)) + Σ_m G_m C_y^m P_m w_m, while CMF (eq. 36) is
μ_p + Σ_m G_m (y^m − μ_y(m)) = μ_p + Σ_m G_m (μ_y^m − μ_y(m)) + Σ_m G_m C_y^m w_m. Hence

    μ_DMF − μ_CMF = Σ_m G_m C_y^m (P_m − I) w_m = −Σ_m (G_m C_y^m N_m)(N_mᵀ w_m).

Exactness. As y^m ranges over ℝ^{l_m}, w_m does too, independently per sensor; so DMF = CMF for
every measurement iff every *gap gain* G_m C_y^m N_m is zero, i.e. ker C_xy^m ⊆ ker G_m C_y^m.
Full column rank (N_m empty, Proposition 1) is sufficient, not necessary: a measurement component
uncorrelated with the state and with every other component has a zero column in C_xy^m and still
leaves DMF exact. Full column rank needs l_m ≤ D (rank C_xy^m ≤ min(D, l_m)).

Repair. The part of w_m that eq. 35 cannot recover is N_mᵀ w_m: μ_e^m − μ_p^m determines w_m only
on range(C_xy^mᵀ) (its kernel component is annihilated by C_xy^m). If sensor m also sends the
l_m − r_m numbers r_m = N_mᵀ w_m (:func:`repair_message`), the centre adds Σ_m G_m C_y^m N_m r_m
and recovers CMF exactly. Sensor and centre compute N_m from the same C_xy^m with the same rank
tolerance (:func:`kernel_split`), so they agree on the basis.

Numerics. Ranks use an explicit absolute singular-value tolerance (default numpy's matrix_rank
rule σ_max · max(D, l_m) · eps); singular values at or below it count as zero, and the
pseudo-inverse in eq. 35 uses the same decision. A gap gain counts as zero when
‖G_m C_y^m N_m‖₂ ≤ algebra_rtol(cond C_y) · ‖G_m‖₂ ‖C_y^m‖₂ — the rounding level of forming the
product through a solve with the central C_y.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from gpfverify.fusion.case import FusionCase, LocalReport
from gpfverify.linalg import RankReport, solve_spd
from gpfverify.tolerances import algebra_rtol, numpy_rank_tol


@dataclass(frozen=True)
class KernelSplit:
    """C_xy^m = U S Vᵀ split at the rank tolerance: ``rank`` (singular values, tol),
    ``pinv`` (l, D) = V_r S_r⁻¹ U_rᵀ, ``kernel_basis`` N (l, l − r) orthonormal."""

    rank: RankReport
    pinv: np.ndarray
    kernel_basis: np.ndarray


def kernel_split(cross_cov: np.ndarray, tol: float | None = None) -> KernelSplit:
    """SVD of a sensor's cross covariance C_xy^m (D, l) with absolute tolerance ``tol``
    (default numpy's matrix_rank rule)."""
    u, s, vt = np.linalg.svd(cross_cov, full_matrices=True)
    used = numpy_rank_tol(s, cross_cov.shape) if tol is None else float(tol)
    r = int(np.sum(s > used))
    pinv = (vt[:r].T / s[:r]) @ u[:, :r].T
    return KernelSplit(RankReport(r, s, used, cross_cov.shape), pinv, vt[r:].T)


@dataclass(frozen=True)
class SensorExactness:
    """Exactness evidence for sensor ``index``: its kernel split, the gap gain G_m C_y^m N_m
    (D, l − r), its 2-norm ``residual`` and the tolerance ``tol`` that decides ``exact``."""

    index: int
    split: KernelSplit
    gap_gain: np.ndarray
    residual: float
    tol: float

    @property
    def exact(self) -> bool:
        return self.residual <= self.tol

    @property
    def full_column_rank(self) -> bool:
        return self.split.rank.full_column_rank

    @property
    def repair_dim(self) -> int:
        return self.split.kernel_basis.shape[1]


def analyse_sensors(case: FusionCase, gain: np.ndarray, rank_tol: float | None = None
                    ) -> tuple[SensorExactness, ...]:
    """Kernel split and gap gain of every sensor; ``rank_tol`` (default ``case.rank_tol``, else
    numpy's rule per matrix) is the absolute singular-value tolerance."""
    tol = case.rank_tol if rank_tol is None else rank_tol
    eig = np.linalg.eigvalsh(case.central.C_y)
    rtol = algebra_rtol(eig[-1] / eig[0])
    out = []
    for m, (block, local) in enumerate(zip(case.central.blocks, case.locals)):
        split = kernel_split(local.C_xy, tol)
        g_m = gain[:, block]
        gap_gain = g_m @ local.C_y @ split.kernel_basis
        residual = float(np.linalg.norm(gap_gain, 2)) if gap_gain.size else 0.0
        scale = float(np.linalg.norm(g_m, 2) * np.linalg.norm(local.C_y, 2))
        out.append(SensorExactness(m, split, gap_gain, residual, rtol * scale))
    return tuple(out)


def whitened_innovation(local: LocalReport, y_m: np.ndarray) -> np.ndarray:
    """w_m = (C_y^m)⁻¹ (y^m − μ_y^m), the vector the local update multiplies by C_xy^m."""
    return solve_spd(local.C_y, y_m - local.mu_y, "local C_y")


def repair_message(local: LocalReport, y_m: np.ndarray, rank_tol: float | None = None) -> np.ndarray:
    """What sensor m sends besides eq. 34 so that DMF is exact: r_m = N_mᵀ w_m (l_m − r_m numbers)."""
    return kernel_split(local.C_xy, rank_tol).kernel_basis.T @ whitened_innovation(local, y_m)


def predicted_gap(case: FusionCase, sensors: tuple[SensorExactness, ...]) -> np.ndarray:
    """Closed-form μ_DMF − μ_CMF = −Σ_m (G_m C_y^m N_m)(N_mᵀ w_m) (needs ``case.y``)."""
    gap = np.zeros(case.state_dim)
    for s, local in zip(sensors, case.locals):
        w = whitened_innovation(local, case.local_measurement(s.index))
        gap -= s.gap_gain @ (s.split.kernel_basis.T @ w)
    return gap


def local_consistency_residual(case: FusionCase, m: int) -> np.ndarray:
    """μ_e^m − μ_p^m − C_xy^m w_m: zero when the logged local posterior is the local update with the
    logged y (eq. 32); when it is not, the observed gap need not equal the predicted one."""
    local = case.locals[m]
    return local.mu_e - local.mu_p - local.C_xy @ whitened_innovation(local, case.local_measurement(m))


def range_condition_number(split: KernelSplit) -> float:
    """σ_max / σ_r over the singular values kept by the rank decision (1 for a zero matrix)."""
    s = split.rank.singular_values[: split.rank.rank]
    return float(s[0] / s[-1]) if s.size else 1.0


def equivalence_tolerance(case: FusionCase, gain: np.ndarray, sensors: tuple[SensorExactness, ...]) -> float:
    """Rounding bound on ‖μ_DMF − μ_CMF‖ when DMF is exact *at the rank tolerance used* (every
    sensor's verdict ``exact``; a singular value at or below the tolerance is dropped, and its
    effect is then the closed-form gap, not rounding):

        algebra_rtol(κ) · (‖μ_p‖ + ‖G‖₂ Σ_m [‖C_y^m‖₂ ‖(C_xy^m)⁺‖₂ (‖μ_e^m‖ + ‖μ_p^m‖)
                                               + ‖μ_y^m‖ + ‖μ_y(m)‖ + ‖y^m‖]),
        κ = max(cond C_y, max_m cond(C_xy^m on its range) · cond C_y^m).

    Each term is the size of an operand eq. 35 or 36 works with, which loses ≈ eps·κ of itself.
    The recovered innovation (C_xy^m)⁺(μ_e^m − μ_p^m) carries the rounding of μ_e^m and μ_p^m —
    of their sizes, not of their difference: when C_xy^m is small the local update C_xy^m w_m can
    fall below eps·‖μ_e^m‖ and be lost in the report itself, and (C_xy^m)⁺ amplifies that loss by
    1/σ_r. Norms are BLAS nrm2 (scipy.linalg.norm), which does not underflow for tiny entries.
    Needs ``case.y``."""
    c = case.central
    eig = np.linalg.eigvalsh(c.C_y)
    cond, terms = eig[-1] / eig[0], 0.0
    for s, block, local in zip(sensors, c.blocks, case.locals):
        eig_m = np.linalg.eigvalsh(local.C_y)
        cond = max(cond, range_condition_number(s.split) * eig_m[-1] / eig_m[0])
        terms += (sla.norm(local.C_y, 2) * sla.norm(s.split.pinv, 2) * (sla.norm(local.mu_e) + sla.norm(local.mu_p))
                  + sla.norm(local.mu_y) + sla.norm(c.mu_y[block])
                  + sla.norm(case.local_measurement(s.index)))
    return algebra_rtol(cond) * (sla.norm(c.mu_p) + sla.norm(gain, 2) * terms)
