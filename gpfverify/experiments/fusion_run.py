"""One Monte Carlo run of the fusion paper's experiments (seed 000 §4), shared by ``ct2d`` and
``ungm1d``, and the summaries both write.

A run: simulate one trajectory (:mod:`gpfverify.scenarios.fusion_models`), learn the transition GP
and each sensor's measurement GP from its training part, then filter the test part with twelve
methods — for each filter family F ∈ {GP-ADF, GP-UKF}:

* ``Sensor1-F``, ``Sensor2-F``: each sensor's own filter (eq. 15–19 / 21–31);
* ``CMF-F``: the centralized filter on the stacked measurement (:func:`~gpfverify.fusion.model_fusion.cmf_step`);
* ``DMF-F``: the distributed rule (eq. 35) with its own recursion — the centre predicts from the
  previous *DMF* posterior and fuses the sensors' reports (:func:`~gpfverify.fusion.model_fusion.dmf_step`);
* ``CW-F``: convex combination of the local posteriors; ``RCC-CI-F``: relaxed-Chebyshev-centre CI
  of the local posteriors (ellipsoid size c = χ²_D(0.99) unless given; when the ellipsoids do not
  intersect, c is enlarged to twice the smallest intersecting size and the step is counted).

Per step and method the run records ‖x − x̂‖² (for the RMSE, eq. 45) and the squared Mahalanobis
distance (x − x̂)ᵀC⁻¹(x − x̂) (eq. 44 as written), and its own computation time. For the
equivalence analysis it records the singular values of every local C_xy^m and the rank decision
at the rank tolerance used by eq. 35 (numpy's / MATLAB's ``rank`` rule σ_max · max(D, l) · eps
unless ``rank_tol`` is given), the recursive gap ‖μ_DMF − μ_CMF‖ between the two fused filters,
the one-step gap of eq. 35 against CMF *from the same central prediction*, and the full audit
(:func:`~gpfverify.audit.audit_case`: gap actual vs closed-form prediction, exact or not) of every
step on which a rank condition failed.

GP hyperparameters (:func:`~gpfverify.models.fit_gp_model`): evidence maximisation (``restarts``
starts) on at most ``fit_points`` training samples evenly spaced along the trajectory; the GP then
conditions on *all* training samples with those hyperparameters. The cap keeps fitting O(fit_points³) per evaluation (measured in
``benchmarks/bench_ct2d.py``); with fit_points ≥ the training size it is plain evidence maximisation.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from gpfverify.audit import audit_case
from gpfverify.errors import InputError
from gpfverify.filters.families import gaussian_family
from gpfverify.filters.records import Gaussian, StepRecord
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.fusion.centralized import cmf_update
from gpfverify.fusion.convex import convex_combination
from gpfverify.fusion.distributed import dmf_update
from gpfverify.fusion.model_fusion import cmf_step, dmf_step
from gpfverify.fusion.rcc_ci import rcc_ci
from gpfverify.linalg import solve_spd
from gpfverify.models import GPModel, fit_gp_model
from gpfverify.scenarios.fusion_models import FusionData
from gpfverify.tolerances import algebra_rtol

FAMILIES: tuple[str, ...] = ("GP-ADF", "GP-UKF")
RULES: tuple[str, ...] = ("Sensor1", "Sensor2", "CMF", "DMF", "RCC-CI", "CW")
#: the twelve method names of the paper's figures (CONTRACT.md)
METHODS: tuple[str, ...] = tuple(f"{rule}-{family}" for family in FAMILIES for rule in RULES)
#: the local filters whose cross terms C_xy^m decide Proposition 1
LOCAL_FILTERS: tuple[str, ...] = tuple(f"Sensor{m}-{family}" for family in FAMILIES for m in (1, 2))
#: relative singular-value tolerances (σ_min > rtol · σ_max) at which the full-rank ratio is also
#: reported, to show how a "ratio of full column rank" figure depends on the tolerance chosen
RELATIVE_RANK_TOLS: tuple[float, ...] = (1e-12, 1e-10, 1e-8, 1e-6, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2)
RANK_RULE = "numpy/MATLAB rank rule: sigma_max * max(D, l_m) * eps (absolute, per matrix)"
#: audit entries kept verbatim in results.json (all are counted)
AUDIT_ENTRIES_KEPT = 200
_FAMILY_KEY = {"GP-ADF": "gp-adf", "GP-UKF": "gp-ukf"}


def add_method_arguments(parser, fit_points: int) -> None:
    """Options shared by ct2d and ungm1d: GP fitting, RCC-CI size, rank tolerance, sigma points."""
    parser.add_argument("--restarts", type=int, default=1, help="evidence-maximisation restarts (default 1)")
    parser.add_argument("--fit-points", type=int, default=fit_points,
                        help=f"at most this many training samples for hyperparameter fitting (default {fit_points})")
    parser.add_argument("--rcc-size", type=float, default=None,
                        help="RCC-CI ellipsoid size c (default the chi-square 99%% quantile)")
    parser.add_argument("--rank-tol", type=float, default=None,
                        help="absolute singular-value tolerance for rank(C_xy^m) in eq. 35 "
                             "(default numpy/MATLAB rule sigma_max * max(D, l) * eps)")
    parser.add_argument("--alpha", type=float, default=1.0, help="sigma-point alpha (default 1)")
    parser.add_argument("--beta", type=float, default=0.0, help="sigma-point beta (default 0)")
    parser.add_argument("--sigma-kappa", type=float, default=2.0, help="sigma-point kappa (default 2)")


def method_params(args) -> dict:
    """The shared options of :func:`add_method_arguments` as params entries."""
    if args.fit_points < 3:
        raise InputError(f"--fit-points must be at least 3, got {args.fit_points}")
    return {"restarts": args.restarts, "fit_points": args.fit_points, "rcc_size": args.rcc_size,
            "rcc_on_empty": "enlarge to 2 x smallest intersecting size", "rank_tol": args.rank_tol,
            "alpha": args.alpha, "beta": args.beta, "sigma_kappa": args.sigma_kappa}


def params_with(add_arguments, params_from_args, **overrides) -> dict:
    """An experiment's command-line defaults as a params dict, with ``overrides`` applied to the
    parsed options (option names with underscores) before ``params_from_args``."""
    import argparse

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args([])
    for key, value in overrides.items():
        setattr(args, key, value)
    return params_from_args(args)


def train_models(data: FusionData, restarts: int, fit_points: int, rng: np.random.Generator) -> GPModel:
    """The run's GP model learned from its training part (:func:`~gpfverify.models.fit_gp_model`)."""
    return fit_gp_model(data.transition_inputs, data.transition_targets, data.measurement_inputs,
                        data.measurement_targets, rng, restarts=restarts, fit_points=fit_points)


