"""The fusion paper's Monte Carlo runs (seed 000 §4) advanced together: :func:`run_family_batch`
filters B runs' test segments at once with the twelve methods of
:mod:`gpfverify.papers.fusion.run` and returns each run's record exactly as
:func:`~gpfverify.papers.fusion.run.run_family` would (the same fields, the same meaning).

Each run keeps its own data, GPs (a :func:`~gpfverify.models.batch_gp_models` model, run b's GPs
at b) and starts; per step the batch takes

* the sensors' local filters, CMF and DMF's central prediction: the Gaussian family's steps on
  beliefs (B, D) (:mod:`gpfverify.filters`);
* eq. 35 with its rank decisions and exactness evidence and the per-step audit (gap, its rounding
  bound, the closed-form gap): the block route over the runs (:func:`gpfverify.audit.block.block_dmf`,
  :func:`gpfverify.audit.block.block_audits`), or the per-step route run by run where a factor of
  some run's step needs jitter;
* CW on arrays (:func:`gpfverify.fusion.batched.convex_combination_batch`); RCC-CI with its conic
  data formed for the batch and one Clarabel solve per run — an interior-point solve whose
  iterations would couple the runs if their problems were solved as one
  (:func:`gpfverify.fusion.rcc_ci.rcc_ci_batch`).

A run's record does not depend on B or on which runs share its batch (tests/test_batch_experiments.py
checks batches of 1, 3 and a split, bit for bit, outside the timing fields) and equals the per-run
path to :data:`~gpfverify.tolerances.PER_RUN_RTOL` relative to the size of what is compared.

Timing. A method's time per step is the CPU time (:data:`~gpfverify.papers.fusion.run.CPU_CLOCK`)
of its batched call divided by B, the same for every run of the batch: a measurement of the batch,
not of one run (results.json says so; the timing claims pair the methods within each run, so their
ratio is the batch's ratio).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from gpfverify.audit.block import dmf_runs
from gpfverify.papers.fusion.contract import (DEFAULT_RULE, FAMILIES, FUSION_RULES, FamilyRun, FusionRun,
                                              family_methods)
from gpfverify.contract.methods import Method
from gpfverify.papers.fusion.run import CPU_CLOCK, ROUNDING_PROBE, _audit_entry, hyperparameters
from gpfverify.filters.families import GaussianFamily, gaussian_family
from gpfverify.filters.records import Gaussian
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.audit.block import case_block, cmf_update_block
from gpfverify.fusion.batched import convex_combination_batch, squared_mahalanobis_batch
from gpfverify.fusion.case import CentralPrediction
from gpfverify.fusion.exactness import parse_rank_rule
from gpfverify.fusion.rcc_ci import rcc_ci_batch
from gpfverify.models import GPModel, batch_gp_models
from gpfverify.papers.fusion.scenario import FusionData


class _BatchClock:
    """Per-step CPU time per method of a batch of ``runs`` runs: each call's time divided by B."""

    def __init__(self, steps: int, methods: Sequence[str], runs: int):
        self.seconds = {m: np.zeros(steps) for m in methods}
        self.runs = runs

    def run(self, method: str, step: int, fn: Callable, *args: Any, **kwargs: Any) -> Any:
        start = CPU_CLOCK()
        out = fn(*args, **kwargs)
        self.seconds[method][step] += (CPU_CLOCK() - start) / self.runs
        return out


def _central_prediction(chosen: GaussianFamily, belief: Gaussian, model: GPModel, k: int) -> CentralPrediction:
    prediction = chosen.predict(belief, model, k=k)
    moments = chosen.measurement(prediction, model, k=k)
    return CentralPrediction(prediction.mean, prediction.cov, moments.mu_y, moments.C_y, moments.C_xy,
                             tuple(model.sizes), tuple(model.circular), tuple(model.circular_state))


