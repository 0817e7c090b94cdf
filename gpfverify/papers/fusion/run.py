"""One Monte Carlo run of the fusion paper's experiments (seed 000 §4), shared by ``ct2d`` and
``ungm1d``, the summaries both write and the claims both check. The records are the typed
contract types of :mod:`gpfverify.papers.fusion.contract`.

A run: simulate one trajectory (:mod:`gpfverify.papers.fusion.scenario`), learn the transition GP
and each sensor's measurement GP from its training part, then filter the test part with twelve
methods (:data:`gpfverify.papers.fusion.contract.METHODS`) — for each filter family F ∈ {GP-ADF, GP-UKF}:

* ``Sensor1-F``, ``Sensor2-F``: each sensor's own filter (eq. 15–19 / 21–31);
* ``CMF-F``: the centralized filter on the stacked measurement (:func:`~gpfverify.model_fusion.cmf_step`);
* ``DMF-F``: the distributed rule (eq. 35) with its own recursion — the centre predicts from the
  previous *DMF* posterior and fuses the sensors' reports (:func:`~gpfverify.model_fusion.dmf_step`);
* ``CW-F``: convex combination of the local posteriors; ``RCC-CI-F``: relaxed-Chebyshev-centre CI
  of the local posteriors (ellipsoid size c = χ²_D(0.99) unless given; when the ellipsoids do not
  intersect, c is enlarged to twice the smallest intersecting size and the step is counted).

Per step and method the run records ‖x − x̂‖² (for the RMSE, eq. 45) and the squared Mahalanobis
distance (x − x̂)ᵀC⁻¹(x − x̂) (eq. 44 as written), and its own computation time — CPU time of the
process (:data:`CPU_CLOCK`), which other processes on a busy machine perturb far less than wall
time. For the equivalence analysis it records the singular values of every local C_xy^m (and,
under the canonical rule, the canonical correlations) and the rank decision of the rule eq. 35 is
run with (the canonical-correlation rule unless another is given), the recursive gap
‖μ_DMF − μ_CMF‖ between the two fused filters, the one-step gap of eq. 35 against CMF *from the
same central prediction* with the audit's measure of it and its rounding bound (both in prior
standard deviations: :func:`~gpfverify.fusion.exactness.gap_size`,
:func:`~gpfverify.fusion.exactness.equivalence_tolerance`), and the full audit
(:func:`~gpfverify.audit.case.audit_case`: gap actual vs closed-form prediction, exact or not) of every
step on which a rank condition failed.

GP hyperparameters (:func:`~gpfverify.models.fit_gp_model`): evidence maximisation (``restarts``
starts) on at most ``fit_points`` training samples evenly spaced along the trajectory; the GP then
conditions on *all* training samples with those hyperparameters. The cap keeps fitting
O(fit_points³) per evaluation (measured in
``benchmarks/bench_ct2d.py``); with fit_points ≥ the training size it is plain evidence maximisation.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from gpfverify.audit.case import CaseAudit, audit_case
from gpfverify.contract.claims import (PROPOSITION_1, ClaimRecord, PairedDifference, PairedRatio, Statement, Verdict,
                                      combine)
from gpfverify.papers.fusion.contract import (DEFAULT_RULE, FAMILIES, FUSION_RULES, LOCAL_FILTERS, METHODS, PAPER,
                                              AuditEntry, FamilyRun, FittedModels, FusionRun, GPHyperparameters,
                                              SensorAuditRecord, family_methods)
from gpfverify.contract.methods import Method
from gpfverify.filters.families import gaussian_family
from gpfverify.filters.records import Gaussian, StepRecord
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.fusion.centralized import cmf_update
from gpfverify.fusion.convex import convex_combination
from gpfverify.fusion.exactness import equivalence_tolerance, gap_size, parse_rank_rule
from gpfverify.model_fusion import cmf_step, dmf_step
from gpfverify.fusion.rcc_ci import rcc_ci
from gpfverify.health import HealthCheck, divergence_check, nees_values_check
from gpfverify.linalg import solve_spd
from gpfverify.models import GPModel, fit_gp_model
from gpfverify.papers.fusion.scenario import FusionData
from gpfverify.tolerances import RESOLVABLE_GAP

__all__ = ["FAMILIES", "LOCAL_FILTERS", "METHODS"]

#: relative singular-value tolerances (σ_min > rtol · σ_max) at which the full-rank ratio is also
#: reported, to show how a "ratio of full column rank" figure depends on the tolerance chosen
RELATIVE_RANK_TOLS: tuple[float, ...] = (1e-12, 1e-10, 1e-8, 1e-6, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2)
RANK_RULE = "numpy/MATLAB rank rule: sigma_max * max(D, l_m) * eps (absolute, per matrix)"


def rank_rule_text(spec: str) -> str:
    """The rank rule of a run in words (:meth:`FusionParams.rank_rule_spec` → text); the numpy rule
    keeps :data:`RANK_RULE`, the wording of the reference results."""
    rule = parse_rank_rule(spec)
    return RANK_RULE if rule.name == "numpy" else rule.describe()
#: audit entries kept verbatim in results.json (all are counted)
AUDIT_ENTRIES_KEPT = 200
#: the method keys of results.json, in figure order
METHOD_KEYS: tuple[str, ...] = tuple(m.key for m in METHODS)
LOCAL_KEYS: tuple[str, ...] = tuple(m.key for m in LOCAL_FILTERS)


def train_models(data: FusionData, restarts: int, fit_points: int, rng: np.random.Generator) -> GPModel:
    """The run's GP model learned from its training part (:func:`~gpfverify.models.fit_gp_model`)."""
    return fit_gp_model(data.transition_inputs, data.transition_targets, data.measurement_inputs,
                        data.measurement_targets, rng, restarts=restarts, fit_points=fit_points)


