"""Shared pieces of the fusion paper's report pages (``ct2d`` and ``ungm1d``): paired Monte Carlo
verdicts, the equivalence and rank-failure-audit tables, and the paper-style figures."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gpfverify.experiments.fusion_run import FAMILIES, LOCAL_FILTERS, METHODS, RULES
from gpfverify.report.document import Claim, Table, fmt
from gpfverify.report.figures import new_figure, save
from gpfverify.tolerances import monte_carlo_atol

_MARKERS = {"Sensor1": "", "Sensor2": "", "CMF": "D", "DMF": "*", "RCC-CI": "^", "CW": "s"}
_STYLE = {"GP-ADF": "-", "GP-UKF": "-."}
FUSION_METHODS = tuple(m for m in METHODS if not m.startswith("Sensor"))


def out_dir(ctx_or_dir, slug: str) -> Path:
    return ctx_or_dir.section_dir(slug) if hasattr(ctx_or_dir, "section_dir") else Path(ctx_or_dir)


def failed_runs_note(results_by_label: dict) -> str:
    """'' when every run succeeded, else which runs failed and why (they are left out of every number)."""
    failed = [f"{label} run {f['index']} ({f['error']})" for label, r in results_by_label.items()
              for f in r.get("failed_runs", [])]
    return "" if not failed else ". Failed runs, left out of every number: " + "; ".join(failed)


def paired(per_run: dict, better: str, worse: str) -> tuple[bool | None, float, float]:
    """Is ``better``'s per-run mean error below ``worse``'s? Paired difference d = better − worse
    over runs: held if mean(d) < −atol, NOT held if mean(d) > atol, else undecided, with
    atol = monte_carlo_atol(std d, runs). Returns (verdict, mean d, atol)."""
    d = np.asarray(per_run[better]) - np.asarray(per_run[worse])
    if d.size < 2:
        return None, float(np.mean(d)), float("nan")
    atol = float(monte_carlo_atol(np.std(d, ddof=1), d.size))
    mean = float(np.mean(d))
    return (True if mean < -atol else False if mean > atol else None), mean, atol


def combine(verdicts: list[bool | None]) -> bool | None:
    """All held -> held; any NOT held -> NOT held; otherwise undecided."""
    if any(v is False for v in verdicts):
        return False
    return True if all(v is True for v in verdicts) else None


def comparison_claim(text: str, per_run: dict, pairs: list[tuple[str, str]], unit: str) -> Claim:
    parts, verdicts = [], []
    for better, worse in pairs:
        verdict, mean, atol = paired(per_run, better, worse)
        verdicts.append(verdict)
        parts.append(f"{better} − {worse}: {fmt(mean, 3)} ± {fmt(atol, 2)} {unit}")
    return Claim(text, combine(verdicts), "; ".join(parts) + " (mean paired difference over runs ± 5 s.e.)")


def fusion_beats_sensors(per_run: dict, family: str, unit: str) -> Claim:
    pairs = [(f"{f}-{family}", f"Sensor{m}-{family}") for f in ("CMF", "DMF") for m in (1, 2)]
    return comparison_claim(f"{family}: CMF and DMF beat each single sensor", per_run, pairs, unit)


def fusion_beats_baselines(per_run: dict, family: str, unit: str) -> Claim:
    pairs = [(f"{f}-{family}", f"{b}-{family}") for f in ("CMF", "DMF") for b in ("RCC-CI", "CW")]
    return comparison_claim(f"{family}: CMF and DMF beat RCC-CI and CW", per_run, pairs, unit)


def equivalence_claim(results: dict, family: str, metric: str = "rmse") -> Claim:
    """DMF = CMF on the steps where every C_xy^m has full column rank (one-step gap to rounding);
    the evidence also gives the largest difference of the two filters' ``metric`` curves."""
    g = results["one_step_gap"][family]
    curves = np.abs(np.subtract(results[metric][f"DMF-{family}"], results[metric][f"CMF-{family}"]))
    n, ok = g["steps_full_rank"], g["full_rank_steps_within_rounding"]
    held = None if n == 0 else ok == n
    outside = g.get("max_smallest_singular_value_outside_rounding")
    why = "" if outside is None else (
        f"; on the {n - ok} full-rank steps outside rounding the smaller σ_min(C_xy^m) of the two sensors was at "
        f"most {fmt(outside, 3)}: a cross term that small counts as full rank for the σ_max-relative rule, yet "
        "its pseudo-inverse in eq. 35 amplifies the rounding of μ_e^m − μ_p^m")
    return Claim(f"{family}: DMF = CMF when the rank condition holds (eq. 35 from the same central "
                 "prediction)", held,
                 f"{ok} of {n} full-rank steps within rounding ({g['rounding_rule']}); max gap "
                 f"{fmt(g['max_when_full_rank'], 3)} (relative to the update "
                 f"{fmt(g['max_relative_when_full_rank'], 3)}); "
                 f"recursive filters: max ‖μ_DMF − μ_CMF‖ = {fmt(results['max_equivalence_gap'][family], 3)}, "
                 f"rounding amplification of one step {fmt(results['rounding_sensitivity'][family]['median'], 3)} "
                 f"(median) for a {results['rounding_sensitivity'][family]['probe']:g} relative nudge; "
                 f"largest |DMF − CMF| of the {metric} curves {fmt(float(curves.max()), 3)}{why}")


