"""Deisenroth, Huber, Hanebeck (ICML 2009) scalar benchmark: UKF, EKF (true model) against GP-UKF
and GP-ADF (GPs trained on 100 noisy samples), one predict–update step from 200 priors
N(μ₀, 0.5²), μ₀ ~ U[−10, 10]; see :mod:`gpfverify.papers.gpadf_scalar.scenario`.

One run = one seed: draw both training sets, fit both GPs by evidence maximisation, draw the test
cases, run the four filters (batched over test cases) and score each posterior N(μₑ, σₑ²)
against the true x₁:

* NLL = −log N(x₁ | μₑ, σₑ²) = ½ log(2π σₑ²) + ½ (x₁ − μₑ)²/σₑ²  (nats, constant included);
* Mahalanobis distance |x₁ − μₑ| / σₑ — the square-root form, as in Deisenroth et al.; its
  square (the NEES) has expectation 1 for a consistent filter;
* squared error (x₁ − μₑ)², pooled into the RMSE;
* the fraction of cases with the true x₁ outside μₑ ± 2σₑ (4.55 % for a calibrated Gaussian).

``summarize`` pools the test cases of all runs: mean ± standard error (sample std / √N over the
N = runs × test points cases; the RMSE's s.e. by the delta method, s.e.(MSE) / (2 RMSE)) and, as
the seed-to-seed spread, the standard error of the per-run means; then decides the paper's claims
(:func:`claims`). Types: :mod:`gpfverify.papers.gpadf_scalar.contract`.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from gpfverify.contract.claims import ClaimRecord, PairedDifference, combine
from gpfverify.papers.gpadf_scalar.claims import TABLE_1
from gpfverify.papers.gpadf_scalar.contract import (CALIBRATED_EXCEEDANCE, DEFAULT_RUNS, GP_ADF, METHODS, NAME, PAPER,
                                                    PROFILES, Cases, Example, FittedGPs, Hyperparameters, Params,
                                                    PerRun, Posterior, RunRecord, Scores, TableRow)
from gpfverify.filters.ekf import ekf_step
from gpfverify.filters.gp_adf import gp_adf_step
from gpfverify.filters.gp_ukf import gp_ukf_step
from gpfverify.filters.records import Gaussian
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.filters.ukf import ukf_step
from gpfverify.gp import GaussianProcess
from gpfverify.models import GPModel
from gpfverify.rng import generator
from gpfverify.papers.gpadf_scalar.scenario import ScalarSetting, draw_cases, draw_training_data
from gpfverify.tolerances import MONTE_CARLO_SIGMAS, monte_carlo_atol

__all__ = ["DEFAULT_RUNS", "METHODS", "NAME", "PAPER", "PROFILES", "Params", "RunRecord", "claims",
           "fit_models", "gaussian_scores", "run_one", "summarize"]

SCORES = ("nll", "maha", "sq_err")
_LOG_2PI = float(np.log(2.0 * np.pi))
#: where Deisenroth et al. state the claims


def _setting(params: Params) -> ScalarSetting:
    return ScalarSetting(prior_std=params.prior_std, system_noise_std=params.system_noise_std,
                         measurement_noise_std=params.measurement_noise_std, domain=params.domain,
                         train_points=params.train_points, test_points=params.test_points)


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


def _hyperparameters(gp: GaussianProcess) -> Hyperparameters:
    return Hyperparameters(float(gp.lengthscales[0, 0]), float(gp.signal_var[0]), float(gp.noise_var[0]))


def run_one(params: Params, seed_sequence: Any) -> RunRecord:
    setting = _setting(params)
    rng = generator(seed_sequence)
    started = time.perf_counter()
    transition_gp, measurement_gp = fit_models(draw_training_data(setting, rng), params.restarts, rng)
    fit_seconds = time.perf_counter() - started
    cases = draw_cases(setting, rng)

    model, gp_model = setting.model(), GPModel(transition_gp, [measurement_gp])
    sigma = SigmaParams(params.alpha, params.beta, params.kappa)
    n = cases.prior_mean.size
    belief0 = Gaussian(cases.prior_mean[:, None], np.full((n, 1, 1), setting.prior_std**2))
    y = cases.y1[:, None]
    steps = {"UKF": lambda: ukf_step(belief0, model, y, k=1, params=sigma),
             "EKF": lambda: ekf_step(belief0, model, y, k=1),
             "GP-UKF": lambda: gp_ukf_step(belief0, gp_model, y, k=1, params=sigma),
             "GP-ADF": lambda: gp_adf_step(belief0, gp_model, y, k=1)}
    scores, posteriors, seconds = {}, {}, {}
    for method in METHODS:
        start = time.perf_counter()
        record = steps[method.rule]()
        seconds[method.key] = time.perf_counter() - start
        mean, var = record.mu_e[:, 0], record.C_e[:, 0, 0]
        s = gaussian_scores(mean, var, cases.x1)
        scores[method.key] = Scores(tuple(s["nll"].tolist()), tuple(s["maha"].tolist()), tuple(s["sq_err"].tolist()))
        posteriors[method.key] = Posterior(tuple(mean.tolist()), tuple(np.sqrt(var).tolist()))
    return RunRecord(scores, posteriors, seconds, fit_seconds,
                     Cases(tuple(cases.prior_mean.tolist()), tuple(cases.x1.tolist()), tuple(cases.y1.tolist())),
                     FittedGPs(_hyperparameters(transition_gp), _hyperparameters(measurement_gp)))


def _mean_se(values: np.ndarray) -> tuple[float, float]:
    se = float(np.std(values, ddof=1) / np.sqrt(values.size)) if values.size > 1 else float("nan")
    return float(np.mean(values)), se


def _table_row(records: list[RunRecord], key: str) -> tuple[TableRow, PerRun]:
    pooled = {k: np.concatenate([getattr(r.scores[key], k) for r in records]) for k in SCORES}
    nll, nll_se = _mean_se(pooled["nll"])
    maha, maha_se = _mean_se(pooled["maha"])
    nees_terms = pooled["maha"] ** 2
    nees, nees_se = _mean_se(nees_terms)
    mse, mse_se = _mean_se(pooled["sq_err"])
    rmse = float(np.sqrt(mse))
    run_means = {k: np.array([float(np.mean(getattr(r.scores[key], k))) for r in records]) for k in SCORES}
    nees_std = float(np.std(nees_terms, ddof=1)) if nees_terms.size > 1 else float("nan")
    row = TableRow(nll=nll, nll_se=nll_se, maha=maha, maha_se=maha_se, rmse=rmse,
                   rmse_se=mse_se / (2.0 * rmse) if rmse > 0 else float("nan"), nees=nees, nees_se=nees_se,
                   nees_std=nees_std, outside_2sigma=float(np.mean(pooled["maha"] > 2.0)),
                   cases=int(pooled["nll"].size), nll_se_runs=_mean_se(run_means["nll"])[1],
                   maha_se_runs=_mean_se(run_means["maha"])[1])
    per_run = PerRun(tuple(run_means["nll"].tolist()), tuple(run_means["maha"].tolist()),
                     tuple(float(np.sqrt(v)) for v in run_means["sq_err"]))
    return row, per_run


def summarize(params: Params, records: list[RunRecord]) -> dict:
    table, per_run = {}, {}
    for method in METHODS:
        table[method.key], per_run[method.key] = _table_row(records, method.key)
    return {"table": table, "per_run": per_run,
            "time_per_run": {m.key: float(np.mean([r.seconds[m.key] for r in records])) for m in METHODS},
            "fit_time_per_run": float(np.mean([r.fit_seconds for r in records])),
            "gps": [r.gps for r in records],
            "example": Example(records[0].cases, records[0].posteriors),
            "claims": claims(table, per_run, len(records))}


def exceedance_tolerance(cases: int) -> float:
    """Monte Carlo tolerance on the ±2σ exceedance frequency of a calibrated filter (binomial)."""
    p = CALIBRATED_EXCEEDANCE
    return float(monte_carlo_atol(np.sqrt(p * (1.0 - p)), cases))


def nees_deviation(row: TableRow) -> float:
    """|mean NEES − 1| in units of its Monte Carlo tolerance (5 s.e.)."""
    return abs(row.nees - 1.0) / float(monte_carlo_atol(row.nees_std, row.cases))


def exceedance_excess(row: TableRow) -> float:
    """Observed ±2σ exceedance minus the calibrated 4.55 %, in units of its tolerance."""
    return (row.outside_2sigma - CALIBRATED_EXCEEDANCE) / exceedance_tolerance(row.cases)


def _pm(value: float, se: float) -> str:
    return f"{value:.4g} ± {se:.2g}"


def claims(table: dict[str, TableRow], per_run: dict[str, PerRun], runs: int) -> list[ClaimRecord]:
    """The claims of Deisenroth et al. (2009) on this benchmark, decided on the pooled table and
    the per-run means."""
    source = TABLE_1.source
    common: dict[str, Any] = {"paper": PAPER, "n": runs, "paper_n": DEFAULT_RUNS}
    adf = table[GP_ADF.key]
    others = [m for m in METHODS if m != GP_ADF]

    # 1. smallest NLL: paired over runs (the same test cases), GP-ADF − other at 5 s.e.
    diffs = {m.key: PairedDifference.of(per_run[GP_ADF.key].nll, per_run[m.key].nll) for m in others}
    z = [d.mean / d.atol * MONTE_CARLO_SIGMAS for d in diffs.values() if d.atol]
    out = [ClaimRecord(
        claim="GP-ADF has the smallest negative log-likelihood (NLL) of the four filters",
        source=source, verdict=combine([d.verdict for d in diffs.values()]),
        statistic=max(z) if len(z) == len(diffs) else None, threshold=-MONTE_CARLO_SIGMAS,
        evidence="NLL " + ", ".join(f"{m.key} {_pm(table[m.key].nll, table[m.key].nll_se)}" for m in METHODS)
        + "; per-run mean NLL of GP-ADF minus each other filter, paired over runs: "
        + ", ".join(f"{k} {d.mean:+.3g}" + (f" ({MONTE_CARLO_SIGMAS:g} s.e. = {d.atol:.2g})" if d.atol is not None
                                             else " (one run: no standard error)")
                    for k, d in diffs.items())
        + f"; held when every difference is below −{MONTE_CARLO_SIGMAS:g} standard errors, NOT held when one "
          f"is above +{MONTE_CARLO_SIGMAS:g}; the statistic is the largest difference in standard errors",
        id=f"{NAME}/smallest-nll", **common)]

    # 2. GP-ADF consistent: mean NEES within 5 s.e. of 1 and ±2σ exceedance within 5 s.e. of 4.55 %
    deviation = max(nees_deviation(adf), abs(exceedance_excess(adf)))
    out.append(ClaimRecord(
        claim="GP-ADF is consistent: mean NEES compatible with 1 and ±2σ exceedance compatible with 4.55 %",
        source=source, verdict="held" if deviation <= 1.0 else "NOT held", statistic=deviation, threshold=1.0,
        evidence=f"NEES {_pm(adf.nees, adf.nees_se)} ((NEES − 1)/s.e. = {(adf.nees - 1.0) / adf.nees_se:+.1f}; "
                 f"below 0: conservative); outside ±2σ {100 * adf.outside_2sigma:.2f} % (tolerance "
                 f"±{100 * exceedance_tolerance(adf.cases):.2f} points) over {adf.cases} cases; the statistic "
                 f"is the larger of the two deviations in units of its {MONTE_CARLO_SIGMAS:g}-standard-error "
                 "tolerance",
        id=f"{NAME}/gp-adf-consistent", **common))

    # 3. the other filters are over-confident: ±2σ exceedance above 4.55 % + 5 binomial s.e.
    for m in others:
        row = table[m.key]
        limit = CALIBRATED_EXCEEDANCE + exceedance_tolerance(row.cases)
        out.append(ClaimRecord(
            claim=f"{m.key} is over-confident: the true state lies outside ±2σ significantly more often "
                  "than 4.55 %",
            source=source, verdict="held" if row.outside_2sigma > limit else "NOT held",
            statistic=row.outside_2sigma, threshold=limit,
            evidence=f"outside ±2σ {100 * row.outside_2sigma:.2f} % of {row.cases} cases (limit "
                     f"{100 * limit:.2f} %: 4.55 % plus {MONTE_CARLO_SIGMAS:g} binomial standard errors); NEES "
                     f"{_pm(row.nees, row.nees_se)}",
            id=f"{NAME}/over-confident/{m.key}", **common))
    return [TABLE_1.applied(r) for r in out]
