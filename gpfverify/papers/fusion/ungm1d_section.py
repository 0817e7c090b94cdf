"""Report page: the fusion paper's 1-D two-sensor example (Liao et al. 2019 §4.1, Figs. 2–4) — the
claims checked, the average squared Mahalanobis distance per step for σ² = 1 and 2, the σ² sweep and
the DMF/CMF equivalence. Renders the ``ungm1d`` run's ``results.json``; computes nothing."""

from __future__ import annotations

from pathlib import Path

from gpfverify.contract.claims import read_claims
from gpfverify.papers.fusion.contract import METHODS, NEES_POLICY, PAPER
from gpfverify.contract.methods import Method
from gpfverify.contract.papers import PAPERS
from gpfverify.papers.fusion.ungm1d_contract import FIGURE_NOISES, INTERPRETATIONS, NAME, Params, noise_key
from gpfverify.report.document import (Figure, Paragraph, Section, Table, claim_tables, fmt,
                                       interpretations_table)
from gpfverify.report.figures import new_figure, save
from gpfverify.report.inputs import SectionInput
from gpfverify.papers.fusion.section import (audit_table, equivalence_table, failed_runs_note, health_paragraph,
                                             health_table, interpretations_paragraph, load_words, method_style,
                                             method_table, plot_per_step, rank_rule_paragraph)

SLUG = "ungm1d"
TITLE = "Fusion paper: 1-D two-sensor example (Figs. 2–4)"


def render_section(data: SectionInput) -> Section:
    """The page from the section's ``ungm1d`` run (the first one, if several)."""
    return data.render_single(NAME, TITLE, render)


def by_noise(results: dict) -> dict[str, dict]:
    """Every σ²'s summary, in σ² order: the main one is the top level of ``results.json``, the others
    are under ``per_noise``."""
    out = {results["main_noise"]: results, **results["per_noise"]}
    return {k: out[k] for k in sorted(out, key=float)}


