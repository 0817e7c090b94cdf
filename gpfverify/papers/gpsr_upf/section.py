"""Report page: Meng et al. 2015 (seed 001 §3, Fig. 1–6 and Table 1) — GPSR-UPF against the
basic UPF in SINS/GPS integrated navigation, with the claim records the experiment wrote. A pure
renderer: it reads ``results.json`` (through :mod:`gpfverify.papers.gpsr_upf.contract`'s types) and
computes no experiment."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gpfverify.contract.claims import AS_RUN, ClaimRecord, read_claims
from gpfverify.contract.papers import PAPERS
from gpfverify.papers.gpsr_upf.contract import (COLLAPSE_FACTOR, CRUISE_RANGE_SDS, GP_SR_UKF, GPSR_UPF, INTERPRETATIONS,
                                                NAME, PAPER, PAPER_CRUISE_RANGE, PARTICLE_FILTERS, QUANTITIES,
                                                REFERENCES, SR_UKF, TRUE_SR_UKF, UNITS, UPF, Params, collapsed)
from gpfverify.report.document import (Figure, Paragraph, Section, Table, claim_tables, fmt,
                                       interpretations_table)
from gpfverify.report.figures import new_figure, save
from gpfverify.report.inputs import SectionInput

SLUG = "sins-gps"
AXES = ("E", "N", "U")


def _references(results: dict) -> list:
    """The reference filters the results hold (runs saved before the true-model ceiling lack it)."""
    return [m for m in REFERENCES if m.key in results["reference"]["rms"]]


def render_section(data: SectionInput) -> Section:
    return data.render_single(NAME, _title(), render)


def _title() -> str:
    return f"GPSR-UPF in SINS/GPS integrated navigation ({PAPERS[PAPER].short})"


def _pct(value) -> str:
    return "—" if value is None else f"{100 * value:.1f} %"


def _scale_factor_text(p: Params) -> str:
    if not p.accel_scale_ppm:
        return ""
    return (f"; and it leaves out an accelerometer scale factor of {fmt(p.accel_scale_ppm)} ppm on every axis, "
            "the velocity forcing Δt s fⁿ (a vertical acceleration error s g in cruise)")


def _noise_text(p: Params) -> str:
    if p.accel_noise_scale == 1.0:
        return ""
    return (f"; and its process noise is mis-specified: the flight's accelerometer white noise is "
            f"{fmt(p.accel_noise_scale)} times the model's, so the true velocity block of Q is "
            f"{fmt(p.accel_noise_scale ** 2)} times the filters' (the GP's noise variance learns it)")


def render(results: dict, out_dir: Path) -> Section:
    """The page from one ``results.json`` body; figures go to ``out_dir``."""
    p = Params.from_json(results["params"])
    upf, gpsr, sr, gp_sr = UPF.key, GPSR_UPF.key, SR_UKF.key, GP_SR_UKF.key
    section = Section(SLUG, _title())
    floor = "none" if not any(p.noise_floor) else ", ".join(fmt(v, 3) for v in p.noise_floor)
    section.add(Paragraph(
        "Scenario (gpfverify.papers.gpsr_upf.scenario): the 15-state φ-angle SINS error model in east-north-up "
        "axes (attitude, velocity, position in local metres, gyro drift, accelerometer bias) along a generated "
        f"{fmt(p.duration)} s flight from 109°E, 34°N, 1000 m: take-off roll and climb 0–200 s, cruise, "
        "acceleration and a 153° coordinated turn 500–600 s, cruise; GPS position (σ = "
        f"{fmt(p.gps_position_sd)} m) and velocity (σ = {fmt(p.gps_velocity_sd)} m/s, our interpretation) "
        f"differences every {fmt(p.dt)} s. Model mismatch (our choice, the paper does not state its own): the "
        "filters' model evaluates the fⁿ × φ coupling with the level-flight specific force [0, 0, g], exact in "
        "straight level cruise and wrong in every manoeuvre" + _scale_factor_text(p) + _noise_text(p)
        + ". GPSR-UPF learns the "
        f"residual{' Δt (fⁿ − f̂ⁿ) × φ' if not p.accel_scale_ppm else ''} with a "
        f"Gaussian process on (φ, fⁿ − f̂ⁿ) from {p.train_points} transitions of training flights flown from "
        f"headings {', '.join(fmt(h) for h in p.train_headings)}° (the test flight starts at 45°), and uses "
        "its predictive variance as the velocity process noise."))
    section.add(Paragraph(
        f"Both particle filters: N = {p.particles} particles, systematic resampling when the effective sample "
        f"size N_eff falls below {fmt(p.resample_threshold)} N, prior N(0, P₀), process-noise floor {floor}, "
        f"filter-design Q = {fmt(p.q_inflation)} × the model's Q, each particle's covariance {p.particle_covariance}"
        f", move after resampling: {p.jitter}. "
        "UPF: per-particle UKF proposal on the inaccurate model; GPSR-UPF: per-particle square-root UKF "
        f"proposal on the inaccurate model plus the learned residual. {results['runs_ok']} of {results['runs']} "
        f"runs finished (root seed {results['seed']})" + _failed(results) + ". Errors are estimate − truth of "
        "the error state; curves are per-step RMS over runs of the 3-axis error norm, reductions "
        "1 − RMS(GPSR-UPF)/RMS(UPF) over runs and steps."))
    section.add(*claim_tables(read_claims(results), f"Claims of {PAPERS[PAPER].short} checked"))
    rows = []
    ceiling = results["reference"].get("ceiling")
    for q in QUANTITIES:
        rows.append([f"{q} ({UNITS[q]})", results["rms"][upf][q], results["rms"][gpsr][q],
                     _pct(results["reduction"][q]), _pct(results["segment_reduction"]["manoeuvre"][q]),
                     _pct(results["segment_reduction"]["cruise"][q]), results["reference"]["rms"][sr][q],
                     results["reference"]["rms"][gp_sr][q], _pct(results["reference"]["reduction"][q]),
                     _pct(ceiling[q]) if ceiling else "—"])
    section.add(Table(["error", upf, gpsr, "reduction", "in manoeuvres", "in cruise", sr, gp_sr,
                       "reduction (single filters)", "true-model ceiling"], rows,
                      "RMS errors (Table 1 layout); the single-filter columns run each particle filter's "
                      "proposal filter alone (— where the flight has no such segment); the true-model ceiling "
                      f"is 1 − RMS({TRUE_SR_UKF.key})/RMS({sr}), the reduction an SR-UKF reaches by knowing the "
                      "model that generated the flight: no correction of the inaccurate model can reach more "
                      "(— for runs saved before it was run)"))
    ess, rate = results["mean_ess_fraction"], results["resample_rate"]
    per_run, per_step = results["time_per_run"], results["time_per_step"]
    section.add(Table(["filter", "mean N_eff / N", "resampling rate", "CPU s per run", "CPU ms per step"],
                      [[m.key, ess[m.key], rate[m.key], per_run[m.key], 1e3 * per_step[m.key]]
                       for m in PARTICLE_FILTERS]
                      + [[m.key, "—", "—", per_run[m.key], 1e3 * per_step[m.key]] for m in _references(results)],
                      "Importance-weight health (N_eff/N = 1/N: all weight on one particle) and CPU time"))
    health = results.get("health", [])
    if health:
        section.add(Table(["filter", "check", "passed", "statistic", "healthy side of", "detail"],
                          [[c["subject"], c["name"], "yes" if c["passed"] else "NO", c["statistic"], c["threshold"],
                            c["detail"]] for c in health],
                          "Health checks of the particle filters in this configuration (gpfverify.health): a claim "
                          "comparing them is 'not decidable' when one fails"))
    _add_interpretations(section, read_claims(results), results.get("interpretation_summaries") or {}, health)
    _add_configurations(section, results)
    _add_error_levels(section, results)
    if collapsed(p.particles, ess):
        section.add(Paragraph(
            f"Diagnosis: the importance weights of both particle filters collapse (mean N_eff/N below "
            f"{fmt(COLLAPSE_FACTOR)}/N = {fmt(COLLAPSE_FACTOR / p.particles, 3)}: {upf} "
            f"{fmt(ess[upf], 3)}, {gpsr} {fmt(ess[gpsr], 3)}). With navigation-grade noise the transition density "
            "p(xₖ | xⁱₖ₋₁) has the tiny spread of Q, while each particle's UKF proposal has the spread of its "
            "own filter covariance (arcminutes of attitude, metres of position), so p(xₖ | xⁱₖ₋₁)/q(xₖ) varies "
            "over hundreds of orders of magnitude between particles. The particle filters then follow one "
            "particle's near-deterministic propagation and lose most of the measurement information (position "
            f"RMS: {upf} {fmt(results['rms'][upf]['position'], 3)} m, a single SR-UKF on the same model "
            f"{fmt(results['reference']['rms'][sr]['position'], 3)} m). This is a property of the UPF on this "
            "model, not of the Gaussian process: the claims comparing the two particle filters are not "
            "decidable in this configuration, and the single-filter columns isolate the effect of the learned "
            "residual. Inflating the filter-design Q does not cure it: each particle's own covariance grows with "
            "Q as well, and in the weakly observable gyro-drift and accelerometer-bias states its stationary "
            "value is about T/2 steps of Q (T = 3600 s, 1800 s), whatever the factor; more particles only "
            "lower 1/N, and roughening or a regularisation kernel move the particles after resampling but "
            "leave the proposal as wide as before. Taking each particle's proposal from the particle itself "
            "(the optimal importance density of this linear-Gaussian error model, Doucet, Godsill & Andrieu "
            "2000) removes the mismatch, but it leaves the particles only the diversity Q gives them: under the "
            "true Q the particles collapse onto copies of a few (sample impoverishment) and the position drifts "
            "away, roughening (K = 0.2 in 15 dimensions, after every resampling) feeds on its own spread, and "
            "only an inflated Q keeps them spread; the table of configurations above shows which passed."))
    gp = results["gp_residual"]
    section.add(Paragraph(
        f"Gaussian-process residual: along the test trajectories the true velocity residual has RMS "
        f"{fmt(gp['residual_rms'], 3)} m/s per step; the GP mean misses it by {fmt(gp['error_rms'], 3)} m/s RMS "
        f"(fit: {fmt(gp['fit_seconds'], 3)} s CPU)."))
    for q in QUANTITIES:
        section.add(Figure(_band_figure(results, q, out_dir / f"{q}_bands.png"),
                           f"{q.capitalize()} error per axis (mean ± 1 s.d. over runs) for {upf} (left) and "
                           f"{gpsr} (right), as in the paper's figures; grey: manoeuvres."))
    section.add(Figure(_rms_figure(results, out_dir / "rms_errors.png"),
                       "RMS error norm over runs against time: the two particle filters and, dashed, the "
                       "single SR-UKF on the inaccurate and on the GP-corrected model."))
    return section


def _add_interpretations(section: Section, records: list[ClaimRecord], stored: dict, health: list[dict]) -> None:
    """Per claim, the verdict (and statistic) under each interpretation tried, the robustness
    sentence, and the first configuration in which the particle filters passed their health checks."""
    tried = [r for r in records if r.interpretations]
    if not tried:
        return
    names = [i.name for i in tried[0].interpretations if i.name != AS_RUN]
    why = {spec.name: spec for spec in INTERPRETATIONS}
    section.add(Paragraph(
        "Interpretations tried (the paper does not report how its filters were tuned): "
        + "; ".join(f"{n} ({', '.join(f'{k} = {v}' for k, v in why[n].changes.items())}: {why[n].why})"
                    if n in why else n for n in names) + "."))

    section.add(interpretations_table(tried, "Verdict (statistic) of each claim under each interpretation; 'not "
                                             "decidable' = a particle filter failed its health checks there"))
    comparisons = [r for r in tried if r.id.startswith(f"{NAME}/reduction-")]
    if comparisons:
        # health from the checks themselves where stored: a comparison is also "not decidable" when the
        # claim is beyond the true-model ceiling
        def passed(verdict: str, checks: list[dict] | None) -> bool:
            return all(c["passed"] for c in checks) if checks else verdict != "not decidable"

        healthy = [AS_RUN] if passed(comparisons[0].verdict, health) else []
        healthy += [i.name for i in comparisons[0].interpretations
                    if i.name != AS_RUN and passed(i.verdict, stored.get(i.name, {}).get("health"))]
        within_reach = _within_reach_paragraph(tried, [AS_RUN, *names], healthy)
        if within_reach is not None:
            section.add(within_reach)
        if not healthy:
            section.add(Paragraph("In none of the configurations tried did both particle filters pass their "
                                  "health checks: the paper's comparison is not decidable with these filters."))
        else:
            first = healthy[0]
            faithful = "; ".join(f"{r.id.rsplit('-', 1)[-1]}: {r.verdict}" for r in comparisons)
            def there(r: ClaimRecord) -> str:
                if first == AS_RUN:
                    return r.verdict
                verdict = next(i.verdict for i in r.interpretations if i.name == first)
                runs = stored.get(first, {}).get("claims", {}).get(r.id, {}).get("runs_to_decide")
                return verdict + (f" (about {runs} runs would decide it)" if verdict == "undecided" and runs else "")

            verdicts = "; ".join(f"{r.id.rsplit('-', 1)[-1]}: {there(r)}" for r in comparisons)
            section.add(Paragraph(
                f"First configuration in which both particle filters pass their health checks: {first} "
                f"(healthy: {', '.join(healthy)}). There the paper's reductions are {verdicts} — next to the "
                f"faithful configuration's {faithful}."))


def _within_reach_paragraph(tried: list[ClaimRecord], configurations: list[str],
                            healthy: list[str]) -> Paragraph | None:
    """Per claimed reduction, the configurations that leave it within reach (its true-model-ceiling
    claim held) and those of them whose particle filters are healthy: a comparison decides the
    paper's claim only where both are true. None when the ceiling was not recorded."""
    ceilings = [r for r in tried if r.id.startswith(f"{NAME}/true-model-ceiling-")]
    if not ceilings:
        return None

    def verdict_under(record: ClaimRecord, name: str) -> str | None:
        if name == AS_RUN:
            return record.verdict
        return next((i.verdict for i in record.interpretations if i.name == name), None)

    def listed(names: list[str]) -> str:
        return ", ".join(names) if names else "none"

    parts = []
    for record in ceilings:
        within = [n for n in configurations if verdict_under(record, n) == "held"]
        parts.append(f"{record.id.rsplit('-', 1)[-1]}: within reach in {listed(within)}, healthy there in "
                     f"{listed([n for n in within if n in healthy])}")
    return Paragraph(
        "Where each claimed reduction can be decided: the model error must leave room for it (the true-model "
        "ceiling reaches its threshold: within reach) and both particle filters must pass their health checks "
        f"(healthy: {listed(healthy)}). " + "; ".join(parts) + ".")


