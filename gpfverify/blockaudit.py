"""The rank-condition audit of a block of steps of one layout, vectorised over the steps.

:func:`gpfverify.audit.audit_case` audits one fusion step; a run file's block (B steps with the
same state dimension and sensor sizes, :class:`~gpfverify.fusion.caseblock.CaseBlock`) has the
same small matrices at every step, so the per-step Python around them dominates. This module
computes the same audit for every step of a block at once with stacked numpy linear algebra
(one Cholesky, one SVD, one solve per quantity over the leading step axis) wherever the step's
audit takes the common path:

* the measurement y is given, no output or state component is an angle, no sensitivity is asked;
* every C_xy^m has full column rank under the rank rule (so N_m is empty, DMF is exact,
  P_m = I, the repair message and the predicted gap are zero and the repaired mean is DMF's);
* every factorisation succeeds without jitter.

There the formulas are those of :mod:`gpfverify.fusion.exactness` and :mod:`gpfverify.audit` with
their ranks fixed: canonical correlations ρ = σ(L_p⁻¹ C_xy L_y⁻ᵀ) = σ(U diag(ρ) Vᵀ) of equilibrated
Cholesky factors, G = C_xy C_y⁻¹, eq. 35's left inverse A_m as the rule's split applies it (the
canonical rule: the whitened one, L_y⁻ᵀ V diag(ρ)⁻¹ Uᵀ L_p⁻¹, whose rounding does not depend on
units; the SVD rules: V S⁻¹ U_lᵀ from numpy's SVD), eq. 35's mean
μ_p + G [(μ_y^m − μ_y(m)) + C_y^m A_m (μ_e^m − μ_p^m)]_m, CMF's μ_p + G (y − μ_y), and the
rounding bound of :func:`gpfverify.fusion.rounding.gap_bound` — the same function the per-step
audit calls, here over the block's step axis. Every other step
(a sensor that lost rank, no y, angles, a factorisation that needs jitter) is left to
:func:`~gpfverify.audit.audit_case`, which stays the one definition of the audit: the tests
compare the two routes field by field (tests/test_audit_batched.py).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from gpfverify.audit import CaseAudit, SensorAudit
from gpfverify.fusion.caseblock import CaseBlock
from gpfverify.fusion import rounding
from gpfverify.fusion.exactness import COVARIANCE_CENTRAL, COVARIANCE_LOCAL, RankRule
from gpfverify.fusion.rounding import SensorTerms
from gpfverify.tolerances import ALGEBRA_RTOL, ALGEBRA_SAFETY, EPS


def _sym(a: np.ndarray) -> np.ndarray:
    return 0.5 * (a + np.swapaxes(a, -1, -2))


def _solve_lower(factor: np.ndarray, b: np.ndarray) -> np.ndarray:
    """L⁻¹ b over the step axis (LU solves of the triangular factors)."""
    return np.linalg.solve(factor, b)


def _equilibrated(cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(d, L) with cov = diag(d) L Lᵀ diag(d) at every step (:func:`gpfverify.linalg.equilibrated_cholesky`
    without jitter); LinAlgError when a step's correlation matrix is not positive definite."""
    cov = _sym(cov)
    diag = np.diagonal(cov, axis1=1, axis2=2)
    d = np.sqrt(np.where(diag > 0, diag, 1.0))
    return d, np.linalg.cholesky(cov / (d[:, :, None] * d[:, None, :]))


@dataclass(frozen=True)
class _Canonical:
    """:func:`gpfverify.linalg.canonical_correlations` at every step: K = U diag(ρ) Vᵀ of
    K = L_x⁻¹ C L_y⁻ᵀ with L = diag(d) L_c the equilibrated factors."""

    correlations: np.ndarray
    u: np.ndarray
    vt: np.ndarray
    scale_x: np.ndarray
    factor_x: np.ndarray
    scale_y: np.ndarray
    factor_y: np.ndarray

    def left_inverse(self) -> np.ndarray:
        """A = L_y⁻ᵀ V diag(ρ)⁻¹ Uᵀ L_x⁻¹ (B, l, D) for a full-column-rank C (the canonical split's,
        :func:`gpfverify.fusion.exactness.canonical_split`)."""
        cols = self.vt.shape[1]
        v = np.swapaxes(self.vt, 1, 2) / self.correlations[:, None, :cols]
        left = np.linalg.solve(np.swapaxes(self.factor_y, 1, 2), v) / self.scale_y[:, :, None]        # L_y⁻ᵀ V/ρ
        right = (np.linalg.solve(np.swapaxes(self.factor_x, 1, 2), self.u[:, :, :cols])
                 / self.scale_x[:, :, None])                                                          # L_x⁻ᵀ U_l
        return left @ np.swapaxes(right, 1, 2)

    def left_inverse_condition(self) -> np.ndarray:
        """(κ(L_x,c) + κ(L_y,c)) (1 + ρ_1/ρ_l) (B,): the left inverse's rounding per unit of its result
        (:func:`gpfverify.fusion.rounding.left_inverse_error`)."""
        rho = self.correlations
        whitenings = np.linalg.cond(self.factor_x) + np.linalg.cond(self.factor_y)
        return whitenings * (1.0 + rho[:, 0] / rho[:, -1])


