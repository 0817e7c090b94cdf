"""Report page: the particle-flow paper (Zhou et al. 2020) — the innovation-error particle flow
(IE-PFF) against the bootstrap PF, the UPF and the Daum–Huang exact flow (EDH): Table 1 / Fig. 1
(the grid on its 1-D model), Fig. 2 (gamma process noise), Table 2 / Fig. 3 (bearing-only
tracking), with the paper's claims as the experiments decided them. Renders the ``pff1d`` and
``bearing`` runs' ``results.json`` (and :func:`table1_blocks` the grid of any pff1d run, e.g. an
interpretation's on another model); computes nothing."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gpfverify.papers.particle_flow import bearing_contract
from gpfverify.papers.particle_flow import pff1d_contract as pff_contract
from gpfverify.contract.claims import AS_RUN, ClaimRecord, read_claims
from gpfverify.contract.interpretations import InterpretationSpec
from gpfverify.contract.methods import Method
from gpfverify.contract.papers import PAPERS
from gpfverify.papers.particle_flow.contract import EDH, FLOWS, IE_PFF, PAPER, PF, UPF, Variant
from gpfverify.contract.serial import from_json
from gpfverify.health import HealthCheck
from gpfverify.report.document import (Figure, Paragraph, Section, Table, claim_tables, fmt,
                                       interpretations_table)
from gpfverify.report.figures import new_figure, save
from gpfverify.report.inputs import SectionInput

SLUG = "particle-flow"
TITLE = f"Innovation-error particle flow vs PF, UPF and EDH ({PAPERS[PAPER].short})"
COLORS = {PF: "C0", UPF: "C2", EDH: "C1", IE_PFF: "C3"}
#: bearing-only figure: PF (small N), PF (large N), IE-PFF
BEARING_COLORS = ("C0", "C9", "C3", "C1")


def render_section(data: SectionInput) -> Section:
    """The page from the section's ``pff1d`` and ``bearing`` runs (the first of each, if several)."""
    pff, brg = data.of(pff_contract.NAME), data.of(bearing_contract.NAME)
    section = Section(SLUG, TITLE)
    section.add(_methods_paragraph())
    records = []
    if pff:
        entry, results = pff[0]
        _render_pff1d(section, results, data.folder, entry.setting)
        records += read_claims(results)
    else:
        section.add(Paragraph("No pff1d run was found in this report folder."))
    if brg:
        _render_bearing(section, brg[0][1], data.folder)
        records += read_claims(brg[0][1])
    else:
        section.add(Paragraph("No bearing run was found in this report folder."))
    levels = sorted({r["significance_level"] for _, r in (*pff, *brg)})
    section.add(*claim_tables(records, f"Claims of {PAPERS[PAPER].short} (paired t-test over runs at level "
                                             f"{' / '.join(f'{v:g}' for v in levels)}; ±: one standard error; "
                                             "a divergence where the other filter stayed finite loses the comparison; "
                                             "a comparison whose filters failed a health gate is withheld, the "
                                             "comparisons of working filters decide)"))
    section.add(*_sensitivity(records))
    section.add(Paragraph(
        "Run times are CPU seconds (process time) of this Python implementation on the machine that wrote the "
        "page (numpy, one process); one run at a time the PF's cost is dominated by per-step overhead, not by N, "
        "so time ratios say little about the algorithms' operation counts. Runs filtered together "
        "(reproduce --batch B) each carry their batch's CPU time divided by B, which divides that overhead by B; "
        "the timing claims' caveats say so. The timing claims (Table 1's running times and "
        "Table 2's) compare them as paired per-run ratios (their geometric mean against the claim's bound, 5 "
        "standard errors of the log ratio) and are counted apart from the accuracy claims."))
    return section


def _methods_paragraph() -> Paragraph:
    return Paragraph(
        "IE-PFF: per step the predicted particles flow in pseudo-time λ ∈ [0, 1] along "
        "dX/dλ = K (z − (h(X) + ĥ)/2) with the Galerkin gain of the coordinate basis, K = Cov(X, h(X)) R⁻¹, "
        "recomputed at every explicit-Euler λ-step; no weights, no resampling. EDH: the Daum–Huang exact flow "
        "with the parallel EKF covariance. PF: bootstrap SIR, systematic resampling every step. UPF: one UKF "
        "per particle as proposal, exact transition densities, systematic resampling every step. "
        "Verified separately (tests): IE-PFF and EDH reach the Kalman update at first order in Δλ on "
        "linear-Gaussian models, a frozen gain does not; PF and UPF agree with the Kalman filter within "
        "Monte Carlo error; UPF weights gamma noise exactly (quadrature).")


