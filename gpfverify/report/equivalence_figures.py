"""Figures of the equivalence report (:mod:`gpfverify.report.equivalence`): matplotlib (Agg) plots
drawn from arrays only — the one-step gap against its rounding bound, the rank/exactness strip,
RMSE, ANEES/NIS with their χ² bands, the recursive drift, the smallest canonical correlations."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.colors import ListedColormap

from gpfverify.report.figures import new_figure
from gpfverify.report.figures import save as _save

#: runs drawn one line each; with more, the median and the min–max range
MAX_RUN_LINES = 5
#: pixels per inch of a compact view's figure (a notebook shows it at its own size: its 10 pt text at
#: 11 px), a third of the bytes of the pages' (gpfverify.report.figures.DPI)
COMPACT_DPI = 80
#: strip categories: full column rank (exact), rank lost but exact, not exact
VERDICT_COLORS = ("#4daf4a", "#ffbf00", "#e41a1c")
VERDICT_LABELS = ("full column rank", "rank lost, exact anyway", "not exact")


def _log_steps_axes(ax, ylabel: str, title: str) -> None:
    """Log y-axis over the steps k, labels, the legend right of the plot, a light grid."""
    ax.set_yscale("log")
    ax.set_xlabel("step k")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    ax.grid(True, which="major", alpha=0.3)


def save(fig, path: Path, dpi: int | None = None) -> Path:
    """Save with integer step ticks on every x axis labelled 'step k' (at ``dpi``, default the pages')."""
    from matplotlib.ticker import MaxNLocator

    for ax in fig.axes:
        if ax.get_xlabel() == "step k" or ax.get_title().startswith(("rank verdict", "fraction", "ANIS", "ANEES")):
            ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    return _save(fig, path) if dpi is None else _save(fig, path, dpi=dpi)


def log_floor(*arrays) -> float:
    """A positive value under every positive entry: where zeros are drawn on a log axis."""
    values = np.concatenate([np.ravel(np.asarray(a, dtype=float)) for a in arrays])
    positive = values[np.isfinite(values) & (values > 0)]
    return float(positive.min() / 10) if positive.size else 1e-17


def _runs_plot(ax, ks, values: np.ndarray, color: str, label: str, floor: float | None = None,
               linestyle: str = "-", run_labels=None) -> None:
    """(R, T) values against ks: one line per run (few runs) or median and range (many)."""
    values = np.asarray(values, dtype=float)
    if floor is not None:
        values = np.where(values > 0, values, floor)
    if values.shape[0] <= MAX_RUN_LINES:
        for r, row in enumerate(values):
            tag = label if values.shape[0] == 1 else f"{label}, run {run_labels[r] if run_labels else r}"
            ax.plot(ks, row, linestyle, color=color, alpha=1.0 if r == 0 else 0.55, lw=1.2, label=tag,
                    marker="." if len(ks) <= 60 else None, ms=3)
    else:
        ax.plot(ks, np.median(values, axis=0), linestyle, color=color, lw=1.5, label=f"{label}, median of runs")
        ax.fill_between(ks, values.min(axis=0), values.max(axis=0), color=color, alpha=0.2,
                        label=f"{label}, range over runs")


#: the one-step gap as the check pages plot it (unit-free) and as a run file's audit does (state units)
GAP_IN_PRIOR_SD = ("‖L_p⁻¹(μ_DMF − μ_CMF)‖", "one-step gap (prior standard deviations)")
GAP_IN_STATE_UNITS = ("‖μ_DMF − μ_CMF‖", "one-step gap (state units)")


def plot_gap(ks, gap: np.ndarray, bound: np.ndarray | None, inexact: np.ndarray, path: Path, run_labels=None,
             predicted: np.ndarray | None = None, quantity: tuple[str, str] = GAP_IN_PRIOR_SD,
             dpi: int | None = None) -> tuple[Path, float]:
    """The one-step gap per step against the rounding bound, log scale; steps judged not exact
    marked. ``gap``/``bound``/``inexact`` are (R, T); ``quantity`` names what ``gap`` holds (legend,
    axis): :data:`GAP_IN_PRIOR_SD` or :data:`GAP_IN_STATE_UNITS`. Returns the path and the floor
    where zeros are drawn."""
    floor = log_floor(*[a for a in (gap, bound, predicted) if a is not None])
    fig, axes = new_figure(width=9.0, height=4.2)
    ax = axes[0, 0]
    if bound is not None:
        _runs_plot(ax, ks, bound, "0.45", "rounding bound", floor, "--", run_labels)
    if predicted is not None:
        _runs_plot(ax, ks, predicted, "tab:orange", "predicted gap (closed form)", floor, ":", run_labels)
    _runs_plot(ax, ks, gap, "tab:blue", quantity[0], floor, "-", run_labels)
    rows, cols = np.nonzero(inexact)
    if rows.size:
        shown = np.where(gap[rows, cols] > 0, gap[rows, cols], floor)
        ax.scatter(np.asarray(ks)[cols], shown, s=22, facecolors="none", edgecolors="tab:red", zorder=5,
                   label="step judged not exact")
    _log_steps_axes(ax, quantity[1], "DMF − CMF from the same central prediction")
    return save(fig, path, dpi), floor


def verdict_codes(full_rank: np.ndarray, exact: np.ndarray) -> np.ndarray:
    """0 full column rank (and exact), 1 rank lost but exact, 2 not exact."""
    full_rank, exact = np.asarray(full_rank, bool), np.asarray(exact, bool)
    return np.where(~exact, 2, np.where(full_rank, 0, 1))


def _strip(ax, ks, codes: np.ndarray, sensor_labels: list[str]) -> None:
    """codes (T, N) as a categorical image, steps along x, sensors along y."""
    ks = np.asarray(ks)
    step = ks[1] - ks[0] if len(ks) > 1 else 1
    extent = (ks[0] - step / 2, ks[-1] + step / 2, len(sensor_labels) - 0.5, -0.5)
    ax.imshow(codes.T, aspect="auto", interpolation="nearest", cmap=ListedColormap(VERDICT_COLORS),
              vmin=-0.5, vmax=2.5, extent=extent)
    ax.set_yticks(range(len(sensor_labels)))
    ax.set_yticklabels(sensor_labels, fontsize=8)


def plot_verdict_strip(ks, full_rank: np.ndarray, exact: np.ndarray, sensor_labels: list[str], path: Path,
                       first_label: str = "first run") -> Path:
    """Heat-map strips steps × sensors: the verdict of the first run and, with several runs, the
    fraction of runs with full column rank and the fraction exact. ``full_rank``/``exact`` (R, T, N)."""
    from matplotlib.patches import Patch

    full_rank, exact = np.asarray(full_rank, bool), np.asarray(exact, bool)
    runs, _, n = full_rank.shape
    panels = 1 if runs == 1 else 3
    height = 0.35 * n + 1.1
    fig, axes = new_figure(nrows=panels, width=9.0, height=height)
    ax = axes[0, 0]
    _strip(ax, ks, verdict_codes(full_rank[0], exact[0]), sensor_labels)
    ax.set_title(f"rank verdict and exactness per step ({first_label})", fontsize=9)
    ax.legend(handles=[Patch(color=c, label=l) for c, l in zip(VERDICT_COLORS, VERDICT_LABELS)],
              loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    if runs > 1:
        ks_arr = np.asarray(ks)
        step = ks_arr[1] - ks_arr[0] if len(ks_arr) > 1 else 1
        extent = (ks_arr[0] - step / 2, ks_arr[-1] + step / 2, n - 0.5, -0.5)
        for ax, data, title in (
                (axes[1, 0], full_rank.mean(axis=0), f"fraction of the {runs} runs with full column rank"),
                (axes[2, 0], exact.mean(axis=0), f"fraction of the {runs} runs where the sensor is exact")):
            image = ax.imshow(data.T, aspect="auto", interpolation="nearest", cmap="RdYlGn", vmin=0, vmax=1,
                              extent=extent)
            ax.set_yticks(range(n))
            ax.set_yticklabels(sensor_labels, fontsize=8)
            ax.set_title(title, fontsize=9)
            fig.colorbar(image, ax=ax, fraction=0.03, pad=0.01)
    axes[-1, 0].set_xlabel("step k")
    return save(fig, path)


def plot_rmse(ks, rmse: dict[str, list], local_rmse: list[list], local_labels: list[str], path: Path) -> Path:
    """RMSE per step of every fusion method (solid) and local filter (dashed), log scale."""
    fig, axes = new_figure(width=9.0, height=4.2)
    ax = axes[0, 0]
    for method, values in rmse.items():
        ax.plot(ks, values, lw=1.4 if method in ("cmf", "dmf") else 1.1, label=method.upper(),
                ls="--" if method == "dmf" else "-")
    for label, values in zip(local_labels, local_rmse):
        ax.plot(ks, values, ":", lw=1.0, label=label)
    _log_steps_axes(ax, "RMSE over runs", "RMSE per step")
    return save(fig, path)


def _band_panel(ax, ks, series: list[tuple[str, dict]], title: str) -> None:
    """Averages of χ² statistics with their bands (one shaded band per distinct band)."""
    drawn = []
    for i, (label, stat) in enumerate(series):
        band = tuple(stat["band"])
        color = f"C{i}"
        if band not in drawn:
            ax.axhspan(band[0], band[1], color=color, alpha=0.12)
            drawn.append(band)
        ax.plot(ks, stat["average"], color=color, lw=1.2, ls="--" if label == "DMF" else "-",
                label=f"{label} ({100 * stat['fraction_inside']:.0f} % inside its band)")
    values = np.concatenate([np.asarray(stat["average"], float) for _, stat in series] +
                            [np.asarray(b, float) for b in drawn])
    positive = values[np.isfinite(values) & (values > 0)]
    if positive.size and positive.max() / positive.min() > 30:
        ax.set_yscale("log")
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("step k")
    ax.legend()
    ax.grid(True, which="major", alpha=0.3)


def plot_consistency(ks, nees: dict | None, nis_cmf: dict, nis_local: list[dict], local_labels: list[str],
                     path: Path) -> Path:
    """ANEES of every method with its χ² band (when the truth is known), and the ANIS of CMF and of
    every local filter, each against its own band (degrees of freedom differ)."""
    panels: list[tuple[str, tuple[str, dict] | None]] = [] if nees is None else [("nees", None)]
    panels += [("nis", ("CMF", nis_cmf))] + [("nis", (label, s)) for label, s in zip(local_labels, nis_local)]
    ncols = 2
    nrows = (len(panels) + ncols - 1) // ncols
    fig, axes = new_figure(ncols=ncols, nrows=nrows, width=4.8, height=3.2)
    flat = axes.ravel()
    for ax, (kind, payload) in zip(flat, panels):
        if kind == "nees":
            assert nees is not None  # the NEES panel is drawn only with nees
            first = next(iter(nees.values()))
            _band_panel(ax, ks, [(m.upper(), s) for m, s in nees.items()],
                        f"ANEES (χ²_{first['dof']} per run, {first['runs']} runs, "
                        f"{100 * first['level']:.0f} % band)")
        else:
            assert payload is not None  # every NIS panel carries (label, statistics)
            label, stat = payload
            _band_panel(ax, ks, [(label, stat)],
                        f"ANIS of {label} (χ²_{stat['dof']}, {100 * stat['level']:.0f} % band)")
    for ax in flat[len(panels):]:
        ax.set_visible(False)
    return save(fig, path)


def plot_drift(ks, recursive: np.ndarray, one_step: np.ndarray, path: Path, run_labels=None,
               quantity: tuple[str, str] = GAP_IN_PRIOR_SD) -> tuple[Path, float]:
    """The difference of the two recursive filters (each from its own previous posterior) against
    the one-step gap, both as ``quantity`` says (:data:`GAP_IN_PRIOR_SD` or
    :data:`GAP_IN_STATE_UNITS`), log scale."""
    floor = log_floor(recursive, one_step)
    fig, axes = new_figure(width=9.0, height=3.8)
    ax = axes[0, 0]
    _runs_plot(ax, ks, one_step, "0.5", "one-step gap", floor, "--", run_labels)
    _runs_plot(ax, ks, recursive, "tab:purple", "recursive DMF − CMF", floor, "-", run_labels)
    _log_steps_axes(ax, quantity[0] + (" (prior sd)" if quantity is GAP_IN_PRIOR_SD else " (state units)"),
                    "drift of the recursive filters")
    return save(fig, path), floor


def plot_min_per_sensor(ks, values: np.ndarray, sensor_labels: list[str], path: Path, ylabel: str, title: str,
                        threshold: np.ndarray | float | None = None, threshold_label: str = "threshold") -> Path:
    """A per-step, per-sensor quantity (T, N) — e.g. the smallest canonical correlation or singular
    value — on a log axis, with a threshold (scalar or (T, N)) dashed."""
    values = np.asarray(values, dtype=float)
    floor = log_floor(values) if threshold is None else log_floor(values, threshold)
    fig, axes = new_figure(width=9.0, height=3.8)
    ax = axes[0, 0]
    for m, label in enumerate(sensor_labels):
        column = values[:, m]
        ax.plot(ks, np.where(column > 0, column, floor), color=f"C{m}", lw=1.2, label=label,
                marker="." if len(ks) <= 60 else None, ms=3)
        if threshold is not None and np.ndim(threshold) == 2:
            ax.plot(ks, np.asarray(threshold, float)[:, m], "--", color=f"C{m}", lw=0.9,
                    label=f"{threshold_label}, {label}")
    if threshold is not None and np.ndim(threshold) == 0:
        ax.axhline(float(threshold), color="0.3", ls="--", lw=1.0, label=threshold_label)
    ax.set_yscale("log")
    ax.set_xlabel("step k")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.legend(ncol=2)
    ax.grid(True, which="major", alpha=0.3)
    return save(fig, path)


def plot_repair(ks, repair_dim: np.ndarray, sensor_labels: list[str], path: Path) -> Path:
    """Repair message size (numbers per step) per sensor, (T, N)."""
    repair_dim = np.asarray(repair_dim, dtype=float)
    fig, axes = new_figure(width=9.0, height=3.2)
    ax = axes[0, 0]
    n = len(sensor_labels)
    width = 0.8 / max(n, 1)
    ks = np.asarray(ks, dtype=float)
    for m, label in enumerate(sensor_labels):
        ax.bar(ks + (m - (n - 1) / 2) * width, repair_dim[:, m], width=width, color=f"C{m}", label=label)
    ax.set_xlabel("step k")
    ax.set_ylabel("numbers per step")
    ax.set_title("repair message size l_m − rank C_xy^m")
    ax.yaxis.get_major_locator().set_params(integer=True)
    ax.legend()
    return save(fig, path)