def render(results: dict, folder: Path, command: str | None = None) -> Section:
    """The page from the ``results.json`` of ``ungm1d``; figures go to ``folder``. ``command`` (if
    given) is quoted as the one that made it."""
    p = Params.from_json(results["params"])
    paper = PAPERS[PAPER]
    section = Section(SLUG, TITLE)
    section.add(Paragraph(f"{paper.citation} §4.1: the one-dimensional two-sensor example."))
    phases = ", ".join(fmt(z, 3) for z in p.sensor_phases)
    section.add(Paragraph(
        "Setting: xₖ₊₁ = 0.5xₖ + 25xₖ/(1 + xₖ²) + w, w ~ N(0, σ²); yᵐ = 5 sin(2x + zₘ) + vᵐ, "
        f"z = ({phases}) (0 and π/4); {p.train} training and {p.test_steps} test samples of one trajectory per run "
        f"and σ². Interpretations stated as parameters: measurement noise variance {fmt(p.measurement_noise_var)}; "
        f"every filter's prior at the first test step N({fmt(p.prior_mean)}, {fmt(p.prior_var)}); the trajectory "
        f"starts at x₁ ~ N(0, {fmt(p.trajectory_start_var)}); σ² values "
        + ", ".join(fmt(v) for v in p.noise_vars)
        + " (Fig. 4's values were lost). Metric: the squared Mahalanobis distance (x − x̂)ᵀC⁻¹(x − x̂) of eq. 44 as "
        f"written, averaged over runs per step. GP hyperparameters by evidence maximisation ({p.restarts} "
        f"start(s), at most {p.fit_points} samples). {results['runs_ok']} of {results['runs']} runs ok (seed "
        f"{results['seed']}; {load_words(results)})" + failed_runs_note({"": results}) + ". The paper states no "
        "computation time for this example (§4.1: its timing figures are the constant-turn example's), so no "
        f"timing claim is checked here; the methods' times ({results.get('time_clock', 'wall-clock time')}) are in "
        "the table below."))
    compared = {("mahalanobis", "squared"): "the squared Mahalanobis distance (eq. 44 as written)",
                ("mahalanobis", "root"): "the Mahalanobis distance in the square-root form |x − x̂|/σ",
                }.get((p.metric, p.mahalanobis), "the squared error ‖x − x̂‖² (the RMSE of eq. 45)")
    section.add(Paragraph(
        "Reading the metric: for a calibrated Gaussian posterior the squared Mahalanobis distance has mean D = 1 "
        "whatever the filter's accuracy, so it ranks filters by calibration more than by error; values far above 1 "
        "mean an over-confident filter (error large against its own covariance). The paper reads lower as better. "
        f"The claims as run compare {compared}, per run averaged over the steps; the interpretations "
        "'mahalanobis-root' (the square-root form of Deisenroth et al. 2009, whom eq. 44 cites) and 'rmse' (the "
        "squared error of eq. 45) read the same runs with the other metrics."))
    section.add(Paragraph(
        "Why CMF-GP-UKF collapses. With one state GP-UKF has 2D + 1 = 3 sigma points (eq. 25), drawn from the "
        "predicted N(μₚ, Cₚ). Their images (x, y₁, y₂) under the two sensors' GP means are three points in three "
        "dimensions: the sigma-point joint of (x, y₁, y₂) has rank 2, so on the sigma points the state is an exact "
        "linear function of the two outputs, x = a + bᵀy. The fused variance is then Cₑ = Cₚ − Cₓᵧ Cᵧ⁻¹ Cₓᵧᵀ = "
        "bᵀ(S⁻¹ + R⁻¹)⁻¹b ≤ bᵀRb (S the sigma points' output covariance, R the GP noise of eq. 26): it falls to the "
        "scale of the measurement noise whatever the state's real uncertainty, and the squared Mahalanobis distance "
        "of CMF-GP-UKF runs into the hundreds and thousands. One sensor's (x, y) from three points has rank 2 of 2 "
        "and no such relation; GP-ADF matches the moments exactly (no sigma points). The identity and the bound are "
        "checked numerically on this model step by step in the test suite (tests/test_ungm1d.py). It is a property "
        "of the unscented transform with 2D + 1 points and more outputs than states, not of the fusion rule; DMF "
        "inherits it through the centre's stacked prediction."))
    section.add(interpretations_paragraph(INTERPRETATIONS, "NAMES"))
    if command:
        section.add(Paragraph(f"Made by: `{command}`"))
    claims = read_claims(results)
    settings = list(dict.fromkeys(c.setting for c in claims))
    for setting in settings:
        mine = [c for c in claims if c.setting == setting]
        caption = f"Claims of {paper.short} checked — {setting}" if setting else \
            f"Claim of {paper.short} across σ² (Fig. 4)"
        section.add(*claim_tables(mine, caption))
        table = interpretations_table(mine, "Verdicts under each interpretation tried"
                                      + (f" — {setting}" if setting else "") + " (the statistic in brackets)")
        if table is not None:
            section.add(table)
    noises = by_noise(results)
    section.add(health_paragraph(NEES_POLICY + "; the claims here compare the paper's metric, the average squared "
                                 "Mahalanobis distance, which is the NEES itself: an over-confident filter scores "
                                 "worse on it, as the paper reads it"))
    health = health_table({f"σ² = {fmt(float(k))}": r for k, r in noises.items()})
    if health is not None:
        section.add(health)
    section.add(rank_rule_paragraph(noises))
    section.add(equivalence_table({f"σ² = {fmt(float(k))}": r for k, r in noises.items()}))
    main = f"σ² = {fmt(p.system_noise_var)}"
    if results["rank_failure_audit"]["entries"]:
        section.add(audit_table({main: results}))
    section.add(method_table(results, "mahalanobis", "average squared Mahalanobis distance",
                             f"The twelve methods, {main}"))
    for noise in FIGURE_NOISES:
        if noise_key(noise) in noises:
            curves = noises[noise_key(noise)]["average_mahalanobis"]
            section.add(Figure(plot_per_step(curves, "average Mahalanobis distance (squared)", f"σ² = {fmt(noise)}",
                                             folder / f"mahalanobis-s{noise_key(noise)}.png", log=True),
                               f"Average squared Mahalanobis distance per step, σ² = {fmt(noise)} (Figs. 2, 3); "
                               "GP-ADF solid in blues and greens, GP-UKF dash-dotted in reds and browns"))
    section.add(Figure(_sweep_figure(results, folder / "sweep.png"),
                       "Average squared Mahalanobis distance (mean over steps) against σ² (Fig. 4)"))
    table = results["average_mahalanobis_by_noise"]
    rows = [[fmt(float(k))] + [fmt(v[m.key], 4) for m in METHODS] for k, v in sorted(table.items(),
                                                                                   key=lambda kv: float(kv[0]))]
    section.add(Table(["σ²"] + [m.key for m in METHODS], rows, "Mean over steps of the average Mahalanobis distance"))
    return section


def _sweep_figure(results: dict, path: Path) -> Path:
    table = results["average_mahalanobis_by_noise"]
    noises = sorted(table, key=float)
    fig, axes = new_figure(1, 1, width=9.0, height=4.5)
    ax = axes[0, 0]
    for key in table[noises[0]]:
        method = Method.parse(key)
        style = {**method_style(method), "marker": method_style(method)["marker"] or "o"}
        ax.plot([float(n) for n in noises], [table[n][key] for n in noises], ms=4, label=key, **style)
    ax.set_yscale("log")
    ax.set_xlabel("system noise σ²")
    ax.set_ylabel("average Mahalanobis distance (squared)")
    ax.legend(ncol=2, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return save(fig, path)