# ----------------------------------------------------------------------------- pff1d

def _render_pff1d(section: Section, results: dict, folder: Path, setting: str) -> None:
    p = pff_contract.Params.from_json(results["params"])
    gamma = pff_contract.gamma_entries(results)
    runs = results["runs_ok"]
    where = f" ({setting})" if setting else ""
    section.add(Paragraph(
        f"pff1d{where}: {runs} of {results['runs']} runs (seeds spawned from root seed {results['seed']}); the "
        f"paper used {pff_contract.PAPER_RUNS}."))
    section.add(Table(["interpretation", "choice"], _pff1d_interpretations(p),
                      "Interpretations, §3.1 (the paper's model equations and parameter lists were lost in "
                      "extraction)"))
    section.add(*table1_blocks(results, folder))
    gamma_rows = [[r, label, e.mean_rmse, f"{e.diverged}/{runs}", e.time_per_run]
                  for r, entries in gamma.items() for label, e in entries.items()]
    section.add(Table(["R", "method", "mean RMSE", "diverged", "CPU s per run"], gamma_rows,
                      f"Γ({p.gamma_shape:g}, rate {p.gamma_rate:g}) process noise (van der Merwe et al. 2000 "
                      f"benchmark), N = {p.particles}, Δλ = {p.gamma_dlambda:g}"))
    section.add(Figure(_fig2(p, gamma, runs, folder / "pff_fig2_gamma.png"),
                       f"Fig. 2: RMSE per step under gamma process noise for each R ({p.main_spacing} λ-steps)"))
    section.add(*health_blocks("pff1d", results))


def table1_blocks(results: dict, folder: Path) -> list:
    """Table 1 of a pff1d run on its model (``params.table_model``), its divergence counts and Fig. 1
    (``pff_fig1_<model>.png`` in ``folder``)."""
    p = pff_contract.Params.from_json(results["params"])
    rows = pff_contract.table1_rows(results)
    name = pff_contract.TABLE_MODEL_NAMES[p.table_model]
    return [
        Table(["Q", "R", "method", "Δλ", "λ-steps", "mean RMSE", "diverged", "CPU s per run"],
              [[r.Q, r.R, r.method, "" if r.dlambda is None else r.dlambda, r.spacing or "", r.mean_rmse,
                f"{r.diverged}/{r.runs}", r.time_per_run] for r in rows],
              f"Table 1 ({name}, N = {p.particles}, T = {p.steps}, {results['runs_ok']} runs): RMSE averaged over "
              "time, over the runs that did not diverge"),
        Paragraph(_divergence_summary(results, name)),
        Figure(_fig1(p, rows, folder / f"pff_fig1_{p.table_model}.png"),
               f"Fig. 1: {name} RMSE per step at the smallest and largest Q of the grid (first R, finest Δλ, "
               f"{p.main_spacing} λ-steps); a filter that diverged in every run has no curve")]


def _divergence_summary(results: dict, name: str) -> str:
    counts = from_json(list[pff_contract.DivergenceCount], results["divergences"], "divergences")
    parts = [f"{c.method} Δλ = {c.dlambda:g} {c.spacing}: {c.diverged}/{c.total}" for c in counts]
    return (f"Divergences over the whole {name} grid (cells × runs): " + "; ".join(parts) + ". The flows are "
            "integrated by explicit Euler in λ; on a linear model the particle spread is multiplied by "
            "(1 − Δλ·K·∂h/∂x/2) per step, so a step with Δλ·K·∂h/∂x > 4 amplifies instead of contracting — "
            "a quadratic measurement (the UNGM's x²/20, the benchmark's 0.2x²) with small R makes K·∂h/∂x "
            "large. Divergence that disappears as Δλ shrinks "
            "is this instability, not a property of the continuous flow. The stiffness sits at λ = 0: along the "
            "exact flow of a linear model P(λ) = P₀/(1 + λP₀H²/R), so the contraction rate PH²/(2R) falls from "
            "P₀H²/(2R) to about 1/(2λ). A uniform schedule must take every step below 4R/(P₀H²); a geometric one "
            "keeps Δλ/λ near ratio − 1 (stable) and needs only its first step below that bound — 10 steps of "
            "ratio 1.2 start at 0.039, Li & Coates' 29 steps at 0.001.")


