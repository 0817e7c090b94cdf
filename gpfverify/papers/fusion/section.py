"""Shared pieces of the fusion paper's report pages (``ct2d`` and ``ungm1d``): the equivalence and
rank-failure-audit tables, the per-method table and the paper-style figures. Renders
``results.json`` data only; methods are :class:`~gpfverify.contract.methods.Method` values read
back with :meth:`Method.parse`."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from gpfverify.papers.fusion.contract import FAMILIES, LOCAL_FILTERS, METHODS
from gpfverify.contract.interpretations import InterpretationSpec
from gpfverify.contract.methods import Method
from gpfverify.report.document import Cell, Paragraph, Table, fmt
from gpfverify.report.figures import new_figure, save

#: each family its own colour family and line style (GP-ADF: solid, blues and greens; GP-UKF:
#: dash-dotted, reds and browns), each rule its marker as in the paper's figures
_COLOURS = {
    "GP-ADF": {"Sensor1": "#74c476", "Sensor2": "#238b45", "CMF": "#08306b", "DMF": "#4292c6",
               "RCC-CI": "#6a51a3", "CW": "#17becf"},
    "GP-UKF": {"Sensor1": "#fdae6b", "Sensor2": "#e6550d", "CMF": "#a50f15", "DMF": "#fb6a4a",
               "RCC-CI": "#c51b7d", "CW": "#8c6d31"},
}
_MARKERS = {
    "GP-ADF": {"CMF": "D", "DMF": "*", "RCC-CI": "^", "CW": "s"},
    "GP-UKF": {"CMF": "o", "DMF": "x", "RCC-CI": "v", "CW": "+"},
}
_LINES = {"GP-ADF": "-", "GP-UKF": "-."}


def _rule(method: Method) -> str:
    return f"{method.rule}{method.sensor}" if method.is_sensor else method.rule


def method_style(method: Method) -> dict:
    """Matplotlib style of a method's curve: colour, line style, marker."""
    family = method.family or "GP-ADF"
    return {"color": _COLOURS[family][_rule(method)], "linestyle": _LINES[family],
            "marker": _MARKERS[family].get(_rule(method)) or None}


def failed_runs_note(results_by_label: dict) -> str:
    """'' when every run succeeded, else which runs failed and why (they are left out of every number)."""
    failed = [f"{label} run {f['index']} ({f['error']})" for label, r in results_by_label.items()
              for f in r.get("failed_runs", [])]
    return "" if not failed else ". Failed runs, left out of every number: " + "; ".join(failed)


def equivalence_table(results_by_label: dict) -> Table:
    rows = []
    for label, r in results_by_label.items():
        for family in FAMILIES:
            g, a = r["one_step_gap"][family], r["rank_failure_audit"]["by_family"][family]
            rows.append([label, family, g["steps_full_rank"], g["full_rank_steps_reproduced"],
                         g["full_rank_steps_unresolved"], g["full_rank_steps_outside"],
                         fmt(g["max_when_full_rank"], 3), fmt(r["max_equivalence_gap"][family], 3),
                         fmt(r["rounding_sensitivity"][family]["median"], 3), a["steps"], a["exact"],
                         fmt(a["max_gap_norm"], 3), fmt(a["max_gap_error"], 3)])
    return Table(["setting", "family", "full-rank steps", "DMF = CMF to rounding", "unresolved", "beyond rounding",
                  "largest one-step gap", "largest recursive gap", "one-step rounding amplification",
                  "rank-failure steps", "of which exact", "largest gap there", "largest ‖gap − predicted‖"], rows,
                 "DMF against CMF: the one-step gap (eq. 35 against CMF from the same central prediction) judged as "
                 "the audit judges a step — reproduced when within the step's rounding bound, unresolved when that "
                 "bound exceeds √eps prior standard deviations —, the gap between the two recursive filters, and the "
                 "audit of the steps where the rank condition failed")


def rank_rules_table(readings: dict[str, dict[str, dict]]) -> Table:
    """Proposition 1 step by step under each rank rule read: ``readings`` maps a reading ("canonical,
    as run, 1000 runs", "numpy-rank, 100 runs") to ``{setting label: {family: one_step_gap}}`` (the
    ``"one_step_gap"`` summaries of its results.json)."""
    rows = []
    for reading, by_label in readings.items():
        for label, gaps in by_label.items():
            for family in FAMILIES:
                g = gaps[family]
                rows.append([reading, label, family, g["steps_full_rank"], g["full_rank_steps_reproduced"],
                             g["full_rank_steps_unresolved"], g["full_rank_steps_outside"],
                             fmt(g["max_gap_size_unresolved"], 3), fmt(g["max_gap_bound_unresolved"], 3),
                             fmt(g["max_when_full_rank"], 3)])
    return Table(["reading", "setting", "family", "full-rank steps", "DMF = CMF to rounding", "unresolved",
                  "beyond rounding", "largest unresolved gap (prior SD)", "its rounding bound up to",
                  "largest one-step ‖μ(DMF) − μ(CMF)‖"], rows,
                 "Proposition 1 under each rank rule: the full-rank steps of eq. 35 against CMF from the same central "
                 "prediction, as run (the canonical rule) and under numpy's rule; an unresolved step is one whose "
                 "rounding bound exceeds √eps prior standard deviations")