@dataclass(frozen=True)
class RunInputs:
    """What a run filters: its ``data``, its learned GP ``models``, each sensor's starting belief and
    the fused filters' one, and the CPU seconds its GPs took to learn."""

    data: FusionData
    models: GPModel
    local_starts: Sequence[Gaussian]
    fused_start: Gaussian
    training_seconds: float


def sigma_params(params) -> SigmaParams:
    """The sigma-point parameters of an experiment's ``params`` (``alpha``, ``beta``, ``sigma_kappa``)."""
    return SigmaParams(params.alpha, params.beta, params.sigma_kappa)


def hyperparameters(models: GPModel) -> FittedModels:
    """The fitted hyperparameters as a record."""
    def one(gp) -> GPHyperparameters:
        return GPHyperparameters(tuple(tuple(float(v) for v in row) for row in gp.lengthscales),
                                 tuple(float(v) for v in gp.signal_var), tuple(float(v) for v in gp.noise_var))
    return FittedModels(one(models.transition), tuple(one(gp) for gp in models.sensors))


def squared_mahalanobis(truth: np.ndarray, estimate: Gaussian) -> float:
    """(x − x̂)ᵀ C⁻¹ (x − x̂) (eq. 44 as written: the squared form)."""
    err = truth - estimate.mean
    return float(err @ solve_spd(estimate.cov, err, "estimate covariance"))


#: the clock every method of a run is timed with: the CPU time of this process (all its threads; BLAS
#: runs one thread in gpfverify's calls), not wall time, which counts whatever else the machine runs
CPU_CLOCK: Callable[[], float] = time.process_time
#: what results.json says the times are
CLOCK_WORDS = "CPU time of the process (time.process_time), per method and step"


class _Clock:
    """Accumulates per-step CPU time (:data:`CPU_CLOCK`) per method."""

    def __init__(self, steps: int, methods: Sequence[str]):
        self.seconds = {m: np.zeros(steps) for m in methods}

    def run(self, method: str, step: int, fn: Callable, *args: Any, **kwargs: Any) -> Any:
        start = CPU_CLOCK()
        out = fn(*args, **kwargs)
        self.seconds[method][step] += CPU_CLOCK() - start
        return out


def _rcc_ci(estimates, size: float | None, on_empty: str, circular_state=()) -> tuple[Gaussian, bool]:
    """RCC-CI (with the ellipsoids enlarged when they do not intersect, for on_empty="enlarge");
    (estimate, enlarged)."""
    result = rcc_ci(estimates, c=size, on_empty=on_empty, circular_state=circular_state)
    return Gaussian(result.mean, result.cov), result.enlarged


def _audit_entry(step: int, family: str, audit: CaseAudit, mu_p: np.ndarray) -> AuditEntry:
    """The record of a rank-failure step's audit (``mu_p`` the centre's prior mean)."""
    gap, predicted = audit.gap, audit.predicted_gap
    if gap is None or predicted is None:  # audit_case computes both when the case has measurements
        raise ValueError("the audit of a rank-failure step needs the measurements")
    return AuditEntry(
        step=step + 1, family=family, condition_holds=bool(audit.condition_holds), exact=bool(audit.exact),
        gap_norm=float(np.linalg.norm(gap)), predicted_gap_norm=float(np.linalg.norm(predicted)),
        gap_error=float(np.linalg.norm(gap - predicted)),
        correction_norm=float(np.linalg.norm(audit.cmf_mean - mu_p)),
        sensors=tuple(SensorAuditRecord(int(s.index), int(s.rank), int(s.cols), float(s.tol),
                                        tuple(float(v) for v in s.singular_values), float(s.gap_gain_norm),
                                        bool(s.exact)) for s in audit.sensors))