def _pff1d_interpretations(p: pff_contract.Params) -> list[list[str]]:
    def values(xs: tuple) -> str:
        return "{" + ", ".join(f"{x:g}" if isinstance(x, float) else str(x) for x in xs) + "}"

    benchmark = ("van der Merwe et al. (2000): xₖ = 1 + sin(0.04π(k − 1)) + xₖ₋₁/2 + wₖ, yₖ = 0.2xₖ² + vₖ (k ≤ 30), "
                 f"0.5xₖ − 2 + vₖ (k > 30); prior N({fmt(p.gamma_prior.mean)}, {fmt(p.gamma_prior.var)})")
    ungm = ("UNGM xₖ = xₖ₋₁/2 + 25xₖ₋₁/(1 + xₖ₋₁²) + 8 cos(1.2k) + wₖ, yₖ = "
            + ("xₖ²/20" if p.ungm_measurement == "quadratic" else "xₖ") + " + vₖ; x₀ and every filter's prior "
            f"N({fmt(p.ungm_prior.mean)}, {fmt(p.ungm_prior.var)})")
    return [
        ["1-D model, Gaussian cases (Table 1)",
         ungm if p.table_model == "ungm" else f"vdM-Gaussian: {benchmark}, with wₖ ~ N(0, Q)"],
        ["1-D model, gamma case", benchmark],
        [f"Γ({p.gamma_shape:g}, {p.gamma_rate:g})",
         f"shape {p.gamma_shape:g}, rate {p.gamma_rate:g} (mean {fmt(p.gamma_shape / p.gamma_rate)}, variance "
         f"{fmt(p.gamma_shape / p.gamma_rate ** 2)}); Gaussian approximation (f + mean, Q = variance) for the "
         "UKF proposal and the EKF covariance"],
        ["Table-1 grid", f"Q ∈ {values(p.table_q)}, R ∈ {values(p.table_r)}, Δλ ∈ {values(p.dlambda)}; λ-steps "
                         f"{values(p.spacings)} (exponential: "
                         + (f"{p.exponential_steps} steps whatever Δλ" if p.exponential_steps else
                            "the same number of steps as Δλ gives")
                         + f", each {p.exponential_ratio:g} times the previous)"],
        ["noise values", "Q and R of the grid and the gamma case's R are "
                         + ("variances" if p.noise_values == "variance" else
                            "standard deviations (the models use their squares)")],
        ["main gamma case ('rmse' of results.json)", f"R = {p.gamma_main_r:g}, {p.main_spacing} λ-steps"],
        ["diverged", "a filter whose estimate became non-finite or raised a numerical error; left out of "
                     "its RMSE curve, counted in the tables, and a loss in paired claims"],
    ]


def _row(rows: list[pff_contract.Table1Row], q: float, r: float, variant: Variant) -> pff_contract.Table1Row:
    return next(row for row in rows if (row.Q, row.R, row.variant) == (q, r, variant))


def _variant(method: Method, dlambda: float, spacing: pff_contract.Spacing) -> Variant:
    return Variant(method, dlambda, spacing) if method in FLOWS else Variant(method)


def _fig1(p: pff_contract.Params, rows: list[pff_contract.Table1Row], path: Path) -> Path:
    r, dlam, spacing = p.table_r[0], min(p.dlambda), p.main_spacing
    qs = sorted({min(p.table_q), max(p.table_q)})
    fig, axes = new_figure(len(qs), 1, width=5.0)
    for ax, q in zip(axes[0], qs):
        for m in pff_contract.TABLE_METHODS:
            row = _row(rows, q, r, _variant(m, dlam, spacing))
            curve = np.asarray(row.rmse, dtype=float)
            ax.plot(np.arange(1, len(curve) + 1), curve, color=COLORS[m],
                    label=f"{m.key} ({row.diverged}/{row.runs} diverged)")
        ax.set_title(f"Q = {q:g}, R = {r:g}, Δλ = {dlam:g}")
        ax.set_xlabel("k")
        ax.set_ylabel("RMSE")
        ax.set_yscale("log")
        ax.legend(fontsize=8)
    return save(fig, path)


