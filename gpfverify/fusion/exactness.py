r"""When the distributed rule (seed 000 eq. 35) reproduces centralized fusion, and how to repair it.

Notation. Sensor m's local update (eq. 32) is μ_e^m − μ_p^m = C_xy^m w_m with the *whitened local
innovation* w_m = (C_y^m)⁻¹ (y^m ⊖ μ_y^m) ∈ ℝ^{l_m}, where ⊖ is the difference with sensor m's angle
outputs (``circular``) wrapped to (−π, π]. With the thin SVD C_xy^m = U S Vᵀ at rank
r_m, let P_m = (C_xy^m)⁺ C_xy^m = V_r V_rᵀ (projector onto range(C_xy^mᵀ)) and N_m an orthonormal
basis of ker C_xy^m (l_m − r_m columns, I − P_m = N_m N_mᵀ). G = C_xy C_y⁻¹ (central) is split
into column blocks G_m.

Gap. Since (C_xy^m)⁺(μ_e^m − μ_p^m) = P_m w_m, the DMF mean (eq. 35) is
μ_p + Σ_m G_m (μ_y^m ⊖ μ_y(m)) + Σ_m G_m C_y^m P_m w_m, while CMF (eq. 36) is
μ_p + Σ_m G_m (y^m ⊖ μ_y(m)). Without angles y^m − μ_y(m) = (μ_y^m − μ_y(m)) + C_y^m w_m, hence

    μ_DMF − μ_CMF = Σ_m G_m C_y^m (P_m − I) w_m = −Σ_m (G_m C_y^m N_m)(N_mᵀ w_m).

Angles: branch offsets. On an angle output j of sensor m write a = wrap(μ_y^m − μ_y(m))_j (DMF's
first term), b = wrap(y^m − μ_y^m)_j (the local innovation, (C_y^m w_m)_j) and
c = wrap(y^m − μ_y(m))_j (CMF's innovation). Since a ≡ μ_y^m − μ_y(m) and b ≡ y^m − μ_y^m modulo 2π,
a + b ≡ y^m − μ_y(m) ≡ c; and a, b ∈ (−π, π] give a + b ∈ (−2π, 2π], so c = wrap(a + b) and

    a + b − c = 2π n_j,   n_j = 0 if a + b ∈ (−π, π],  +1 if a + b > π,  −1 if a + b ≤ −π.

So with full column rank (P_m = I) DMF's block-m innovation a + b equals CMF's c exactly when the
sum of the two separately wrapped terms stays in (−π, π]; otherwise they differ by 2π n_j on output
j. In general (any rank) the block-m innovations differ by 2π n_m − C_y^m N_m N_mᵀ w_m, and

    μ_DMF − μ_CMF = Σ_m [2π G_m n_m − (G_m C_y^m N_m)(N_mᵀ w_m)]          (:func:`predicted_gap`),

n_m ∈ {−1, 0, 1}^{l_m} the *branch offsets* (:func:`branch_offsets`; zero on non-angle outputs).
Both wrapped terms are small when the central and local predictions agree and the measurement is
near its prediction, so a nonzero offset means |a| + |b| > π: predictions or innovations of
more than π/2 on an angle. Repair messages do not remove it (they restore only N_mᵀ w_m).

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

from gpfverify.angles import TWO_PI, difference, wrap
from gpfverify.fusion.case import FusionCase, LocalReport
from gpfverify.fusion.centralized import fusion_gain
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
    """w_m = (C_y^m)⁻¹ (y^m ⊖ μ_y^m), the vector the local update multiplies by C_xy^m (angle
    outputs wrapped)."""
    return solve_spd(local.C_y, difference(y_m, local.mu_y, local.circular), "local C_y")


def repair_message(local: LocalReport, y_m: np.ndarray, rank_tol: float | None = None) -> np.ndarray:
    """What sensor m sends besides eq. 34 so that DMF is exact: r_m = N_mᵀ w_m (l_m − r_m numbers)."""
    return kernel_split(local.C_xy, rank_tol).kernel_basis.T @ whitened_innovation(local, y_m)


def branch_offsets(case: FusionCase) -> tuple[np.ndarray, ...]:
    """Per sensor the integers n_m ∈ {−1, 0, 1}^{l_m} with
    wrap(μ_y^m − μ_y(m)) + wrap(y^m − μ_y^m) − wrap(y^m − μ_y(m)) = 2π n_m on the angle outputs
    (zero elsewhere; module docstring, "branch offsets"). Needs ``case.y``."""
    out = []
    for m, (block, local) in enumerate(zip(case.central.blocks, case.locals)):
        n = np.zeros(local.mu_y.shape[0], dtype=int)
        if local.circular:
            j = list(local.circular)
            central_part = wrap(local.mu_y[j] - case.central.mu_y[block][j])
            total = central_part + wrap(case.local_measurement(m)[j] - local.mu_y[j])
            n[j] = np.rint((total - wrap(total)) / TWO_PI).astype(int)
        out.append(n)
    return tuple(out)


def sensor_gap(case: FusionCase, sensor: SensorExactness, gain: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Sensor m's share of μ_DMF − μ_CMF: 2π G_m n_m − (G_m C_y^m N_m)(N_mᵀ w_m) (needs ``case.y``)."""
    w = whitened_innovation(case.locals[sensor.index], case.local_measurement(sensor.index))
    g_m = gain[:, case.central.blocks[sensor.index]]
    return TWO_PI * (g_m @ offsets) - sensor.gap_gain @ (sensor.split.kernel_basis.T @ w)


def predicted_gap(case: FusionCase, sensors: tuple[SensorExactness, ...], gain: np.ndarray | None = None
                  ) -> np.ndarray:
    """Closed-form μ_DMF − μ_CMF = Σ_m [2π G_m n_m − (G_m C_y^m N_m)(N_mᵀ w_m)], the sum of
    :func:`sensor_gap` (``gain`` G defaults to the case's; needs ``case.y``)."""
    gain = fusion_gain(case.central) if gain is None else gain
    gap = np.zeros(case.state_dim)
    for s, n in zip(sensors, branch_offsets(case)):
        gap += sensor_gap(case, s, gain, n)
    return gap


def local_consistency_residual(case: FusionCase, m: int) -> np.ndarray:
    """μ_e^m − μ_p^m − C_xy^m w_m (w_m from the wrapped innovation): zero when the logged local
    posterior is the local update with the logged y (eq. 32); when it is not, the observed gap
    need not equal the predicted one."""
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