def equivalence_table(results_by_label: dict) -> Table:
    rows = []
    for label, r in results_by_label.items():
        for family in FAMILIES:
            g, a = r["one_step_gap"][family], r["rank_failure_audit"]["by_family"][family]
            rows.append([label, family, g["steps_full_rank"], g["full_rank_steps_within_rounding"],
                         fmt(g["max_when_full_rank"], 3), fmt(r["max_equivalence_gap"][family], 3),
                         fmt(r["rounding_sensitivity"][family]["median"], 3), a["steps"], a["exact"],
                         fmt(a["max_gap_norm"], 3), fmt(a["max_gap_error"], 3)])
    return Table(["setting", "family", "full-rank steps", "DMF = CMF to rounding", "max one-step gap",
                  "max recursive gap", "1-step rounding amplification", "rank-fail steps",
                  "of which exact", "max gap there", "max |gap − predicted|"], rows,
                 "DMF vs CMF: one-step gap (eq. 35 against CMF from the same central prediction), the gap "
                 "between the two recursive filters, and the audit of rank-failure steps")


def audit_table(results_by_label: dict, limit: int = 20) -> Table:
    rows = []
    for label, r in results_by_label.items():
        for e in r["rank_failure_audit"]["entries"][:limit]:
            sv = "; ".join(f"S{s['index'] + 1}: rank {s['rank']}/{s['cols']}, σ = "
                           + ", ".join(fmt(v, 3) for v in s["singular_values"]) for s in e["sensors"])
            rows.append([label, e["run"], e["step"], e["family"], sv, fmt(e["gap_norm"], 3),
                         fmt(e["predicted_gap_norm"], 3), fmt(e["gap_error"], 2), str(e["exact"])])
    return Table(["setting", "run", "step", "family", "C_xy^m ranks and singular values", "‖gap‖",
                  "‖predicted gap‖", "‖gap − predicted‖", "exact"], rows,
                 f"Rank-failure audit (first {limit} steps per setting; totals in the table above)")


def method_table(results: dict, metric: str, unit: str) -> Table:
    rows = [[m, fmt(float(np.mean(results[metric][m])), 4), fmt(results[metric][m][-1], 4),
             fmt(1e3 * results["time_per_step"][m], 3), fmt(results["time_per_run"][m], 3)] for m in METHODS]
    return Table(["method", f"mean over steps ({unit})", "last step", "ms per step", "s per run"], rows)


def plot_per_step(series: dict, ylabel: str, title: str, path: Path, log: bool = False,
                  methods=METHODS) -> Path:
    fig, axes = new_figure(1, 1, width=8.0, height=4.8)
    ax = axes[0, 0]
    for method in methods:
        rule, family = method.rsplit("-GP-", 1)[0], "GP-" + method.rsplit("-GP-", 1)[1]
        colour = f"C{RULES.index(rule)}"
        ax.plot(np.arange(1, len(series[method]) + 1), series[method], _STYLE[family],
                marker=_MARKERS[rule] or None, markevery=5, ms=5, color=colour, lw=1.2, label=method)
    if log:
        ax.set_yscale("log")
    ax.set_xlabel("time step")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=7, ncol=2)
    return save(fig, path)


def plot_full_rank(results: dict, title: str, path: Path) -> Path:
    fig, axes = new_figure(2, 1, width=5.6, height=4.0)
    ax = axes[0, 0]
    for i, name in enumerate(LOCAL_FILTERS):
        ratio = 100 * np.asarray(results["full_rank_ratio"][name])
        ax.plot(np.arange(1, ratio.size + 1), ratio, "-" if "ADF" in name else "-.", color=f"C{i}", label=name)
    ax.set_ylim(-5, 105)
    ax.set_xlabel("time step")
    ax.set_ylabel("full column rank of C_xy^m (%)")
    ax.set_title(f"{title}\n(tolerance: σ_max · max(D, l) · eps)", fontsize=9)
    ax.legend(fontsize=7)
    ax = axes[0, 1]
    by_tol = results["full_rank_ratio_by_relative_tolerance"]
    tols = sorted(by_tol, key=float)
    for i, name in enumerate(LOCAL_FILTERS):
        ax.semilogx([float(t) for t in tols], [100 * np.mean(by_tol[t][name]) for t in tols],
                    "-o" if "ADF" in name else "-.s", color=f"C{i}", label=name)
    ax.set_ylim(-5, 105)
    ax.set_xlabel("relative tolerance: full rank iff σ_min > tol · σ_max")
    ax.set_ylabel("full-rank ratio, mean over steps (%)")
    ax.set_title("dependence on the rank tolerance", fontsize=9)
    return save(fig, path)