def _fig2(p: pff_contract.Params, gamma: dict[str, dict[str, pff_contract.GammaEntry]], runs: int,
          path: Path) -> Path:
    fig, axes = new_figure(len(gamma), 1, width=4.5)
    for ax, (r, entries) in zip(axes[0], gamma.items()):
        for m in pff_contract.GAMMA_METHODS:
            e = entries[_variant(m, p.gamma_dlambda, p.main_spacing).label]
            ax.plot(np.arange(1, len(e.rmse) + 1), e.rmse, color=COLORS[m],
                    label=f"{m.key} ({e.diverged}/{runs} diverged)")
        ax.set_title(f"Γ({p.gamma_shape:g}, {p.gamma_rate:g}) noise, R = {r}")
        ax.set_xlabel("k")
        ax.set_ylabel("RMSE")
        ax.legend(fontsize=8)
    return save(fig, path)


# ----------------------------------------------------------------------------- bearing

def _render_bearing(section: Section, results: dict, folder: Path) -> None:
    b = bearing_contract.Params.from_json(results["params"])
    keys = [f.key for f in b.filters if f.key in results["rmse"]]  # a summary made before IE-PFF-N200 lacks it
    runs = results["runs_ok"]
    section.add(Paragraph(
        f"bearing: {runs} of {results['runs']} runs (seeds spawned from root seed {results['seed']}); the paper "
        f"used {bearing_contract.PAPER_RUNS}."))
    section.add(Table(["interpretation", "choice"], _bearing_interpretations(b),
                      "Interpretations, §3.2 (the paper's parameter list was lost in extraction)"))
    section.add(Table(["method", "mean position RMSE (m)", "final RMSE (m)", "diverged", "CPU s per run"],
                      [[m, results["mean_rmse"][m], results["rmse"][m][-1], f"{results['diverged'][m]}/{runs}",
                        results["time_per_run"][m]] for m in keys],
                      f"Table 2: bearing-only tracking, {runs} runs, {b.duration} s "
                      f"(Δλ = {b.dlambda:g}, {b.spacing} λ-steps)"))
    large = results.get("large_noise")
    if large:
        section.add(Table(["method", "mean position RMSE (m)", "final RMSE (m)", "diverged", "CPU s per run"],
                          [[m, large["mean_rmse"][m], large["rmse"][m][-1], f"{large['diverged'][m]}/{runs}",
                            large["time_per_run"][m]] for m in large["rmse"]],
                          f"Table 2 at larger process noise (r1 and r2 × {b.large_noise_factor:g}: the paper's values "
                          f"were lost): a second trajectory of every run, the same filters"))
    section.add(Figure(_fig3(results, keys, b.switch_time, folder / "pff_fig3_bearing.png"),
                       "Fig. 3: position RMSE per step, bearing-only tracking (the turn starts at the dashed line)"))
    section.add(*health_blocks("bearing", results))


def _bearing_interpretations(b: bearing_contract.Params) -> list[list[str]]:
    x0 = ", ".join(f"{v:g}" for v in b.initial_state)
    return [
        ["noise settings", f"r1 = {b.q_pos:g}, r2 = {b.q_vel:g} read as process-noise variances of position and "
                           f"velocity; bearing noise σ = {b.bearing_std:g} rad (lost, chosen)"],
        ["scenario", f"{b.duration} s in total, constant velocity until {b.switch_time:g} s, then a constant "
                     f"turn at {b.omega_deg:g}°/s; the filters know the mode schedule; x₀ = [{x0}]; prior "
                     f"N(x₀, diag({b.prior_std_pos:g}², {b.prior_std_vel:g}², {b.prior_std_pos:g}², "
                     f"{b.prior_std_vel:g}²))"],
        ["diverged", "a filter whose estimate became non-finite or raised a numerical error; left out of "
                     "its RMSE curve, counted in the tables, and a loss in paired claims"],
    ]


