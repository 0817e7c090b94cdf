"""The fusion paper's 1-D two-sensor example (Liao et al. 2019 §4.1, Figs. 2–4):
xₖ₊₁ = 0.5xₖ + 25xₖ/(1 + xₖ²) + w, yᵐ = 5 sin(2x + zₘ) + vᵐ; one trajectory of 250 samples per run
and σ², the first 200 train the GPs, the last 50 are filtered by the twelve methods of
:mod:`gpfverify.papers.fusion.run`; average squared Mahalanobis distance per step (eq. 44), and
the paper's claims as records.

Every run simulates one independent trajectory per σ² (the main setting's and the sweep's; child
seeds of the run's seed). Parameters, profiles and the run record: :mod:`gpfverify.papers.fusion.ungm1d_contract`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from gpfverify.contract.claims import ClaimRecord, combine
from gpfverify.papers.fusion.contract import FAMILIES, METHODS, PAPER, family_methods
from gpfverify.contract.methods import Method
from gpfverify.papers.fusion.ungm1d_contract import (DEFAULT_RUNS, FIGURE_NOISES, INTERPRETATIONS, NAME, PROFILES,
                                                     SUMMARY_FIELDS, Params, RunRecord, noise_key)
from gpfverify.contract.serial import to_json
from gpfverify.papers.fusion.batch import gp_batch_bytes, run_setting_batch
from gpfverify.papers.fusion.run import (CPU_CLOCK, ClaimContext, RunInputs, _num, checks_of, equivalence_claim,
                                         fusion_beats_baselines, fusion_beats_sensors, health_checks, paired_claim,
                                         run_setting, sigma_params, summarize_setting, train_models)
from gpfverify.filters.records import Gaussian
from gpfverify.rng import generator
from gpfverify.papers.fusion.scenario import simulate_data, ungm_scenario

__all__ = ["DEFAULT_RUNS", "INTERPRETATIONS", "NAME", "PAPER", "PROFILES", "Params", "RunRecord", "SUMMARY_FIELDS",
           "batch_run_bytes", "run_batch", "run_one", "summarize"]

#: the per-σ² fields repeated under "sweep" for σ² other than the main one
SWEEP_FIELDS = ("rmse", "max_equivalence_gap", "one_step_gap", "full_rank_ratio", "time_per_step", "health")
#: the state dimension D (the NEES of a consistent filter has mean D)
STATE_DIM = 1


def _prepare(params: Params, seed_sequence: np.random.SeedSequence, setting: int) -> RunInputs:
    """Run ``seed_sequence``'s data, learned GPs (timed) and starts at the ``setting``-th σ², from the
    setting-th child of the run's seed (built explicitly: spawn() would depend on earlier spawns)."""
    child = np.random.SeedSequence(seed_sequence.entropy, spawn_key=tuple(seed_sequence.spawn_key) + (setting,))
    rng = generator(child)
    scenario = ungm_scenario(params.noise_vars[setting], params.measurement_noise_var, params.trajectory_start_var,
                             params.train, params.test_steps, tuple(params.sensor_phases))
    data = simulate_data(scenario, rng)
    started = CPU_CLOCK()
    models = train_models(data, params.restarts, params.fit_points, rng)
    training = CPU_CLOCK() - started
    prior = Gaussian(np.array([params.prior_mean]), np.array([[params.prior_var]]))
    return RunInputs(data, models, [prior, prior], prior, training)


def run_one(params: Params, seed_sequence: np.random.SeedSequence) -> RunRecord:
    settings = {}
    for i, noise_var in enumerate(params.noise_vars):
        run = _prepare(params, seed_sequence, i)
        settings[noise_key(noise_var)] = run_setting(run.data, run.models, run.local_starts, run.fused_start,
                                                     sigma_params(params), params.rcc_size, params.rank_rule_spec,
                                                     run.training_seconds, params.rcc_on_empty)
    return RunRecord(settings)


def run_batch(params: Params, seed_sequences: Sequence[np.random.SeedSequence]) -> list[RunRecord]:
    """:func:`run_one` of every seed, each σ²'s runs advancing together
    (:func:`~gpfverify.papers.fusion.batch.run_setting_batch`); each run's GPs are learned on
    its own, by its own optimiser path (per-run L-BFGS), as in :func:`run_one`."""
    per_setting = {}
    for i, noise_var in enumerate(params.noise_vars):
        runs = [_prepare(params, seed, i) for seed in seed_sequences]
        per_setting[noise_key(noise_var)] = run_setting_batch(
            [r.data for r in runs], [r.models for r in runs], [r.local_starts for r in runs],
            [r.fused_start for r in runs], sigma_params(params), params.rcc_size, params.rank_rule_spec,
            [r.training_seconds for r in runs], params.rcc_on_empty)
    return [RunRecord({key: records[b] for key, records in per_setting.items()}) for b in range(len(seed_sequences))]


