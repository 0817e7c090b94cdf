"""Report page: the fusion paper's 1-D two-sensor example (seed 000 §4.1, Figs. 2–4) — average
squared Mahalanobis distance per step for σ² = 1 and 2, the σ² sweep, the paper's claims and the
DMF/CMF equivalence."""

from __future__ import annotations

from gpfverify.experiments import ungm1d
from gpfverify.experiments.fusion_run import FAMILIES, METHODS, RULES
from gpfverify.report.document import Claim, Figure, Paragraph, Section, Table, claims_table, fmt
from gpfverify.report.figures import new_figure, save
from gpfverify.report.sections.fusion_paper import (audit_table, comparison_claim, equivalence_claim,
                                                    equivalence_table, failed_runs_note, fusion_beats_baselines,
                                                    fusion_beats_sensors, method_table, out_dir,
                                                    plot_per_step)

SLUG = "ungm1d"
QUICK_RUNS = 4
#: σ² of the paper's Figs. 2 and 3
FIGURE_NOISES = (1.0, 2.0)


def build(ctx) -> Section:
    from gpfverify.report import run_for_report

    if ctx.quick:
        params, runs = ungm1d.default_params(sweep=[2.0]), QUICK_RUNS
    else:
        params, runs = ungm1d.default_params(), ungm1d.DEFAULT_RUNS
    return render(run_for_report(ctx, SLUG, ungm1d, params, runs), ctx)


def setting_claims(r: dict, noise: str) -> list[Claim]:
    per_run = r["run_mean_mahalanobis"]
    out = []
    for family in FAMILIES:
        out += [equivalence_claim(r, family, "average_mahalanobis"), fusion_beats_sensors(per_run, family, ""),
                fusion_beats_baselines(per_run, family, "")]
        out.append(comparison_claim(f"{family}: Sensor 2 performs better than Sensor 1", per_run,
                                    [(f"Sensor2-{family}", f"Sensor1-{family}")], ""))
    if float(noise) not in FIGURE_NOISES:
        return out
    better, worse = ("ADF", "UKF") if float(noise) == FIGURE_NOISES[0] else ("UKF", "ADF")
    out.append(comparison_claim(f"σ² = {noise}: fusion with GP-{better} beats fusion with GP-{worse}", per_run,
                                [(f"CMF-GP-{better}", f"CMF-GP-{worse}")], ""))
    return out


def render(results: dict, ctx_or_dir, command: str | None = None) -> Section:
    """The page from the ``results.json`` of ``ungm1d``; ``command`` (if given) is quoted as the one
    that made it."""
    folder = out_dir(ctx_or_dir, SLUG)
    p = results["params"]
    section = Section(SLUG, "Fusion paper: 1-D two-sensor example (Figs. 2–4)")
    section.add(Paragraph(
        "Setting (seed 000 §4.1): x_{k+1} = 0.5x_k + 25x_k/(1 + x_k²) + w, w ~ N(0, σ²); y^m = 5 sin(2x + z_m) + v^m, "
        f"z = (0, π/4); {p['train']} training and {p['test_steps']} test samples of one trajectory per run and σ². "
        f"Interpretations stated as parameters: measurement noise variance {p['measurement_noise_var']}; every "
        f"filter's prior at the first test step N({p['prior_mean']}, {p['prior_var']}); trajectory start "
        f"{p['trajectory_start']}; σ² values {p['noise_vars']} (Fig. 4's values were lost). Metric: "
        f"{p['mahalanobis']}, averaged over runs per step. GP hyperparameters by evidence maximisation "
        f"({p['restarts']} start(s), at most {p['fit_points']} samples). {results['runs_ok']} of {results['runs']} "
        f"runs ok (seed {results['seed']}; the paper used {ungm1d.DEFAULT_RUNS})" + failed_runs_note({"": results}) + "."))
    section.add(Paragraph(
        "Reading the metric: for a calibrated Gaussian posterior the squared Mahalanobis distance has mean D = 1; "
        "values far above 1 mean an over-confident filter (error large against its own covariance). The paper "
        "reads lower as better, and the claims below follow the paper's reading."))
    if command:
        section.add(Paragraph(f"Made by: `{command}`"))
    sweep = results["sweep"]
    by_noise = {k: _setting(results, k) for k in sweep}
    for noise, r in by_noise.items():
        section.add(claims_table(setting_claims(r, noise), f"Claims of the paper checked — σ² = {noise}"))
    section.add(claims_table([_sweep_claim(results)], "Claim across σ² (Fig. 4)"))
    section.add(equivalence_table({f"σ² = {k}": r for k, r in by_noise.items() if "one_step_gap" in r}))
    if results["rank_failure_audit"]["entries"]:
        section.add(audit_table({f"σ² = {p['system_noise_var']}": results}))
    section.add(method_table(results, "mahalanobis", f"avg. Mahalanobis, σ² = {p['system_noise_var']}"))
    for noise in sweep:
        if float(noise) in FIGURE_NOISES:
            section.add(Figure(plot_per_step(sweep[noise]["mahalanobis"], "average Mahalanobis distance (squared)",
                                             f"σ² = {noise}", folder / f"mahalanobis-s{noise}.png", log=True),
                               f"Average squared Mahalanobis distance per step, σ² = {noise} (Figs. 2, 3)"))
    section.add(Figure(_sweep_figure(results, folder / "sweep.png"),
                       "Average squared Mahalanobis distance (mean over steps) against σ² (Fig. 4)"))
    rows = [[k] + [fmt(v[m], 4) for m in METHODS] for k, v in results["average_mahalanobis_by_noise"].items()]
    section.add(Table(["σ²"] + list(METHODS), rows, "Mean over steps of the average Mahalanobis distance"))
    return section


def _setting(results: dict, noise: str) -> dict:
    """One σ²'s summary in the shape the shared claim helpers expect."""
    return results["per_noise"][noise] if "per_noise" in results else results


def _sweep_claim(results: dict) -> Claim:
    table = results["average_mahalanobis_by_noise"]
    held, parts = [], []
    for noise, v in table.items():
        for family in FAMILIES:
            fused = max(v[f"CMF-{family}"], v[f"DMF-{family}"])
            single = min(v[f"Sensor1-{family}"], v[f"Sensor2-{family}"])
            held.append(fused < single)
            parts.append(f"σ² = {noise} {family}: fused {fmt(fused, 3)} vs best sensor {fmt(single, 3)}")
    return Claim("fusion beats the single sensors for every σ² (point estimates of the step-mean)", all(held),
                 "; ".join(parts))


def _sweep_figure(results: dict, path):
    table = results["average_mahalanobis_by_noise"]
    noises = sorted(table, key=float)
    fig, axes = new_figure(1, 1, width=7.0, height=4.5)
    ax = axes[0, 0]
    for method in METHODS:
        rule, family = method.rsplit("-GP-", 1)
        ax.plot([float(n) for n in noises], [table[n][method] for n in noises], "-" if family == "ADF" else "-.",
                marker="o", ms=4, color=f"C{RULES.index(rule)}", label=method)
    ax.set_yscale("log")
    ax.set_xlabel("system noise σ²")
    ax.set_ylabel("average Mahalanobis distance (squared)")
    ax.legend(fontsize=7, ncol=2)
    return save(fig, path)
