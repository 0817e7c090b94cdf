r"""Sensor m's kernel split and exactness evidence at every step of a block of one layout, vectorised
over the steps: the batched counterpart of :func:`~gpfverify.fusion.exactness.sensor_split`, the
exactness evidence of :func:`~gpfverify.fusion.exactness.analyse_sensors` and
:func:`~gpfverify.fusion.exactness.sensor_terms` (the formulas, and eq. 35's, are derived there and
in :mod:`gpfverify.fusion.rounding`; this module computes the same ones over a leading step axis).

Every stack of small matrices (B steps) is factored, solved and decomposed by one numpy call: the
equilibrated Cholesky factors L = diag(d) L_c of C_p^m and C_y^m, the canonical SVD
L_p⁻¹ C_xy^m L_y⁻ᵀ = U diag(ρ) Vᵀ and numpy's SVD of C_xy^m. The rank r_m the rule decides varies
between steps, and with it the shapes of what depends on it (V_r, the kernel basis N_m, the
generalised inverse A_m), so those are computed per group of the steps of one rank (at most l_m + 1
groups):

* A_m, eq. 35's inverse: under the canonical rule the whitened left inverse
  L_y⁻ᵀ V diag(ρ)⁻¹ Uᵀ L_p⁻¹ where the rank is full, and the Moore–Penrose inverse
  V_r S_r⁻¹ U_rᵀ truncated at r in C_xy^m's Jacobi SVD (:func:`~gpfverify.linalg.graded_svd`,
  one LAPACK call per step: LAPACK has no batched Jacobi SVD) where it is lost; under the SVD rules
  numpy's SVD truncated at r;
* the repair projector I − P_m = N_m N_mᵀ, N_m = V_⊥ of that SVD (empty at full rank);
* the gap gain R_m = ‖L_p⁻¹ G_m C_y^m Π_m L_y⁻ᵀ‖₂ and its rounding bound τ_m
  (:func:`~gpfverify.fusion.rounding.exactness_bound`; zero at full rank);
* the operands of the step's gap bound (:class:`~gpfverify.fusion.rounding.SensorTerms`), among them
  the reconstruction error e_m of the route that computed A_m.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from gpfverify.fusion.caseblock import LocalBlock
from gpfverify.fusion.exactness import COVARIANCE_CENTRAL, COVARIANCE_LOCAL, RankRule
from gpfverify.fusion.rounding import (FusedRounding, SensorTerms, estimate_floor, exactness_bound,
                                      left_inverse_error, spectral_norms, svd_inverse_error, vector_norms)
from gpfverify.linalg import graded_svd
from gpfverify.tolerances import EPS, RESOLVABLE_GAP


def transposed(a: np.ndarray) -> np.ndarray:
    """Every matrix of a stack transposed (a view)."""
    return np.swapaxes(a, -1, -2)


def symmetric(a: np.ndarray) -> np.ndarray:
    """(A + Aᵀ)/2 for every matrix of a stack."""
    return 0.5 * (a + transposed(a))


def apply(a: np.ndarray, v: np.ndarray) -> np.ndarray:
    """A_b v_b for every step: (B, n, k) × (B, k) → (B, n)."""
    return np.einsum("bij,bj->bi", a, v)


def solve_lower(factor: np.ndarray, b: np.ndarray) -> np.ndarray:
    """L⁻¹ b over the step axis (LU solves of the triangular factors: numpy has no batched
    triangular solve)."""
    return np.linalg.solve(factor, b)


def correlation_matrices(cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(d, cov / (d dᵀ)) at every step, d the square roots of the diagonal (1 where it is not
    positive): the scaling that makes the equilibrated factors and conditions unit-free."""
    diag = np.diagonal(cov, axis1=1, axis2=2)
    d = np.sqrt(np.where(diag > 0, diag, 1.0))
    return d, cov / (d[:, :, None] * d[:, None, :])


