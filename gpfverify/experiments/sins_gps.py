"""Seed 001 §3 (Fig. 1–6, Table 1): SINS/GPS integrated navigation with a basic UPF on the
inaccurate model against GPSR-UPF (SR-UKF proposal on the inaccurate model + GP-learned residual).

Scenario, model mismatch and noise: :mod:`gpfverify.scenarios.sins_gps` (the filters' model
evaluates f^n × φ with the level-flight specific force; the GP learns the residual from training
flights flown from other headings). Both filters use the same particle count, resampling rule
(systematic, N_eff < N_T = threshold · N), prior N(0, P₀) and measurements; the truth starts from
a draw of N(0, P₀).

Process noise: the filters use the scenario's Q (GPSR-UPF takes the velocity rows of its Q from
the GP predictive variance). ``noise_floor`` (standard deviations per step of φ, δv, δp, ε, ∇,
default 0) adds the same diagonal floor to both filters' Q, a tuning the paper does not report.
With navigation-grade Q the transition density p(x_k | x^i_{k−1}) is far narrower than each
particle's UKF proposal, so the importance weights degenerate (N_eff ≈ 1 at every step);
``ess_fraction`` reports it. For reference, the proposal filters are also run alone as single
Gaussian filters: ``SR-UKF`` (inaccurate model) and ``GP-SR-UKF`` (model + GP residual).

Errors are estimate − truth of the error state, per axis: attitude (arcmin), velocity (m/s),
position (m). ``position_error`` etc. are per-step RMS over runs of the 3-axis error norm;
``reduction`` is 1 − RMS(GPSR-UPF)/RMS(UPF) with the RMS over runs and steps.
"""

from __future__ import annotations

import argparse
import functools
import json
import time

import numpy as np

from gpfverify.errors import InputError
from gpfverify.experiments.particle_methods import child_rng
from gpfverify.filters.gpsr_upf import GPResidualModel, gpsr_upf_step, sr_ukf_proposal
from gpfverify.filters.resampling import Particles
from gpfverify.filters.upf import upf_step
from gpfverify.gp.residual import fit_residual
from gpfverify.rng import generator
from gpfverify.scenarios.sins_gps import (ATTITUDE, POSITION, STATE_DIM, VELOCITY, SinsGpsConfig, build_models,
                                          generate_flight, training_set)

NAME = "sins-gps"
DEFAULT_RUNS = 20
METHODS = ("UPF", "GPSR-UPF")
#: single Gaussian filters on the same models, for reference: the proposal filters run alone
REFERENCES = ("SR-UKF", "GP-SR-UKF")
QUANTITIES = {"attitude": ATTITUDE, "velocity": VELOCITY, "position": POSITION}
#: per-step standard deviations of the filters' noise floor: φ (arcmin), δv (m/s), δp (m), ε (°/h), ∇ (mg)
DEFAULT_FLOOR = (0.0, 0.0, 0.0, 0.0, 0.0)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--particles", type=int, default=50, help="particles per filter (default 50)")
    parser.add_argument("--resample-threshold", type=float, default=0.5,
                        help="resample when N_eff < threshold · N (default 0.5)")
    parser.add_argument("--duration", type=float, default=1000.0, help="flight time in s (default 1000)")
    parser.add_argument("--train-points", type=int, default=200, help="GP training points (default 200)")
    parser.add_argument("--train-headings", type=float, nargs="+", default=[15.0, 75.0],
                        help="initial headings (°) of the training flights (test flight: 45)")
    parser.add_argument("--train-seed", type=int, default=0, help="seed of the training data and GP fit")
    parser.add_argument("--restarts", type=int, default=1, help="evidence-maximisation restarts (default 1)")
    parser.add_argument("--noise-floor", type=float, nargs=5, default=list(DEFAULT_FLOOR),
                        metavar=("PHI", "DV", "DP", "EPS", "NABLA"),
                        help="filter process-noise floor, s.d. per step (arcmin, m/s, m, °/h, mg)")


def params_from_args(args: argparse.Namespace) -> dict:
    if args.particles < 2 or args.train_points < 10 or args.duration < 1:
        raise InputError("--particles must be ≥ 2, --train-points ≥ 10 and --duration ≥ 1")
    if not 0 < args.resample_threshold <= 1 or min(args.noise_floor) < 0:
        raise InputError("--resample-threshold must be in (0, 1] and --noise-floor non-negative")
    return {"particles": args.particles, "resample_threshold": args.resample_threshold,
            "duration": args.duration, "train_points": args.train_points,
            "train_headings": list(args.train_headings), "train_seed": args.train_seed,
            "restarts": args.restarts, "noise_floor": list(args.noise_floor), "dt": 1.0}


