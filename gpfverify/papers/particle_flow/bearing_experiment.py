"""Bearing-only tracking (Zhou et al. 2020 §3.2, Table 2, Fig. 3) of a target that moves at
constant velocity and then turns (model in :mod:`gpfverify.papers.particle_flow.bearing_scenario`); bootstrap PF with
N = 50 and N = 200 against the innovation-error particle flow (IE-PFF) with N = 50, 200 runs.

Every run simulates the truth from x₀ = [1000, 10, 1500, 15]; every filter starts from particles
drawn from N(x₀, P₀), P₀ = diag(σ_p², σ_v², σ_p², σ_v²) (interpretation: the paper gives no prior).
The metric is the position RMSE per step over runs, √(mean_runs[(x̂ − x)² + (ŷ − y)²]).

Health checks (results.json ``"health"``): every filter for divergence (a non-finite estimate or a
position error above ``divergence_bound``), the PFs for weight collapse (median N_eff/N); a claim
whose compared filters fail one is "not decidable" (:meth:`gpfverify.contract.claims.ClaimRecord.checked`).
Every run also filters a second trajectory with the process noise × ``large_noise_factor`` (§3.2's
remark on larger process noise) with Table 2's three filters, and the first with an IE-PFF of
``flow_particles_large`` particles (its remark on more particles).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from gpfverify.papers.particle_flow.bearing_contract import (INTERPRETATIONS, NAME, PAPER_RUNS, PROFILES, FilterRun,
                                                            Params, RunRecord)
from gpfverify.contract.claims import ClaimRecord, PairedRatio, combine
from gpfverify.contract.health_records import HealthCheck, stored_checks
from gpfverify.contract.serial import to_json
from gpfverify.papers.particle_flow.claims import statement_of
from gpfverify.papers.particle_flow.contract import IE_PFF, PAPER
from gpfverify.papers.particle_flow.methods import (Comparison, divergence_health, ess_health, flow_steps,
                                                    paired_comparison, ratio_comparison, run_methods, schedule_words)
from gpfverify.models import StateSpaceModel
from gpfverify.rng import child_rng, child_seed
from gpfverify.papers.particle_flow.bearing_scenario import bearing_model

__all__ = ["DEFAULT_RUNS", "INTERPRETATIONS", "NAME", "PAPER", "PROFILES", "Params", "RunRecord",
           "judge", "run_batch", "run_one", "summarize"]

DEFAULT_RUNS = PAPER_RUNS
#: two-sided level of the paired t-test that decides the accuracy claims
SIGNIFICANCE_LEVEL = 0.05
#: "not improved" (并沒有提高) with more particles, which the paper gives no number for: the flow's
#: per-run RMSE lowered by less than this share
NO_GAIN = 0.1


def _model(params: Params, noise_factor: float = 1.0) -> StateSpaceModel:
    """The bearing model with the filters' prior N(x₀, P₀), the process noise × ``noise_factor``."""
    q_pos, q_vel = params.process_variances
    return bearing_model(noise_factor * q_pos, noise_factor * q_vel, params.bearing_std, np.deg2rad(params.omega_deg),
                         params.switch_time, prior_std_pos=params.prior_std_pos,
                         prior_std_vel=params.prior_std_vel, initial_state=np.asarray(params.initial_state, float))


#: the sub-stream keys of a run's second trajectory (larger process noise) and of its filters, apart
#: from the first trajectory's (0) and its filters' (1, 2, …)
LARGE_NOISE_KEY = 100


def run_one(params: Params, seed_seq: np.random.SeedSequence) -> RunRecord:
    return run_batch(params, [seed_seq])[0]