def _floats(values) -> tuple[float, ...]:
    return tuple(float(v) for v in values)


def run_family(family: str, models: GPModel, data: FusionData, local_starts: Sequence[Gaussian],
               fused_start: Gaussian, sigma: SigmaParams, rcc_size: float | None,
               rank_rule: str = DEFAULT_RULE, rcc_on_empty: str = "enlarge") -> FamilyRun:
    """Filter the test segment with the six methods of one family; per-step records (see module
    docstring). ``rank_rule``: the rule eq. 35 decides rank(C_xy^m) with, as
    :func:`~gpfverify.fusion.exactness.parse_rank_rule` reads it."""
    rule = parse_rank_rule(rank_rule)
    ys_local = data.test_measurements
    ys = data.stacked_test_measurements()
    steps = ys.shape[0]
    methods = family_methods(family)
    names = [m.key for m in methods]
    sensor_keys = [Method.sensor_filter(m + 1, family).key for m in range(len(local_starts))]
    cmf_key, dmf_key, rcc_key, cw_key = (Method(rule, family).key for rule in FUSION_RULES)
    clock = _Clock(steps, names)
    online = {k: np.zeros(steps) for k in (cmf_key, dmf_key)}
    local_step = gaussian_family(family, sigma).step
    sensor_models = [models.sensor_model(m) for m in range(len(models.sensors))]
    locals_ = list(local_starts)
    cmf_belief, dmf_belief = fused_start, fused_start
    sq_err: dict[str, list[float]] = {n: [] for n in names}
    maha: dict[str, list[float]] = {n: [] for n in names}
    singular_values: dict[str, list[tuple[float, ...]]] = {k: [] for k in sensor_keys}
    correlations: dict[str, list[tuple[float, ...]]] = {k: [] for k in sensor_keys}
    full_rank: dict[str, list[bool]] = {k: [] for k in sensor_keys}
    tols: dict[str, list[float]] = {k: [] for k in sensor_keys}
    recursive_gap, one_step_gap, one_step_gap_rel, holds, sizes, bounds = [], [], [], [], [], []
    audit: list[AuditEntry] = []
    rcc_enlarged = 0
    for k in range(steps):
        records: list[StepRecord] = [
            clock.run(key, k, local_step, belief, sensor_model, ys_local[m][k], k=k + 1)
            for m, (key, belief, sensor_model) in enumerate(zip(sensor_keys, locals_, sensor_models))]
        locals_ = [r.posterior for r in records]
        cmf = clock.run(cmf_key, k, cmf_step, cmf_belief, models, ys[k], k=k + 1, family=family, params=sigma)
        dmf = clock.run(dmf_key, k, dmf_step, dmf_belief, models, ys[k], local_records=records, k=k + 1,
                        family=family, params=sigma, rank_rule=rule, clock=CPU_CLOCK)
        cmf_belief, dmf_belief = cmf.posterior, dmf.record.posterior
        cw = clock.run(cw_key, k, convex_combination, locals_, models.circular_state)
        rcc, enlarged = clock.run(rcc_key, k, _rcc_ci, locals_, rcc_size, rcc_on_empty, models.circular_state)
        rcc_enlarged += int(enlarged)

        # the update alone (what is left once the measurements arrive), CMF vs eq. 35 (timed
        # within dmf_step): CMF's update from the same central prediction as DMF's
        start = CPU_CLOCK()
        same = cmf_update(dmf.case.central, ys[k])
        online[cmf_key][k] = CPU_CLOCK() - start
        online[dmf_key][k] = dmf.update_seconds

        truth = data.test_states[k]
        estimates = dict(zip(names, [*locals_, cmf_belief, dmf_belief, Gaussian(rcc.mean, rcc.cov),
                                     Gaussian(cw.mean, cw.cov)]))
        for name, est in estimates.items():
            sq_err[name].append(float(np.sum((truth - est.mean) ** 2)))
            maha[name].append(squared_mahalanobis(truth, est))
        for s in dmf.result.sensors:
            key = Method.sensor_filter(s.index + 1, family).key
            singular_values[key].append(_floats(s.split.rank.singular_values))
            correlations[key].append(() if s.split.correlations is None else _floats(s.split.correlations))
            full_rank[key].append(bool(s.full_column_rank))
            tols[key].append(float(s.split.rank.tol))
        gap = dmf.result.mean - same.mean
        recursive_gap.append(float(np.linalg.norm(dmf_belief.mean - cmf_belief.mean)))
        one_step_gap.append(float(np.linalg.norm(gap)))
        correction = float(np.linalg.norm(same.mean - dmf.case.central.mu_p))
        one_step_gap_rel.append(float(np.linalg.norm(gap)) / correction if correction > 0 else 0.0)
        holds.append(bool(dmf.result.condition_holds))
        # the audit's measure and bound of the same gap (unit-free, prior standard deviations)
        sizes.append(gap_size(dmf.case, gap, dmf.result.scale))
        bounds.append(equivalence_tolerance(dmf.case, dmf.result.gain, dmf.result.sensors, dmf.result.scale))
        if not dmf.result.condition_holds:
            audit.append(_audit_entry(k, family, audit_case(dmf.case, rank_rule=dmf.result.rank_rule, dmf=dmf.result),
                                      dmf.case.central.mu_p))
    return FamilyRun(
        sq_err={n: tuple(v) for n, v in sq_err.items()}, maha={n: tuple(v) for n, v in maha.items()},
        singular_values={n: tuple(v) for n, v in singular_values.items()},
        full_rank={n: tuple(v) for n, v in full_rank.items()}, rank_tol={n: tuple(v) for n, v in tols.items()},
        recursive_gap=tuple(recursive_gap), one_step_gap=tuple(one_step_gap),
        one_step_gap_rel=tuple(one_step_gap_rel), condition_holds=tuple(holds), gap_size=tuple(sizes),
        gap_bound=tuple(bounds), audit=tuple(audit), rcc_enlarged=rcc_enlarged,
        rounding_sensitivity=rounding_sensitivity(family, models, fused_start, ys[0], sigma),
        seconds={n: _floats(s) for n, s in clock.seconds.items()},
        online_seconds={n: _floats(s) for n, s in online.items()},
        correlations={n: tuple(v) for n, v in correlations.items()} if rule.name == "canonical" else {})


