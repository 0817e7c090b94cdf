"""Seed 003 §3.2 (Table 2, Fig. 3): bearing-only tracking of a target that moves at constant
velocity and then turns (model in :mod:`gpfverify.scenarios.bearing`); bootstrap PF with N = 50
and N = 200 against the innovation-error particle flow (IE-PFF) with N = 50, 200 runs.

Every run simulates the truth from x₀ = [1000, 10, 1500, 15]; every filter starts from particles
drawn from N(x₀, P₀), P₀ = diag(σ_p², σ_v², σ_p², σ_v²) (interpretation: the seed gives no prior).
The metric is the position RMSE per step over runs, √(mean_runs[(x̂ − x)² + (ŷ − y)²]).
"""

from __future__ import annotations

import argparse

import numpy as np

from gpfverify.errors import InputError
from gpfverify.experiments.particle_methods import child_rng, flow_steps, run_method
from gpfverify.scenarios.bearing import INITIAL_STATE, bearing_model

NAME = "bearing"
DEFAULT_RUNS = 200
#: reported name -> (filter, particle count parameter)
METHODS = {"PF-N50": ("PF", "pf_small"), "PF-N200": ("PF", "pf_large"), "IE-PFF-N50": ("IE-PFF", "flow_particles")}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--q-pos", type=float, default=0.05, help="process-noise variance of x, y (r1 = 0.05)")
    parser.add_argument("--q-vel", type=float, default=0.1, help="process-noise variance of ẋ, ẏ (r2 = 0.1)")
    parser.add_argument("--bearing-std", type=float, default=0.01,
                        help="bearing noise standard deviation in rad (lost in the seed; default 0.01)")
    parser.add_argument("--prior-std-pos", type=float, default=10.0, help="prior std of x, y in m")
    parser.add_argument("--prior-std-vel", type=float, default=1.0, help="prior std of ẋ, ẏ in m/s")
    parser.add_argument("--omega-deg", type=float, default=5.0, help="turn rate in °/s (default 5)")
    parser.add_argument("--switch-time", type=float, default=40.0, help="start of the turn in s")
    parser.add_argument("--duration", type=int, default=60, help="steps of 1 s (default 60)")
    parser.add_argument("--dlambda", type=float, default=0.05, help="Δλ of the flow (default 0.05)")
    parser.add_argument("--spacing", choices=["uniform", "exponential"], default="uniform",
                        help="λ-step schedule of the flow (default uniform, the seed's)")


def params_from_args(args: argparse.Namespace) -> dict:
    if min(args.q_pos, args.q_vel, args.bearing_std, args.prior_std_pos, args.prior_std_vel) <= 0:
        raise InputError("noise variances and standard deviations must be positive")
    if args.duration < 1 or not 0 < args.dlambda <= 1:
        raise InputError("--duration must be at least 1 and --dlambda in (0, 1]")
    return {"q_pos": args.q_pos, "q_vel": args.q_vel, "bearing_std": args.bearing_std,
            "prior_std_pos": args.prior_std_pos, "prior_std_vel": args.prior_std_vel,
            "omega_deg": args.omega_deg, "switch_time": args.switch_time, "duration": args.duration,
            "dlambda": args.dlambda, "spacing": args.spacing, "pf_small": 50, "pf_large": 200,
            "flow_particles": 50, "initial_state": INITIAL_STATE.tolist()}


def _model(params: dict):
    """The bearing model with the filters' prior N(x₀, P₀)."""
    return bearing_model(params["q_pos"], params["q_vel"], params["bearing_std"],
                         np.deg2rad(params["omega_deg"]), params["switch_time"],
                         prior_std_pos=params["prior_std_pos"], prior_std_vel=params["prior_std_vel"],
                         initial_state=np.asarray(params["initial_state"], dtype=float))


def run_one(params: dict, seed_seq: np.random.SeedSequence) -> dict:
    model = _model(params)
    xs, ys = model.simulate(params["duration"], child_rng(seed_seq, 0), x0=model.prior_mean)
    steps = flow_steps(params["dlambda"], params["spacing"])
    out = {}
    for i, (name, (method, count_key)) in enumerate(METHODS.items(), 1):
        run = run_method(method, model, ys, params[count_key], child_rng(seed_seq, i),
                         steps if method == "IE-PFF" else None)
        sq = None if run.estimates is None else ((run.estimates - xs)[:, [0, 2]] ** 2).sum(axis=1).tolist()
        out[name] = {"sq_pos_err": sq, "seconds": run.seconds}
    return out


def summarize(params: dict, results: list[dict]) -> dict:
    """Position RMSE per step over the runs that did not diverge, its time average, the per-run
    RMS position error (None where the filter diverged) and the mean filter time per run."""
    rmse, times, diverged, mean_rmse, run_rmse = {}, {}, {}, {}, {}
    for name in METHODS:
        sq = [r[name]["sq_pos_err"] for r in results if r[name]["sq_pos_err"] is not None]
        curve = np.sqrt(np.mean(sq, axis=0)) if sq else np.full(params["duration"], np.nan)
        rmse[name] = curve.tolist()
        mean_rmse[name] = float(np.mean(curve))
        times[name] = float(np.mean([r[name]["seconds"] for r in results]))
        diverged[name] = len(results) - len(sq)
        run_rmse[name] = [None if r[name]["sq_pos_err"] is None else float(np.sqrt(np.mean(r[name]["sq_pos_err"])))
                          for r in results]
    return {"rmse": rmse, "time_per_run": times, "mean_rmse": mean_rmse, "diverged": diverged,
            "run_rmse": run_rmse}