def _filter_runs(model: StateSpaceModel, filters, params: Params, seed_seqs: Sequence[np.random.SeedSequence],
                 truth_key: int, first_filter_key: int) -> list[dict[str, FilterRun]]:
    """Every filter of ``filters`` on each run's trajectory of ``model`` (drawn from sub-stream
    ``truth_key``; the i-th filter from sub-stream ``first_filter_key + i``)."""
    simulated = [model.simulate(params.duration, child_rng(s, truth_key), x0=model.prior_mean) for s in seed_seqs]
    truth, ys = np.stack([xs for xs, _ in simulated]), np.stack([y for _, y in simulated])
    steps = flow_steps(params.dlambda, params.spacing, params.exponential_ratio, params.exponential_steps)
    out: list[dict[str, FilterRun]] = [{} for _ in seed_seqs]
    for i, sized in enumerate(filters):
        runs = run_methods(sized.method, model, ys, sized.particles,
                           [child_seed(s, first_filter_key + i) for s in seed_seqs],
                           steps if sized.method == IE_PFF else None)
        for filtered, run, xs in zip(out, runs, truth):
            sq = None if run.estimates is None else tuple(((run.estimates - xs)[:, [0, 2]] ** 2).sum(axis=1).tolist())
            ess = None if run.ess_fraction is None else tuple(run.ess_fraction.tolist())
            filtered[sized.key] = FilterRun(sq, run.seconds, ess)
    return out


def run_batch(params: Params, seed_seqs: Sequence[np.random.SeedSequence]) -> list[RunRecord]:
    """The runs of ``seed_seqs`` filtered together (:func:`~gpfverify.papers.particle_flow.methods.run_methods`):
    every record but its CPU seconds (the batch's over its runs) is the same whatever the batch."""
    base = _filter_runs(_model(params), params.filters, params, seed_seqs, 0, 1)
    large = _filter_runs(_model(params, params.large_noise_factor), params.large_noise_filters, params, seed_seqs,
                         LARGE_NOISE_KEY, LARGE_NOISE_KEY + 1)
    return [RunRecord(b, lg) for b, lg in zip(base, large)]


def _summary(params: Params, filters, runs: list[dict[str, FilterRun]], label: str) -> tuple[dict, list[HealthCheck]]:
    """Position RMSE per step over the runs that did not diverge, its time average, the per-run RMS
    position error (None where the filter diverged) and CPU seconds, and the filters' health
    (subjects named with ``label``)."""
    out: dict[str, dict] = {k: {} for k in ("rmse", "time_per_run", "mean_rmse", "diverged", "run_rmse",
                                             "run_seconds")}
    health: list[HealthCheck] = []
    for sized in filters:
        name = sized.key
        mine = [r[name] for r in runs]
        sq = [f.sq_pos_err for f in mine if f.sq_pos_err is not None]
        curve = np.sqrt(np.mean(sq, axis=0)) if sq else np.full(params.duration, np.nan)
        out["rmse"][name] = curve.tolist()
        out["mean_rmse"][name] = float(np.mean(curve))
        out["time_per_run"][name] = float(np.mean([f.seconds for f in mine]))
        out["diverged"][name] = len(runs) - len(sq)
        out["run_rmse"][name] = [None if f.sq_pos_err is None else float(np.sqrt(np.mean(f.sq_pos_err))) for f in mine]
        out["run_seconds"][name] = [f.seconds for f in mine]
        errors = [None if f.sq_pos_err is None else tuple(np.sqrt(f.sq_pos_err).tolist()) for f in mine]
        health.append(divergence_health(name + label, errors, params.duration, params.divergence_bound))
        if sized.method != IE_PFF:
            ess = ess_health(name + label, [f.ess_fraction for f in mine], sized.particles)
            if ess is not None:
                health.append(ess)
    return out, health


def large_noise_label(params: Params) -> str:
    """How the filters on the trajectory with the larger process noise are named in the health checks."""
    return f" (process noise × {params.large_noise_factor:g})"


def summarize(params: Params, records: list[RunRecord]) -> dict[str, Any]:
    """The summaries of both trajectories (:func:`_summary`), the filters' health and the claims."""
    body, health = _summary(params, params.filters, [r.filters for r in records], "")
    large, large_health = _summary(params, params.large_noise_filters, [r.large_noise for r in records],
                                   large_noise_label(params))
    body.update({"large_noise": large, "health": to_json([*health, *large_health]),
                 "significance_level": SIGNIFICANCE_LEVEL})
    accuracy, timing = judge(params, body, len(records))
    return {**body, "claims": [*accuracy, *timing]}


