"""The rank-condition audit of a block of steps of one layout, vectorised over the steps.

:func:`gpfverify.audit.case.audit_case` audits one fusion step; a run file's block (B steps with the
same state dimension, sensor sizes and angle components, :class:`~gpfverify.fusion.caseblock.CaseBlock`)
has the same small matrices at every step, so the per-step Python around them dominates. This
module computes the same audit for every step of a block at once with stacked numpy linear algebra
(one Cholesky, one SVD, one solve per quantity over the leading step axis), whatever rank each
sensor's C_xy^m has at each step, with or without the measurement y, with angle outputs and angle
state components:

* each sensor's kernel split, gap gain and exactness evidence
  (:func:`gpfverify.audit.blockexactness.analyse_sensor`, per group of steps of one rank);
* eq. 35's mean μ_p + G [(μ_y^m ⊖ μ_y(m)) + C_y^m A_m (μ_e^m ⊖ μ_p^m)]_m (angle state components
  wrapped), and where a sensor lost rank under the canonical rule the unit-free variant's mean
  (A_m the whitened inverse) and its distance from DMF's;
* with y: CMF's μ_p + G (y ⊖ μ_y), each sensor's whitened innovation w_m = (C_y^m)⁻¹(y^m ⊖ μ_y^m),
  its repair message k_m = N_m N_mᵀ w_m, branch offsets n_m and share of the gap
  2π G_m n_m − G_m C_y^m k_m, the repaired mean (A_m (μ_e^m ⊖ μ_p^m) + N_m N_mᵀ k_m in place of the
  reconstruction), the observed and predicted gaps in prior standard deviations, and the rounding
  bound of :func:`gpfverify.fusion.rounding.gap_bound` — the same function the per-step audit calls,
  here over the block's step axis.

A block whose steps need something else is left to :func:`~gpfverify.audit.case.audit_case`, which stays
the one definition of the audit: a factorisation that needs jitter at some step (the per-step route
adds it), or sensitivities (casadi, per step). The tests compare the two routes field by field
(tests/test_audit_batched.py).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from gpfverify.angles import TWO_PI, difference, wrap, wrap_components
from gpfverify.audit.case import CaseAudit, SensorAudit, audit_case
from gpfverify.audit.blockexactness import (CentralBlock, SensorBlock, analyse_sensor, apply, correlation_conditions,
                                            equilibrated, right_solve_factored, sensor_terms, solve_lower, symmetric,
                                            transposed)
from gpfverify.filters.records import Gaussian, StepRecord
from gpfverify.fusion.case import CentralPrediction, split_circular
from gpfverify.fusion.caseblock import CaseBlock, LocalBlock
from gpfverify.fusion.distributed import dmf_update
from gpfverify.fusion.exactness import RankRule
from gpfverify.fusion.rounding import FusedRounding, SensorTerms, gap_bound
from gpfverify.tolerances import algebra_rtols


def block_audits(block: CaseBlock, rule: RankRule, dmf: BlockDMF | None = None) -> list[CaseAudit | None]:
    """The audit of every step of ``block`` under ``rule``, or None for every step when the block
    is left to :func:`~gpfverify.audit.case.audit_case` (module docstring); ``dmf`` the block's eq. 35
    when :func:`block_dmf` has already computed it under ``rule``."""
    steps = len(block)
    if not steps:
        return []
    try:
        # a step's quantities that its audit does not report (a kernel's at full rank, y's without y)
        # may divide by zero here: they are discarded
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            return _block_audits(block, rule, _block_dmf(block, rule) if dmf is None else dmf)
    except np.linalg.LinAlgError:  # a factor needs jitter at some step: the per-step route decides
        return [None] * steps


@dataclass(frozen=True)
class SensorDMF:
    """Sensor m's part of eq. 35 at every step of a block: its ``split`` and evidence, μ_e^m ⊖ μ_p^m
    (``change``), μ_y^m ⊖ μ_y(m) (``predicted``) and A_m (μ_e^m ⊖ μ_p^m) (``recovered``)."""

    split: SensorBlock
    change: np.ndarray
    predicted: np.ndarray
    recovered: np.ndarray


@dataclass(frozen=True)
class BlockDMF:
    """Eq. 35 at every step of a block (the DMF step, before any audit): the centre's rounding
    operands and C_y factors (``central``), each sensor's part, the fused ``mean`` (B, D) and
    covariance ``cov`` = C_p − G C_xyᵀ (B, D, D), shared with CMF."""

    central: CentralBlock
    sensors: tuple[SensorDMF, ...]
    mean: np.ndarray
    cov: np.ndarray

    @property
    def condition_holds(self) -> np.ndarray:
        """Proposition 1's condition at every step: every C_xy^m of full column rank (B,)."""
        return np.all([s.split.rank == s.split.size for s in self.sensors], axis=0)


