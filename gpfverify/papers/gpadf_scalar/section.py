"""Report page: the scalar benchmark of Deisenroth et al. (ICML 2009) — UKF, EKF, GP-UKF, GP-ADF
after one predict–update step, scored by NLL, Mahalanobis distance and RMSE. Renders the
``gpadf-scalar`` experiment's ``results.json``; computes nothing."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gpfverify.contract.claims import read_claims
from gpfverify.papers.gpadf_scalar.contract import GP_ADF, METHODS, NAME, PAPER, Example, FittedGPs, TableRow
from gpfverify.contract.papers import PAPERS
from gpfverify.contract.serial import from_json
from gpfverify.report.document import Figure, Paragraph, Section, Table, claim_tables, fmt
from gpfverify.report.figures import new_figure, save
from gpfverify.report.inputs import SectionInput

SLUG = "gpadf-scalar"
#: the posterior figure's vertical range (a few UKF/EKF means lie beyond it)
FIGURE_YLIM = 30.0


def render_section(data: SectionInput) -> Section:
    """The page from the section's ``gpadf-scalar`` run (the first one, if several)."""
    return data.render_single(NAME, "GP-ADF scalar benchmark (Deisenroth et al. 2009)", render)


def _pm(value: float, se: float) -> str:
    return f"{fmt(value)} ± {fmt(se, 2)}"


def render(results: dict, out_dir: Path) -> Section:
    """The page from a ``results.json`` body; figures go to ``out_dir``."""
    p = results["params"]
    table = {k: from_json(TableRow, v, f"table.{k}") for k, v in results["table"].items()}
    gps = [from_json(FittedGPs, g, "gps") for g in results["gps"]]
    adf = table[GP_ADF.key]
    section = Section(SLUG, "GP-ADF scalar benchmark (Deisenroth et al. 2009)")
    section.add(Paragraph(
        f"{PAPERS[PAPER].citation} The benchmark of the GP-ADF filter that {PAPERS['seed000'].short} "
        "(reference [7]) build their fusion rules on."))
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
        f"{adf.cases} test cases pooled."))
    section.add(Paragraph(
        "Conventions: NLL = −log N(x₁ | μₑ, σₑ²) in nats including ½ log 2π; Mahalanobis distance in the "
        "square-root form |x₁ − μₑ|/σₑ (as in Deisenroth et al.), whose square, the NEES, has mean 1 for a "
        "consistent filter; RMSE of μₑ. Mean ± standard error over all pooled test cases (RMSE by the "
        "delta method); the NLL standard error over per-run means, which also carries the GP-training "
        "variability, is given in its own column."))
    rows = [[m, _pm(r.nll, r.nll_se), fmt(r.nll_se_runs, 2), _pm(r.maha, r.maha_se), _pm(r.rmse, r.rmse_se),
             _pm(r.nees, r.nees_se), f"{100 * r.outside_2sigma:.1f} %", fmt(1e3 * results["time_per_run"][m], 3)]
            for m, r in table.items()]
    section.add(Table(["filter", "NLL", "NLL s.e. (runs)", "Mahalanobis", "RMSE", "NEES",
                       "outside ±2σ", f"ms per {p['test_points']} steps"], rows,
                      "One-step filtering on the scalar benchmark (mean ± s.e.)"))
    section.add(*claim_tables(read_claims(results), "Claims of Deisenroth et al. (2009) checked"))

    def median(gp: str, field: str) -> str:
        return fmt(float(np.median([getattr(getattr(g, gp), field) for g in gps])), 3)

    section.add(Paragraph(
        f"Fitted hyperparameters (median over runs): transition GP ℓ = {median('transition', 'lengthscale')}, "
        f"noise variance {median('transition', 'noise_var')} (true {fmt(p['system_noise_std'] ** 2, 3)}); "
        f"measurement GP ℓ = {median('measurement', 'lengthscale')}, noise variance "
        f"{median('measurement', 'noise_var')} (true {fmt(p['measurement_noise_std'] ** 2, 3)}). GP fitting "
        f"took {fmt(results['fit_time_per_run'], 3)} s per run."))
    example = from_json(Example, results["example"], "example")
    section.add(Figure(_figure(example, out_dir / "posteriors.png"),
                       "First run: posterior mean ± 2σ of each filter (colour) and the true x₁ (black) "
                       f"against the prior mean μ₀; the vertical axis is clipped to ±{FIGURE_YLIM:g} (a few "
                       "UKF/EKF means lie beyond)."))
    return section


def _figure(example: Example, path: Path) -> Path:
    mu0 = np.asarray(example.cases.prior_mean)
    x1 = np.asarray(example.cases.x1)
    order = np.argsort(mu0)
    fig, axes = new_figure(2, 2, width=5.0, height=3.6)
    for ax, (i, method) in zip(axes.ravel(), enumerate(METHODS)):
        post = example.posteriors[method.key]
        mean, std = np.asarray(post.mean)[order], np.asarray(post.std)[order]
        ax.errorbar(mu0[order], mean, yerr=2 * std, fmt="o", ms=2.5, color=f"C{i}", ecolor=f"C{i}",
                    elinewidth=0.8, alpha=0.8, label=f"{method.key} μₑ ± 2σₑ")
        ax.plot(mu0[order], x1[order], "k.", ms=3, label="true x₁")
        ax.set_ylim(-FIGURE_YLIM, FIGURE_YLIM)
        ax.set_title(method.key)
        ax.set_xlabel("prior mean μ₀")
        ax.set_ylabel("x₁")
        ax.legend(loc="upper left")
    return save(fig, path)