def hyperparameters(models: GPModel) -> dict:
    """The fitted hyperparameters, JSON-able."""
    def one(gp):
        return {"lengthscales": gp.lengthscales.tolist(), "signal_var": gp.signal_var.tolist(),
                "noise_var": gp.noise_var.tolist()}
    return {"transition": one(models.transition), "sensors": [one(gp) for gp in models.sensors]}


def squared_mahalanobis(truth: np.ndarray, estimate: Gaussian) -> float:
    """(x − x̂)ᵀ C⁻¹ (x − x̂) (eq. 44 as written: the squared form)."""
    err = truth - estimate.mean
    return float(err @ solve_spd(estimate.cov, err, "estimate covariance"))


class _Clock:
    """Accumulates per-step computation time per method."""

    def __init__(self, steps: int, methods: Sequence[str]):
        self.seconds = {m: np.zeros(steps) for m in methods}

    def run(self, method: str, step: int, fn, *args, **kwargs):
        start = time.perf_counter()
        out = fn(*args, **kwargs)
        self.seconds[method][step] += time.perf_counter() - start
        return out


def _rcc_ci(estimates, size):
    """RCC-CI with the ellipsoids enlarged when they do not intersect; (estimate, enlarged)."""
    result = rcc_ci(estimates, c=size, on_empty="enlarge")
    return Gaussian(result.mean, result.cov), result.enlarged


def _audit_entry(step: int, family: str, case) -> dict:
    audit = audit_case(case, rank_rule=None if case.rank_tol is not None else "numpy")  # eq. 35's rule
    gap, predicted = audit.gap, audit.predicted_gap
    return {"step": step + 1, "family": family, "condition_holds": audit.condition_holds,
            "exact": audit.exact,
            "gap_norm": float(np.linalg.norm(gap)), "predicted_gap_norm": float(np.linalg.norm(predicted)),
            "gap_error": float(np.linalg.norm(gap - predicted)),
            "correction_norm": float(np.linalg.norm(audit.cmf_mean - case.central.mu_p)),
            "sensors": [{"index": s.index, "rank": s.rank, "cols": s.cols, "tol": s.tol,
                         "singular_values": s.singular_values.tolist(),
                         "gap_gain_norm": s.gap_gain_norm, "exact": s.exact} for s in audit.sensors]}