def run_family_batch(family: str, models: GPModel, data: Sequence[FusionData], local_starts: Sequence[Gaussian],
                     fused_start: Gaussian, sigma: SigmaParams, rcc_size: float | None,
                     rank_rule: str = DEFAULT_RULE, rcc_on_empty: str = "enlarge") -> list[FamilyRun]:
    """:func:`~gpfverify.papers.fusion.run.run_family` of B runs at once: ``models`` their GP
    models batched (:func:`~gpfverify.models.batch_gp_models`), ``data`` each run's data,
    ``local_starts[m]`` sensor m's starting beliefs (B, D), ``fused_start`` the fused filters' (B, D);
    one :class:`~gpfverify.papers.fusion.contract.FamilyRun` per run, in order."""
    rule = parse_rank_rule(rank_rule)
    runs = len(data)
    sensors = len(local_starts)
    ys_local = [np.stack([d.test_measurements[m] for d in data]) for m in range(sensors)]  # (B, T, l_m)
    ys = np.concatenate(ys_local, axis=2)
    truth = np.stack([d.test_states for d in data])
    steps = ys.shape[1]
    methods = family_methods(family)
    names = [m.key for m in methods]
    sensor_keys = [Method.sensor_filter(m + 1, family).key for m in range(sensors)]
    cmf_key, dmf_key, rcc_key, cw_key = (Method(r, family).key for r in FUSION_RULES)
    clock = _BatchClock(steps, names, runs)
    online = {k: np.zeros(steps) for k in (cmf_key, dmf_key)}
    chosen = gaussian_family(family, sigma)
    sensor_models = [models.sensor_model(m) for m in range(sensors)]
    locals_ = list(local_starts)
    cmf_belief, dmf_belief = fused_start, fused_start
    # per method, run and step, the methods in the order of ``names``
    sq_err, maha = np.empty((len(names), runs, steps)), np.empty((len(names), runs, steps))
    singular_values: dict[str, list[np.ndarray]] = {k: [] for k in sensor_keys}
    correlations: dict[str, list[np.ndarray]] = {k: [] for k in sensor_keys}
    full_rank = {k: np.empty((runs, steps), dtype=bool) for k in sensor_keys}
    tols = {k: np.empty((runs, steps)) for k in sensor_keys}
    recursive_gap, one_step_gap, one_step_gap_rel, sizes, bounds = (np.empty((runs, steps)) for _ in range(5))
    holds = np.empty((runs, steps), dtype=bool)
    audit: list[list] = [[] for _ in range(runs)]
    rcc_enlarged = np.zeros(runs, dtype=int)
    circular_state = models.circular_state
    for k in range(steps):
        records = [clock.run(key, k, chosen.step, belief, sensor_model, ys_local[m][:, k], k=k + 1)
                   for m, (key, belief, sensor_model) in enumerate(zip(sensor_keys, locals_, sensor_models))]
        locals_ = [r.posterior for r in records]
        cmf = clock.run(cmf_key, k, chosen.step, cmf_belief, models, ys[:, k], k=k + 1)

        start = CPU_CLOCK()
        central = _central_prediction(chosen, dmf_belief, models, k + 1)
        block = case_block(central, records, ys[:, k], central.sizes, central.circular, central.circular_state)
        dmf = dmf_runs(block, rule, CPU_CLOCK)
        # the whole DMF step, less the audit (which the per-run path runs outside the method's clock)
        clock.seconds[dmf_key][k] += (CPU_CLOCK() - start - dmf.audit_seconds) / runs
        online[dmf_key][k] = dmf.online
        cmf_belief, dmf_belief = cmf.posterior, Gaussian(dmf.mean, dmf.cov)
        local_means = np.stack([b.mean for b in locals_], axis=1)
        local_covs = np.stack([b.cov for b in locals_], axis=1)
        cw = clock.run(cw_key, k, convex_combination_batch, local_means, local_covs, circular_state)
        rcc = clock.run(rcc_key, k, rcc_ci_batch, local_means, local_covs, rcc_size, rcc_on_empty, circular_state)
        rcc_enlarged += rcc.enlarged

        start = CPU_CLOCK()
        same = cmf_update_block(block)  # CMF's update from the same central prediction as DMF's
        online[cmf_key][k] = (CPU_CLOCK() - start) / runs

        # every method's estimate stacked (M, B, D): one Cholesky and one solve per step for all of them
        estimates = [*locals_, cmf_belief, dmf_belief, Gaussian(rcc.mean, rcc.cov), cw]
        means, covs = np.stack([e.mean for e in estimates]), np.stack([e.cov for e in estimates])
        sq_err[:, :, k] = np.sum((truth[:, k] - means) ** 2, axis=-1)
        maha[:, :, k] = squared_mahalanobis_batch(truth[:, k], means, covs)
        for m, key in enumerate(sensor_keys):
            singular_values[key].append(dmf.singular_values[m])
            correlations[key].append(dmf.correlations[m])
            full_rank[key][:, k] = dmf.full_rank[m]
            tols[key][:, k] = dmf.tol[m]
        gaps = np.array([a.gap for a in dmf.audits])
        recursive_gap[:, k] = np.linalg.norm(dmf_belief.mean - cmf_belief.mean, axis=-1)
        one_step_gap[:, k] = np.linalg.norm(gaps, axis=-1)
        correction = np.linalg.norm(same.mean - block.mu_p, axis=-1)
        one_step_gap_rel[:, k] = np.where(correction > 0, one_step_gap[:, k] / np.where(correction > 0, correction, 1),
                                          0.0)
        holds[:, k] = dmf.condition_holds
        sizes[:, k] = [a.gap_size for a in dmf.audits]
        bounds[:, k] = [a.gap_bound for a in dmf.audits]
        for b in np.flatnonzero(~holds[:, k]).tolist():
            audit[b].append(_audit_entry(k, family, dmf.audits[b], block.mu_p[b]))
    sensitivity = rounding_sensitivity_batch(chosen, models, fused_start, ys[:, 0])
    canonical = rule.name == "canonical"
    per_sensor = {key: np.stack(values, axis=1).tolist() for key, values in singular_values.items()}  # (B, T, l)
    per_sensor_rho = {key: np.stack(values, axis=1).tolist() for key, values in correlations.items()}
    seconds = {n: tuple(s.tolist()) for n, s in clock.seconds.items()}
    online_seconds = {n: tuple(s.tolist()) for n, s in online.items()}

    def series(values: dict[str, np.ndarray], b: int) -> dict[str, tuple]:
        return {n: tuple(v[b].tolist()) for n, v in values.items()}
    return [FamilyRun(
        sq_err=series(dict(zip(names, sq_err)), b), maha=series(dict(zip(names, maha)), b),
        singular_values={n: tuple(tuple(step) for step in v[b]) for n, v in per_sensor.items()},
        full_rank=series(full_rank, b), rank_tol=series(tols, b),
        recursive_gap=tuple(recursive_gap[b].tolist()), one_step_gap=tuple(one_step_gap[b].tolist()),
        one_step_gap_rel=tuple(one_step_gap_rel[b].tolist()), condition_holds=tuple(holds[b].tolist()),
        gap_size=tuple(sizes[b].tolist()), gap_bound=tuple(bounds[b].tolist()), audit=tuple(audit[b]),
        rcc_enlarged=int(rcc_enlarged[b]), rounding_sensitivity=float(sensitivity[b]),
        seconds=seconds, online_seconds=online_seconds,
        correlations={n: tuple(tuple(step) for step in v[b]) for n, v in per_sensor_rho.items()} if canonical else {})
        for b in range(runs)]