def _canonical(cov_x: np.ndarray, cov_y: np.ndarray, cross: np.ndarray) -> _Canonical:
    """:class:`_Canonical` of (C_x, C_y, C_xy) at every step."""
    dx, lx = _equilibrated(cov_x)
    dy, ly = _equilibrated(cov_y)
    scaled = cross / (dx[:, :, None] * dy[:, None, :])
    left = _solve_lower(lx, scaled)                                       # L_xc⁻¹ C
    k = np.swapaxes(_solve_lower(ly, np.swapaxes(left, 1, 2)), 1, 2)      # … L_yc⁻ᵀ
    u, rho, vt = np.linalg.svd(k, full_matrices=True)
    return _Canonical(rho, u, vt, dx, lx, dy, ly)


def _spd_condition(cov: np.ndarray) -> np.ndarray:
    """:func:`gpfverify.linalg.correlation_condition` at every step."""
    diag = np.diagonal(cov, axis1=1, axis2=2)
    d = np.sqrt(np.where(diag > 0, diag, 1.0))
    eig = np.linalg.eigvalsh(cov / (d[:, :, None] * d[:, None, :]))
    low, high = eig[:, 0], eig[:, -1]
    return np.where(low > 0, high / np.where(low > 0, low, 1.0), np.inf)


def _algebra_rtol(cond: np.ndarray) -> np.ndarray:
    """:func:`gpfverify.tolerances.algebra_rtol` elementwise."""
    return np.where(np.isfinite(cond), np.maximum(ALGEBRA_RTOL, ALGEBRA_SAFETY * EPS * np.maximum(cond, 1.0)),
                    np.inf)


def _decides_full_rank(rule: RankRule, rho: np.ndarray, s: np.ndarray, shape: tuple[int, int]
                       ) -> tuple[np.ndarray, np.ndarray]:
    """(full column rank (B,), the tolerance that decided (B,)) under ``rule``."""
    cols = shape[1]
    if rule.name == "canonical":
        assert rule.tol is not None
        return np.sum(rho > rule.tol, axis=1) == cols, np.full(rho.shape[0], float(rule.tol))
    if rule.name == "absolute":
        assert rule.tol is not None
        tol = np.full(s.shape[0], float(rule.tol))
    else:
        tol = s.max(axis=1, initial=0.0) * max(shape) * EPS
    return np.sum(s > tol[:, None], axis=1) == cols, tol


def block_audits(block: CaseBlock, rule: RankRule) -> list[CaseAudit | None]:
    """The audit of every step of ``block`` under ``rule`` that takes the common path (module
    docstring), None for the others (to be audited by :func:`~gpfverify.audit.audit_case`)."""
    steps = len(block)
    if (steps == 0 or block.y is None or block.circular or block.circular_state
            or max(block.sizes, default=0) > block.state_dim):  # l_m > D: never full column rank
        return [None] * steps
    try:
        # steps off the common path (a zero singular value, say) may divide by zero here: their
        # values are discarded, and the per-step route reports them
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            return _block_audits(block, rule)
    except np.linalg.LinAlgError:  # a factor needs jitter at some step: the per-step route decides
        return [None] * steps