def gap_condition(case) -> float:
    """The largest condition number eq. 35 goes through: the central C_y, each C_y^m and each
    C_xy^m (its pseudo-inverse); rounding in the one-step gap scales with it."""
    conds = [np.linalg.cond(case.central.C_y)]
    for local in case.locals:
        conds += [np.linalg.cond(local.C_y), np.linalg.cond(local.C_xy)]
    return float(max(conds))


def run_family(family: str, models: GPModel, data: FusionData, local_starts: Sequence[Gaussian],
               fused_start: Gaussian, sigma: SigmaParams, rcc_size: float | None,
               rank_tol: float | None) -> dict:
    """Filter the test segment with the six methods of one family; per-step records (see module
    docstring)."""
    ys_local = data.test_measurements
    ys = data.stacked_test_measurements()
    steps = ys.shape[0]
    names = [f"{rule}-{family}" for rule in RULES]
    clock = _Clock(steps, names)
    online = {f"{r}-{family}": np.zeros(steps) for r in ("CMF", "DMF")}
    method = _FAMILY_KEY[family]
    local_step = gaussian_family(method, sigma).step
    sensor_models = [models.sensor_model(m) for m in range(len(models.sensors))]
    locals_ = list(local_starts)
    cmf_belief, dmf_belief = fused_start, fused_start
    out = {"sq_err": {n: [] for n in names}, "maha": {n: [] for n in names},
           "singular_values": {f"Sensor{m + 1}-{family}": [] for m in range(len(locals_))},
           "full_rank": {f"Sensor{m + 1}-{family}": [] for m in range(len(locals_))},
           "rank_tol": {f"Sensor{m + 1}-{family}": [] for m in range(len(locals_))},
           "recursive_gap": [], "one_step_gap": [], "one_step_gap_rel": [], "condition_holds": [],
           "gap_scale": [], "gap_condition": [],
           "audit": [], "rcc_enlarged": 0}
    for k in range(steps):
        records: list[StepRecord] = [
            clock.run(f"Sensor{m + 1}-{family}", k, local_step, belief, sensor_model, ys_local[m][k], k=k + 1)
            for m, (belief, sensor_model) in enumerate(zip(locals_, sensor_models))]
        locals_ = [r.posterior for r in records]
        cmf = clock.run(f"CMF-{family}", k, cmf_step, cmf_belief, models, ys[k], k=k + 1, family=method,
                        params=sigma)
        dmf = clock.run(f"DMF-{family}", k, dmf_step, dmf_belief, models, ys[k], local_records=records, k=k + 1,
                        family=method, params=sigma, rank_tol=rank_tol)
        cmf_belief, dmf_belief = cmf.posterior, dmf.record.posterior
        cw = clock.run(f"CW-{family}", k, convex_combination, locals_)
        rcc, enlarged = clock.run(f"RCC-CI-{family}", k, _rcc_ci, locals_, rcc_size)
        out["rcc_enlarged"] += int(enlarged)

        # the update alone (what is left once the measurements arrive), CMF vs eq. 35
        start = time.perf_counter()
        same = cmf_update(dmf.case.central, ys[k])
        online[f"CMF-{family}"][k] = time.perf_counter() - start
        start = time.perf_counter()
        dmf_update(dmf.case, rank_rule=dmf.result.rank_rule)
        online[f"DMF-{family}"][k] = time.perf_counter() - start

        truth = data.test_states[k]
        estimates = dict(zip(names, [*locals_, cmf_belief, dmf_belief, Gaussian(rcc.mean, rcc.cov),
                                     Gaussian(cw.mean, cw.cov)]))
        for name, est in estimates.items():
            out["sq_err"][name].append(float(np.sum((truth - est.mean) ** 2)))
            out["maha"][name].append(squared_mahalanobis(truth, est))
        for s in dmf.result.sensors:
            key = f"Sensor{s.index + 1}-{family}"
            out["singular_values"][key].append(s.split.rank.singular_values.tolist())
            out["full_rank"][key].append(bool(s.full_column_rank))
            out["rank_tol"][key].append(float(s.split.rank.tol))
        gap = dmf.result.mean - same.mean
        out["recursive_gap"].append(float(np.linalg.norm(dmf_belief.mean - cmf_belief.mean)))
        out["one_step_gap"].append(float(np.linalg.norm(gap)))
        correction = float(np.linalg.norm(same.mean - dmf.case.central.mu_p))
        out["one_step_gap_rel"].append(float(np.linalg.norm(gap)) / correction if correction > 0 else 0.0)
        out["condition_holds"].append(bool(dmf.result.condition_holds))
        out["gap_scale"].append(float(np.linalg.norm(dmf.case.central.mu_p)) + correction)
        out["gap_condition"].append(gap_condition(dmf.case))
        if not dmf.result.condition_holds:
            out["audit"].append(_audit_entry(k, family, dmf.case))
    out["seconds"] = {n: s.tolist() for n, s in clock.seconds.items()}
    out["online_seconds"] = {n: s.tolist() for n, s in online.items()}
    return out