def rounding_sensitivity_batch(chosen: GaussianFamily, models: GPModel, belief: Gaussian, y: np.ndarray) -> np.ndarray:
    """:func:`~gpfverify.papers.fusion.run.rounding_sensitivity` of every run (B,)."""
    base = chosen.step(belief, models, y, k=1)
    spread = np.sqrt(np.diagonal(belief.cov, axis1=-2, axis2=-1))
    shift = ROUNDING_PROBE * (np.abs(belief.mean) + spread)
    nudged = chosen.step(Gaussian(belief.mean + shift, belief.cov), models, y, k=1)
    return np.linalg.norm(nudged.mu_e - base.mu_e, axis=-1)


def run_setting_batch(data: Sequence[FusionData], models: Sequence[GPModel], local_starts: Sequence[Sequence[Gaussian]],
                      fused_starts: Sequence[Gaussian], sigma: SigmaParams, rcc_size: float | None, rank_rule: str,
                      training_seconds: Sequence[float], rcc_on_empty: str = "enlarge") -> list[FusionRun]:
    """:func:`~gpfverify.papers.fusion.run.run_setting` of B runs at once: run b's ``data[b]``,
    ``models[b]``, ``local_starts[b]`` (one belief per sensor), ``fused_starts[b]`` and
    ``training_seconds[b]``; both families, one :class:`~gpfverify.papers.fusion.contract.FusionRun` per run."""
    batched = batch_gp_models(models)
    sensors = len(local_starts[0])
    starts = [_stacked([run[m] for run in local_starts]) for m in range(sensors)]
    fused = _stacked(fused_starts)
    by_family = {family: run_family_batch(family, batched, data, starts, fused, sigma, rcc_size, rank_rule,
                                          rcc_on_empty) for family in FAMILIES}
    return [FusionRun({family: by_family[family][b] for family in FAMILIES}, training_seconds[b],
                      hyperparameters(models[b])) for b in range(len(data))]


def _stacked(beliefs: Sequence[Gaussian]) -> Gaussian:
    """One belief per run as a belief with a leading run axis."""
    return Gaussian(np.stack([b.mean for b in beliefs]), np.stack([b.cov for b in beliefs]))


def gp_batch_bytes(training_points: int, outputs: int) -> int:
    """Working memory of one run in a batch of the fusion experiments: its GPs' K⁻¹ and Cholesky
    factors stacked (``outputs`` GP outputs in all, transition and sensors, n = ``training_points``
    each), twice that for the step's other arrays, and a megabyte for its records."""
    return 2 * (2 * outputs * training_points ** 2 * 8) + (1 << 20)
