"""Report page: the scalar benchmark of Deisenroth et al. (ICML 2009) — UKF, EKF, GP-UKF, GP-ADF
after one predict–update step, scored by NLL, Mahalanobis distance and RMSE."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gpfverify.experiments import gpadf_scalar
from gpfverify.report.document import Claim, Figure, Paragraph, Section, Table, claims_table, fmt
from gpfverify.report.figures import new_figure, save
from gpfverify.tolerances import monte_carlo_atol

SLUG = "gpadf-scalar"
QUICK_RUNS = 5
#: P(|z| > 2) for z ~ N(0, 1): the ±2σ exceedance of a calibrated Gaussian posterior.
CALIBRATED_EXCEEDANCE = 0.04550026389635842


def build(ctx) -> Section:
    runs = QUICK_RUNS if ctx.quick else gpadf_scalar.DEFAULT_RUNS
    results = _run(ctx, runs)
    return render(results, ctx)


def _run(ctx, runs: int) -> dict:
    from gpfverify.report import run_for_report

    return run_for_report(ctx, SLUG, gpadf_scalar, gpadf_scalar.default_params(), runs)


def _pm(value: float, se: float) -> str:
    return f"{fmt(value)} ± {fmt(se, 2)}"


def exceedance_tolerance(cases: int) -> float:
    """Monte Carlo tolerance on the ±2σ exceedance frequency of a calibrated filter (binomial)."""
    p = CALIBRATED_EXCEEDANCE
    return float(monte_carlo_atol(np.sqrt(p * (1.0 - p)), cases))


def nees_consistent(row: dict) -> bool:
    """Mean NEES within the Monte Carlo tolerance (5 s.e.) of 1."""
    return abs(row["nees"] - 1.0) <= float(monte_carlo_atol(row["nees_std"], row["cases"]))


def exceedance_excess(row: dict) -> float:
    """Observed ±2σ exceedance minus the calibrated 4.55 %, in units of its tolerance."""
    return (row["outside_2sigma"] - CALIBRATED_EXCEEDANCE) / exceedance_tolerance(row["cases"])


def claims(results: dict) -> list[Claim]:
    table = results["table"]
    adf = table["GP-ADF"]
    others = [m for m in gpadf_scalar.METHODS if m != "GP-ADF"]
    out = [Claim("GP-ADF has the smallest NLL of the four filters",
                 all(adf["nll"] < table[m]["nll"] for m in others),
                 "NLL " + ", ".join(f"{m} {_pm(table[m]['nll'], table[m]['nll_se'])}"
                                    for m in gpadf_scalar.METHODS))]
    consistent = nees_consistent(adf) and abs(exceedance_excess(adf)) <= 1.0
    out.append(Claim("GP-ADF is consistent: mean NEES compatible with 1 and ±2σ exceedance compatible "
                     "with 4.55 % (each within 5 standard errors)", consistent,
                     f"NEES {_pm(adf['nees'], adf['nees_se'])} ((NEES − 1)/s.e. = "
                     f"{(adf['nees'] - 1.0) / adf['nees_se']:+.1f}; below 0: conservative); outside ±2σ "
                     f"{100 * adf['outside_2sigma']:.2f} % (tolerance ±"
                     f"{100 * exceedance_tolerance(adf['cases']):.2f} points) over {adf['cases']} cases"))
    for m in others:
        row = table[m]
        out.append(Claim(f"{m} is over-confident: true state outside ±2σ significantly more often "
                         "than 4.55 % (more than 5 binomial standard errors)", exceedance_excess(row) > 1.0,
                         f"outside ±2σ {100 * row['outside_2sigma']:.2f} % (tolerance ±"
                         f"{100 * exceedance_tolerance(row['cases']):.2f} points); NEES "
                         f"{_pm(row['nees'], row['nees_se'])}"))
    return out


def render(results: dict, ctx_or_dir) -> Section:
    """The page from a ``results.json`` body; figures go to the section folder of a report
    context, or to the given directory."""
    out_dir = ctx_or_dir.section_dir(SLUG) if hasattr(ctx_or_dir, "section_dir") else Path(ctx_or_dir)
    p, table = results["params"], results["table"]
    section = Section(SLUG, "GP-ADF scalar benchmark (Deisenroth et al. 2009)")
    section.add(Paragraph(
        "Setting: x₁ = 0.5x₀ + 25x₀/(1 + x₀²) + w, w ~ N(0, "
        f"{p['system_noise_std']}²); y₁ = 5 sin(2x₁) + v, v ~ N(0, {p['measurement_noise_std']}²); "
        f"prior x₀ ~ N(μ₀, {p['prior_std']}²) with {p['test_points']} prior means μ₀ drawn uniformly on "
        f"[−{p['domain']}, {p['domain']}] per run (interpretation: the paper says only that the means lie in "
        "that interval), the true x₀ drawn from each prior; one predict–update step. GP-UKF and GP-ADF use "
        f"GPs fitted by evidence maximisation ({p['restarts']} restarts) to {p['train_points']} training "
        f"inputs x ~ U[−{p['domain']}, {p['domain']}] each (separate draws for the transition and the "
        "measurement GP) with noisy targets; UKF and EKF use the true model. Sigma points: "
        f"α = {p['alpha']}, β = {p['beta']}, κ = {p['kappa']}; GP-UKF's Q and R are the GP predictive "
        "variances of a noisy target (latent variance plus learned noise) at the previous and the "
        f"predicted mean. {results['runs_ok']} run(s) (seeds spawned from root seed {results['seed']}), "
        f"{table['GP-ADF']['cases']} test cases pooled."))
    section.add(Paragraph(
        "Conventions: NLL = −log N(x₁ | μₑ, σₑ²) in nats including ½ log 2π; Mahalanobis distance in the "
        "square-root form |x₁ − μₑ|/σₑ (as in Deisenroth et al.), whose square, the NEES, has mean 1 for a "
        "consistent filter; RMSE of μₑ. Mean ± standard error over all pooled test cases (RMSE by the "
        "delta method); the NLL s.e. over per-run means, which also carries the GP-training "
        "variability, is given in its own column."))
    rows = [[m, _pm(r["nll"], r["nll_se"]), fmt(r["nll_se_runs"], 2), _pm(r["maha"], r["maha_se"]),
             _pm(r["rmse"], r["rmse_se"]), _pm(r["nees"], r["nees_se"]), f"{100 * r['outside_2sigma']:.1f} %",
             fmt(1e3 * results["time_per_run"][m], 3)]
            for m, r in table.items()]
    section.add(Table(["filter", "NLL", "NLL s.e. (runs)", "Mahalanobis", "RMSE", "NEES",
                       "outside ±2σ", f"ms per {p['test_points']} steps"], rows,
                      "One-step filtering on the scalar benchmark (mean ± s.e.)"))
    section.add(claims_table(claims(results), "Claims of Deisenroth et al. (2009) checked"))
    gps = results["gps"]
    section.add(Paragraph(
        "Fitted hyperparameters (median over runs): transition GP ℓ = "
        f"{fmt(float(np.median([g['transition']['lengthscale'] for g in gps])), 3)}, noise variance "
        f"{fmt(float(np.median([g['transition']['noise_var'] for g in gps])), 3)} (true "
        f"{fmt(p['system_noise_std'] ** 2, 3)}); measurement GP ℓ = "
        f"{fmt(float(np.median([g['measurement']['lengthscale'] for g in gps])), 3)}, noise variance "
        f"{fmt(float(np.median([g['measurement']['noise_var'] for g in gps])), 3)} (true "
        f"{fmt(p['measurement_noise_std'] ** 2, 3)}). GP fitting took "
        f"{fmt(results['fit_time_per_run'], 3)} s per run."))
    section.add(Figure(_figure(results["example"], out_dir / "posteriors.png"),
                       "First run: posterior mean ± 2σ of each filter (colour) and the true x₁ (black) "
                       "against the prior mean μ₀; the vertical axis is clipped to ±30 (a few UKF/EKF "
                       "means lie beyond)."))
    return section


def _figure(example: dict, path: Path) -> Path:
    mu0 = np.asarray(example["cases"]["prior_mean"])
    x1 = np.asarray(example["cases"]["x1"])
    order = np.argsort(mu0)
    fig, axes = new_figure(2, 2, width=5.0, height=3.6)
    for ax, (i, method) in zip(axes.ravel(), enumerate(gpadf_scalar.METHODS)):
        post = example["posteriors"][method]
        mean, std = np.asarray(post["mean"])[order], np.asarray(post["std"])[order]
        ax.errorbar(mu0[order], mean, yerr=2 * std, fmt="o", ms=2.5, color=f"C{i}", ecolor=f"C{i}",
                    elinewidth=0.8, alpha=0.8, label=f"{method} μₑ ± 2σₑ")
        ax.plot(mu0[order], x1[order], "k.", ms=3, label="true x₁")
        ax.set_ylim(-30, 30)
        ax.set_title(method)
        ax.set_xlabel("prior mean μ₀")
        ax.set_ylabel("x₁")
        ax.legend(fontsize=7, loc="upper left")
    return save(fig, path)
