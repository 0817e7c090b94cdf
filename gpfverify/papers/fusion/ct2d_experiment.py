"""The fusion paper's 2-D constant-turn experiment (Liao et al. 2019 §4.2, Figs. 5–15): two
range–bearing sensors, GPs learned from κ training samples, 50 test steps filtered by twelve
methods (Sensor1/Sensor2/CMF/DMF/RCC-CI/CW × GP-ADF/GP-UKF); RMSE per step (eq. 45), the ratio of
full column rank of each local C_xy^m per step, the DMF − CMF gap, computation time per method,
the audit of every step on which the rank condition failed, and the paper's claims as records.

Parameters, profiles and the run record: :mod:`gpfverify.papers.fusion.ct2d_contract` (the interpretations are
stated there); the methods and records: :mod:`gpfverify.papers.fusion.run`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from gpfverify.contract.claims import PROPOSITION_1, ClaimRecord, PairedRatio, combine, verdict_of
from gpfverify.papers.fusion.ct2d_contract import (DEFAULT_RUNS, INTERPRETATIONS, LARGE_TRAINING, NAME, PROFILES,
                                                   Params, RunRecord, default_perturbation_mean, omega_label)
from gpfverify.papers.fusion.contract import FAMILIES, FUSION_RULES, LOCAL_FILTERS, PAPER
from gpfverify.contract.methods import Method
from gpfverify.contract.serial import to_json
from gpfverify.experiments.batching import BATCH_TIMING
from gpfverify.papers.fusion.batch import gp_batch_bytes, run_setting_batch
from gpfverify.papers.fusion.run import (CPU_CLOCK, ClaimContext, RunInputs, equivalence_claim, fusion_beats_baselines,
                                         fusion_beats_sensors, health_checks, run_setting, sigma_params,
                                         summarize_setting, train_models)
from gpfverify.filters.records import Gaussian
from gpfverify.models import Sensor, StateSpaceModel
from gpfverify.rng import generator
from gpfverify.papers.fusion.scenario import (FusionScenario, polar_to_cartesian, range_bearing, sensor_side,
                                              simulate_data, turn_matrix)

__all__ = ["DEFAULT_RUNS", "INTERPRETATIONS", "NAME", "PAPER", "PROFILES", "Params", "RunRecord", "TIMING_KEYS",
           "batch_run_bytes", "default_perturbation_mean", "run_batch", "run_one", "summarize"]

#: the claims that compare wall-clock times are measurements like the times themselves: they are
#: written under "timing_claims" (named in results.json's "timing_keys"), so that every other
#: field, "claims" included, stays byte-identical across executions (CONTRACT.md, "Provenance")
TIMING_KEYS = ("timing_claims",)
#: the state dimension D (the NEES of a consistent filter has mean D)
STATE_DIM = 2


def scenario(params: Params) -> FusionScenario:
    """The model of eq. 46–47 with the parameters' noise variances and sensor positions."""
    R = np.diag([params.range_noise_var, params.bearing_noise_var])
    sensors = tuple(Sensor(range_bearing(np.array(z)), R, name=f"range-arctan at {z}")
                    for z in params.sensor_positions)
    model = StateSpaceModel(turn_matrix(params.omega), params.process_noise_var * np.eye(2), sensors, np.zeros(2),
                            params.training_start_var * np.eye(2), name="2-D constant turn")
    return FusionScenario(model, params.kappa, params.test_steps)


def starts(params: Params, first_observations, rng: np.random.Generator) -> tuple[list[Gaussian], Gaussian]:
    """Each sensor's initial belief and the fused filters' one (see :mod:`gpfverify.papers.fusion.ct2d_contract`)."""
    cov = params.start_cov_scale * np.eye(2)
    means = [polar_to_cartesian(y, z, sensor_side(z))
             + rng.normal(params.start_mean, params.perturbation_std, size=2)
             for y, z in zip(first_observations, params.sensor_positions)]
    return [Gaussian(m, cov) for m in means], Gaussian(np.mean(means, axis=0), cov)


