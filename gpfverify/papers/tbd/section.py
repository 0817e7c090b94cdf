"""Report page: Chen et al. 2015 (seed 004) — PF-TBD against the two-stage TPFTBD in Rutten's
scenario, laid out like the paper's figures 1–6 and table 1, with the claim records the experiment
wrote. A pure renderer: it reads ``results.json`` (through :mod:`gpfverify.papers.tbd.contract`'s types)
and computes no experiment."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from gpfverify.contract.claims import AS_RUN, ClaimRecord, read_claims
from gpfverify.contract.papers import PAPERS
from gpfverify.papers.tbd.contract import (DETECTION_READINGS, GAIN_METHODS_ONLY, INTERPRETATIONS, NAME, PAPER,
                                           PAPER_RUNS, READINGS, SUMMARY_FIELDS, Params, TbdMethod)
from gpfverify.health import MIN_ESS_FRACTION
from gpfverify.tolerances import MONTE_CARLO_SIGMAS
from gpfverify.report.document import (Figure, Paragraph, Section, Table, claim_tables, fmt,
                                       interpretations_table)
from gpfverify.report.figures import new_figure, save
from gpfverify.report.inputs import SectionInput

SLUG = "tbd"
#: the settings a reduced run changes, in words
REDUCIBLE = {"particles": "PF-TBD particles", "tpf_particles": "TPFTBD particles",
             "zeta_sweep_particles": "ζ-sweep particles", "snr": "SNR values"}


def render_section(data: SectionInput) -> Section:
    return data.render_single(NAME, _title(), render)


def _title() -> str:
    return f"Track-before-detect: PF-TBD against the two-stage TPFTBD ({PAPERS[PAPER].short})"


def _values(values) -> str:
    return ", ".join(fmt(v) for v in values)


def render(results: dict, out_dir: Path) -> Section:
    """The page from one ``results.json`` body; figures go to ``out_dir``."""
    p = Params.from_json(results["params"])
    pfa = fmt(p.pfa)
    section = Section(SLUG, _title())
    section.add(Paragraph(
        f"Rutten's scenario: {p.grid_size}×{p.grid_size} cells of size Δ = {fmt(p.cell_size)}, blur Σ = {fmt(p.blur)}, "
        f"q₁ = {fmt(p.q1)}, q₂ = {fmt(p.q2)}, T = {fmt(p.period)}, birth and death probabilities "
        f"{fmt(p.p_birth)} and {fmt(p.p_death)}, {p.frames} frames, the target in frames {p.first_frame}–"
        f"{p.last_frame} starting at [{_values(p.initial_state)}]. {results['runs_ok']} runs (root seed "
        f"{results['seed']}), each with a target-present and a target-absent sequence at every SNR in "
        f"{_values(p.snr)} dB ({p.snr_convention} convention); PF-TBD with N = {p.particles}, TPFTBD with "
        f"N = {_values(p.tpf_particles)} and ζ = {fmt(p.zeta)}. The paper used {PAPER_RUNS} runs at each SNR "
        f"from 1 to 9 dB and N = 2000 (PF-TBD), 2000 and 1000 (TPFTBD)." + _reduced_note(results, p)))
    section.add(Table(["what", "how this implementation does it"], [[k, v] for k, v in READINGS.items()],
                      f"Choices as run ({PAPERS[PAPER].short}: the parameter table and equations were lost in "
                      "extraction; the sensitivity study below tries the other readings)"))
    focus = fmt(results["focus_snr_db"])
    section.add(Figure(_main_figure(results, p, out_dir / "tbd_fig1_4.png"),
                       f"The paper's figures 1–4: existence probability (solid: target present, dashed: absent), "
                       f"ROC and position RMSE at {focus} dB, and the detection probability Pd at false-alarm "
                       f"rate Pfa = {pfa} against SNR (±1 standard error)."))
    rows = [[key, fmt(results["pd_at_pfa"][key], 3), fmt(results["pd_at_pfa_se"][key], 2),
             fmt(results["rmse_mean"][key], 3), fmt(results["time_per_run"][key], 3)]
            for key in results["existence_prob"]]
    section.add(Table(["method", f"Pd at Pfa = {pfa}", "s.e.", "position RMSE (cells)", "CPU s per sequence"], rows,
                      f"The paper's table 1 and the {focus} dB summary"))
    section.add(Table(["method"] + [f"{fmt(v)} dB" for v in results["snr_db"]],
                      [[key] + [fmt(v, 3) for v in values] for key, values in results["pd_vs_snr"].items()],
                      f"Pd at Pfa = {pfa} against SNR"))
    intervals = results.get("snr_gain_interval", {})
    gains = [[key, "—" if g is None else fmt(g["mean_gain_db"], 3),
              "—" if g is None else f"{fmt(g['pd_levels'][0], 2)}–{fmt(g['pd_levels'][-1], 2)}",
              *_interval_cells(intervals.get(key))]
             for key, g in results.get("snr_gain", {}).items()]
    if gains:
        section.add(Table(["method", "mean SNR gain over PF-TBD (dB)", "over Pd levels", "bootstrap s.e. (dB)",
                           "95 % bootstrap interval (dB)"], gains,
                          "Horizontal distance between the Pd-against-SNR curves (linear interpolation between "
                          "the simulated SNRs; — when the curves share no Pd level); its Monte Carlo spread from "
                          "resampling whole runs"))
    sweep = results.get("zeta_sweep")
    if sweep:
        sweep_snr = fmt(sweep["snr_db"])
        section.add(Figure(_sweep_figure(sweep, out_dir / "tbd_fig5_6.png"),
                           f"The paper's figures 5–6: ROC and position RMSE for ζ ∈ {{{_values(sweep['zeta'])}}} "
                           f"(N = {sweep['n_particles']}) against PF-TBD at {sweep_snr} dB."))
        rows = [[key, fmt(sweep["pd_at_pfa"][key], 3), fmt(sweep["pd_at_pfa_se"][key], 2),
                 fmt(sweep["rmse_mean"][key], 3)] for key in sweep["methods"]]
        section.add(Table(["method", f"Pd at Pfa = {pfa}", "s.e.", "position RMSE (cells)"], rows,
                          f"ζ sweep at {sweep_snr} dB"))
        section.add(Paragraph(
            "ζ = 1 replaces no particle, so TPFTBD with ζ = 1 is PF-TBD with the same N (the tests check "
            "equality for the same random stream). The paper nevertheless reports ζ = 1 at N = 1000 beating "
            "PF-TBD at N = 2000, which suggests that its reported estimate includes the second-stage mean even "
            "when no particle is transferred; we report the expected mean of the transferred particles (see the "
            "interpretations), which for ζ = 1 is the PF estimate."))
    sigmas = fmt(MONTE_CARLO_SIGMAS)
    section.add(Paragraph(
        "How the verdicts are decided. Detection comparisons (“A detects at least as well as B”, the ζ claims): "
        "the paired difference over runs of each run's Pd (the share of its target frames above the method's "
        f"threshold τ, τ set from all runs at the false-alarm rate); held when A's Pd exceeds B's by more than "
        f"{sigmas} standard errors of the difference, NOT held when it falls short by more, undecided in between "
        "(a claim made of several comparisons is NOT held when one part is, held when all are). The SNR gain: "
        "the mean horizontal distance between the Pd-against-SNR curves, with its standard error from "
        f"{results['params'].get('bootstrap', 1000)} bootstrap resamples of whole runs (the same runs for both "
        f"methods at every SNR; τ re-estimated in each); held when it exceeds the paper's 1 dB by more than "
        f"{sigmas} standard errors, NOT held when it falls short by more, undecided in between. An undecided "
        "verdict states about how many runs would decide it, were the mean and spread seen here the true ones "
        "(the tolerance shrinks as 1/√runs). Before a verdict stands, the filters it compares pass their health "
        "checks (below); otherwise it is “not decidable”. Times are CPU seconds of this implementation, in which "
        "the PF step is vectorised over particles and patch pixels, so the second stage's weighted moments over "
        "all merged particles weigh relatively more than in the paper's implementation; the timing claims compare "
        "them as paired per-sequence ratios (their geometric mean against the claimed bound, 5 standard errors of "
        "the log ratio) and are counted apart from the detection claims. Runs filtered together "
        "(reproduce --batch B) each carry their batch's CPU time divided by B; part of TPFTBD's second stage (each "
        "run's products with its overlapping particles, its Gaussian update and Cholesky factor) runs run by run "
        "while the PF stage runs on the whole batch, so its time relative to PF-TBD grows with B: the time "
        "claims are the paper's kind at B = 1."))
    section.add(*_health_blocks(results))
    claims = read_claims(results)
    section.add(*claim_tables(claims, f"Claims of {PAPERS[PAPER].short} checked"))
    section.add(*_sensitivity_blocks(claims))
    section.add(*_detection_blocks(p, claims))
    return section


#: the claim whose verdict depends most on how a detection is counted
GAIN_CLAIM = f"{NAME}/snr-gain-equal-n"


def _detection_blocks(p: Params, claims: list[ClaimRecord]) -> list:
    """How a detection is counted and how births are proposed: the definition as run, the SNR gain
    under each birth proposal (rows) read with each detection definition (columns), the reading most
    favourable to the paper, and which detection reading the paper's figures most plausibly used
    (argued from its text)."""
    gain = next((c for c in claims if c.id == GAIN_CLAIM), None)
    blocks: list = [Paragraph(f"Detection as run: '{p.detection}' — {DETECTION_READINGS[p.detection]}.")]
    grid = _gain_grid(p, gain) if gain is not None else None
    if grid is not None:
        blocks += grid
    blocks.append(Paragraph(
        "Which definition the paper's figures most plausibly used. Seed 004 never defines a detection, but its "
        "text narrows the choice. (1) Fig. 4 plots the “平均檢測概率” — the *average* detection probability — "
        "at a fixed false-alarm probability of 0.05, and Fig. 2 the ROC of the same filters: an average of a "
        "per-frame decision on the existence probability of Fig. 1, which is itself averaged frame by frame "
        "over the runs. That favours a frame-level count ('frames', 'settled', 'track') over one decision per "
        "run ('last-frame', 'run'). (2) §3.2 explains why the gain shrinks above 8 dB: there “more particles "
        "capture the true target position earlier” (較早地捕獲), so the second stage has little left to "
        "improve. Early capture changes Pd only when the acquisition frames count, i.e. when Pd runs over every "
        "frame from the target's appearance ('frames', frames 7–22), not when the first frames are left out "
        "('settled') or only the last frame counts. (3) No position gate is mentioned, and §3.2's account of the "
        "low-SNR limit — many false measurements resembling the target — is an account of false alarms, not of "
        "detections in the wrong place. The most plausible reading is therefore the one run here, 'frames'; "
        "'settled' and 'last-frame' are the detection readings most favourable to the paper, tried above with every "
        "birth proposal run, with the verdicts and run counts they need."))
    return blocks


#: a birth proposal's fields (the rows of the gain grid)
BIRTH_FIELDS = ("birth_threshold", "birth_uniform_share")


@dataclass(frozen=True)
class _Reading:
    """The SNR-gain claim under one birth proposal and detection definition."""

    birth: str
    detection: str
    verdict: str
    gain: float | None
    runs: int | None
    to_decide: int | None

    def shown(self) -> str:
        value = "—" if self.gain is None else f"{fmt(self.gain, 3)} dB"
        decide = f", about {self.to_decide} runs would decide" if self.verdict == "undecided" and self.to_decide else ""
        return f"{value}: {self.verdict}{decide}"


def _gain_grid(p: Params, gain: ClaimRecord) -> list | None:
    """The SNR-gain claim under every birth proposal × detection definition it was read with (the
    claim's own record and its interpretation entries) and the runs each rests on, with the readings'
    largest gains as bounds beside the verdict as run (:func:`_bound_paragraphs`); None when no
    detection reading was tried."""
    readable = SUMMARY_FIELDS | set(BIRTH_FIELDS) | set(GAIN_METHODS_ONLY) | {"image_exit"}
    readings = [_Reading(_birth_words(p, {}), _detection_words(p, {}), gain.verdict, gain.statistic, gain.n,
                         gain.runs_to_decide)]
    readings += [_Reading(_birth_words(p, i.params), _detection_words(p, i.params), i.verdict, i.statistic,
                          i.n, i.runs_to_decide)
                 for i in gain.interpretations if i.name != AS_RUN and set(i.params) <= readable]
    if len(readings) == 1:
        return None
    births = list(dict.fromkeys(r.birth for r in readings))
    detections = list(dict.fromkeys(r.detection for r in readings))
    cell = {(r.birth, r.detection): r for r in readings}
    runs = {b: sorted({r.runs for r in readings if r.birth == b and r.runs is not None}) for b in births}
    rows = [[f"{b} ({', '.join(str(n) for n in runs[b])} runs)",
             *(cell[(b, d)].shown() if (b, d) in cell else "—" for d in detections)] for b in births]
    blocks: list = [Table(["birth proposal", *(f"detection '{d}'" for d in detections)], rows,
                          f"The ≥ {fmt(gain.threshold)} dB SNR-gain claim under each birth proposal (rows) read "
                          "with each detection definition (columns): mean gain and the verdict under that reading "
                          "alone (each row's runs read the detection definitions differently; no runs of their "
                          "own). The first cell is the verdict as run; the others are readings, not the claim's "
                          "verdict")]
    blocks += _bound_paragraphs(p, gain, readings)
    return blocks


def _bound_paragraphs(p: Params, gain: ClaimRecord, readings: list[_Reading]) -> list:
    """The headline is the verdict as run; the readings' gains are bounds: the largest of all the
    readings tried, and the largest with the detection definition as run (said with how many
    readings each is the best of)."""
    decided = [r for r in readings if r.gain is not None]
    if not decided:
        return []
    as_run = readings[0]

    def best_of(pool: list[_Reading]) -> _Reading:
        return max(pool, key=lambda r: r.gain if r.gain is not None else -np.inf)

    def said(r: _Reading) -> str:
        decide = f"; about {r.to_decide} runs would decide it" if r.verdict == "undecided" and r.to_decide else ""
        return (f"{fmt(r.gain, 3)} dB (birth proposal '{r.birth}', detection '{r.detection}', {r.runs} runs; that "
                f"reading alone: {r.verdict}{decide})")

    best = best_of(decided)
    framed = [r for r in decided if r.detection == as_run.detection]
    out = [Paragraph(
        f"The headline is the verdict as run — birth proposal '{as_run.birth}', detection '{as_run.detection}': "
        f"{fmt(as_run.gain, 3)} dB, {gain.verdict}. The most favourable of the {len(readings)} readings tried "
        f"reaches {said(best)}: a bound on what the paper's unstated choices can give, not a verdict — the largest "
        f"of {len(readings)} gains leans towards the paper"
        + (", and the detection it uses is one this page argues the paper's figures did not use" if
           best.detection != as_run.detection else "") + ".")]
    if framed and best_of(framed) is not as_run and best.detection != as_run.detection:
        out.append(Paragraph(
            f"With the detection definition as run ('{as_run.detection}'), the most favourable of the "
            f"{len(framed)} readings reaches {said(best_of(framed))}."))
    return out


def _detection_words(p: Params, changes: dict) -> str:
    """The detection definition of a reading with the setting it takes (the run's own where
    ``changes`` leave it): 'settled' with its frames left out, 'track' with its gate."""
    detection = changes.get("detection", p.detection)
    if detection == "settled":
        return f"settled, {changes.get('settle_frames', p.settle_frames)} frames"
    if detection == "track":
        return f"track, gate {fmt(changes.get('detection_gate', p.detection_gate))}"
    return detection


def _birth_words(p: Params, changes: dict) -> str:
    """The birth proposal of a reading (the run's own where ``changes`` leave it) in words."""
    threshold = changes.get("birth_threshold", p.birth_threshold)
    share = changes.get("birth_uniform_share", p.birth_uniform_share)
    words = ("uniform over the image" if share >= 1.0 else f"cells above {fmt(threshold)}σ, {fmt(100 * share)} % "
             "uniform")
    if changes.get("image_exit", p.image_exit) != p.image_exit:
        words += f"; a particle leaving the image {changes['image_exit']}"
    return words


def _interval_cells(interval: dict | None) -> list[str]:
    if not interval or interval.get("se") is None:
        return ["—", "—"]
    return [fmt(interval["se"], 3), f"[{fmt(interval['low'], 3)}, {fmt(interval['high'], 3)}]"]


def _health_blocks(results: dict) -> list:
    """The health checks of every method at every SNR: one row per method, the median N_eff/N, the
    diverged runs and the track loss per SNR; the failed checks spelled out."""
    health = results.get("health")
    if not health:
        return [Paragraph("No health checks were recorded for this run (written before they existed).")]
    snrs = sorted({h["snr_db"] for h in health})
    rows: dict[str, dict[float, str]] = {}
    failed = []
    for h in health:
        checks = {c["name"]: c for c in h["checks"]}
        ess = checks.get("weight collapse")
        div = checks["divergence"]
        cell = (f"{'—' if ess is None else fmt(ess['statistic'], 2)} / {fmt(div['statistic'], 2)} / "
                f"{fmt(h['track_loss'], 2)}")
        rows.setdefault(h["method"], {})[h["snr_db"]] = cell + ("" if all(c["passed"] for c in h["checks"]) else " ✗")
        failed += [f"{c['subject']}: {c['name']} — {c['detail']}" for c in h["checks"] if not c["passed"]]
    table = Table(["method"] + [f"{fmt(s)} dB" for s in snrs],
                  [[key] + [cells.get(s, "") for s in snrs] for key, cells in rows.items()],
                  f"Health checks: median N_eff/N over the target frames (collapsed at or below "
                  f"{fmt(MIN_ESS_FRACTION)}) / share of runs diverged (estimate not finite or off the image; healthy: "
                  f"0) / share of runs whose position error in the target's last frame exceeds "
                  f"{fmt(results['params'].get('track_loss_distance', 2.0))} cells (track loss, reported, not a "
                  "check: at low SNR it is the missed detection the claims measure); ✗ marks a failed check")
    text = ("Every filter passed its health checks in every configuration run here (N_eff/N not collapsed, no "
            "divergence), so the verdicts rest on working filters." if not failed else
            "Failed health checks (the verdicts resting on these filters are withheld as not decidable): "
            + "; ".join(failed) + ".")
    return [table, Paragraph(text)]


def grid_only(params: dict) -> bool:
    """A reading shown in the birth × detection grid alone: another birth proposal (or rule for a
    particle leaving the image) read with another detection definition (its verdicts are there; the
    sensitivity tables keep the runs' own readings)."""
    return bool(set(params) & {*BIRTH_FIELDS, "image_exit"}) and bool(set(params) & SUMMARY_FIELDS)


def _sensitivity_blocks(claims: list[ClaimRecord]) -> list:
    """Per claim, its verdict as run and under each interpretation tried (with the statistic), the
    robustness sentence and the runs that would decide an undecided verdict (the readings of the
    birth × detection grid in the grid only)."""
    claims = [replace(c, interpretations=tuple(i for i in c.interpretations if not grid_only(i.params)))
              for c in claims]
    tried = [c for c in claims if c.interpretations]
    if not tried:
        return [Paragraph("No interpretation was tried for this run (`gpfverify reproduce tbd --interpretations "
                          "all` tries " + ", ".join(s.name for s in INTERPRETATIONS) + ").")]
    names = list(dict.fromkeys(i.name for c in tried for i in c.interpretations if i.name != AS_RUN))
    why = {s.name: s.why for s in INTERPRETATIONS}
    blocks: list = [Table(["interpretation", "parameters changed", "why it is plausible"],
                          [[name, ", ".join(f"{k} = {v}" for k, v in next(i.params for c in tried
                                                                           for i in c.interpretations
                                                                           if i.name == name).items()),
                            why.get(name, "")] for name in names],
                          "Interpretations tried (each a full run of the experiment with the same seed, except the "
                          "detection definitions, which read the main run's runs)")]
    blocks.append(interpretations_table(tried, "Verdicts (statistic) under each interpretation tried, as the "
                                               "claims table states them"))
    return blocks


def _reduced_note(results: dict, p: Params) -> str:
    """A warning when the run used fewer runs, particles or SNRs than the paper."""
    paper = Params()
    reduced = [words for name, words in REDUCIBLE.items() if getattr(p, name) != getattr(paper, name)]
    if not reduced and results["runs"] >= PAPER_RUNS:
        return ""
    return (f" Reduced settings (e.g. the report's quick profile): {results['runs']} runs instead of {PAPER_RUNS}"
            + (f", other {', '.join(reduced)}" if reduced else "")
            + ", so the numbers are noisier"
            + (" and the second stage's fixed per-frame cost weighs more in the time ratios"
               if p.particles < paper.particles else "")
            + "; `gpfverify report --full` uses the paper's settings.")


def _plot_curves(ax, curves: dict, ylabel: str) -> None:
    for i, (key, values) in enumerate(curves.items()):
        y = np.array([np.nan if v is None else v for v in values], dtype=float)
        ax.plot(np.arange(1, y.size + 1), y, color=_colour(key, i), marker=".", label=key)
    ax.set_xlabel("frame")
    ax.set_ylabel(ylabel)


def _colour(key: str, index: int) -> str:
    """PF-TBD in black, the TPFTBD variants in the colour cycle."""
    return "k" if TbdMethod.parse(key).kind == "PFTBD" else f"C{index}"


def _plot_roc(ax, roc: dict) -> None:
    for i, (key, curve) in enumerate(roc.items()):
        ax.plot(curve["pfa"], curve["pd"], color=_colour(key, i), label=key)
    ax.set_xscale("symlog", linthresh=0.01)
    ax.set_xlim(0, 1)
    ax.set_xlabel("false-alarm probability")
    ax.set_ylabel("detection probability")


def _main_figure(results: dict, p: Params, path: Path) -> Path:
    fig, axes = new_figure(2, 2, width=5.2, height=3.6)
    ax = axes[0, 0]
    _plot_curves(ax, results["existence_prob"], "existence probability")
    for i, (key, values) in enumerate(results["existence_prob_absent"].items()):
        ax.plot(np.arange(1, len(values) + 1), values, color=_colour(key, i), ls="--", lw=0.8)
    ax.legend(fontsize=8)
    _plot_roc(axes[0, 1], results["roc"])
    axes[0, 1].legend(fontsize=8)
    _plot_curves(axes[1, 0], results["rmse"], "position RMSE (cells)")
    ax = axes[1, 1]
    for i, (key, values) in enumerate(results["pd_vs_snr"].items()):
        ax.errorbar(results["snr_db"], values, yerr=results["pd_vs_snr_se"][key], color=_colour(key, i),
                    marker="o", capsize=2, label=key)
    ax.set_xlabel("SNR (dB)")
    ax.set_ylabel(f"Pd at Pfa = {fmt(p.pfa)}")
    ax.legend(fontsize=8)
    return save(fig, path)


def _sweep_figure(sweep: dict, path: Path) -> Path:
    fig, axes = new_figure(2, 1, width=5.2, height=3.6)
    _plot_roc(axes[0, 0], sweep["roc"])
    axes[0, 0].legend(fontsize=8)
    _plot_curves(axes[0, 1], sweep["rmse"], "position RMSE (cells)")
    axes[0, 1].legend(fontsize=8)
    return save(fig, path)