def _fig3(results: dict, keys: list[str], switch_time: float, path: Path) -> Path:
    fig, axes = new_figure(1, 1, width=6.0)
    ax = axes[0, 0]
    for m, color in zip(keys, BEARING_COLORS):
        ax.plot(np.arange(1, len(results["rmse"][m]) + 1), results["rmse"][m], color=color,
                label=f"{m} (mean {results['mean_rmse'][m]:.1f} m, {results['time_per_run'][m]:.3f} s/run)")
    ax.axvline(switch_time, color="0.5", ls="--")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("position RMSE (m)")
    ax.legend(fontsize=8)
    return save(fig, path)


# ----------------------------------------------------------------------------- health and sensitivity

def health_blocks(name: str, results: dict) -> list:
    """The health checks of a run (results.json "health"): the failed ones in full, the passed
    ones counted; nothing for results written before the checks existed."""
    if "health" not in results:
        return [Paragraph(f"{name}: this run recorded no health checks.")]
    checks = from_json(list[HealthCheck], results["health"], "health")
    failed = [c for c in checks if not c.passed]
    kinds = sorted({c.name for c in checks})
    text = (f"{name} health checks: {len(checks) - len(failed)} of {len(checks)} passed ({', '.join(kinds)}; "
            "divergence: a non-finite estimate or an error above the run's bound in any run fails it; weight "
            "collapse: median N_eff/N over runs and steps at or below the threshold). NEES is not checked: the "
            "flows' and PFs' posteriors on these models are far from Gaussian (the UNGM's is bimodal), so NEES "
            "bounds would not measure health.")
    blocks: list = [Paragraph(text)]
    if failed:
        blocks.append(Table(["filter (cell)", "check", "statistic", "threshold", "detail"],
                            [[c.subject, c.name, c.statistic, c.threshold, c.detail] for c in failed],
                            f"{name}: the health checks that failed"))
    passed_ess = [c for c in checks if c.passed and c.name == "weight collapse"]
    if passed_ess:
        low = min(passed_ess, key=lambda c: c.statistic)
        blocks.append(Paragraph(f"Lowest median N_eff/N of a particle filter that passed: {low.statistic:.3g} "
                                f"({low.subject})."))
    return blocks


def _declared() -> dict[tuple[str, str], InterpretationSpec]:
    """(experiment, interpretation name) -> its declaration in the contract."""
    return {(contract.NAME, s.name): s for contract in (pff_contract, bearing_contract)
            for s in contract.INTERPRETATIONS}


def _sensitivity(records: list[ClaimRecord]) -> list:
    """Per claim, its verdict as run and under every interpretation tried, and the robustness
    sentence; then what each interpretation changes and why."""
    tried = [r for r in records if r.interpretations]
    if not tried:
        return [Paragraph("No interpretation was tried for these runs (gpfverify reproduce NAME "
                          "--interpretations all runs them).")]
    blocks: list = [interpretations_table(tried, "Sensitivity: every claim's verdict (statistic) under each "
                                                 "interpretation tried (the same seeds; a column whose runs "
                                                 "differ from the main run's says how many; '—': the "
                                                 "interpretation does not run that claim's setting)")]
    declared = _declared()
    names = list(dict.fromkeys((r.id.split("/")[0], i.name) for r in tried for i in r.interpretations
                               if i.name != AS_RUN))
    spec_rows = []
    for experiment, name in names:
        changes = next(i.params for r in tried for i in r.interpretations
                       if i.name == name and r.id.split("/")[0] == experiment)
        spec = declared.get((experiment, name))
        spec_rows.append([experiment, name, ", ".join(f"{k} = {_value(v)}" for k, v in changes.items()),
                          spec.why if spec else ""])
    blocks.append(Table(["experiment", "interpretation", "parameters changed", "why"], spec_rows,
                        "Interpretations tried"))
    return blocks


def _value(v) -> str:
    if isinstance(v, (list, tuple)):
        return "(" + ", ".join(_value(x) for x in v) + ")"
    return f"{v:g}" if isinstance(v, float) else str(v)