def _health_words(health: list[dict], method: str) -> str:
    mine = [c for c in health if c["subject"].split(" ")[0] == method]
    failed = [c["subject"].removeprefix(method).strip() or c["name"] for c in mine if not c["passed"]]
    return "passed" if not failed else "FAILED: " + ", ".join(
        ("weight collapse" if f == "weight collapse" else f"{f} divergence") for f in failed)


def _add_configurations(section: Section, results: dict) -> None:
    """Per configuration (as run and each interpretation whose summary the reference page stored in
    ``interpretation_summaries``): each particle filter's mean N_eff/N, health and RMS errors."""
    stored = results.get("interpretation_summaries") or {}
    if not stored:
        return
    configurations = [(AS_RUN, results["runs_ok"], results.get("health", []), results["mean_ess_fraction"],
                       results["rms"], results["reduction"])]
    configurations += [(name, s["runs_ok"], s["health"], s["mean_ess_fraction"], s["rms"], s["reduction"])
                       for name, s in stored.items()]
    rows = []
    for name, runs, health, ess, rms, reduction in configurations:
        for m in PARTICLE_FILTERS:
            rows.append([name, runs, m.key, ess[m.key], _health_words(health, m.key),
                         *(rms[m.key][q] for q in QUANTITIES),
                         *((_pct(reduction[q]) if m == GPSR_UPF else "") for q in QUANTITIES)])
    confirm = results.get("confirmation")
    if confirm:
        claims = [confirm["claims"][f"{NAME}/reduction-{q}"] for q in QUANTITIES]
        section.add(Paragraph(
            f"Confirmation at more runs of {confirm['interpretation'] or 'one configuration'} "
            f"(`{confirm['command']}`, {confirm['runs_ok']} runs; health: "
            + ", ".join(f"{m.key} {_health_words(confirm['health'], m.key)} (mean N_eff/N "
                        f"{fmt(confirm['mean_ess_fraction'][m.key], 3)})" for m in PARTICLE_FILTERS)
            + "): " + "; ".join(
                f"{q}: {c['verdict']}" + (f" (about {c['runs_to_decide']} runs would decide it)"
                                          if c.get("runs_to_decide") else "") + f" — {c['evidence'].split('; over')[0]}"
                for q, c in zip(QUANTITIES, claims)) + "."))
    section.add(Table(["configuration", "runs", "filter", "mean N_eff / N", "health",
                       *(f"RMS {q} ({UNITS[q]})" for q in QUANTITIES), *(f"reduction {q}" for q in QUANTITIES)],
                      rows, "Each configuration tried: the particle filters' weight health and RMS errors over runs "
                            "and steps (reduction = 1 − RMS(GPSR-UPF)/RMS(UPF))"))