def run_setting(data: FusionData, models: GPModel, local_starts: Sequence[Gaussian],
                fused_start: Gaussian, sigma: SigmaParams, rcc_size: float | None,
                rank_rule: str, training_seconds: float, rcc_on_empty: str = "enlarge") -> FusionRun:
    """Both families on one run's data."""
    return FusionRun({family: run_family(family, models, data, local_starts, fused_start, sigma, rcc_size,
                                         rank_rule, rcc_on_empty) for family in FAMILIES},
                     training_seconds, hyperparameters(models))


#: relative perturbation of the fused start used by :func:`rounding_sensitivity`
ROUNDING_PROBE = 1e-14


def rounding_sensitivity(family: str, models: GPModel, belief: Gaussian, y: np.ndarray,
                         sigma: SigmaParams) -> float:
    """‖Δμ_e‖ of one CMF step when the prior mean moves by :data:`ROUNDING_PROBE` · (|μ| + σ) per
    coordinate (σ the prior standard deviations): how far
    rounding-level differences between two mathematically equal beliefs (DMF's and CMF's) are
    amplified by one filter step. Large values explain a recursive DMF − CMF drift that the
    one-step gap (zero to rounding) does not."""
    base = cmf_step(belief, models, y, family=family, params=sigma)
    shift = ROUNDING_PROBE * (np.abs(belief.mean) + np.sqrt(np.diag(belief.cov)))
    nudged = cmf_step(Gaussian(belief.mean + shift, belief.cov), models, y, family=family, params=sigma)
    return float(np.linalg.norm(nudged.mu_e - base.mu_e))


# -- summaries -----------------------------------------------------------------------------------

def _per_method(results: Sequence[FusionRun], field: str) -> dict[str, np.ndarray]:
    """(runs, T) array of a per-step field for every method."""
    out = {}
    for family in FAMILIES:
        for name in getattr(results[0].families[family], field):
            out[name] = np.array([getattr(r.families[family], field)[name] for r in results], dtype=float)
    return out


