"""Bearing-only tracking (Zhou et al. 2020 §3.2, Table 2, Fig. 3) of a target that moves at
constant velocity and then turns (model in :mod:`gpfverify.papers.particle_flow.bearing_scenario`); bootstrap PF with
N = 50 and N = 200 against the innovation-error particle flow (IE-PFF) with N = 50, 200 runs.

Every run simulates the truth from x₀ = [1000, 10, 1500, 15]; every filter starts from particles
drawn from N(x₀, P₀), P₀ = diag(σ_p², σ_v², σ_p², σ_v²) (interpretation: the paper gives no prior).
The metric is the position RMSE per step over runs, √(mean_runs[(x̂ − x)² + (ŷ − y)²]).

Health checks (results.json ``"health"``): every filter for divergence (a non-finite estimate or a
position error above ``divergence_bound``), the PFs for weight collapse (median N_eff/N); a claim
whose compared filters fail one is "not decidable" (:func:`gpfverify.health.decide`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from gpfverify.papers.particle_flow.bearing_contract import (INTERPRETATIONS, NAME, PAPER_RUNS, PROFILES, FilterRun,
                                                            Params, RunRecord)
from gpfverify.contract.claims import ClaimRecord, PairedRatio
from gpfverify.health import HealthCheck, decide
from gpfverify.contract.papers import PAPERS
from gpfverify.experiments.batching import BATCH_TIMING
from gpfverify.papers.particle_flow.contract import IE_PFF, PAPER
from gpfverify.papers.particle_flow.methods import (divergence_health, ess_health, flow_steps, paired_comparison,
                                                    run_methods, schedule_words)
from gpfverify.models import StateSpaceModel
from gpfverify.rng import child_rng, child_seed
from gpfverify.papers.particle_flow.bearing_scenario import bearing_model

__all__ = ["DEFAULT_RUNS", "INTERPRETATIONS", "NAME", "PAPER", "PROFILES", "Params", "RunRecord",
           "run_batch", "run_one", "summarize"]

DEFAULT_RUNS = PAPER_RUNS
#: two-sided level of the paired t-test that decides the accuracy claim
SIGNIFICANCE_LEVEL = 0.05
SOURCE = f"{PAPERS[PAPER].short}, §3.2, Table 2 and Fig. 3"


def _model(params: Params) -> StateSpaceModel:
    """The bearing model with the filters' prior N(x₀, P₀)."""
    return bearing_model(*params.process_variances, params.bearing_std, np.deg2rad(params.omega_deg),
                         params.switch_time, prior_std_pos=params.prior_std_pos,
                         prior_std_vel=params.prior_std_vel, initial_state=np.asarray(params.initial_state, float))


def run_one(params: Params, seed_seq: np.random.SeedSequence) -> RunRecord:
    return run_batch(params, [seed_seq])[0]


def run_batch(params: Params, seed_seqs: Sequence[np.random.SeedSequence]) -> list[RunRecord]:
    """The runs of ``seed_seqs`` filtered together (:func:`~gpfverify.papers.particle_flow.methods.run_methods`):
    every record but its CPU seconds (the batch's over its runs) is the same whatever the batch."""
    model = _model(params)
    simulated = [model.simulate(params.duration, child_rng(s, 0), x0=model.prior_mean) for s in seed_seqs]
    truth, ys = np.stack([xs for xs, _ in simulated]), np.stack([y for _, y in simulated])
    steps = flow_steps(params.dlambda, params.spacing, params.exponential_ratio, params.exponential_steps)
    out: list[dict[str, FilterRun]] = [{} for _ in seed_seqs]
    for i, sized in enumerate(params.filters, 1):
        runs = run_methods(sized.method, model, ys, sized.particles, [child_seed(s, i) for s in seed_seqs],
                           steps if sized.method == IE_PFF else None)
        for filters, run, xs in zip(out, runs, truth):
            sq = None if run.estimates is None else tuple(((run.estimates - xs)[:, [0, 2]] ** 2).sum(axis=1).tolist())
            ess = None if run.ess_fraction is None else tuple(run.ess_fraction.tolist())
            filters[sized.key] = FilterRun(sq, run.seconds, ess)
    return [RunRecord(filters) for filters in out]