def judge(params: Params, body: dict, runs: int) -> tuple[list[ClaimRecord], list[ClaimRecord]]:
    """§3.2's claims (:mod:`gpfverify.papers.particle_flow.claims`) judged on a summary ``body`` of
    ``runs`` runs, and apart those on computation time: the flow against the PF with the same and
    with four times the particles, in accuracy (paired t-test over runs, a divergence counts as a
    loss) and in CPU time (paired per-run ratio); the flow against the PF at the larger process
    noise; the PF with more particles against fewer, and the flow likewise (its RMSE "not improved":
    read as lowered by less than :data:`NO_GAIN` of itself). A summary made before the second IE-PFF
    and the larger process noise were run judges those claims not ("not decidable", what they need),
    and the timing claims only from per-run seconds."""
    small, large, flow, flow_large = params.filters
    checks = stored_checks(body["health"])
    schedule = schedule_words(params.dlambda, params.spacing, params.exponential_ratio, params.exponential_steps)
    noise = f", bearing σ = {params.bearing_std:g} rad" + (", r1 and r2 read as standard deviations"
                                                           if params.noise_values == "std" else "")
    level = SIGNIFICANCE_LEVEL
    run_rmse = body["run_rmse"]

    def record(slug: str, claim: str, setting: str, comparisons: list[tuple[str, Comparison]], compared: list[str],
               caveats: tuple[str, ...] = ()) -> ClaimRecord:
        verdict = combine([c.verdict for _, c in comparisons])
        decided = [c for _, c in comparisons if c.t is not None]
        worst = max(decided, key=lambda c: c.t if c.t is not None else -np.inf) if decided else None
        undecided = [c.runs_to_decide for _, c in comparisons if c.verdict == "undecided" and c.runs_to_decide]
        made = ClaimRecord(
            claim=claim, source="", verdict=verdict, statistic=None if worst is None else worst.t,
            threshold=None if worst is None or worst.critical is None else -worst.critical, n=runs,
            evidence="; ".join(f"{name}: {c.evidence} (m)" for name, c in comparisons),
            caveats=(*caveats, f"statistic: the largest paired t statistic (negative favours the claim); threshold: "
                               f"minus the two-sided Student quantile at level {level:g}"),
            id=f"{NAME}/{slug}", paper=PAPER, setting=setting, paper_n=PAPER_RUNS,
            runs_to_decide=max(undecided) if verdict == "undecided" and undecided else None)
        return statement_of(made.id).applied(made).checked(compared, checks)

    def pending(slug: str, claim: str, setting: str, compared: list[str], needs: str, timing: bool = False):
        made = ClaimRecord(claim=claim, source="", verdict="not decidable", statistic=None, threshold=None, n=runs,
                           evidence="not judged", id=f"{NAME}/{slug}", paper=PAPER, setting=setting,
                           paper_n=PAPER_RUNS, timing=timing, needs=needs)
        return statement_of(made.id).applied(made).checked(compared, checks)

    def timed(slug: str, claim: str, setting: str, a: str, b: str) -> ClaimRecord:
        if "run_seconds" not in body:
            return pending(slug, claim, setting, [a, b], "each run's CPU seconds per filter (results.json "
                           "'run_seconds'), which a summary made before they were kept does not have", timing=True)
        t = PairedRatio.of(body["run_seconds"][a], body["run_seconds"][b])
        made = ClaimRecord(
            claim=claim, source="", verdict=t.verdict, statistic=t.ratio, threshold=t.bound, n=runs,
            evidence=f"{t.evidence(a, b)}; means {np.mean(body['run_seconds'][a]):.3g} s against "
                     f"{np.mean(body['run_seconds'][b]):.3g} s",
            runs_to_decide=t.runs_to_decide if t.verdict == "undecided" else None,
            caveats=("CPU (process) time of this Python implementation; one run at a time the PF's cost is dominated "
                     "by per-step overhead, not by N, so the ratio says little about the algorithms' operation "
                     "counts",),
            id=f"{NAME}/{slug}", paper=PAPER, setting=setting, paper_n=PAPER_RUNS, timing=True)
        return statement_of(made.id).applied(made).checked([a, b], checks)

    def against(n_flow: int, n_pf: int) -> str:
        return f"N = {n_flow} flow particles against N = {n_pf} PF particles, {schedule}{noise}"

    out = [
        record("ie-pff-more-accurate-same-n", f"IE-PFF with N = {flow.particles} is more accurate than PF with "
               f"N = {small.particles}", against(flow.particles, small.particles),
               [(f"{flow.key} vs {small.key}", paired_comparison(run_rmse[flow.key], run_rmse[small.key], level))],
               [flow.key, small.key]),
        record("ie-pff-more-accurate-than-larger-pf", f"IE-PFF with N = {flow.particles} is more accurate than PF "
               f"with N = {large.particles}", against(flow.particles, large.particles),
               [(f"{flow.key} vs {large.key}", paired_comparison(run_rmse[flow.key], run_rmse[large.key], level))],
               [flow.key, large.key]),
        record("pf-improves-with-particles", f"PF with N = {large.particles} is more accurate than PF with "
               f"N = {small.particles}", f"{large.key} against {small.key}{noise}",
               [(f"{large.key} vs {small.key}", paired_comparison(run_rmse[large.key], run_rmse[small.key], level))],
               [large.key, small.key])]
    if flow_large.key in run_rmse:
        out.append(record(
            "ie-pff-no-gain-with-particles", f"IE-PFF with N = {flow_large.particles} is not more accurate than "
            f"with N = {flow.particles} (its per-run RMSE lowered by less than {100 * NO_GAIN:.0f} %)",
            f"{flow_large.key} against {flow.key}, {schedule}{noise}",
            [(f"{flow.key} / {flow_large.key}", ratio_comparison(run_rmse[flow.key], run_rmse[flow_large.key],
                                                                 1.0 / (1.0 - NO_GAIN), level))],
            [flow.key, flow_large.key]))
    else:
        out.append(pending("ie-pff-no-gain-with-particles", f"IE-PFF with N = {flow_large.particles} is not more "
                           f"accurate than with N = {flow.particles}", f"{flow_large.key} against {flow.key}",
                           [flow.key, flow_large.key], f"runs of {flow_large.key}, which this run did not make"))
    label = large_noise_label(params)
    if "large_noise" in body:
        big = body["large_noise"]["run_rmse"]
        out.append(record(
            "ie-pff-robust-to-process-noise", f"At larger process noise (× {params.large_noise_factor:g}) IE-PFF "
            f"with N = {flow.particles} is more accurate than PF with N = {small.particles} and "
            f"N = {large.particles}", f"process noise × {params.large_noise_factor:g}, {schedule}{noise}",
            [(f"{flow.key} vs {pf.key}", paired_comparison(big[flow.key], big[pf.key], level))
             for pf in (small, large)],
            [f"{k}{label}" for k in (flow.key, small.key, large.key)],
            (f"the paper's larger process noise was lost with Table 2; read as r1 and r2 × "
             f"{params.large_noise_factor:g}",)))
    else:
        out.append(pending("ie-pff-robust-to-process-noise", "At larger process noise IE-PFF is more accurate than "
                           "PF", f"process noise × {params.large_noise_factor:g}",
                           [f"{k}{label}" for k in (flow.key, small.key, large.key)],
                           "runs at a larger process noise, which this run did not make"))
    timing = [timed("ie-pff-faster-same-n", f"IE-PFF with N = {flow.particles} runs in less time than PF with "
                    f"N = {small.particles}", against(flow.particles, small.particles), flow.key, small.key),
              timed("ie-pff-faster-than-larger-pf", f"IE-PFF with N = {flow.particles} runs in less time than PF "
                    f"with N = {large.particles}", against(flow.particles, large.particles), flow.key, large.key)]
    return out, timing