def one_step_equivalence(record: FamilyRun) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per step of one family's run record: whether the rank condition held; whether eq. 35
    reproduced CMF from the same central prediction to the step's rounding bound (the audit's
    "reproduced": ‖L_p⁻¹ gap‖ ≤ its bound, :func:`~gpfverify.fusion.exactness.equivalence_tolerance`);
    and whether that bound resolves the comparison (at most
    :data:`~gpfverify.tolerances.RESOLVABLE_GAP` prior standard deviations — above it, eq. 35 at the
    rank decided amplifies rounding beyond what the arithmetic can tell from a gap)."""
    f = record
    size, bound = np.array(f.gap_size), np.array(f.gap_bound)
    return np.array(f.condition_holds, dtype=bool), size <= bound, bound <= RESOLVABLE_GAP


def full_rank_ratio_at(results: Sequence[FusionRun], rtol: float) -> dict[str, list[float]]:
    """Fraction of runs in which σ_min(C_xy^m) > rtol · σ_max(C_xy^m), per step and local filter."""
    out = {}
    for family in FAMILIES:
        for name in results[0].families[family].singular_values:
            sv = np.array([r.families[family].singular_values[name] for r in results])  # (R, T, l)
            full = sv[..., -1] > rtol * sv[..., 0]
            out[name] = np.mean(full, axis=0).tolist()
    return out


def _audit_summary(results: Sequence[FusionRun], rule_text: str = RANK_RULE) -> dict:
    entries = [{**to_dict(e), "run": i} for i, r in enumerate(results) for f in FAMILIES
               for e in r.families[f].audit]
    by_family = {}
    for family in FAMILIES:
        mine = [e for e in entries if e["family"] == family]
        by_family[family] = {
            "steps": len(mine), "exact": sum(e["exact"] for e in mine),
            "max_gap_norm": max((e["gap_norm"] for e in mine), default=0.0),
            "max_gap_error": max((e["gap_error"] for e in mine), default=0.0),
            "max_relative_gap": max((e["gap_norm"] / e["correction_norm"] for e in mine
                                     if e["correction_norm"] > 0), default=0.0)}
    return {"rank_rule": rule_text, "by_family": by_family, "entries": entries[:AUDIT_ENTRIES_KEPT],
            "entries_total": len(entries)}


def to_dict(entry: AuditEntry) -> dict:
    from gpfverify.contract.serial import to_json

    return to_json(entry)


def summarize_setting(results: Sequence[FusionRun], rank_rule: str) -> dict:
    """Per-step and per-method summaries of one setting over runs (see module docstring);
    ``rank_rule`` the rule's spec (:meth:`FusionParams.rank_rule_spec`), named in the summary."""
    rule_text = rank_rule_text(rank_rule)
    sq_err = _per_method(results, "sq_err")
    maha = _per_method(results, "maha")
    seconds = _per_method(results, "seconds")
    online = _per_method(results, "online_seconds")
    full_rank = _per_method(results, "full_rank")
    out: dict[str, Any] = {
        "rmse": {m: np.sqrt(np.mean(sq_err[m], axis=0)).tolist() for m in METHOD_KEYS},
        "average_mahalanobis": {m: np.mean(maha[m], axis=0).tolist() for m in METHOD_KEYS},
        "full_rank_ratio": {m: np.mean(full_rank[m], axis=0).tolist() for m in LOCAL_KEYS},
        "rank_tolerance": rule_text,
        "full_rank_ratio_by_relative_tolerance": {f"{t:g}": full_rank_ratio_at(results, t)
                                                  for t in RELATIVE_RANK_TOLS},
        "time_clock": CLOCK_WORDS,
        "time_per_step": {m: float(np.mean(seconds[m])) for m in METHOD_KEYS},
        "time_per_run": {m: float(np.mean(np.sum(seconds[m], axis=1))) for m in METHOD_KEYS},
        "online_time_per_step": {m: float(np.mean(online[m])) for m in online},
        "time_per_step_series": {m: np.mean(seconds[m], axis=0).tolist() for m in METHOD_KEYS},
        "run_mean_sq_err": {m: np.mean(sq_err[m], axis=1).tolist() for m in METHOD_KEYS},
        # each method's CPU seconds per run (the whole fusion step; and CMF's and DMF's update alone):
        # what the claims on computation time compare as paired per-run ratios
        "run_seconds": {m: np.sum(seconds[m], axis=1).tolist() for m in METHOD_KEYS},
        "run_online_seconds": {m: np.sum(online[m], axis=1).tolist() for m in online},
        "run_mean_mahalanobis": {m: np.mean(maha[m], axis=1).tolist() for m in METHOD_KEYS},
    }
    out["max_equivalence_gap"] = {}
    out["equivalence_gap_per_step"] = {}
    out["one_step_gap"] = {}
    for family in FAMILIES:
        fam = [r.families[family] for r in results]
        gaps = np.array([f.recursive_gap for f in fam])
        one_step = np.array([f.one_step_gap for f in fam])
        one_rel = np.array([f.one_step_gap_rel for f in fam])
        size = np.array([f.gap_size for f in fam])
        bound = np.array([f.gap_bound for f in fam])
        holds, reproduced, resolved = (np.array(v) for v in zip(*(one_step_equivalence(f) for f in fam)))
        unresolved = holds & reproduced & ~resolved
        # (runs, T): the smaller σ_min of the two sensors' C_xy^m, and of their canonical correlations
        sv_min = np.min([[np.array(sv)[:, -1] for sv in f.singular_values.values()] for f in fam], axis=1)
        rho_min = (np.min([[[min(step) for step in rho] for rho in f.correlations.values()] for f in fam], axis=1)
                   if all(f.correlations for f in fam) else None)
        out["max_equivalence_gap"][family] = float(np.max(gaps))
        out["equivalence_gap_per_step"][family] = np.max(gaps, axis=0).tolist()
        out["one_step_gap"][family] = {
            "max_when_full_rank": float(np.max(one_step[holds], initial=0.0)),
            "max_relative_when_full_rank": float(np.max(one_rel[holds], initial=0.0)),
            "max_when_rank_fails": float(np.max(one_step[~holds], initial=0.0)),
            "steps_full_rank": int(np.sum(holds)), "steps_rank_fails": int(np.sum(~holds)),
            "full_rank_steps_reproduced": int(np.sum(holds & reproduced & resolved)),
            "full_rank_steps_unresolved": int(np.sum(unresolved)),
            "full_rank_steps_outside": int(np.sum(holds & ~reproduced)),
            "max_gap_size_resolved": float(np.max(size[holds & resolved], initial=0.0)),
            "max_gap_bound_resolved": float(np.max(bound[holds & resolved], initial=0.0)),
            "max_gap_size_unresolved": float(np.max(size[unresolved], initial=0.0)),
            "max_gap_bound_unresolved": float(np.max(bound[unresolved], initial=0.0)),
            "max_gap_ratio_outside": (float(np.max(size[holds & ~reproduced] / bound[holds & ~reproduced]))
                                      if np.any(holds & ~reproduced) else None),
            "unresolved_max_smallest_singular_value": float(np.max(sv_min[unresolved])) if unresolved.any() else None,
            "unresolved_max_smallest_correlation": (float(np.max(rho_min[unresolved]))
                                                    if unresolved.any() and rho_min is not None else None),
            "rounding_rule": "reproduced: |L_p^-1 gap| <= the step's rounding bound (the audit's gap_bound); resolved: "
                             f"that bound <= {RESOLVABLE_GAP:.3g} prior standard deviations"}
    out["rounding_sensitivity"] = {f: {
        "probe": ROUNDING_PROBE,
        "median": float(np.median([r.families[f].rounding_sensitivity for r in results])),
        "max": float(np.max([r.families[f].rounding_sensitivity for r in results]))}
        for f in FAMILIES}
    out["rank_failure_audit"] = _audit_summary(results, rule_text)
    out["rcc_ci_enlarged_steps"] = {f: int(sum(r.families[f].rcc_enlarged for r in results)) for f in FAMILIES}
    out["training_time_per_run"] = float(np.mean([r.training_seconds for r in results]))
    return out


