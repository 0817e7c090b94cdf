"""The fusion paper's 1-D two-sensor example (seed 000 §4.1, Figs. 2–4): x_{k+1} = 0.5 x_k +
25 x_k/(1 + x_k²) + w, y^m = 5 sin(2x + z_m) + v^m; one trajectory of 250 samples per run, the
first 200 train the GPs, the last 50 are filtered by the twelve methods of
:mod:`gpfverify.experiments.fusion_run`; average squared Mahalanobis distance per step (eq. 44).

Settings: the system noise σ² of the main setting (``--system-noise-var``, Fig. 2: 1; Fig. 3: 2)
and a sweep (``--sweep``, Fig. 4, whose σ² values were lost in extraction: interpretation
0.5, 1, 2, 3). Every run simulates one independent trajectory per σ² (child seeds of the run's seed).

Interpretations (each in ``params``): measurement noise variance 0.01; the filters' prior at step
200 is N(0, 1) for every method; the trajectory starts at x_1 ~ N(0, 1).
"""

from __future__ import annotations

import time

import numpy as np

from gpfverify.errors import InputError
from gpfverify.experiments.fusion_run import (METHODS, add_method_arguments, hyperparameters, method_params,
                                              params_with, run_setting, summarize_setting, train_models)
from gpfverify.filters.records import Gaussian
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.rng import generator
from gpfverify.scenarios.fusion_models import ungm_scenario, simulate_data

NAME = "ungm1d"
DEFAULT_RUNS = 1000
DEFAULT_SWEEP = (0.5, 1.0, 2.0, 3.0)


def add_arguments(parser) -> None:
    parser.add_argument("--system-noise-var", type=float, default=1.0,
                        help="σ² of the main setting (paper: 1 and 2; default 1)")
    parser.add_argument("--sweep", type=float, nargs="*", default=list(DEFAULT_SWEEP),
                        help="further σ² values (Fig. 4; default 0.5 1 2 3)")
    parser.add_argument("--measurement-noise-var", type=float, default=0.01,
                        help="sensor noise variance (interpretation; default 0.01)")
    parser.add_argument("--prior-var", type=float, default=1.0,
                        help="variance of the filters' prior N(0, ·) at step 200 (interpretation; default 1)")
    parser.add_argument("--train", type=int, default=200, help="training samples (default 200)")
    parser.add_argument("--test-steps", type=int, default=50, help="test steps (default 50)")
    add_method_arguments(parser, fit_points=200)

def params_from_args(args) -> dict:
    values = sorted({float(args.system_noise_var), *map(float, args.sweep)})
    if min(values) <= 0 or args.measurement_noise_var <= 0 or args.prior_var <= 0:
        raise InputError("noise and prior variances must be positive")
    if args.train < 3 or args.test_steps < 1:
        raise InputError(f"--train must be >= 3 and --test-steps >= 1, got {args.train}, {args.test_steps}")
    return {"system_noise_var": float(args.system_noise_var), "noise_vars": values,
            "measurement_noise_var": args.measurement_noise_var, "sensor_phases": [0.0, float(np.pi / 4)],
            "prior_mean": 0.0, "prior_var": args.prior_var, "trajectory_start": "x_1 ~ N(0, 1)",
            "train": args.train, "test_steps": args.test_steps,
            "mahalanobis": "squared form (x - x_hat)^T C^-1 (x - x_hat), eq. 44", **method_params(args)}


def default_params(**overrides) -> dict:
    """The command line's defaults as a params dict, with ``overrides`` applied to the options."""
    return params_with(add_arguments, params_from_args, **overrides)


def run_one(params: dict, seed_sequence) -> dict:
    sigma = SigmaParams(params["alpha"], params["beta"], params["sigma_kappa"])
    prior = Gaussian(np.array([params["prior_mean"]]), np.array([[params["prior_var"]]]))
    settings = {}
    for i, noise_var in enumerate(params["noise_vars"]):
        # the i-th child of the run's seed, built explicitly: spawn() would depend on earlier spawns
        child = np.random.SeedSequence(seed_sequence.entropy, spawn_key=tuple(seed_sequence.spawn_key) + (i,))
        rng = generator(child)
        scenario = ungm_scenario(noise_var, params["measurement_noise_var"], 1.0, params["train"],
                                 params["test_steps"], tuple(params["sensor_phases"]))
        data = simulate_data(scenario, rng)
        started = time.perf_counter()
        models = train_models(data, params["restarts"], params["fit_points"], rng)
        training = time.perf_counter() - started
        record = run_setting(data, models, [prior, prior], prior, sigma, params["rcc_size"], params["rank_tol"])
        record["training_seconds"] = training
        record["hyperparameters"] = hyperparameters(models)
        settings[repr(noise_var)] = record
    return {"settings": settings}


def summarize(params: dict, results: list[dict]) -> dict:
    per_setting = {}
    for noise_var in params["noise_vars"]:
        runs = [r["settings"][repr(noise_var)] for r in results]
        body = summarize_setting(runs)
        body["training_time_per_run"] = float(np.mean([r["training_seconds"] for r in runs]))
        per_setting[repr(noise_var)] = body
    main = per_setting[repr(params["system_noise_var"])]
    return {"mahalanobis": main["average_mahalanobis"], **{k: v for k, v in main.items()},
            "sweep": {k: {"mahalanobis": v["average_mahalanobis"], "rmse": v["rmse"],
                          "max_equivalence_gap": v["max_equivalence_gap"],
                          "one_step_gap": v["one_step_gap"], "full_rank_ratio": v["full_rank_ratio"],
                          "time_per_step": v["time_per_step"]}
                      for k, v in per_setting.items()},
            "per_noise": per_setting,
            "average_mahalanobis_by_noise": {k: {m: float(np.mean(v["average_mahalanobis"][m])) for m in METHODS}
                                             for k, v in per_setting.items()}}