def block_dmf(block: CaseBlock, rule: RankRule) -> BlockDMF | None:
    """Eq. 35 under ``rule`` at every step of ``block`` — with each sensor's rank decision, split and
    exactness evidence (:func:`~gpfverify.audit.blockexactness.analyse_sensor`) — or None when a
    factorisation needs jitter at some step (the per-step route, :func:`~gpfverify.fusion.distributed.dmf_update`,
    decides those)."""
    try:
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            return _block_dmf(block, rule)
    except np.linalg.LinAlgError:
        return None


def _block_dmf(block: CaseBlock, rule: RankRule) -> BlockDMF:
    steps, dim, states = len(block), block.state_dim, block.circular_state
    c_p = symmetric(block.C_p)
    dpx, lpx = equilibrated(c_p)  # L_p = diag(d_p) L_pc: differences in prior standard deviations
    inverse = solve_lower(lpx, np.broadcast_to(np.eye(dim), (steps, dim, dim)) / dpx[:, :, None])  # L_p⁻¹
    dy, ly = equilibrated(block.C_y)
    gain = right_solve_factored(block.C_xy, dy, ly)                                                # C_xy C_y⁻¹
    central = CentralBlock(FusedRounding(inverse, gain, block.mu_p, block.mu_y), block.C_y, dy, ly)
    ends = np.cumsum(block.sizes).tolist()
    sensors = []
    for size, end, local, angles in zip(block.sizes, ends, block.locals, split_circular(block.circular, block.sizes)):
        cols = slice(end - size, end)
        split = analyse_sensor(local, c_p, rule, central, cols)
        change = difference(local.mu_e, local.mu_p, states)
        sensors.append(SensorDMF(split, change, difference(local.mu_y, block.mu_y[:, cols], angles),
                                 apply(split.pinv, change)))
    parts = [s.predicted + apply(local.C_y, s.recovered) for s, local in zip(sensors, block.locals)]
    mean = wrap_components(block.mu_p + apply(gain, np.concatenate(parts, axis=1)), states)
    return BlockDMF(central, tuple(sensors), mean, symmetric(c_p - gain @ transposed(block.C_xy)))