# -- health ----------------------------------------------------------------------------------------

def health_checks(results: Sequence[FusionRun], dim: int, divergence_bound: float,
                  level: float) -> list[HealthCheck]:
    """Per method: divergence (‖x − x̂‖ above ``divergence_bound`` or not finite in some run) and
    the ANEES per step against its χ² interval at ``level``."""
    sq_err, maha = _per_method(results, "sq_err"), _per_method(results, "maha")
    out = []
    for m in METHOD_KEYS:
        out.append(divergence_check(m, np.sqrt(sq_err[m]), bound=divergence_bound))
        out.append(nees_values_check(m, maha[m], dim, level))
    return out


# -- claims ----------------------------------------------------------------------------------------

def _num(value: float | None, digits: int = 3) -> str:
    return "none" if value is None else f"{value:.{digits}g}"


#: what a claim on computation time needs that runs summarised before per-run times were kept lack
PER_RUN_TIMES = ("each method's CPU time in every run (results.json 'run_seconds'), which runs summarised before "
                 "they were kept do not have: their means alone decide no paired ratio")


@dataclass(frozen=True)
class ClaimContext:
    """What every claim of one setting shares: the experiment, the setting's label and slug (for
    ids), the runs used and the paper's count, the statement of each claim at this setting (the
    paper's catalogue, :mod:`gpfverify.papers.fusion.claims`) and the setting's health checks."""

    experiment: str
    setting: str
    slug: str
    n: int
    paper_n: int | None
    statement: Callable[[str], Statement]
    checks: tuple[HealthCheck, ...] = ()

    def record(self, name: str, claim: str, verdict: Verdict, statistic: float | None, threshold: float | None,
               evidence: str, compared: Sequence[Method] = (), caveats: tuple[str, ...] = (), timing: bool = False,
               paper_n: int | None | Literal["same"] = "same", theorem: str = "", runs_to_decide: int | None = None,
               needs: str = "") -> ClaimRecord:
        """The claim ``name`` ("fusion-beats-sensors/GP-ADF": its statement is the first part's),
        said to come from its statement, with the health of the ``compared`` methods (the gate
        applied, :meth:`~gpfverify.contract.claims.ClaimRecord.checked`)."""
        slug = f"{self.slug}/" if self.slug else ""
        statement = self.statement(name.split("/")[0])
        record = ClaimRecord(claim=claim, source=statement.source, verdict=verdict, statistic=statistic,
                             threshold=threshold, n=self.n, evidence=evidence, caveats=caveats,
                             id=f"{self.experiment}/{slug}{name}", paper=PAPER, setting=self.setting,
                             paper_n=self.paper_n if paper_n == "same" else paper_n, timing=timing, theorem=theorem,
                             runs_to_decide=runs_to_decide if verdict == "undecided" else None, needs=needs)
        return statement.applied(record).checked([m.key for m in compared], self.checks)


