"""The check page's trajectory figure, drawn from ``results.json``'s ``trajectory`` (the first run)
only: the truth against each method's estimate with its covariance ellipse, one panel per method,
and the repaired DMF mean at the steps whose audit proposes a repair (the repair message restores
CMF's mean: :attr:`gpfverify.audit.case.CaseAudit.repaired_dmf_mean`).

A state of two or more components is drawn in the plane of its first two (x₀, x₁) with the
marginal covariance's ellipse {p : (p − μ)ᵀ C⁻¹ (p − μ) = χ²₂(level)}; a scalar state against the
step k with the band μ ± √(χ²₁(level) C).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.stats import chi2

from gpfverify.report.figures import new_figure, save

#: the probability mass inside each drawn ellipse (or band)
ELLIPSE_LEVEL = 0.95
#: at most this many ellipses per panel (every n-th step beyond)
MAX_ELLIPSES = 25
#: one colour per method, in the order of the check's methods
COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2")


def ellipse_points(mean: np.ndarray, cov: np.ndarray, level: float = ELLIPSE_LEVEL, n: int = 64) -> np.ndarray:
    """(n, 2) points of the ellipse (p − μ)ᵀ C⁻¹ (p − μ) = χ²₂(level) of a 2-D Gaussian N(μ, C):
    μ + V √Λ r (cos θ, sin θ) with C = V Λ Vᵀ and r² the χ² quantile (a PSD C with a zero
    eigenvalue gives a flat ellipse)."""
    values, vectors = np.linalg.eigh(0.5 * (cov + cov.T))
    radius = np.sqrt(chi2.ppf(level, 2))
    theta = np.linspace(0.0, 2.0 * np.pi, n)
    circle = np.stack([np.cos(theta), np.sin(theta)])
    return (mean[:, None] + vectors @ (np.sqrt(np.clip(values, 0.0, None))[:, None] * radius * circle)).T


def ellipse_steps(count: int) -> list[int]:
    """The indices of the steps given an ellipse: every step up to :data:`MAX_ELLIPSES`, else
    evenly spaced ones including the last."""
    every = max(1, -(-count // MAX_ELLIPSES))
    return sorted({*range(0, count, every), count - 1})


def plot_trajectory(trajectory: dict, path: Path) -> Path:
    """The figure (module docstring): one panel per method of ``trajectory["means"]``."""
    ks = np.asarray(trajectory["k"])
    truth = None if trajectory.get("truth") is None else np.asarray(trajectory["truth"], float)
    methods = list(trajectory["means"])
    repaired = trajectory.get("repaired") or []
    cols = min(2, len(methods))
    rows = -(-len(methods) // cols)
    fig, axes = new_figure(cols, rows, width=4.6, height=3.8)
    for index, method in enumerate(methods):
        ax = axes[index // cols][index % cols]
        color = COLORS[index % len(COLORS)]
        title = method.upper() if method != "rcc-ci" else "RCC-CI"
        at = [t for t, m in enumerate(trajectory["means"][method]) if m is not None]
        means = np.asarray([trajectory["means"][method][t] for t in at], float).reshape(len(at), -1)
        covs = np.asarray([trajectory["covs"][method][t] for t in at], float).reshape(len(at), means.shape[1], -1)
        planar = means.shape[1] >= 2
        if truth is not None:
            if planar:
                ax.plot(truth[:, 0], truth[:, 1], "k.-", lw=1.0, ms=3, label="truth")
            else:
                ax.plot(ks, truth[:, 0], "k.-", lw=1.0, ms=3, label="truth")
        if planar:
            ax.plot(means[:, 0], means[:, 1], ".-", color=color, lw=1.0, ms=3, label=f"{title} estimate")
            for j in ellipse_steps(len(at)):
                points = ellipse_points(means[j, :2], covs[j, :2, :2])
                ax.plot(points[:, 0], points[:, 1], color=color, lw=0.6, alpha=0.6)
        else:
            half = np.sqrt(chi2.ppf(ELLIPSE_LEVEL, 1) * covs[:, 0, 0])
            ax.plot(ks[at], means[:, 0], ".-", color=color, lw=1.0, ms=3, label=f"{title} estimate")
            ax.fill_between(ks[at], means[:, 0] - half, means[:, 0] + half, color=color, alpha=0.2)
        if repaired and method in ("cmf", "dmf"):
            fixed = np.asarray([r["mean"] for r in repaired], float)
            if planar:
                ax.plot(fixed[:, 0], fixed[:, 1], "x", color="#ff7f0e", ms=6, label="repaired DMF")
            else:
                ax.plot([r["k"] for r in repaired], fixed[:, 0], "x", color="#ff7f0e", ms=6, label="repaired DMF")
        ax.set_title(title)
        ax.set_xlabel("x₀" if planar else "step k")
        ax.set_ylabel("x₁" if planar else "x₀")
        ax.grid(True, alpha=0.3)
        ax.legend(frameon=False)
    for index in range(len(methods), rows * cols):
        axes[index // cols][index % cols].set_visible(False)
    return save(fig, path)


def trajectory_caption(trajectory: dict) -> str:
    """What :func:`plot_trajectory` drew, in words."""
    dim = len(next((m for ms in trajectory["means"].values() for m in ms if m is not None), [0]))
    count = len(trajectory["k"])
    shown = len(ellipse_steps(count))
    where = ("state components x₀ (across) and x₁ (up)" if dim >= 2 else "the state against the step k")
    text = (f"First run, {where}: {'the truth (black) and ' if trajectory.get('truth') is not None else ''}"
            f"each method's estimate with its {ELLIPSE_LEVEL * 100:g} % "
            + ("covariance ellipse" + (f" at {shown} of the {count} steps" if shown < count else " at every step")
               if dim >= 2 else "band"))
    if trajectory.get("truth") is None:
        text += " (the truth is not known: logged measurements without x)"
    repaired = trajectory.get("repaired") or []
    if repaired:
        text += (f"; ✕ on the CMF and DMF panels: the repaired DMF mean at the {len(repaired)} step(s) whose audit "
                 "proposes a repair message (it restores CMF's one-step mean)")
    return text + "."
