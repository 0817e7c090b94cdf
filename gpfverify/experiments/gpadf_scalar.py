"""Deisenroth, Huber, Hanebeck (ICML 2009) scalar benchmark: UKF, EKF (true model) against GP-UKF
and GP-ADF (GPs trained on 100 noisy samples), one predict–update step from 200 priors
N(μ_0, 0.5²), μ_0 ~ U[−10, 10]; see :mod:`gpfverify.scenarios.scalar_benchmark`.

One run = one seed: draw both training sets, fit both GPs by evidence maximisation, draw the test
cases, run the four filters (batched over test cases) and score each posterior N(μ_e, σ_e²)
against the true x_1:

* NLL = −log N(x_1 | μ_e, σ_e²) = ½ log(2π σ_e²) + ½ (x_1 − μ_e)²/σ_e²  (nats, constant included);
* Mahalanobis distance |x_1 − μ_e| / σ_e — the square-root form, as in Deisenroth et al.; its
  square (the NEES) has expectation 1 for a consistent filter;
* squared error (x_1 − μ_e)², pooled into the RMSE;
* the fraction of cases with the true x_1 outside μ_e ± 2σ_e (4.55 % for a calibrated Gaussian).

``summarize`` pools the test cases of all runs: mean ± standard error (sample std / √N over the
N = runs × test points cases; the RMSE's s.e. by the delta method, s.e.(MSE) / (2 RMSE)) and, as
the seed-to-seed spread, the standard error of the per-run means.
"""

from __future__ import annotations

import time

import numpy as np

from gpfverify.errors import InputError
from gpfverify.filters.ekf import ekf_step
from gpfverify.filters.gp_adf import gp_adf_step
from gpfverify.filters.gp_ukf import gp_ukf_step
from gpfverify.filters.records import Gaussian
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.filters.ukf import ukf_step
from gpfverify.gp import GaussianProcess
from gpfverify.models import GPModel
from gpfverify.rng import generator
from gpfverify.scenarios.scalar_benchmark import ScalarSetting, draw_cases, draw_training_data
from gpfverify.validate import as_positive

NAME = "gpadf-scalar"
DEFAULT_RUNS = 20
METHODS = ("UKF", "EKF", "GP-UKF", "GP-ADF")
SCORES = ("nll", "maha", "sq_err")
_LOG_2PI = float(np.log(2.0 * np.pi))


def add_arguments(parser) -> None:
    d = ScalarSetting()
    parser.add_argument("--train-points", type=int, default=d.train_points,
                        help=f"training points per GP (default {d.train_points})")
    parser.add_argument("--test-points", type=int, default=d.test_points,
                        help=f"test cases per run (default {d.test_points})")
    parser.add_argument("--prior-std", type=float, default=d.prior_std, help=f"default {d.prior_std}")
    parser.add_argument("--system-noise-std", type=float, default=d.system_noise_std,
                        help=f"default {d.system_noise_std}")
    parser.add_argument("--measurement-noise-std", type=float, default=d.measurement_noise_std,
                        help=f"default {d.measurement_noise_std}")
    parser.add_argument("--domain", type=float, default=d.domain,
                        help=f"training inputs and prior means on [-domain, domain] (default {d.domain})")
    parser.add_argument("--restarts", type=int, default=3, help="evidence-maximisation restarts (default 3)")
    parser.add_argument("--alpha", type=float, default=1.0, help="sigma-point alpha (default 1)")
    parser.add_argument("--beta", type=float, default=0.0, help="sigma-point beta (default 0)")
    parser.add_argument("--kappa", type=float, default=2.0, help="sigma-point kappa (default 2)")


def params_from_args(args) -> dict:
    """Every parameter, checked (:class:`InputError` naming the option)."""
    for name, least in (("train_points", 2), ("test_points", 2), ("restarts", 1)):
        if getattr(args, name) < least:
            option = "--" + name.replace("_", "-")
            raise InputError(f"{option} must be at least {least}, got {getattr(args, name)}")
    for name in ("prior_std", "system_noise_std", "measurement_noise_std", "domain"):
        as_positive(getattr(args, name), f"--{name.replace('_', '-')}")
    return {"train_points": args.train_points, "test_points": args.test_points,
            "prior_std": args.prior_std, "system_noise_std": args.system_noise_std,
            "measurement_noise_std": args.measurement_noise_std, "domain": args.domain,
            "restarts": args.restarts, "alpha": args.alpha, "beta": args.beta, "kappa": args.kappa}


def default_params(**overrides) -> dict:
    """The command line's defaults (the paper's setting) as a params dict, with ``overrides``."""
    import argparse

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    return {**params_from_args(parser.parse_args([])), **overrides}


def _setting(params: dict) -> ScalarSetting:
    return ScalarSetting(**{k: params[k] for k in ("prior_std", "system_noise_std", "measurement_noise_std",
                                                    "domain", "train_points", "test_points")})