def audit_table(results_by_label: dict, limit: int = 20) -> Table:
    rows = []
    for label, r in results_by_label.items():
        for e in r["rank_failure_audit"]["entries"][:limit]:
            sv = "; ".join(f"sensor {s['index'] + 1}: rank {s['rank']}/{s['cols']}, σ = "
                           + ", ".join(fmt(v, 3) for v in s["singular_values"]) for s in e["sensors"])
            rows.append([label, e["run"], e["step"], e["family"], sv, fmt(e["gap_norm"], 3),
                         fmt(e["predicted_gap_norm"], 3), fmt(e["gap_error"], 2), str(e["exact"])])
    return Table(["setting", "run", "step", "family", "ranks and singular values of Cₓᵧᵐ", "‖gap‖",
                  "‖predicted gap‖", "‖gap − predicted‖", "exact"], rows,
                 f"Rank-failure audit (the first {limit} steps per setting; totals in the table above)")


def health_table(results_by_label: dict) -> Table | None:
    """The health checks of every setting (divergence and NEES per method), None without any."""
    rows = []
    for label, r in results_by_label.items():
        checks = {(h["subject"], h["name"]): h for h in r.get("health", [])}
        for m in METHODS:
            div, nees = checks.get((m.key, "divergence")), checks.get((m.key, "NEES"))
            if div is None or nees is None:
                continue
            rows.append([label, m.key, Cell("passed" if div["passed"] else "FAILED", "v-held" if div["passed"]
                                            else "v-not-held", div["detail"]),
                         Cell("consistent" if nees["passed"] else nees["detail"].split(":")[0],
                              "v-held" if nees["passed"] else "v-undecided", nees["detail"]),
                         fmt(nees["statistic"], 3), fmt(nees["threshold"])])
    if not rows:
        return None
    return Table(["setting", "method", "divergence", "NEES (ANEES per step against its χ² interval)",
                  "mean ANEES", "expected (D)"], rows,
                 "Health of the filters compared: divergence of any run, and NEES consistency where the truth is "
                 "known")


def health_paragraph(policy: str) -> Paragraph:
    """How the health checks enter the verdicts (the policy the claims applied)."""
    return Paragraph(
        "Health checks before a verdict stands: a filter that diverged in some run (error above the bound or not "
        "finite) makes every comparison it is part of 'not decidable'. " + policy + ". The NEES of a "
        "consistent Gaussian filter has mean D; 'optimistic' means over-confident (errors large against the "
        "filter's own covariance).")


def interpretations_paragraph(specs: Sequence[InterpretationSpec], option: str) -> Paragraph:
    """The interpretations an experiment tries besides its defaults, each with its parameter changes
    and why; ``option`` is the ``--interpretations`` value the page's command uses."""
    return Paragraph(
        "Interpretations tried besides the defaults (each a set of parameter changes, run with the same seeds "
        f"and run count; `--interpretations {option}`): "
        + "; ".join(f"{spec.name} ({', '.join(f'{k} = {v}' for k, v in spec.changes.items())}): {spec.why}"
                    for spec in specs) + ".")


def rank_rule_paragraph(results_by_label: dict) -> Paragraph:
    """Which rank rule decided eq. 35 in the runs shown, how a full-rank step is judged, and why
    numpy's rule is an interpretation."""
    rules = sorted({r["rank_tolerance"] for r in results_by_label.values()})
    return Paragraph(
        "Rank rule of eq. 35 in the runs shown: " + "; ".join(rules) + ". The paper does not say how it decides "
        "rank(Cₓᵧᵐ). Proposition 1's verdicts are judged under the project's one rule, the canonical correlations "
        "of state and sensor output under the sensor's predicted joint above τ = √eps (gpfverify.fusion.exactness): "
        "unit-free, the default of check and audit. Each full-rank step is judged as the audit judges a step: eq. 35 "
        "reproduces CMF from the same central prediction when their gap, in prior standard deviations, lies within "
        "the step's own rounding bound — which grows with the conditioning of eq. 35's reconstruction, the "
        "pseudo-inverse of Cₓᵧᵐ; a step whose bound exceeds √eps prior standard deviations cannot be resolved by "
        "the arithmetic and decides nothing (the claim's caveat counts such steps). The interpretation 'numpy-rank' "
        "re-runs the experiment with numpy's/MATLAB's rank() rule, σ > σ_max · max(D, l) · eps — perhaps the "
        "paper's. That rule depends on units, and with a 1 × 1 cross term (the 1-D example) it calls any nonzero "
        "value full rank: a cross covariance near zero then counts as full rank, and its inverse in eq. 35 "
        "multiplies the rounding of μₑᵐ − μₚᵐ by 1/Cₓᵧᵐ, so DMF can leave CMF by a large fraction of the state's "
        "spread on a step where the condition is said to hold. The rounding bound explains such a gap, and the step "
        "is unresolved rather than a counterexample: a verdict on the rank rule, not on Proposition 1, whose proof "
        "assumes exact arithmetic. The canonical rule drops such a correlation (below τ). The rule also changes DMF "
        "itself where a correlation is dropped, so every claim is re-decided under it.")


