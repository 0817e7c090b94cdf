"""The fusion paper's 2-D constant-turn experiment (seed 000 §4.2, Figs. 5–15): two range–bearing
sensors, GPs learned from κ training samples, 50 test steps filtered by twelve methods
(Sensor1/Sensor2/CMF/DMF/RCC-CI/CW × GP-ADF/GP-UKF); RMSE per step (eq. 45), the ratio of full
column rank of each local C_xy^m per step, the DMF − CMF gap, computation time per method, and
the audit of every step on which the rank condition failed.

Interpretations (each a parameter recorded in ``params``): sensor positions z₁ = [−200, 200],
z₂ = [200, 200]; each sensor's filter starts at the polar→Cartesian conversion of its *first test
observation* plus a per-coordinate N(b, 1) perturbation (b = 10 for κ = 300, 20 for κ = 30, 60),
with initial covariance (b² + 1) I — the second moment of that perturbation; the fused filters
start at the mean of the sensors' starts with the same covariance. See
:mod:`gpfverify.experiments.fusion_run` for the methods and the records.
"""

from __future__ import annotations

import numpy as np

from gpfverify.errors import InputError
from gpfverify.experiments.fusion_run import (add_method_arguments, hyperparameters, method_params,
                                              params_with, run_setting, summarize_setting, train_models)
from gpfverify.filters.records import Gaussian
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.rng import generator
from gpfverify.scenarios.fusion_models import (CT_SENSOR_POSITIONS, ct_scenario, polar_to_cartesian,
                                               sensor_side, simulate_data)

NAME = "ct2d"
DEFAULT_RUNS = 1000
#: κ = 300 uses an N(10, 1) start perturbation, κ = 30, 60 an N(20, 1) one (seed 000 §4.2)
LARGE_TRAINING = 300


def default_perturbation_mean(kappa: int) -> float:
    return 10.0 if kappa >= LARGE_TRAINING else 20.0


def add_arguments(parser) -> None:
    parser.add_argument("--kappa", type=int, default=300, help="training samples κ (paper: 300, 30, 60)")
    parser.add_argument("--omega", type=float, default=2 * np.pi / 90,
                        help="turn rate Ω in rad/s (paper: 2π/90 ≈ 0.0698 and 0.5)")
    parser.add_argument("--test-steps", type=int, default=50, help="test steps (default 50)")
    parser.add_argument("--perturbation-mean", type=float, default=None,
                        help="mean b of the N(b, 1) start perturbation (default 10 for κ ≥ 300, else 20)")
    parser.add_argument("--perturbation-std", type=float, default=1.0, help="its std (default 1)")
    add_method_arguments(parser, fit_points=100)

def params_from_args(args) -> dict:
    if args.kappa < 3:
        raise InputError(f"--kappa must be at least 3, got {args.kappa}")
    if args.test_steps < 1:
        raise InputError(f"--test-steps must be at least 1, got {args.test_steps}")
    b = default_perturbation_mean(args.kappa) if args.perturbation_mean is None else args.perturbation_mean
    s = args.perturbation_std
    return {"kappa": args.kappa, "omega": args.omega, "test_steps": args.test_steps,
            "sensor_positions": [list(z) for z in CT_SENSOR_POSITIONS],
            "process_noise_cov": "5 I", "measurement_noise_cov": "diag(5, (0.1 pi/180)^2)",
            "training_start": "x ~ N(0, I)",
            "start_observation": "first test observation, polar->Cartesian on the origin's side",
            "perturbation_mean": b, "perturbation_std": s, "initial_cov_scale": b * b + s * s,
            "fused_start": "mean of the sensors' starts, same covariance", **method_params(args)}


def default_params(**overrides) -> dict:
    """The command line's defaults as a params dict, with ``overrides`` applied to the options."""
    return params_with(add_arguments, params_from_args, **overrides)


def starts(params: dict, first_observations, rng: np.random.Generator) -> tuple[list[Gaussian], Gaussian]:
    """Each sensor's initial belief and the fused filters' one (see module docstring)."""
    cov = params["initial_cov_scale"] * np.eye(2)
    means = [polar_to_cartesian(y, z, sensor_side(z))
             + rng.normal(params["perturbation_mean"], params["perturbation_std"], size=2)
             for y, z in zip(first_observations, params["sensor_positions"])]
    return [Gaussian(m, cov) for m in means], Gaussian(np.mean(means, axis=0), cov)


def run_one(params: dict, seed_sequence) -> dict:
    import time

    rng = generator(seed_sequence)
    scenario = ct_scenario(params["omega"], params["kappa"], params["test_steps"],
                           tuple(tuple(z) for z in params["sensor_positions"]))
    data = simulate_data(scenario, rng)
    started = time.perf_counter()
    models = train_models(data, params["restarts"], params["fit_points"], rng)
    training = time.perf_counter() - started
    local_starts, fused_start = starts(params, [y[0] for y in data.test_measurements], rng)
    sigma = SigmaParams(params["alpha"], params["beta"], params["sigma_kappa"])
    record = run_setting(data, models, local_starts, fused_start, sigma, params["rcc_size"], params["rank_tol"])
    record["training_seconds"] = training
    record["hyperparameters"] = hyperparameters(models)
    return record


def summarize(params: dict, results: list[dict]) -> dict:
    body = summarize_setting(results)
    body["training_time_per_run"] = float(np.mean([r["training_seconds"] for r in results]))
    return body