def _whitened_sizes(inverse: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """‖L_p⁻¹ v‖₂ at every step: a state difference in prior standard deviations."""
    return np.linalg.norm(apply(inverse, vectors), axis=1)


def _block_audits(block: CaseBlock, rule: RankRule, dmf_block: BlockDMF) -> list[CaseAudit | None]:
    steps, dim, states = len(block), block.state_dim, block.circular_state
    mu_p, central = block.mu_p, dmf_block.central
    inverse, gain = central.rounding.inverse, central.rounding.gain
    has_y = block.has_y
    y = np.where(has_y[:, None], block.y, 0.0) if block.y is not None else np.zeros_like(block.mu_y)
    ends = np.cumsum(block.sizes).tolist()
    sensors = [_sensor_run(block, slice(end - size, end), local, angles, central, y, part)
               for size, end, local, angles, part in zip(block.sizes, ends, block.locals,
                                                         split_circular(block.circular, block.sizes),
                                                         dmf_block.sensors)]

    def fused(parts: list[np.ndarray]) -> np.ndarray:
        """μ_p + G v, v stacked from the sensors' terms (angle state components wrapped)."""
        return wrap_components(mu_p + apply(gain, np.concatenate(parts, axis=1)), states)

    dmf = dmf_block.mean
    full = dmf_block.condition_holds
    exact = np.all([s.sensor.exact for s in sensors], axis=0)
    variant = dependence = None
    if rule.name == "canonical" and not full.all():  # the unit-free variant, where a sensor lost rank
        variant = fused([s.variant_part for s in sensors])
        dependence = _whitened_sizes(inverse, difference(dmf, variant, states)).tolist()
    cmf = wrap_components(mu_p + apply(gain, difference(y, block.mu_y, block.circular)), states)
    repaired = fused([s.repaired_part for s in sensors])
    gap = difference(dmf, cmf, states)
    predicted = np.sum([s.share for s in sensors], axis=0)
    gap_sizes = _whitened_sizes(inverse, gap).tolist()
    errors = _whitened_sizes(inverse, difference(gap, predicted, states)).tolist()
    bounds = gap_bound(central.rounding, y, [s.terms for s in sensors]).tolist()
    measured, full, exact = has_y.tolist(), full.tolist(), exact.tolist()
    out: list[CaseAudit | None] = []
    for t in range(steps):
        audits = tuple(_sensor_audit(t, m, s, rule, dim, measured[t]) for m, s in enumerate(sensors))
        variant_t = None if variant is None or full[t] else variant[t]
        dependence_t = None if dependence is None or full[t] else dependence[t]
        if not measured[t]:
            out.append(CaseAudit(audits, rule, full[t], exact[t], dmf[t], unit_free_dmf_mean=variant_t,
                                 unit_dependence=dependence_t))
            continue
        out.append(CaseAudit(audits, rule, full[t], exact[t], dmf[t], cmf[t], gap[t], predicted[t], repaired[t],
                             gap_size=gap_sizes[t], gap_bound=bounds[t], prediction_error=errors[t],
                             unit_free_dmf_mean=variant_t, unit_dependence=dependence_t))
    return out


def _branch_offsets(local_mu_y: np.ndarray, central_mu_y: np.ndarray, y: np.ndarray, angles) -> np.ndarray:
    """n_m at every step (:func:`gpfverify.fusion.exactness.branch_offsets`): on each angle output,
    wrap(μ_y^m − μ_y(m)) + wrap(y^m − μ_y^m) − wrap(y^m − μ_y(m)) = 2π n (zero elsewhere)."""
    offsets = np.zeros(local_mu_y.shape, dtype=int)
    if angles:
        j = list(angles)
        total = wrap(local_mu_y[:, j] - central_mu_y[:, j]) + wrap(y[:, j] - local_mu_y[:, j])
        offsets[:, j] = np.rint((total - wrap(total)) / TWO_PI).astype(int)
    return offsets


@dataclass(frozen=True)
class _SensorRun:
    """One sensor over a block: its split and evidence, its terms of the fused means (eq. 35's
    ``dmf_part``, the unit-free variant's, the repaired one's), what needs y (repair ``message``
    k_m, ``share`` of the gap, branch ``offsets``, the gap bound's ``terms``), and the per-step
    numbers read into :class:`~gpfverify.audit.case.SensorAudit` records, as Python lists."""

    sensor: SensorBlock
    dmf_part: np.ndarray
    variant_part: np.ndarray
    repaired_part: np.ndarray
    message: np.ndarray
    share: np.ndarray
    offsets: np.ndarray
    terms: SensorTerms
    residual: list[float]
    consistency_tol: list[float]
    share_size: list[float]
    rank: list[int]
    tol: list[float]
    condition: list[float]
    gap_gain: list[float]
    bound: list[float]
    exact: list[bool]


def _sensor_run(block: CaseBlock, cols: slice, local: LocalBlock, angles: tuple[int, ...], central: CentralBlock,
                y: np.ndarray, part: SensorDMF) -> _SensorRun:
    """Sensor m (columns ``cols``, angle outputs ``angles``, its part of eq. 35 ``part``) at every
    step of ``block``; ``y`` the stacked measurements (zero rows where a step has none, whose results
    are not reported)."""
    sensor, change, predicted_term, recovered = part.split, part.change, part.predicted, part.recovered
    innovation = difference(y[:, cols], local.mu_y, angles)
    w = np.linalg.solve(local.C_y, innovation[:, :, None])[:, :, 0]                               # (C_y^m)⁻¹(…)
    message = apply(sensor.projector, w)                                                          # k_m = N_m N_mᵀ w_m
    offsets = _branch_offsets(local.mu_y, block.mu_y[:, cols], y[:, cols], angles)
    g_m = central.rounding.gain[:, :, cols]
    share = TWO_PI * apply(g_m, offsets) - apply(g_m @ local.C_y, message)
    corr_cond = correlation_conditions(local.C_y)
    size = (np.linalg.norm(local.mu_e - local.mu_p, axis=1) + np.linalg.norm(local.mu_e, axis=1)
            + np.linalg.norm(local.mu_p, axis=1))
    s = sensor.singular_values
    return _SensorRun(
        sensor, predicted_term + apply(local.C_y, recovered),
        predicted_term + apply(local.C_y, apply(sensor.reconstruction, change)),
        predicted_term + apply(local.C_y, recovered + apply(sensor.projector, message)),
        message, share, offsets, sensor_terms(sensor, local, cols, change, innovation, corr_cond),
        np.linalg.norm(change - apply(local.C_xy, w), axis=1).tolist(), (algebra_rtols(corr_cond) * size).tolist(),
        _whitened_sizes(central.rounding.inverse, share).tolist(), sensor.rank.tolist(), sensor.tol.tolist(),
        np.where(s[:, -1] != 0.0, s[:, 0] / s[:, -1], np.inf).tolist(), sensor.residual.tolist(),
        sensor.bound.tolist(), sensor.exact.tolist())


def _sensor_audit(t: int, m: int, c: _SensorRun, rule: RankRule, dim: int, measured: bool) -> SensorAudit:
    """Sensor m's :class:`SensorAudit` at step t."""
    s, rank, on = c.sensor, c.rank[t], measured
    return SensorAudit(
        index=m, rows=dim, cols=s.size, rank=rank, singular_values=s.singular_values[t], tol=c.tol[t],
        condition_number=c.condition[t], gap_gain_norm=c.gap_gain[t], exactness_tol=c.bound[t],
        exact=c.exact[t], repair_basis=s.kernel_vectors[t][:, rank:], repair_message=c.message[t] if on else None,
        local_consistency_residual=c.residual[t] if on else None, consistency_tol=c.consistency_tol[t] if on else None,
        gap_contribution=c.share[t] if on else None, gap_contribution_size=c.share_size[t] if on else None,
        branch_offsets=c.offsets[t] if on else None, rank_rule=rule, canonical_correlations=s.correlations[t],
        covariance=s.covariance[t])


# -- many Monte Carlo runs' steps (one step each) ---------------------------------------------------

@dataclass(frozen=True)
class RunsDMF:
    """Eq. 35 at one step of B Monte Carlo runs (a block of their cases) with its audit: the fused
    ``mean`` (B, D) and ``cov``; per sensor the singular values of C_xy^m (B, l), its canonical
    correlations (B, min(D, l)), whether it has full column rank and the tolerance that decided
    (B,); the ``audits`` of the step (one per run); ``online`` the time of eq. 35 itself per run,
    ``audit_seconds`` the audit's for the batch (on the caller's clock)."""

    mean: np.ndarray
    cov: np.ndarray
    singular_values: list[np.ndarray]
    correlations: list[np.ndarray]
    full_rank: list[np.ndarray]
    tol: list[np.ndarray]
    audits: list[CaseAudit]
    online: float
    audit_seconds: float

    @property
    def condition_holds(self) -> np.ndarray:
        return np.all(self.full_rank, axis=0)


def dmf_runs(block: CaseBlock, rule: RankRule, clock: Callable[[], float] = time.perf_counter) -> RunsDMF:
    """Eq. 35 and the audit of every run's step: the block route, eq. 35 alone and the audit alone
    timed. Where a factor of some run's step needs jitter the block route refuses the block; each
    run is then taken alone — by the block route when its own step allows it (the same bits as in
    any batch), else by the per-step route, which adds the jitter — so that no run's numbers depend
    on another's."""
    start = clock()
    dmf = block_dmf(block, rule)
    online = (clock() - start) / len(block)
    start = clock()
    audits = [] if dmf is None else block_audits(block, rule, dmf)
    audit_seconds = clock() - start
    if dmf is None or not all(audits):
        if len(block) == 1:
            return _dmf_per_step(block, rule, clock)
        return _concatenated_runs([dmf_runs(block.take(slice(b, b + 1)), rule, clock) for b in range(len(block))])
    splits = [s.split for s in dmf.sensors]
    return RunsDMF(dmf.mean, dmf.cov, [s.singular_values for s in splits], [s.correlations for s in splits],
                     [s.rank == s.size for s in splits], [s.tol for s in splits],
                     [a for a in audits if a is not None], online, audit_seconds)


def _concatenated_runs(parts: list[RunsDMF]) -> RunsDMF:
    """Single runs' :class:`RunsDMF` as one (times: their mean per run, the audit's sum)."""
    sensors = range(len(parts[0].singular_values))
    join = lambda get: [np.concatenate([get(p)[m] for p in parts]) for m in sensors]  # noqa: E731
    return RunsDMF(np.concatenate([p.mean for p in parts]), np.concatenate([p.cov for p in parts]),
                     join(lambda p: p.singular_values), join(lambda p: p.correlations), join(lambda p: p.full_rank),
                     join(lambda p: p.tol), [a for p in parts for a in p.audits],
                     float(np.mean([p.online for p in parts])), float(sum(p.audit_seconds for p in parts)))


def _dmf_per_step(block: CaseBlock, rule: RankRule, clock: Callable[[], float]) -> RunsDMF:
    """:func:`dmf_runs` run by run by the per-step route (dmf_update and audit_case)."""
    runs = len(block)
    start = clock()
    cases = [block.case(b) for b in range(runs)]
    results = [dmf_update(case, rank_rule=rule) for case in cases]
    online = (clock() - start) / runs
    start = clock()
    audits = [audit_case(case, rank_rule=rule) for case in cases]
    audit_seconds = clock() - start
    per_sensor = range(len(block.sizes))

    def stacked(get) -> list[np.ndarray]:
        return [np.array([get(r.sensors[m]) for r in results]) for m in per_sensor]
    return RunsDMF(np.array([r.mean for r in results]), np.array([r.cov for r in results]),
                     stacked(lambda s: s.split.rank.singular_values),
                     stacked(lambda s: np.full(0, np.nan) if s.split.correlations is None else s.split.correlations),
                     stacked(lambda s: s.full_column_rank), stacked(lambda s: s.split.rank.tol), audits, online,
                     audit_seconds)


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
    G = C_xy C_y⁻¹ by the equilibrated Cholesky factor of C_y (as :func:`block_dmf`
    forms it, so the one-step gap is the audit's to the bit), μ_e = μ_p + G (y ⊖ μ_y) with the angle
    outputs wrapped and the angle state components of μ_e wrapped, C_e = C_p − G C_xyᵀ."""
    gain = right_solve_factored(block.C_xy, *equilibrated(block.C_y))
    mean = wrap_components(block.mu_p + apply(gain, difference(block.y, block.mu_y, block.circular)),
                           block.circular_state)
    return Gaussian(mean, symmetric(symmetric(block.C_p) - gain @ transposed(block.C_xy)))