def gaussian_scores(mean: np.ndarray, var: np.ndarray, truth: np.ndarray) -> dict[str, np.ndarray]:
    """Per-case NLL, Mahalanobis distance (square-root form) and squared error of scalar
    Gaussians N(mean, var) at ``truth``; all arrays (N,)."""
    err2 = (truth - mean) ** 2
    return {"nll": 0.5 * (_LOG_2PI + np.log(var)) + 0.5 * err2 / var,
            "maha": np.sqrt(err2 / var), "sq_err": err2}


def fit_models(data, restarts: int, rng: np.random.Generator) -> tuple[GaussianProcess, GaussianProcess]:
    """Transition and measurement GPs by evidence maximisation."""
    seeds = rng.integers(1 << 31, size=2)
    return (GaussianProcess.fit(data.transition_inputs, data.transition_targets, restarts, int(seeds[0])),
            GaussianProcess.fit(data.measurement_inputs, data.measurement_targets, restarts, int(seeds[1])))


def run_one(params: dict, seed_sequence) -> dict:
    setting = _setting(params)
    rng = generator(seed_sequence)
    started = time.perf_counter()
    transition_gp, measurement_gp = fit_models(draw_training_data(setting, rng), params["restarts"], rng)
    fit_seconds = time.perf_counter() - started
    cases = draw_cases(setting, rng)

    model, gp_model = setting.model(), GPModel(transition_gp, [measurement_gp])
    sigma = SigmaParams(params["alpha"], params["beta"], params["kappa"])
    n = cases.prior_mean.size
    belief0 = Gaussian(cases.prior_mean[:, None], np.full((n, 1, 1), setting.prior_std**2))
    y = cases.y1[:, None]
    steps = {"UKF": lambda: ukf_step(belief0, model, y, k=1, params=sigma),
             "EKF": lambda: ekf_step(belief0, model, y, k=1),
             "GP-UKF": lambda: gp_ukf_step(belief0, gp_model, y, k=1, params=sigma),
             "GP-ADF": lambda: gp_adf_step(belief0, gp_model, y, k=1)}
    scores, posteriors, seconds = {}, {}, {}
    for method, step in steps.items():
        start = time.perf_counter()
        record = step()
        seconds[method] = time.perf_counter() - start
        mean, var = record.mu_e[:, 0], record.C_e[:, 0, 0]
        scores[method] = {k: v.tolist() for k, v in gaussian_scores(mean, var, cases.x1).items()}
        posteriors[method] = {"mean": mean.tolist(), "std": np.sqrt(var).tolist()}
    return {"scores": scores, "posteriors": posteriors, "seconds": seconds, "fit_seconds": fit_seconds,
            "cases": {"prior_mean": cases.prior_mean.tolist(), "x1": cases.x1.tolist(),
                      "y1": cases.y1.tolist()},
            "gps": {name: {"lengthscale": float(gp.lengthscales[0, 0]), "signal_var": float(gp.signal_var[0]),
                           "noise_var": float(gp.noise_var[0])}
                    for name, gp in (("transition", transition_gp), ("measurement", measurement_gp))}}


def _mean_se(values: np.ndarray) -> tuple[float, float]:
    se = float(np.std(values, ddof=1) / np.sqrt(values.size)) if values.size > 1 else float("nan")
    return float(np.mean(values)), se


def summarize(params: dict, results: list[dict]) -> dict:
    table, per_run = {}, {}
    for method in METHODS:
        pooled = {k: np.concatenate([r["scores"][method][k] for r in results]) for k in SCORES}
        nll, nll_se = _mean_se(pooled["nll"])
        maha, maha_se = _mean_se(pooled["maha"])
        nees_terms = pooled["maha"] ** 2
        nees, nees_se = _mean_se(nees_terms)
        mse, mse_se = _mean_se(pooled["sq_err"])
        rmse = float(np.sqrt(mse))
        run_means = {k: [float(np.mean(r["scores"][method][k])) for r in results] for k in SCORES}
        table[method] = {"nll": nll, "nll_se": nll_se, "maha": maha, "maha_se": maha_se,
                         "rmse": rmse, "rmse_se": mse_se / (2.0 * rmse) if rmse > 0 else float("nan"),
                         "nees": nees, "nees_se": nees_se, "nees_std": float(np.std(nees_terms, ddof=1)),
                         "outside_2sigma": float(np.mean(pooled["maha"] > 2.0)),
                         "cases": int(pooled["nll"].size),
                         "nll_se_runs": _mean_se(np.array(run_means["nll"]))[1],
                         "maha_se_runs": _mean_se(np.array(run_means["maha"]))[1]}
        per_run[method] = {"nll": run_means["nll"], "maha": run_means["maha"],
                           "rmse": [float(np.sqrt(v)) for v in run_means["sq_err"]]}
    return {"table": table, "per_run": per_run,
            "time_per_run": {m: float(np.mean([r["seconds"][m] for r in results])) for m in METHODS},
            "fit_time_per_run": float(np.mean([r["fit_seconds"] for r in results])),
            "gps": [r["gps"] for r in results],
            "example": {"cases": results[0]["cases"], "posteriors": results[0]["posteriors"]}}