def prepare(params: Params, seed_sequence: np.random.SeedSequence) -> RunInputs:
    """A run's data, learned GPs (timed) and starts, drawn from its own stream in that order."""
    rng = generator(seed_sequence)
    data = simulate_data(scenario(params), rng)
    started = CPU_CLOCK()
    models = train_models(data, params.restarts, params.fit_points, rng)
    training = CPU_CLOCK() - started
    local_starts, fused_start = starts(params, [y[0] for y in data.test_measurements], rng)
    return RunInputs(data, models, local_starts, fused_start, training)


def run_one(params: Params, seed_sequence: np.random.SeedSequence) -> RunRecord:
    run = prepare(params, seed_sequence)
    return run_setting(run.data, run.models, run.local_starts, run.fused_start, sigma_params(params),
                       params.rcc_size, params.rank_rule_spec, run.training_seconds, params.rcc_on_empty)


def run_batch(params: Params, seed_sequences: Sequence[np.random.SeedSequence]) -> list[RunRecord]:
    """:func:`run_one` of every seed, the runs' filters advancing together
    (:func:`~gpfverify.papers.fusion.batch.run_setting_batch`); each run's GPs are learned on
    its own, by its own optimiser path (per-run L-BFGS), as in :func:`run_one`."""
    runs = [prepare(params, seed) for seed in seed_sequences]
    return run_setting_batch([r.data for r in runs], [r.models for r in runs], [r.local_starts for r in runs],
                             [r.fused_start for r in runs], sigma_params(params), params.rcc_size,
                             params.rank_rule_spec, [r.training_seconds for r in runs], params.rcc_on_empty)


def batch_run_bytes(params: Params) -> int:
    """Working memory of one run in a batch: its GPs' K⁻¹ and Cholesky factors (the transition GP's two
    outputs and each sensor's two, κ training points), twice for the rest of the step's arrays."""
    return gp_batch_bytes(params.kappa, 2 + 2 * len(params.sensor_positions))


def summarize(params: Params, results: list[RunRecord]) -> dict:
    body = summarize_setting(results, params.rank_rule_spec)
    body["health"] = [to_json(c) for c in health_checks(results, STATE_DIM, params.divergence_bound,
                                                         params.nees_level)]
    # the start the runs used (params hold None for "the paper's choice for κ")
    body["start_perturbation"] = {"mean": params.start_mean, "std": params.perturbation_std,
                                  "initial_cov_scale": params.start_cov_scale}
    ctx = ClaimContext(NAME, params.label, "", len(results), DEFAULT_RUNS)
    body["claims"] = claims(params, body, ctx)
    body["timing_claims"] = time_claims(ctx, run_seconds(results, "seconds"), run_seconds(results, "online_seconds"))
    return body


def run_seconds(results: list[RunRecord], field: str) -> dict[str, np.ndarray]:
    """Each method's CPU seconds per run (the sum over the test steps of ``field``, "seconds" or
    "online_seconds" of :class:`~gpfverify.papers.fusion.contract.FamilyRun`)."""
    out = {}
    for family in FAMILIES:
        for key in getattr(results[0].families[family], field):
            out[key] = np.array([np.sum(getattr(r.families[family], field)[key]) for r in results])
    return out


def claims(params: Params, r: dict, ctx: ClaimContext) -> list[ClaimRecord]:
    """The paper's claims checked on one setting's summary, except those on computation time
    (:func:`time_claims`)."""
    out = []
    for family in FAMILIES:
        out += [equivalence_claim(ctx, r, family, "rmse", "Proposition 1 and eq. 35; Figs. 6, 7 (§4.2, case 1)"),
                fusion_beats_sensors(ctx, r, family, "run_mean_sq_err", "m²", "Figs. 6, 7, 12, 13 (§4.2)",
                                     health=r["health"]),
                fusion_beats_baselines(ctx, r, family, "run_mean_sq_err", "m²", "Figs. 6, 7, 12, 13 (§4.2)",
                                       health=r["health"])]
    if params.kappa < LARGE_TRAINING:
        out.append(rank_claim(ctx, params, r))
    return out