def _floor_cov(floor) -> np.ndarray:
    return np.diag(np.repeat(np.asarray(floor, dtype=float), 3) ** 2)


@functools.lru_cache(maxsize=2)
def _setup(key: str):
    """Flight, models and the fitted residual GP for one parameter set (cached per process: every
    run of an experiment shares the training flights and the GP)."""
    params = json.loads(key)
    config = SinsGpsConfig(duration=params["duration"], dt=params["dt"])
    models = build_models(generate_flight(config), config)
    rng = generator(params["train_seed"])
    data = training_set(config, params["train_headings"], params["train_points"], rng)
    started = time.process_time()
    residual = fit_residual(data.states, data.next_true, data.next_approx, outputs=range(3, 6),
                            state_inputs=range(3), inputs=data.inputs, restarts=params["restarts"], seed=rng)
    fit_seconds = time.process_time() - started
    floor = _floor_cov(params["noise_floor"])
    upf_model = models.approx.with_noise(process_cov=models.approx.Q + floor)
    gpsr_model = GPResidualModel(models.approx, residual, transition_inputs=models.transition_inputs,
                                 extra_noise=floor)
    return config, models, upf_model, gpsr_model, fit_seconds


def setup(params: dict):
    return _setup(json.dumps(params, sort_keys=True))


def _run_filter(method: str, params: dict, upf_model, gpsr_model, prior_cov, ys, rng):
    belief = Particles.from_gaussian(np.zeros(STATE_DIM), prior_cov, params["particles"], rng)
    step, model = (upf_step, upf_model) if method == "UPF" else (gpsr_upf_step, gpsr_model)
    estimates, ess, resampled = [], [], 0
    min_diag = np.inf
    started = time.process_time()
    for k, y in enumerate(ys, 1):
        record = step(belief, model, y, k=k, rng=rng, resample_threshold=params["resample_threshold"])
        belief = record.posterior
        estimates.append(record.mean)
        ess.append(record.ess)
        resampled += record.resampled
        min_diag = min(min_diag, float(np.diagonal(belief.sqrt_covs, axis1=1, axis2=2).min()))
    return (np.array(estimates), time.process_time() - started,
            {"ess_mean": float(np.mean(ess)) / params["particles"], "resample_rate": resampled / len(ys),
             "min_factor_diagonal": min_diag})


def _run_reference(method: str, upf_model, gpsr_model, prior_cov, ys):
    """One SR-UKF (a batch of one) on the inaccurate or on the GP-corrected model."""
    mean, factor = np.zeros((1, STATE_DIM)), np.linalg.cholesky(prior_cov)[None]
    estimates = []
    started = time.process_time()
    for k, y in enumerate(ys, 1):
        one = Particles(mean, np.zeros(1), factor)
        if method == "SR-UKF":
            mean, factor = sr_ukf_proposal(one, upf_model, y, k=k)
        else:
            mean, factor = sr_ukf_proposal(one, gpsr_model.at_step(k), y, k=k, process_sqrt=gpsr_model.process_sqrt)
        estimates.append(mean[0])
    return np.array(estimates), time.process_time() - started


def run_one(params: dict, seed_seq: np.random.SeedSequence) -> dict:
    config, models, upf_model, gpsr_model, fit_seconds = setup(params)
    prior_cov = config.initial_cov()
    truth_rng = child_rng(seed_seq, 0)
    x0 = truth_rng.multivariate_normal(np.zeros(STATE_DIM), prior_cov)
    xs, ys = models.true.simulate(config.steps, truth_rng, x0=x0)
    # how well the GP knows this run's residual Δt (f^n − f̂^n) × φ along the true trajectory
    previous = np.vstack([x0, xs[:-1]])
    true_residual = np.einsum("kij,kj->ki", models.transitions_true - models.transitions_approx, previous)[:, VELOCITY]
    gp_residual = gpsr_model.transition.mean(previous, models.transition_inputs[:-1])
    out = {"residual_rms": float(np.sqrt(np.mean(true_residual**2))),
           "gp_residual_error_rms": float(np.sqrt(np.mean((gp_residual - true_residual) ** 2))),
           "gp_fit_seconds": fit_seconds}
    for i, method in enumerate(METHODS, 1):
        estimates, seconds, info = _run_filter(method, params, upf_model, gpsr_model, prior_cov, ys,
                                               child_rng(seed_seq, i))
        errors = estimates - xs
        out[method] = {"seconds": seconds, **info,
                       **{q: errors[:, sl].tolist() for q, sl in QUANTITIES.items()}}
    for method in REFERENCES:
        estimates, seconds = _run_reference(method, upf_model, gpsr_model, prior_cov, ys)
        errors = estimates - xs
        out[method] = {"seconds": seconds, **{q: errors[:, sl].tolist() for q, sl in QUANTITIES.items()}}
    return out