def paired_claim(ctx: ClaimContext, name: str, claim: str, per_run: dict[str, list[float]],
                 pairs: Sequence[tuple[Method, Method]], unit: str, caveats: tuple[str, ...] = ()) -> ClaimRecord:
    """"A beats B" for every pair (A, B), each by the paired Monte Carlo difference of per-run mean
    errors (:class:`~gpfverify.contract.claims.PairedDifference`); the statistic is the least
    favourable pair's mean difference (largest against its tolerance) and the threshold that
    pair's tolerance. The health gate of the compared methods applies (:meth:`ClaimContext.record`)."""
    results = [(a, b, PairedDifference.of(per_run[a.key], per_run[b.key])) for a, b in pairs]

    def standing(d: PairedDifference) -> float:
        return d.mean / d.atol if d.atol else (np.inf if d.mean > 0 else -np.inf if d.mean < 0 else 0.0)

    worst = max(results, key=lambda item: standing(item[2]))[2]
    unit_text = f" {unit}" if unit else ""
    parts = [f"{a.key} − {b.key}: {_num(d.mean)} ± {_num(d.atol, 2)}{unit_text}" for a, b, d in results]
    evidence = ("; ".join(parts) + " (mean paired difference of per-run means over runs ± 5 standard errors; "
                "held when every difference is below minus its tolerance, NOT held when one is above it)")
    verdict = combine([d.verdict for _, _, d in results])
    undecided = [d.runs_to_decide for _, _, d in results if d.verdict == "undecided" and d.runs_to_decide]
    return ctx.record(name, claim, verdict, worst.mean, worst.atol, evidence, [m for pair in pairs for m in pair],
                      caveats, runs_to_decide=max(undecided) if undecided else None)


def fusion_beats_sensors(ctx: ClaimContext, results: dict, family: str, per_run_key: str, unit: str,
                         caveats: tuple[str, ...] = ()) -> ClaimRecord:
    pairs = [(Method(rule, family), Method.sensor_filter(m, family)) for rule in ("CMF", "DMF") for m in (1, 2)]
    return paired_claim(ctx, f"fusion-beats-sensors/{family}", f"{family}: CMF and DMF beat each single sensor",
                        results[per_run_key], pairs, unit, caveats)


def fusion_beats_baselines(ctx: ClaimContext, results: dict, family: str, per_run_key: str, unit: str,
                           caveats: tuple[str, ...] = ()) -> ClaimRecord:
    pairs = [(Method(rule, family), Method(base, family)) for rule in ("CMF", "DMF") for base in ("RCC-CI", "CW")]
    return paired_claim(ctx, f"fusion-beats-baselines/{family}", f"{family}: CMF and DMF beat RCC-CI and CW",
                        results[per_run_key], pairs, unit, caveats)


def family_claim(ctx: ClaimContext, name: str, claim: str, results: dict, per_run_key: str, better: str,
                 worse: str, unit: str, caveats: tuple[str, ...] = ()) -> ClaimRecord:
    """Fusion with the ``better`` family beats fusion with the ``worse`` one: CMF against CMF and DMF
    against DMF, each by the paired rule (:func:`paired_claim`)."""
    pairs = [(Method(rule, better), Method(rule, worse)) for rule in ("CMF", "DMF")]
    return paired_claim(ctx, name, claim, results[per_run_key], pairs, unit, caveats)


def time_claim(ctx: ClaimContext, name: str, claim: str, parts: list[tuple[Method, Method, str]],
               results: dict, words: str) -> ClaimRecord:
    """A claim on computation time: for every part (A, B, field) A's CPU seconds per run at most B's,
    paired per run (:class:`~gpfverify.contract.claims.PairedRatio`: held when the geometric mean
    of the per-run ratios lies below 1 beyond the Monte Carlo tolerance, NOT held above it, undecided
    in between; held when every part is, NOT held when one is). ``field``: "run_seconds" (the whole
    fusion step) or "run_online_seconds" (the update alone); a summary without them (runs made
    before they were kept) judges nothing and says what it needs."""
    compared = [m for a, b, _ in parts for m in (a, b)]
    if any(field not in results for _, _, field in parts):
        return ctx.record(name, claim, "not decidable", None, 1.0, words, compared, timing=True,
                          needs=PER_RUN_TIMES)
    ratios = [(a.key, b.key, PairedRatio.of(results[field][a.key], results[field][b.key])) for a, b, field in parts]
    worst = max(ratios, key=lambda item: item[2].ratio)[2]
    evidence = (f"{words}; " + "; ".join(r.evidence(a, b) for a, b, r in ratios)
                + ("" if len(ratios) == 1 else "; held when every ratio is, NOT held when one is"))
    verdict = combine([r.verdict for _, _, r in ratios])
    undecided = [r.runs_to_decide for _, _, r in ratios if r.verdict == "undecided" and r.runs_to_decide]
    return ctx.record(name, claim, verdict, worst.ratio, worst.bound, evidence, compared, timing=True,
                      runs_to_decide=max(undecided) if undecided else None)