def batch_run_bytes(params: Params) -> int:
    """Working memory of one run in a batch: its GPs' K⁻¹ and Cholesky factors (the transition GP and
    each sensor's, n training points), twice for the rest of the step's arrays."""
    return gp_batch_bytes(params.train, 1 + len(params.sensor_phases))


def summarize(params: Params, results: list[RunRecord]) -> dict:
    """The body of ``results.json``: the main σ²'s summary once, at top level (``"mahalanobis"``
    and the keys of
    :func:`~gpfverify.papers.fusion.run.summarize_setting`); ``"per_noise"`` the full summaries of
    the *other* σ² values; ``"sweep"`` the per-step curves of every σ² except the main one's (which are
    the top-level ones); ``"average_mahalanobis_by_noise"`` the step-mean of every σ²."""
    per_noise = {}
    for v in params.noise_vars:
        runs = [r.settings[noise_key(v)] for r in results]
        summary = summarize_setting(runs, params.rank_rule_spec)
        summary["health"] = [to_json(c) for c in health_checks(runs, STATE_DIM, params.divergence_bound,
                                                                params.nees_level)]
        # the square-root form of eq. 44 per run (Deisenroth et al.'s): mean over steps of |x − x̂|/σ
        summary["run_mean_root_mahalanobis"] = {
            m.key: [float(np.mean(np.sqrt(r.families[family].maha[m.key]))) for r in runs]
            for family in FAMILIES for m in family_methods(family)}
        per_noise[noise_key(v)] = summary
    main_key = noise_key(params.system_noise_var)
    main = per_noise[main_key]
    others = {k: v for k, v in per_noise.items() if k != main_key}
    return {
        "mahalanobis": main["average_mahalanobis"], **main,
        "main_noise": main_key,
        "noise_vars": list(params.noise_vars),
        "sweep": {k: {"mahalanobis": v["average_mahalanobis"], **{f: v[f] for f in SWEEP_FIELDS}}
                  for k, v in others.items()},
        "per_noise": others,
        "average_mahalanobis_by_noise": {k: {m.key: float(np.mean(v["average_mahalanobis"][m.key])) for m in METHODS}
                                         for k, v in per_noise.items()},
        "claims": claims(params, per_noise, len(results)),
    }


#: the per-run key of a setting's summary each metric reading compares, and its name on the page
METRIC_KEYS: dict[tuple[str, str], tuple[str, str]] = {
    ("mahalanobis", "squared"): ("run_mean_mahalanobis", "squared Mahalanobis distance (eq. 44 as written)"),
    ("mahalanobis", "root"): ("run_mean_root_mahalanobis", "Mahalanobis distance |x − x̂|/σ (square-root form)"),
    ("squared-error", "squared"): ("run_mean_sq_err", "squared error ‖x − x̂‖² (the RMSE of eq. 45)"),
    ("squared-error", "root"): ("run_mean_sq_err", "squared error ‖x − x̂‖² (the RMSE of eq. 45)"),
}


def metric_of(params: Params) -> tuple[str, str]:
    """(the per-run key the claims compare, its name) for the parameters' metric reading."""
    return METRIC_KEYS[(params.metric, params.mahalanobis)]


def claims(params: Params, per_noise: dict[str, dict], n: int) -> list[ClaimRecord]:
    out = []
    for noise in params.noise_vars:
        key = noise_key(noise)
        in_figure = noise in FIGURE_NOISES
        ctx = ClaimContext(NAME, f"σ² = {noise:g}", f"s{key}", n, DEFAULT_RUNS if in_figure else None)
        out += setting_claims(ctx, per_noise[key], noise, in_figure, metric_of(params))
    out.append(sweep_claim(params, out, n))
    return out