def _rms(values) -> float | None:
    """√mean, or None for an empty selection (a flight too short to have that segment)."""
    values = np.asarray(values, dtype=float)
    return float(np.sqrt(np.mean(values))) if values.size else None


def _reduction(new, old) -> float | None:
    return None if new is None or old is None else 1.0 - new / old


def summarize(params: dict, results: list[dict]) -> dict:
    """Per-step RMS error norms, per-axis bands (mean ± s.d. over runs), RMS reductions overall and
    by flight segment, filter time per run, importance-weight health and GP residual accuracy."""
    config = SinsGpsConfig(duration=params["duration"], dt=params["dt"])
    manoeuvre = generate_flight(config).manoeuvring()[1:]
    body: dict = {f"{q}_error": {} for q in QUANTITIES}
    bands: dict = {m: {} for m in METHODS}
    overall: dict = {m: {} for m in METHODS}
    per_run: dict = {m: {} for m in METHODS}
    segments: dict = {m: {} for m in METHODS}
    for method in METHODS:
        for q in QUANTITIES:
            err = np.array([r[method][q] for r in results])  # (runs, K, 3)
            sq = np.sum(err**2, axis=2)  # (runs, K)
            body[f"{q}_error"][method] = np.sqrt(sq.mean(axis=0)).tolist()
            bands[method][q] = {"mean": err.mean(axis=0).tolist(), "sd": err.std(axis=0).tolist()}
            overall[method][q] = _rms(sq)
            per_run[method][q] = np.sqrt(sq.mean(axis=1)).tolist()
            segments[method][q] = {"manoeuvre": _rms(sq[:, manoeuvre]), "cruise": _rms(sq[:, ~manoeuvre])}
    reduction = {q: 1.0 - overall["GPSR-UPF"][q] / overall["UPF"][q] for q in QUANTITIES}
    reference: dict = {"error": {q: {} for q in QUANTITIES}, "rms": {m: {} for m in REFERENCES}}
    for method in REFERENCES:
        for q in QUANTITIES:
            sq = np.sum(np.array([r[method][q] for r in results]) ** 2, axis=2)
            reference["error"][q][method] = np.sqrt(sq.mean(axis=0)).tolist()
            reference["rms"][method][q] = _rms(sq)
    reference["reduction"] = {q: 1.0 - reference["rms"]["GP-SR-UKF"][q] / reference["rms"]["SR-UKF"][q]
                              for q in QUANTITIES}
    segment_reduction = {seg: {q: _reduction(segments["GPSR-UPF"][q][seg], segments["UPF"][q][seg])
                               for q in QUANTITIES} for seg in ("manoeuvre", "cruise")}
    return {**body, "reduction": reduction, "rms": overall, "per_run_rms": per_run, "segment_rms": segments,
            "segment_reduction": segment_reduction, "error_bands": bands, "reference": reference,
            "time_per_run": {m: float(np.mean([r[m]["seconds"] for r in results])) for m in METHODS + REFERENCES},
            "time_per_step": {m: float(np.mean([r[m]["seconds"] for r in results])) / config.steps
                              for m in METHODS + REFERENCES},
            "ess_fraction": {m: float(np.mean([r[m]["ess_mean"] for r in results])) for m in METHODS},
            "resample_rate": {m: float(np.mean([r[m]["resample_rate"] for r in results])) for m in METHODS},
            "min_factor_diagonal": {m: float(np.min([r[m]["min_factor_diagonal"] for r in results]))
                                    for m in METHODS},
            "gp_residual": {"residual_rms": _rms([r["residual_rms"] ** 2 for r in results]),
                            "error_rms": _rms([r["gp_residual_error_rms"] ** 2 for r in results]),
                            "fit_seconds": results[0]["gp_fit_seconds"]},
            "time": (np.arange(1, config.steps + 1) * config.dt).tolist(),
            "manoeuvre": manoeuvre.tolist()}