def _add_error_levels(section: Section, results: dict) -> None:
    """The paper's error ranges in cruise against this implementation's (``cruise_range`` of the
    run and of each stored configuration; results saved before it was recorded have none)."""
    stored = results.get("interpretation_summaries") or {}
    configurations = [(AS_RUN, results.get("cruise_range"))]
    configurations += [(name, s.get("cruise_range")) for name, s in stored.items()]

    def span(pair) -> str:
        return "—" if pair is None else f"{fmt(pair[0], 3)} to {fmt(pair[1], 3)}"

    ours = [[name, m.key, *(span(ranges[m.key][q]) for q in QUANTITIES)]
            for name, ranges in configurations if ranges for m in PARTICLE_FILTERS]
    if not ours:
        return
    paper = [["the paper (its text on Figs. 1–6)", m.key, *(span(PAPER_CRUISE_RANGE[m.key][q]) for q in QUANTITIES)]
             for m in PARTICLE_FILTERS]
    section.add(Table(["configuration", "filter", *(f"{q} ({UNITS[q]})" for q in QUANTITIES)], paper + ours,
                      "The paper's error levels as a check: each filter's error range in cruise, the paper's as its "
                      f"text reads them off its figures, ours the smallest and largest of mean ± "
                      f"{fmt(CRUISE_RANGE_SDS)} s.d. over runs over the axes and cruise steps"))