def run_setting(data: FusionData, models: GPModel, local_starts: Sequence[Gaussian],
                fused_start: Gaussian, sigma: SigmaParams, rcc_size: float | None,
                rank_tol: float | None) -> dict:
    """Both families on one run's data: ``{"families": {family: run_family(...)}}``."""
    merged: dict = {"families": {}}
    for family in FAMILIES:
        merged["families"][family] = run_family(family, models, data, local_starts, fused_start,
                                                sigma, rcc_size, rank_tol)
        merged["families"][family]["rounding_sensitivity"] = rounding_sensitivity(
            family, models, fused_start, data.stacked_test_measurements()[0], sigma)
    return merged


#: relative perturbation of the fused start used by :func:`rounding_sensitivity`
ROUNDING_PROBE = 1e-14


def rounding_sensitivity(family: str, models: GPModel, belief: Gaussian, y: np.ndarray,
                         sigma: SigmaParams) -> float:
    """‖Δμ_e‖ of one CMF step when the prior mean moves by :data:`ROUNDING_PROBE` · (|μ| + σ) per
    coordinate (σ the prior standard deviations): how far
    rounding-level differences between two mathematically equal beliefs (DMF's and CMF's) are
    amplified by one filter step. Large values explain a recursive DMF − CMF drift that the
    one-step gap (zero to rounding) does not."""
    method = _FAMILY_KEY[family]
    base = cmf_step(belief, models, y, family=method, params=sigma)
    shift = ROUNDING_PROBE * (np.abs(belief.mean) + np.sqrt(np.diag(belief.cov)))
    nudged = cmf_step(Gaussian(belief.mean + shift, belief.cov), models, y, family=method, params=sigma)
    return float(np.linalg.norm(nudged.mu_e - base.mu_e))


# -- summaries -----------------------------------------------------------------------------------

def _per_method(results: list[dict], field: str) -> dict[str, np.ndarray]:
    """(runs, T) array of a per-step field for every method."""
    out = {}
    for family in FAMILIES:
        for name in results[0]["families"][family][field]:
            out[name] = np.array([r["families"][family][field][name] for r in results], dtype=float)
    return out


def one_step_equivalence(family_record: dict) -> tuple[np.ndarray, np.ndarray]:
    """Per step of one family's run record: whether the rank condition held, and whether the
    one-step DMF − CMF gap is within rounding, ‖gap‖ ≤ algebra_rtol(conditioning) · (‖μ_p‖ +
    ‖μ_CMF − μ_p‖) with the conditioning of :func:`gap_condition`."""
    f = family_record
    within = [g <= algebra_rtol(c) * sc for g, c, sc in zip(f["one_step_gap"], f["gap_condition"], f["gap_scale"])]
    return np.array(f["condition_holds"], dtype=bool), np.array(within, dtype=bool)


def full_rank_ratio_at(results: list[dict], rtol: float) -> dict[str, list[float]]:
    """Fraction of runs in which σ_min(C_xy^m) > rtol · σ_max(C_xy^m), per step and local filter."""
    out = {}
    for family in FAMILIES:
        for name, per_run in results[0]["families"][family]["singular_values"].items():
            sv = np.array([r["families"][family]["singular_values"][name] for r in results])  # (R, T, l)
            full = sv[..., -1] > rtol * sv[..., 0]
            out[name] = np.mean(full, axis=0).tolist()
    return out


def _audit_summary(results: list[dict]) -> dict:
    entries = [dict(e, run=i) for i, r in enumerate(results) for f in FAMILIES for e in r["families"][f]["audit"]]
    by_family = {}
    for family in FAMILIES:
        mine = [e for e in entries if e["family"] == family]
        by_family[family] = {
            "steps": len(mine), "exact": sum(e["exact"] for e in mine),
            "max_gap_norm": max((e["gap_norm"] for e in mine), default=0.0),
            "max_gap_error": max((e["gap_error"] for e in mine), default=0.0),
            "max_relative_gap": max((e["gap_norm"] / e["correction_norm"] for e in mine
                                     if e["correction_norm"] > 0), default=0.0)}
    return {"rank_rule": RANK_RULE, "by_family": by_family, "entries": entries[:AUDIT_ENTRIES_KEPT],
            "entries_total": len(entries)}