def time_claims(ctx: ClaimContext, seconds: dict[str, np.ndarray], online: dict[str, np.ndarray]
                ) -> list[ClaimRecord]:
    """DMF costs less than CMF, RCC-CI costs the most of the fusion methods (Figs. 8, 9, 14, 15),
    decided on the paired per-run ratios of the methods' CPU seconds per run
    (:class:`~gpfverify.contract.claims.PairedRatio`: held when their geometric mean lies below 1
    beyond the Monte Carlo tolerance, NOT held above it, undecided in between). The paper does not
    say what it timed, so "DMF costs less than CMF" is two claims: the whole fusion step (the
    centre's prediction, stacked moments and update) and the update alone once the measurements
    arrive (eq. 35 against CMF's update, from the same central prediction)."""
    def timed(name: str, claim: str, parts: list[tuple[str, str, dict[str, np.ndarray]]], words: str
              ) -> ClaimRecord:
        ratios = [(a, b, PairedRatio.of(times[a], times[b])) for a, b, times in parts]
        worst = max(ratios, key=lambda item: item[2].ratio)[2]
        evidence = (f"{words}; " + "; ".join(r.evidence(a, b) for a, b, r in ratios)
                    + ("" if len(ratios) == 1 else "; held when every ratio is, NOT held when one is"))
        verdict = combine([r.verdict for _, _, r in ratios])
        undecided = [r.runs_to_decide for _, _, r in ratios if r.verdict == "undecided" and r.runs_to_decide]
        record = ctx.record(name, claim, "Figs. 8, 9, 14, 15 (§4.2)", verdict, worst.ratio, worst.bound, evidence,
                            caveats=(BATCH_TIMING,), timing=True)
        return dataclasses.replace(record, runs_to_decide=max(undecided) if verdict == "undecided" and undecided
                                   else None)

    out = []
    for family in FAMILIES:
        cmf, dmf = Method("CMF", family).key, Method("DMF", family).key
        out.append(timed(f"dmf-cheaper-than-cmf/{family}",
                         f"{family}: DMF costs less time than CMF (whole fusion step)", [(dmf, cmf, seconds)],
                         "the whole fusion step (the centre's prediction, stacked moments and update)"))
        out.append(timed(f"dmf-update-cheaper-than-cmf/{family}",
                         f"{family}: DMF costs less time than CMF (the update alone)", [(dmf, cmf, online)],
                         "the update alone once the measurements arrive, from the same central prediction (eq. 35 "
                         "against CMF's update)"))
        rcc = Method("RCC-CI", family).key
        others = [Method(rule, family).key for rule in FUSION_RULES if rule != "RCC-CI"]
        out.append(timed(f"rcc-ci-costs-most/{family}", f"{family}: RCC-CI costs the most time of the fusion methods",
                         [(other, rcc, seconds) for other in others], "each other fusion method against RCC-CI"))
    return out


def rank_claim(ctx: ClaimContext, params: Params, r: dict) -> ClaimRecord:
    """With κ = 30 or 60, GP-UKF's cross covariances lose full column rank on some step while
    GP-ADF's keep it on every step (Figs. 10, 11; under eq. 35's rank rule): a claim on when
    Proposition 1's condition holds, counted with it. Statistic: the smallest full-rank ratio of
    GP-UKF over sensors and steps (below 1 for the claim)."""
    ratio = {m: min(r["full_rank_ratio"][m.key]) for m in LOCAL_FILTERS}
    ukf = min(v for m, v in ratio.items() if m.family == "GP-UKF")
    adf = min(v for m, v in ratio.items() if m.family == "GP-ADF")
    evidence = ("smallest ratio of full column rank over steps: "
                + ", ".join(f"{m.key} {100 * v:.1f} %" for m, v in ratio.items())
                + f" (κ = {params.kappa}, Ω = {omega_label(params.omega)}; rank rule: {r['rank_tolerance']})")
    return ctx.record("gp-ukf-loses-full-rank", "GP-UKF loses full column rank with small training sets "
                      "(κ = 30, 60) while GP-ADF keeps it", "Figs. 10, 11 (§4.2, case 2)",
                      verdict_of(ukf < 1.0 and adf == 1.0), ukf, 1.0, evidence, theorem=PROPOSITION_1)