def _block_audits(block: CaseBlock, rule: RankRule) -> list[CaseAudit | None]:
    steps, dim = len(block), block.state_dim
    assert block.y is not None
    y = block.y
    mu_p, c_p = block.mu_p, _sym(block.C_p)
    dpx, lpx = _equilibrated(c_p)  # L_p = diag(d_p) L_pc: the gap in prior standard deviations
    inverse = _solve_lower(lpx, np.broadcast_to(np.eye(dim), (steps, dim, dim)) / dpx[:, :, None])  # L_p⁻¹
    gain = np.swapaxes(np.linalg.solve(_sym(block.C_y), np.swapaxes(block.C_xy, 1, 2)), 1, 2)  # C_xy C_y⁻¹

    ok = ~np.all(np.isnan(y), axis=1)
    parts, per_sensor, terms = [], [], []
    start = 0
    for size, local in zip(block.sizes, block.locals):
        cols = slice(start, start + size)
        start += size
        c_y, c_xy = _sym(local.C_y), local.C_xy
        if local.C_e is not None:
            solved = np.swapaxes(np.linalg.solve(c_y, np.swapaxes(c_xy, 1, 2)), 1, 2)           # C_xy C_y⁻¹
            recovered_prior = _sym(local.C_e + solved @ np.swapaxes(c_xy, 1, 2))
            has_c_e = local.has_C_e
            prior = np.where(has_c_e[:, None, None], recovered_prior, c_p)
        else:
            has_c_e = np.zeros(steps, dtype=bool)
            prior = c_p
        canonical = _canonical(prior, c_y, c_xy)
        u, s, vt = np.linalg.svd(c_xy, full_matrices=True)
        full, tol = _decides_full_rank(rule, canonical.correlations, s, (dim, size))
        ok &= full
        factor_y = canonical.scale_y[:, :, None] * canonical.factor_y                          # L_y^m
        change = local.mu_e - local.mu_p
        if rule.name == "canonical":  # the canonical split's left inverse, unit-free rounding
            pinv = canonical.left_inverse()
            recovered = np.einsum("bij,bj->bi", pinv, change)
            error = rounding.left_inverse_error(canonical.left_inverse_condition(), factor_y, recovered)
        else:                         # numpy's SVD, as the SVD rules' split
            pinv = (np.swapaxes(vt, 1, 2) / s[:, None, :]) @ np.swapaxes(u[:, :, :size], 1, 2)   # V S⁻¹ U_lᵀ
            recovered = np.einsum("bij,bj->bi", pinv, change)
            error = rounding.svd_inverse_error(s, size, factor_y, recovered)
        parts.append(local.mu_y - block.mu_y[:, cols] + np.einsum("bij,bj->bi", c_y, recovered))
        w = np.linalg.solve(c_y, (y[:, cols] - local.mu_y)[:, :, None])[:, :, 0]
        residual = np.linalg.norm(change - np.einsum("bij,bj->bi", c_xy, w), axis=1)
        corr_cond = _spd_condition(c_y)
        scale = (np.linalg.norm(change, axis=1) + np.linalg.norm(local.mu_e, axis=1)
                 + np.linalg.norm(local.mu_p, axis=1))
        terms.append(SensorTerms(cols, local.mu_y, local.mu_p, local.mu_e, c_y, c_xy, pinv, recovered, factor_y,
                                 corr_cond, error))
        range_condition = s[:, 0] / s[:, -1]
        per_sensor.append(_SensorColumns(
            size, s, canonical.correlations, tol.tolist(),
            np.where(s[:, -1] != 0.0, range_condition, np.inf).tolist(),
            residual.tolist(), (_algebra_rtol(corr_cond) * scale).tolist(),
            [COVARIANCE_LOCAL if given else COVARIANCE_CENTRAL for given in has_c_e.tolist()]))
    dmf = mu_p + np.einsum("bij,bj->bi", gain, np.concatenate(parts, axis=1))
    cmf = mu_p + np.einsum("bij,bj->bi", gain, y - block.mu_y)
    gap = dmf - cmf
    gap_size = np.linalg.norm(np.einsum("bij,bj->bi", inverse, gap), axis=1)
    gap_bound = rounding.gap_bound(rounding.FusedRounding(inverse, gain, mu_p, block.mu_y), y, terms)
    zero_state = _zeros(dim)
    sizes, bounds = gap_size.tolist(), gap_bound.tolist()
    return [CaseAudit(tuple(_sensor_audit(t, m, c, rule, dim, zero_state) for m, c in enumerate(per_sensor)),
                      rule, True, True, dmf[t], cmf[t], gap[t], zero_state, dmf[t], gap_size=sizes[t],
                      gap_bound=bounds[t], prediction_error=sizes[t]) if ok[t] else None
            for t in range(steps)]


@dataclass(frozen=True)
class _SensorColumns:
    """One sensor's per-step results over a block (arrays with the step first, or lists)."""

    size: int
    singular_values: np.ndarray
    correlations: np.ndarray
    tol: list[float]
    condition_number: list[float]
    residual: list[float]
    consistency_tol: list[float]
    covariance: list[str]


@functools.lru_cache(maxsize=64)
def _zeros(*shape: int, dtype=float) -> np.ndarray:
    """A read-only array of zeros of ``shape``, shared by every step audit that reports one."""
    out = np.zeros(shape, dtype=dtype)
    out.flags.writeable = False
    return out


def _sensor_audit(t: int, m: int, c: _SensorColumns, rule: RankRule, dim: int, zero_state: np.ndarray
                  ) -> SensorAudit:
    """Sensor m's :class:`SensorAudit` at step t (full column rank: no kernel, exact)."""
    return SensorAudit(
        index=m, rows=dim, cols=c.size, rank=c.size, singular_values=c.singular_values[t], tol=c.tol[t],
        condition_number=c.condition_number[t], gap_gain_norm=0.0, exactness_tol=0.0, exact=True,
        repair_basis=_zeros(c.size, 0), repair_message=_zeros(c.size),
        local_consistency_residual=c.residual[t], consistency_tol=c.consistency_tol[t],
        gap_contribution=zero_state, gap_contribution_size=0.0, branch_offsets=_zeros(c.size, dtype=int),
        rank_rule=rule, canonical_correlations=c.correlations[t], covariance=c.covariance[t])