def summarize_setting(results: list[dict]) -> dict:
    """Per-step and per-method summaries of one setting over runs (see module docstring)."""
    sq_err = _per_method(results, "sq_err")
    maha = _per_method(results, "maha")
    seconds = _per_method(results, "seconds")
    online = _per_method(results, "online_seconds")
    full_rank = _per_method(results, "full_rank")
    out = {
        "rmse": {m: np.sqrt(np.mean(sq_err[m], axis=0)).tolist() for m in METHODS},
        "average_mahalanobis": {m: np.mean(maha[m], axis=0).tolist() for m in METHODS},
        "full_rank_ratio": {m: np.mean(full_rank[m], axis=0).tolist() for m in LOCAL_FILTERS},
        "rank_tolerance": RANK_RULE,
        "full_rank_ratio_by_relative_tolerance": {f"{t:g}": full_rank_ratio_at(results, t)
                                                  for t in RELATIVE_RANK_TOLS},
        "time_per_step": {m: float(np.mean(seconds[m])) for m in METHODS},
        "time_per_run": {m: float(np.mean(np.sum(seconds[m], axis=1))) for m in METHODS},
        "online_time_per_step": {m: float(np.mean(online[m])) for m in online},
        "time_per_step_series": {m: np.mean(seconds[m], axis=0).tolist() for m in METHODS},
        "run_mean_sq_err": {m: np.mean(sq_err[m], axis=1).tolist() for m in METHODS},
        "run_mean_mahalanobis": {m: np.mean(maha[m], axis=1).tolist() for m in METHODS},
    }
    gaps, one_step, one_rel, holds, within = {}, {}, {}, {}, {}
    for family in FAMILIES:
        fam = [r["families"][family] for r in results]
        gaps[family] = np.array([f["recursive_gap"] for f in fam])
        one_step[family] = np.array([f["one_step_gap"] for f in fam])
        one_rel[family] = np.array([f["one_step_gap_rel"] for f in fam])
        holds[family] = np.array([f["condition_holds"] for f in fam], dtype=bool)
        within[family] = np.array([one_step_equivalence(f)[1] for f in fam])
    smallest_sv_outside = {}
    for family in FAMILIES:
        fam = [r["families"][family] for r in results]
        # (runs, T): the smaller σ_min of the two sensors' C_xy^m
        sv_min = np.min([[np.array(sv)[:, -1] for sv in f["singular_values"].values()] for f in fam], axis=1)
        outside = holds[family] & ~within[family]
        smallest_sv_outside[family] = float(np.max(sv_min[outside])) if outside.any() else None
    out["max_equivalence_gap"] = {f: float(np.max(gaps[f])) for f in FAMILIES}
    out["equivalence_gap_per_step"] = {f: np.max(gaps[f], axis=0).tolist() for f in FAMILIES}
    out["one_step_gap"] = {f: {
        "max_when_full_rank": float(np.max(one_step[f][holds[f]], initial=0.0)),
        "max_relative_when_full_rank": float(np.max(one_rel[f][holds[f]], initial=0.0)),
        "max_when_rank_fails": float(np.max(one_step[f][~holds[f]], initial=0.0)),
        "steps_full_rank": int(np.sum(holds[f])), "steps_rank_fails": int(np.sum(~holds[f])),
        "full_rank_steps_within_rounding": int(np.sum(within[f] & holds[f])),
        "max_smallest_singular_value_outside_rounding": smallest_sv_outside[f],
        "rounding_rule": "gap <= algebra_rtol(max cond of C_y, C_y^m, C_xy^m) * (|mu_p| + |mu_CMF - mu_p|)"}
        for f in FAMILIES}
    out["rounding_sensitivity"] = {f: {
        "probe": ROUNDING_PROBE,
        "median": float(np.median([r["families"][f]["rounding_sensitivity"] for r in results])),
        "max": float(np.max([r["families"][f]["rounding_sensitivity"] for r in results]))}
        for f in FAMILIES}
    out["rank_failure_audit"] = _audit_summary(results)
    out["rcc_ci_enlarged_steps"] = {f: int(sum(r["families"][f]["rcc_enlarged"] for r in results))
                                    for f in FAMILIES}
    return out