def summarize(params: Params, records: list[RunRecord]) -> dict[str, Any]:
    """Position RMSE per step over the runs that did not diverge, its time average, the per-run
    RMS position error (None where the filter diverged), the mean filter time per run and the claims."""
    rmse, times, diverged, mean_rmse, run_rmse = {}, {}, {}, {}, {}
    health: dict[str, list[HealthCheck]] = {}
    for sized in params.filters:
        name = sized.key
        runs = [r.filters[name] for r in records]
        sq = [f.sq_pos_err for f in runs if f.sq_pos_err is not None]
        curve = np.sqrt(np.mean(sq, axis=0)) if sq else np.full(params.duration, np.nan)
        rmse[name] = curve.tolist()
        mean_rmse[name] = float(np.mean(curve))
        times[name] = float(np.mean([f.seconds for f in runs]))
        diverged[name] = len(records) - len(sq)
        run_rmse[name] = [None if f.sq_pos_err is None else float(np.sqrt(np.mean(f.sq_pos_err))) for f in runs]
        errors = [None if f.sq_pos_err is None else tuple(np.sqrt(f.sq_pos_err).tolist()) for f in runs]
        health[name] = [divergence_health(name, errors, params.duration, params.divergence_bound)]
        if sized.method != IE_PFF:
            ess = ess_health(name, [f.ess_fraction for f in runs], sized.particles)
            if ess is not None:
                health[name].append(ess)
    seconds = {sized.key: np.array([r.filters[sized.key].seconds for r in records]) for sized in params.filters}
    return {"rmse": rmse, "time_per_run": times, "mean_rmse": mean_rmse, "diverged": diverged,
            "run_rmse": run_rmse, "health": [c for checks in health.values() for c in checks],
            "significance_level": SIGNIFICANCE_LEVEL,
            "claims": claims(params, run_rmse, seconds, len(records), health)}


def claims(params: Params, run_rmse: dict[str, list[float | None]], seconds: dict[str, np.ndarray],
           runs: int, health: dict[str, list[HealthCheck]] | None = None) -> list[ClaimRecord]:
    """The paper's Table-2 claim, in two records: accuracy (paired t-test over runs, a divergence
    counts as a loss) and CPU time (the paired per-run ratio of the CPU seconds, undecided within
    its Monte Carlo tolerance; timing); each "not decidable" when the two filters it compares
    fail a health check."""
    _small, large, flow = params.filters
    checks = [c for key in (flow.key, large.key) for c in (health or {}).get(key, [])]
    schedule = schedule_words(params.dlambda, params.spacing, params.exponential_ratio, params.exponential_steps)
    noise = f", bearing σ = {params.bearing_std:g} rad" + (", r1 and r2 read as standard deviations"
                                                           if params.noise_values == "std" else "")
    setting = (f"N = {flow.particles} flow particles against N = {large.particles} PF particles, "
               f"{schedule}{noise}")
    acc = paired_comparison(run_rmse[flow.key], run_rmse[large.key], SIGNIFICANCE_LEVEL)
    verdict, caveats = decide(acc.verdict, checks)
    accuracy = ClaimRecord(
        claim=f"IE-PFF with N = {flow.particles} is more accurate than PF with N = {large.particles}",
        source=SOURCE, verdict=verdict, statistic=acc.t,
        threshold=None if acc.critical is None else -acc.critical, n=runs,
        evidence=f"position error, {flow.key} vs {large.key}: {acc.evidence} (m)",
        caveats=(*caveats, f"statistic: paired t statistic of the per-run RMS position error ({flow.key} − "
                           f"{large.key}); threshold: minus the two-sided Student quantile at level "
                           f"{SIGNIFICANCE_LEVEL:g}"),
        id=f"{NAME}/ie-pff-more-accurate-than-larger-pf", paper=PAPER, setting=setting, paper_n=PAPER_RUNS,
        runs_to_decide=acc.runs_to_decide if verdict == "undecided" else None)
    t = PairedRatio.of(seconds[flow.key], seconds[large.key])
    timed, timing_caveats = decide(t.verdict, checks)
    mean_flow, mean_pf = float(np.mean(seconds[flow.key])), float(np.mean(seconds[large.key]))
    timing = ClaimRecord(
        claim=f"IE-PFF with N = {flow.particles} runs in less time than PF with N = {large.particles}",
        source=SOURCE, verdict=timed, statistic=t.ratio, threshold=t.bound, n=runs,
        evidence=f"{t.evidence(flow.key, large.key)}; means {mean_flow:.3g} s against {mean_pf:.3g} s",
        runs_to_decide=t.runs_to_decide if timed == "undecided" else None,
        caveats=(*timing_caveats, "CPU (process) time of this Python implementation; one run at a time the PF's "
                 "cost is dominated by per-step overhead, not by N, so the ratio says little about the algorithms' "
                 "operation counts; " + BATCH_TIMING),
        id=f"{NAME}/ie-pff-faster-than-larger-pf", paper=PAPER, setting=setting, paper_n=PAPER_RUNS, timing=True)
    return [accuracy, timing]