def _failed(results: dict) -> str:
    failed = results.get("failed_runs", [])
    if not failed:
        return ""
    return (f"; {len(failed)} run{'s' if len(failed) != 1 else ''} stopped with an error (first: "
            f"{failed[0]['error']}) and are left out of every number and verdict below")


def _shade_manoeuvres(ax, time, manoeuvre) -> None:
    ax.fill_between(time, 0, 1, where=manoeuvre, transform=ax.get_xaxis_transform(), color="0.9", lw=0)


def _band_figure(results: dict, quantity: str, path: Path) -> Path:
    time, manoeuvre = np.asarray(results["time"]), np.asarray(results["manoeuvre"], bool)
    fig, axes = new_figure(2, 1, width=5.2, height=3.4)
    for ax, method in zip(axes[0], PARTICLE_FILTERS):
        band = results["error_bands"][method.key][quantity]
        mean, sd = np.asarray(band["mean"]), np.asarray(band["sd"])
        _shade_manoeuvres(ax, time, manoeuvre)
        for axis in range(3):
            ax.plot(time, mean[:, axis], color=f"C{axis}", lw=0.8, label=AXES[axis])
            ax.fill_between(time, mean[:, axis] - sd[:, axis], mean[:, axis] + sd[:, axis], color=f"C{axis}",
                            alpha=0.2, lw=0)
        ax.set_title(f"{method.key}: {quantity} error")
        ax.set_xlabel("t (s)")
        ax.set_ylabel(UNITS[quantity])
        ax.legend(loc="upper right")
    lo = min(ax.get_ylim()[0] for ax in axes[0])
    hi = max(ax.get_ylim()[1] for ax in axes[0])
    for ax in axes[0]:
        ax.set_ylim(lo, hi)
    return save(fig, path)


def _rms_figure(results: dict, path: Path) -> Path:
    time, manoeuvre = np.asarray(results["time"]), np.asarray(results["manoeuvre"], bool)
    fig, axes = new_figure(1, 3, width=9.0, height=2.4)  # one row per error, the time axes aligned
    for row, (ax, quantity) in enumerate(zip(axes[:, 0], QUANTITIES)):
        _shade_manoeuvres(ax, time, manoeuvre)
        for i, method in enumerate(PARTICLE_FILTERS):
            ax.plot(time, results[f"{quantity}_error"][method.key], color=f"C{i}", lw=0.9, label=method.key)
        for i, method in enumerate(_references(results)):
            ax.plot(time, results["reference"]["error"][quantity][method.key], color=f"C{i}", ls="--", lw=0.9,
                    label=method.key)
        ax.set_yscale("log")
        ax.set_title(f"{quantity} error norm (RMS)")
        ax.set_ylabel(UNITS[quantity])
        if row == len(QUANTITIES) - 1:
            ax.set_xlabel("t (s)")
        if row == 0:  # the same methods in every row: one legend, right of the first
            ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return save(fig, path)