def setting_claims(ctx: ClaimContext, r: dict, noise: float, in_figure: bool,
                   metric: tuple[str, str] = METRIC_KEYS[("mahalanobis", "squared")]) -> list[ClaimRecord]:
    """The claims of one σ²; every comparison through the paired Monte Carlo rule and the health
    gate (:func:`~gpfverify.papers.fusion.run.paired_claim`) on the per-run ``metric``."""
    source = "Figs. 2, 3 (§4.1)" if in_figure else "Fig. 4 (§4.1)"
    caveats = () if in_figure else ("the paper shows this σ² only in Fig. 4, without a run count; the σ² values of "
                                    "Fig. 4 are an interpretation (lost in extraction)",)
    key, words = metric
    compared = (f"compared: the per-run mean of the {words}",)
    out = []
    for family in FAMILIES:
        out += [equivalence_claim(ctx, r, family, "average_mahalanobis", "Proposition 1 and eq. 35; " + source,
                                  caveats=(*caveats, *health_caveats(r, family))),
                fusion_beats_sensors(ctx, r, family, key, "", source, caveats=(*caveats, *compared),
                                     health=r["health"]),
                fusion_beats_baselines(ctx, r, family, key, "", source, caveats=(*caveats, *compared),
                                       health=r["health"]),
                paired_claim(ctx, f"sensor2-beats-sensor1/{family}", f"{family}: Sensor 2 performs better than "
                             "Sensor 1", source, r[key],
                             [(Method.sensor_filter(2, family), Method.sensor_filter(1, family))], "",
                             caveats=(*caveats, *compared), health=r["health"])]
    if noise in FIGURE_NOISES:
        better, worse = ("GP-ADF", "GP-UKF") if noise == FIGURE_NOISES[0] else ("GP-UKF", "GP-ADF")
        out.append(paired_claim(ctx, f"fusion-{better.lower()}-beats-{worse.lower()}",
                                f"σ² = {noise:g}: fusion with {better} beats fusion with {worse}",
                                "§4.1, Figs. 2, 3", r[key],
                                [(Method("CMF", better), Method("CMF", worse))], "", caveats=compared,
                                health=r["health"]))
    return out


def health_caveats(r: dict, family: str) -> tuple[str, ...]:
    """The failed health checks of a family's filters, as a caveat of the equivalence claim: eq. 35 is
    compared with CMF one step at a time from the same central prediction, which does not need the
    filters to be healthy, but the steps it covers are those these filters reached."""
    failed = [c for c in checks_of(r["health"], family_methods(family)) if not c.passed]
    if not failed:
        return ()
    return (f"the {family} filters failed health checks here — " + "; ".join(f"{c.subject}: {c.name} ({c.detail})"
                                                                          for c in failed)
            + " — the verdict compares one step of eq. 35 with CMF from the same central prediction, which stands "
              "whatever the filters' health, but the steps it covers are those these filters reached",)


def sweep_claim(params: Params, records: list[ClaimRecord], n: int) -> ClaimRecord:
    """Fusion beats the single sensors for every σ² (Fig. 4): the per-σ² claims "CMF and DMF beat
    each single sensor" of both families, each decided by the paired rule and the health gate, made
    one: NOT held when one part is, held when all are, not decidable when a part is (and none is NOT
    held), undecided otherwise. Statistic: the least favourable part's (its mean difference and
    tolerance)."""
    parts = [c for c in records if "/fusion-beats-sensors/" in c.id]
    verdict = combine([c.verdict for c in parts])
    decided = [c for c in parts if c.statistic is not None and c.threshold]
    worst = max(decided, key=lambda c: (c.statistic or 0.0) / (c.threshold or 1.0), default=None)
    undecided = [c.runs_to_decide for c in parts if c.verdict == "undecided" and c.runs_to_decide]
    withheld = [f"{c.setting}, {c.claim.split(':')[0]}: {c.caveats[0]}" for c in parts
                if c.verdict == "not decidable" and c.caveats]
    ctx = ClaimContext(NAME, "", "", n, None)
    record = ctx.record(
        "fusion-beats-sensors-every-noise", "fusion beats the single sensors for every σ²", "Fig. 4 (§4.1)", verdict,
        None if worst is None else worst.statistic, None if worst is None else worst.threshold,
        "the claims 'CMF and DMF beat each single sensor' at every σ² and for both families, each by the paired "
        f"difference of per-run means of the {metric_of(params)[1]} over runs (± 5 standard errors) with the "
        "health gate: " + "; ".join(f"{c.setting} {c.claim.split(':')[0]}: {c.verdict}" for c in parts)
        + ("" if worst is None else f"; least favourable part ({worst.setting}, {worst.claim.split(':')[0]}): "
                                    f"{_num(worst.statistic)} against its tolerance {_num(worst.threshold)}"),
        caveats=(*withheld, "the paper states no run count for Fig. 4; its σ² values are an interpretation (lost in "
                            "extraction)"))
    return dataclasses.replace(record, runs_to_decide=max(undecided) if verdict == "undecided" and undecided else None)