def time_words(results: dict) -> str:
    """What the times on the page are (the runs' clock) and the load the runs met."""
    clock = results.get("time_clock")
    if clock is None:  # runs timed before the CPU clock
        return "wall-clock time on the machine that made the runs (a busy machine inflates it)."
    words = (f"{clock} — a busy machine perturbs it far less than wall time; the timing claims compare the methods' "
             "CPU times within each run, as paired per-run ratios, and are counted apart from the accuracy claims.")
    load = results.get("machine_load") or {}
    if load.get("runs_batched"):
        words += (f" {load['runs_batched']} of the runs advanced together with others, in batches of up to "
                  f"{load['largest_batch']} (docs/cluster.md): there a method's time per step is the batch's CPU time "
                  "divided by its size, the same for every run of the batch, so the ratios the timing claims pair are "
                  "the batch's; the filters, fusion rules and audit were batched, each run's GP learning was not "
                  "(its own L-BFGS path, timed on its own).")
    return words


def load_words(results: dict) -> str:
    """The machine load the runs met (results.json's ``machine_load``), in words."""
    load = results.get("machine_load") or {}
    average = load.get("load_average") or []
    if len(average) != 3:
        return "machine load not recorded"
    cpus = f" on {load['cpus']} CPUs" if load.get("cpus") else ""
    return (f"machine load {' / '.join(f'{v:.2f}' for v in average)}{cpus} (1, 5, 15 min; median over "
            f"{load.get('runs_measured', 0)} runs)")


def method_table(results: dict, metric: str, unit: str, caption: str = "") -> Table:
    rows = [[m.key, fmt(float(np.mean(results[metric][m.key])), 4), fmt(results[metric][m.key][-1], 4),
             fmt(1e3 * results["time_per_step"][m.key], 3), fmt(results["time_per_run"][m.key], 3)] for m in METHODS]
    clock = "CPU" if results.get("time_clock") else "wall-clock"
    return Table(["method", f"mean over steps ({unit})", "last step", f"{clock} ms per step", f"{clock} s per run"],
                 rows, caption)


def plot_per_step(series: dict, ylabel: str, title: str, path: Path, log: bool = False,
                  methods: Sequence[Method] = METHODS) -> Path:
    """One curve per method (GP-ADF methods first: the legend's first column)."""
    fig, axes = new_figure(1, 1, width=9.5, height=4.8)
    ax = axes[0, 0]
    for method in methods:
        values = series[method.key]
        ax.plot(np.arange(1, len(values) + 1), values, markevery=max(1, len(values) // 10), ms=5, lw=1.2,
                label=method.key, **method_style(method))
    if log:
        ax.set_yscale("log")
    ax.set_xlabel("time step")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(ncol=2, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return save(fig, path)


def plot_full_rank(results: dict, title: str, path: Path) -> Path:
    fig, axes = new_figure(2, 1, width=5.6, height=4.0)
    ax = axes[0, 0]
    for method in LOCAL_FILTERS:
        ratio = 100 * np.asarray(results["full_rank_ratio"][method.key])
        ax.plot(np.arange(1, ratio.size + 1), ratio, label=method.key, **method_style(method))
    ax.set_ylim(-5, 105)
    ax.set_xlabel("time step")
    ax.set_ylabel("full column rank of Cₓᵧᵐ (%)")
    rule = ("canonical correlations > √eps" if "canonical" in results.get("rank_tolerance", "")
            else "σ_max · max(D, l) · eps")
    ax.set_title(f"{title}\n(rank rule: {rule})", fontsize=9)
    ax.legend()
    ax = axes[0, 1]
    by_tol = results["full_rank_ratio_by_relative_tolerance"]
    tols = sorted(by_tol, key=float)
    for method in LOCAL_FILTERS:
        style = {**method_style(method), "marker": "o" if method.family == "GP-ADF" else "s"}
        ax.semilogx([float(t) for t in tols], [100 * np.mean(by_tol[t][method.key]) for t in tols],
                    label=method.key, **style)
    ax.set_ylim(-5, 105)
    ax.set_xlabel("relative tolerance: full rank iff σ_min > tol · σ_max")
    ax.set_ylabel("full-rank ratio, mean over steps (%)")
    ax.set_title("dependence on the rank tolerance", fontsize=9)
    return save(fig, path)
