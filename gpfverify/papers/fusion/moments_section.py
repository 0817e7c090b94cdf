"""Report page: exact moment matching of a GP at a Gaussian input, checked against Gauss–Hermite
quadrature and Monte Carlo. Renders the ``moments`` experiment's ``results.json``; computes
nothing."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gpfverify.contract.claims import read_claims
from gpfverify.papers.fusion.moments_contract import (CLOSED_FORM, MONTE_CARLO, NAME, PAPER, QUADRATURE,
                                                      SOURCE_EQUATIONS, CaseSummary, Illustration)
from gpfverify.contract.papers import PAPERS
from gpfverify.contract.serial import from_json
from gpfverify.report.document import Figure, Paragraph, Section, Table, claim_tables, fmt
from gpfverify.report.figures import new_figure, save
from gpfverify.report.inputs import SectionInput

SLUG = "moments"
TITLE = "GP moment matching at uncertain inputs"


def render_section(data: SectionInput) -> Section:
    """The page from the section's ``moments`` run (the first one, if several)."""
    return data.render_single(NAME, TITLE, render)


def render(results: dict, out_dir: Path) -> Section:
    """The page from a ``results.json`` body; the figure goes to ``out_dir``."""
    p = results["params"]
    cases = [from_json(CaseSummary, c, "cases") for c in results["cases"]]
    paper = PAPERS[PAPER].short
    section = Section(SLUG, TITLE)
    section.add(
        Paragraph(f"Closed-form moments of a SE-ARD GP at an uncertain input x ~ N(μ, Σ) ({paper}, "
                  f"{SOURCE_EQUATIONS}, after Deisenroth et al. 2009): E[f], Cov[f] (latent, model uncertainty "
                  "on the diagonal, no observation noise) and Cov[x, f], against two independent oracles that "
                  "use only predictions at deterministic inputs (law of total covariance): tensor Gauss–Hermite "
                  f"quadrature and Monte Carlo with {p['samples']} samples of x per case. Each of "
                  f"{results['runs_ok']} run(s) (seeds spawned from root seed {results['seed']}) draws one "
                  f"problem per case: {p['train_points']} training inputs x ~ U[−{p['train_range']}, "
                  f"{p['train_range']}]ᴰ with targets sin(x·wₐ) + noise of standard deviation "
                  f"{p['train_noise_std']} for each output a (wₐ standard normal), a GP fitted by evidence "
                  f"maximisation ({p['restarts']} restarts), an input mean μ ~ U[−{p['mean_range']}, "
                  f"{p['mean_range']}]ᴰ and a correlated input covariance Σ = {p['input_cov_scale']} (AAᵀ/D + "
                  "0.2 I), A standard normal."),
        Paragraph("The quadrature order is raised (×1.5 from 10 nodes per dimension) until two successive rules "
                  f"agree to {p['quadrature_rtol']:.0e} relative to the largest covariance entry, or until the "
                  f"grid would exceed {p['quadrature_max_nodes']} nodes; that change is the oracle's own error "
                  "estimate. The closed form must lie within it plus the exact-algebra rounding tolerance "
                  f"({results['rounding_allowance']:.0e}), and within {results['monte_carlo_sigmas']:g} "
                  "standard errors of Monte Carlo in every entry."),
    )
    rows = [[c.label, c.quadrature_nodes, fmt(c.quadrature_change, 2), fmt(c.rel_err["mean"], 2),
             fmt(c.rel_err["cov"], 2), fmt(c.rel_err["cross_cov"], 2),
             f"{fmt(c.quadrature_error, 2)} / {fmt(c.quadrature_allowance, 2)}", fmt(c.max_z, 3)]
            for c in cases]
    section.add(Table(["case", "quadrature nodes", "change between the last two rules", "E[f] rel. error",
                       "Cov[f] rel. error", "Cov[x, f] rel. error", "error / allowance",
                       "max |closed − Monte Carlo| / s.e."], rows,
                      "Closed form against the two oracles (worst run of each column; relative errors against "
                      "quadrature, max |closed − quadrature| / max |quadrature| per moment)"))
    section.add(*claim_tables(read_claims(results), f"Claims of {paper} checked"))
    t = results["time_per_run"]
    section.add(Paragraph(
        f"Time per run, all cases: closed form {fmt(1e3 * t[CLOSED_FORM.key], 3)} ms, quadrature "
        f"{fmt(t[QUADRATURE.key], 3)} s, Monte Carlo {fmt(t[MONTE_CARLO.key], 3)} s."))
    illustration = from_json(Illustration, results["illustration"], "illustration")
    section.add(Figure(_figure(illustration, out_dir / "moment_matching.png"),
                       "First run: a 1-D GP and its moment-matched prediction at an uncertain input "
                       f"x ~ N({fmt(illustration.input_mean, 3)}, {fmt(illustration.input_var, 3)}); right: the "
                       f"Gaussian from the closed form against a histogram of {illustration.samples} Monte Carlo "
                       "draws of f(x)."))
    return section


def _figure(ill: Illustration, path: Path) -> Path:
    grid, mean, var = np.asarray(ill.grid), np.asarray(ill.grid_mean), np.asarray(ill.grid_var)
    fig, axes = new_figure(2, 1, width=5.0)
    ax = axes[0, 0]
    ax.plot(grid, mean, "C0", label="GP mean")
    ax.fill_between(grid, mean - 2 * np.sqrt(var), mean + 2 * np.sqrt(var), color="C0", alpha=0.2,
                    label="±2σ (latent)")
    ax.plot(ill.train_x, ill.train_y, "k.", ms=4, label="training data")
    density = np.exp(-0.5 * (grid - ill.input_mean) ** 2 / ill.input_var) / np.sqrt(2 * np.pi * ill.input_var)
    low = ax.get_ylim()[0]
    ax.plot(grid, low + density, "C3", label="input density p(x)")
    ax.set_xlabel("x")
    ax.set_ylabel("f(x)")
    ax.legend(fontsize=8)
    ax = axes[0, 1]
    edges = np.asarray(ill.histogram_edges)
    ax.stairs(ill.histogram_density, edges, fill=True, color="0.7", label="Monte Carlo p(f(x))")
    f = np.linspace(edges[0], edges[-1], 300)
    sd = np.sqrt(ill.matched_var)
    ax.plot(f, np.exp(-0.5 * ((f - ill.matched_mean) / sd) ** 2) / (sd * np.sqrt(2 * np.pi)), "C3",
            label="moment-matched Gaussian")
    ax.set_xlabel("f(x)")
    ax.set_ylabel("density")
    ax.legend(fontsize=8)
    return save(fig, path)