def equilibrated(cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(d, L_c) with cov = diag(d) L_c L_cᵀ diag(d) at every step
    (:func:`gpfverify.linalg.equilibrated_cholesky` without jitter); LinAlgError when a step's
    correlation matrix is not positive definite."""
    d, correlation = correlation_matrices(symmetric(cov))
    return d, np.linalg.cholesky(correlation)


def right_solve_factored(b: np.ndarray, scale: np.ndarray, factor: np.ndarray) -> np.ndarray:
    """b C⁻¹ at every step, b (B, n, l), from the equilibrated Cholesky factor of the symmetric
    positive definite C (B, l, l), C = diag(d) L_c L_cᵀ diag(d) (``scale`` d, ``factor`` L_c, from
    :func:`equilibrated`). The per-step route solves with C's Cholesky factor, whose accuracy does not
    depend on the scaling of C's rows and columns; an LU solve of C itself does (a gap gain of 2.5e-12
    against 2.7e-17 where C_y's variances spanned 1e-9 to 2e7)."""
    half = solve_lower(factor, transposed(b) / scale[:, :, None])                                # L_c⁻¹ D⁻¹ bᵀ
    return transposed(np.linalg.solve(transposed(factor), half) / scale[:, :, None])            # (C⁻¹ bᵀ)ᵀ


def correlation_conditions(cov: np.ndarray) -> np.ndarray:
    """:func:`gpfverify.linalg.correlation_condition` at every step."""
    eig = np.linalg.eigvalsh(correlation_matrices(cov)[1])
    low, high = eig[:, 0], eig[:, -1]
    return np.where(low > 0, high / np.where(low > 0, low, 1.0), np.inf)


@dataclass(frozen=True)
class Whitening:
    """:func:`gpfverify.linalg.canonical_correlations` at every step: K = L_x⁻¹ C L_y⁻ᵀ = U diag(ρ) Vᵀ
    (full SVD) with L = diag(d) L_c the equilibrated factors."""

    correlations: np.ndarray
    u: np.ndarray
    vt: np.ndarray
    scale_x: np.ndarray
    factor_x: np.ndarray
    scale_y: np.ndarray
    factor_y: np.ndarray

    def take(self, steps: np.ndarray) -> Whitening:
        """The same at the steps listed."""
        return Whitening(*(getattr(self, f)[steps] for f in self.__dataclass_fields__))

    def left_inverse(self, rank: int) -> np.ndarray:
        """A = L_y⁻ᵀ V_r diag(ρ_r)⁻¹ U_rᵀ L_x⁻¹ (B, l, D): the canonical split's whitened inverse at
        ``rank`` (zero at rank 0)."""
        steps, cols, rows = self.vt.shape[0], self.vt.shape[1], self.u.shape[1]
        if not rank:
            return np.zeros((steps, cols, rows))
        v = transposed(self.vt[:, :rank, :]) / self.correlations[:, None, :rank]
        left = solve_lower(transposed(self.factor_y), v) / self.scale_y[:, :, None]                  # L_y⁻ᵀ V_r/ρ_r
        right = solve_lower(transposed(self.factor_x), self.u[:, :, :rank]) / self.scale_x[:, :, None]  # L_x⁻ᵀ U_r
        return left @ transposed(right)

    def factor_conditions(self) -> np.ndarray:
        """κ(L_x,c) + κ(L_y,c) (B,): how much the two whitenings can amplify rounding."""
        return np.linalg.cond(self.factor_x) + np.linalg.cond(self.factor_y)


def whitening(cov_x: np.ndarray, cross: np.ndarray, dy: np.ndarray, ly: np.ndarray) -> Whitening:
    """:class:`Whitening` of (C_x, C_y, C_xy) at every step, C_y given by its equilibrated factor
    (``dy``, ``ly``, from :func:`equilibrated`)."""
    dx, lx = equilibrated(cov_x)
    scaled = cross / (dx[:, :, None] * dy[:, None, :])
    left = solve_lower(lx, scaled)                                                 # L_xc⁻¹ C
    k = transposed(solve_lower(ly, transposed(left)))                              # … L_yc⁻ᵀ
    u, rho, vt = np.linalg.svd(k, full_matrices=True)
    return Whitening(rho, u, vt, dx, lx, dy, ly)


@dataclass(frozen=True)
class CentralBlock:
    """The centre's side of B steps: ``rounding`` (L_p⁻¹, G, μ_p, μ_y), the central C_y with its
    equilibrated factor (``scale_y``, ``factor_y``, from :func:`equilibrated`) and, formed when a
    sensor has a kernel, the fused estimate's own rounding (:meth:`floor`) and κ(C_y)."""

    rounding: FusedRounding
    cov_y: np.ndarray
    scale_y: np.ndarray
    factor_y: np.ndarray

    def take(self, steps: np.ndarray) -> FusedRounding:
        """The rounding operands at the steps listed."""
        r = self.rounding
        return FusedRounding(r.inverse[steps], r.gain[steps], r.mu_p[steps], r.mu_y[steps])

    @functools.cached_property
    def floor(self) -> np.ndarray:
        """:func:`~gpfverify.fusion.rounding.estimate_floor` at every step."""
        return estimate_floor(self.rounding, self.scale_y[:, :, None] * self.factor_y)

    @functools.cached_property
    def gain_condition(self) -> np.ndarray:
        """κ(C_y) of the central C_y's correlation matrix at every step."""
        return correlation_conditions(self.cov_y)


@dataclass(frozen=True)
class SensorBlock:
    """Sensor m's split and evidence at every step (arrays with the step first): ``rank`` r_m and
    the ``tol`` that decided it (in the rule's units), numpy's ``singular_values`` of C_xy^m, the
    canonical ``correlations`` and the ``covariance`` that whitened the state, ``factor_y`` L_y^m,
    ``pinv`` eq. 35's A_m, ``reconstruction`` the inverse whose operands the rounding bound takes
    (the whitened one under the canonical rule, else A_m), ``kernel_vectors`` whose columns from
    r_m on are N_m, ``projector`` N_m N_mᵀ, and the gap gain ``residual`` R_m with its ``bound``
    τ_m (both zero at full rank); ``whitening_condition`` κ(L_p,c) + κ(L_y,c) (canonical rule)."""

    size: int
    rank: np.ndarray
    tol: np.ndarray
    singular_values: np.ndarray
    correlations: np.ndarray
    covariance: list[str]
    factor_y: np.ndarray
    pinv: np.ndarray
    reconstruction: np.ndarray
    kernel_vectors: np.ndarray
    projector: np.ndarray
    residual: np.ndarray
    bound: np.ndarray
    whitening_condition: np.ndarray | None

    @property
    def exact(self) -> np.ndarray:
        """:attr:`~gpfverify.fusion.exactness.SensorExactness.exact` at every step."""
        return (self.residual <= self.bound) & (self.bound <= RESOLVABLE_GAP)


def _decided_ranks(rule: RankRule, rho: np.ndarray, s: np.ndarray, shape: tuple[int, int]
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(rank (B,), the tolerance that decided it (B,)) under ``rule``."""
    if rule.name == "canonical":
        assert rule.tol is not None
        return np.sum(rho > rule.tol, axis=1), np.full(rho.shape[0], float(rule.tol))
    if rule.name == "absolute":
        assert rule.tol is not None
        tol = np.full(s.shape[0], float(rule.tol))
    else:
        tol = s.max(axis=1, initial=0.0) * max(shape) * EPS
    return np.sum(s > tol[:, None], axis=1), tol


def analyse_sensor(local: LocalBlock, central_cov: np.ndarray, rule: RankRule, central: CentralBlock,
                   cols: slice) -> SensorBlock:
    """Sensor m (its reports ``local``, columns ``cols`` of G) at every step under ``rule``; the
    canonical correlations whiten with the C_p^m recovered from C_e^m where the step has it, else
    with ``central_cov`` (:func:`~gpfverify.fusion.exactness.sensor_prior_covariance`). Raises
    LinAlgError where a factor would need jitter (the per-step route decides those steps)."""
    steps, dim, size = local.C_xy.shape
    cross = local.C_xy
    dy, ly = equilibrated(local.C_y)
    if local.C_e is not None:
        gain_m = right_solve_factored(cross, dy, ly)                                             # C_xy C_y⁻¹
        recovered = symmetric(local.C_e + gain_m @ transposed(cross))
        prior = np.where(local.has_C_e[:, None, None], recovered, central_cov)
        has_c_e = local.has_C_e
    else:
        prior, has_c_e = central_cov, np.zeros(steps, dtype=bool)
    white = whitening(prior, cross, dy, ly)
    u_np, s, vt_np = np.linalg.svd(cross, full_matrices=True)
    rank, tol = _decided_ranks(rule, white.correlations, s, (dim, size))
    factor_y = white.scale_y[:, :, None] * white.factor_y                                        # L_y^m
    canonical = rule.name == "canonical"
    pinv = np.empty((steps, size, dim))
    reconstruction = pinv if not canonical else np.empty((steps, size, dim))
    kernel_vectors = transposed(vt_np).copy()
    projector = np.zeros((steps, size, size))
    residual, bound = np.zeros(steps), np.zeros(steps)
    conditions = white.factor_conditions() if canonical else None
    for r in np.unique(rank).tolist():
        at = np.flatnonzero(rank == r)
        if canonical:
            sub = white.take(at)
            reconstruction[at] = sub.left_inverse(r)
            if r == size:
                pinv[at] = reconstruction[at]
            else:  # eq. 35's Moore–Penrose inverse at the decided rank, in C_xy^m's Jacobi SVD
                for t in at.tolist():
                    u, sg, vt = graded_svd(cross[t])
                    pinv[t] = (vt[:r].T / sg[:r]) @ u[:, :r].T
                    kernel_vectors[t] = vt.T
        else:
            pinv[at] = (transposed(vt_np[at, :r, :]) / s[at, None, :r]) @ transposed(u_np[at, :, :r])  # V_r S_r⁻¹ U_rᵀ
        if r == size:
            continue
        basis = kernel_vectors[at, :, r:]                                                          # N_m
        projector[at] = basis @ transposed(basis)
        residual[at], bound[at] = _evidence(central, at, cols, factor_y[at], basis, r,
                                            white.take(at) if canonical else None,
                                            None if conditions is None else conditions[at], s[at])
    covariance = [COVARIANCE_LOCAL if given else COVARIANCE_CENTRAL for given in has_c_e.tolist()]
    return SensorBlock(size, rank, tol, s, white.correlations, covariance, factor_y, pinv, reconstruction,
                       kernel_vectors, projector, residual, bound, conditions)


def _evidence(central: CentralBlock, at: np.ndarray, cols: slice, factor_y: np.ndarray, basis: np.ndarray,
              rank: int, white: Whitening | None, conditions: np.ndarray | None, s: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """(R_m, τ_m) at the steps ``at``, all of rank ``rank`` < l_m (the exactness evidence of
    :func:`~gpfverify.fusion.exactness.analyse_sensors`): the canonical rule projects in whitened
    coordinates (V_⊥ of the canonical SVD; ω_m = 1, θ_m = (κ(L_p,c) + κ(L_y,c)) ρ_1/ρ_r), the SVD
    rules in C_xy^m's own (N_m; ω_m = ‖L_yᵀN_m‖ ‖L_y⁻¹N_m‖, θ_m = σ_1/σ_r ‖L_y‖ ‖L_y⁻¹N_m‖)."""
    fused = central.take(at)
    whitened_gain = fused.inverse @ fused.gain[:, :, cols] @ factor_y                             # L_p⁻¹ G_m L_y^m
    if white is not None and conditions is not None:
        residual = spectral_norms(whitened_gain @ transposed(white.vt[:, rank:, :]))
        obliqueness = np.ones(len(at))
        rho = white.correlations
        angle = conditions * (rho[:, 0] / rho[:, rank - 1]) if rank else np.zeros(len(at))
    else:
        dual = solve_lower(factor_y, basis)                                                       # L_y⁻¹ N_m
        lifted = transposed(factor_y) @ basis                                                     # L_yᵀ N_m
        residual = spectral_norms(whitened_gain @ lifted @ transposed(dual))
        dual_norm = spectral_norms(dual)
        obliqueness = spectral_norms(lifted) * dual_norm
        angle = (s[:, 0] / s[:, rank - 1] * spectral_norms(factor_y) * dual_norm if rank
                 else np.zeros(len(at)))
    bound = exactness_bound(fused, central.floor[at], central.gain_condition[at], cols, factor_y, obliqueness,
                            angle)
    return residual, bound


def sensor_terms(sensor: SensorBlock, local: LocalBlock, cols: slice, change: np.ndarray,
                 innovation: np.ndarray, cov_y_condition: np.ndarray) -> SensorTerms:
    """Sensor m's operands of the gap bound at every step (:func:`~gpfverify.fusion.exactness.sensor_terms`):
    ``change`` μ_e^m ⊖ μ_p^m and ``innovation`` y^m ⊖ μ_y^m (B, l); ``cov_y_condition`` κ(C_y^m)."""
    recovered = apply(sensor.reconstruction, change)
    error = np.zeros(len(change))
    canonical = sensor.whitening_condition is not None
    for r in np.unique(sensor.rank).tolist():
        if not r:
            continue
        at = np.flatnonzero(sensor.rank == r)
        factor, rec = sensor.factor_y[at], recovered[at]
        if not canonical:
            error[at] = svd_inverse_error(sensor.singular_values[at], r, factor, rec)
            continue
        assert sensor.whitening_condition is not None
        rho = sensor.correlations[at]
        error[at] = left_inverse_error(sensor.whitening_condition[at] * (1.0 + rho[:, 0] / rho[:, r - 1]), factor, rec)
        if r < sensor.size:  # the Jacobi SVD's backward error, carried by the whitened inverse
            carried = np.abs(transposed(factor) @ sensor.reconstruction[at])
            error[at] += vector_norms(apply(carried, apply(np.abs(local.C_xy[at]), np.abs(rec)) + np.abs(change[at])))
    lost = sensor.rank < sensor.size
    accepted = None
    if lost.any():  # the gap an exact-judged kernel may leave: τ_m ‖z_m‖, z_m = L_y^m⁻¹ (y^m ⊖ μ_y^m)
        whitened = solve_lower(sensor.factor_y, innovation[:, :, None])[:, :, 0]
        accepted = np.where(lost, sensor.bound * vector_norms(whitened), 0.0)
    return SensorTerms(cols, local.mu_y, local.mu_p, local.mu_e, local.C_y, local.C_xy, sensor.reconstruction,
                       recovered, sensor.factor_y, cov_y_condition, error, accepted)