def equivalence_claim(ctx: ClaimContext, results: dict, family: str, metric: str,
                      caveats: tuple[str, ...] = ()) -> ClaimRecord:
    """DMF = CMF on the steps where every C_xy^m has full column rank: eq. 35 against CMF from the
    same central prediction, each step judged as the audit judges it (reproduced: the gap, in prior
    standard deviations, within the step's own rounding bound). NOT held when a full-rank step's
    gap exceeds its bound; full-rank steps whose bound does not resolve the comparison (above
    RESOLVABLE_GAP: eq. 35 at the rank decided amplifies rounding that far) decide nothing and are
    named in a caveat; not decidable when no full-rank step is resolved. Statistic: the full-rank
    steps beyond their bound (threshold 0). The family's filters' health is recorded; it withholds
    nothing (one step of eq. 35 from the same prediction stands whatever the filters' health)."""
    g = results["one_step_gap"][family]
    dmf, cmf = Method("DMF", family).key, Method("CMF", family).key
    curves = np.abs(np.subtract(results[metric][dmf], results[metric][cmf]))
    n, ok = g["steps_full_rank"], g["full_rank_steps_reproduced"]
    unresolved, outside = g["full_rank_steps_unresolved"], g["full_rank_steps_outside"]
    verdict: Verdict = "NOT held" if outside else "held" if ok else "not decidable"
    sensitivity = results["rounding_sensitivity"][family]
    evidence = (f"{ok} of {n} full-rank steps reproduced to rounding (‖L_p⁻¹(μ(DMF) − μ(CMF))‖ within the step's "
                "rounding bound, as the audit judges a step, and the bound at most "
                f"{RESOLVABLE_GAP:.2g} prior standard deviations); largest gap there "
                f"{_num(g['max_gap_size_resolved'])} (bound up to {_num(g['max_gap_bound_resolved'])}) prior standard "
                f"deviations; {outside} step(s) beyond their bound"
                + ("" if g["max_gap_ratio_outside"] is None else
                   f" (up to {_num(g['max_gap_ratio_outside'])} × the bound)")
                + f"; {unresolved} unresolved; largest one-step ‖μ(DMF) − μ(CMF)‖ {_num(g['max_when_full_rank'])} "
                f"(relative to the update {_num(g['max_relative_when_full_rank'])}); recursive filters: largest "
                f"‖μ(DMF) − μ(CMF)‖ = {_num(results['max_equivalence_gap'][family])}, one step amplifies a "
                f"{sensitivity['probe']:g} relative nudge of the prior mean to {_num(sensitivity['median'])} (median); "
                f"largest |DMF − CMF| of the per-step curves {_num(float(curves.max()))}")
    notes = list(caveats)
    if n == 0:
        notes.insert(0, "no step had full column rank: Proposition 1's condition never held")
    if unresolved:
        rho = g["unresolved_max_smallest_correlation"]
        notes.insert(0, (
            f"{unresolved} full-rank step(s) unresolved: their rounding bound exceeds {RESOLVABLE_GAP:.2g} prior "
            f"standard deviations (up to {_num(g['max_gap_bound_unresolved'])}), so the arithmetic cannot tell DMF "
            f"from CMF there (largest gap {_num(g['max_gap_size_unresolved'])}); the smaller σ_min(Cₓᵧᵐ) of the two "
            f"sensors was at most {_num(g['unresolved_max_smallest_singular_value'])}"
            + (f" and the smaller canonical correlation at most {_num(rho)}: just above the rule's τ" if rho is not None
               else ": a cross covariance the rule calls full rank however small it is against the state's and "
                    "the output's spreads")
            + " — its pseudo-inverse in eq. 35 multiplies the rounding of μₑᵐ − μₚᵐ"))
    return ctx.record(f"dmf-equals-cmf/{family}",
                      f"{family}: DMF = CMF when the rank condition holds (eq. 35 from the same central prediction)",
                      verdict, float(outside), 0.0, evidence, family_methods(family), tuple(notes),
                      theorem=PROPOSITION_1)
