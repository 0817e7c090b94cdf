"""Contract of the fusion paper's 1-D two-sensor example (Liao et al. 2019 §4.1, Figs. 2–4): its
parameters, report profiles and run record (computed by :mod:`gpfverify.papers.fusion.ungm1d_experiment`).

Model (eq. 42–43): xₖ₊₁ = 0.5xₖ + 25xₖ/(1 + xₖ²) + w, w ~ N(0, σ²); yᵐ = 5 sin(2x + zₘ) + vᵐ,
z = (0, π/4); one trajectory of 250 samples per run and σ², the first 200 train the GPs, the last 50
are filtered. Settings: σ² of the main setting (Fig. 2: 1; Fig. 3: 2) and a sweep (Fig. 4, whose σ²
values were lost in extraction: interpretation 0.5, 1, 2, 3).

Interpretations (each a parameter): measurement noise variance 0.01; every filter's prior at the
first test step N(0, 1); the trajectory starts at x₁ ~ N(0, 1); the metric the claims compare (the
squared Mahalanobis distance of eq. 44 as written; its square root; the squared error of eq. 45).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from gpfverify.contract.experiment import Profile, Setting
from gpfverify.papers.fusion.contract import SENSORS, FusionParams, FusionRun
from gpfverify.contract.interpretations import InterpretationSpec
from gpfverify.contract.params import option
from gpfverify.errors import InputError

NAME = "ungm1d"
#: the paper's run count (Figs. 2 and 3: 1000 independent runs; Fig. 4 states none)
DEFAULT_RUNS = 1000
#: σ² of the paper's Figs. 2 and 3
FIGURE_NOISES: tuple[float, float] = (1.0, 2.0)
DEFAULT_SWEEP: tuple[float, ...] = (0.5, 1.0, 2.0, 3.0)


def noise_key(noise_var: float) -> str:
    """The key of one σ² in ``results.json`` and in a run record: ``repr`` of the float ("1.0")."""
    return repr(float(noise_var))


@dataclass(frozen=True)
class Params(FusionParams):
    """The 1-D example's parameters (see the module docstring); defaults as in the paper."""

    fit_points: int = option(200, "at most this many training samples (evenly spaced) for the hyperparameter "
                             "fit; the GP then conditions on all of them", minimum=3)
    system_noise_var: float = option(1.0, "system noise σ² of the main setting (paper: 1 and 2)", above=0)
    sweep: tuple[float, ...] = option(DEFAULT_SWEEP, "further σ² values (Fig. 4; interpretation of the lost "
                                      "values)", above=0)
    measurement_noise_var: float = option(0.01, "sensor noise variance (interpretation)", above=0)
    sensor_phases: tuple[float, ...] = option((0.0, math.pi / 4), "phases zₘ of the sensors 5 sin(2x + zₘ)",
                                              cli=False)
    prior_mean: float = option(0.0, "mean of every filter's prior at the first test step")
    prior_var: float = option(1.0, "variance of every filter's prior at the first test step (interpretation)",
                              above=0)
    trajectory_start_var: float = option(1.0, "the trajectory starts at x₁ ~ N(0, v); this is v (interpretation)",
                                         above=0)
    train: int = option(200, "training samples at the start of each trajectory", minimum=3, flag="train-points",
                        deprecated=("train",))
    test_steps: int = option(50, "test steps filtered after the training samples", minimum=1)
    mahalanobis: Literal["squared", "root"] = option(
        "squared", "the Mahalanobis distance of eq. 44: 'squared' as written, (x − x̂)ᵀC⁻¹(x − x̂); 'root' its "
                   "square root, the form of Deisenroth et al. (2009) the paper cites for it")
    metric: Literal["mahalanobis", "squared-error"] = option(
        "mahalanobis", "what the claims compare: the Mahalanobis distance (eq. 44, in the form of --mahalanobis) "
                       "or the squared error ‖x − x̂‖² (the RMSE of eq. 45), each per run averaged over the steps")

    divergence_bound: float = option(100.0, "health check: a run diverged when a filter's error |x − x̂| exceeds "
                                     "this (or is not finite) at some step (the state stays within about ±30)",
                                     above=0)

    def check(self) -> None:
        super().check()
        if len(self.sensor_phases) != SENSORS:
            raise InputError(f"sensor_phases must hold {SENSORS} phases, got {len(self.sensor_phases)}")

    @property
    def noise_vars(self) -> tuple[float, ...]:
        """Every σ² run: the main one and the sweep, sorted, without repeats."""
        return tuple(sorted({float(self.system_noise_var), *map(float, self.sweep)}))


@dataclass(frozen=True)
class RunRecord:
    """One run: one independent trajectory per σ², keyed by :func:`noise_key`."""

    settings: dict[str, FusionRun]


def _setting(params: Params) -> Setting:
    values = ", ".join(f"{v:g}" for v in params.noise_vars)
    return Setting(f"σ² = {params.system_noise_var:g}; σ² ∈ {{{values}}}", "sweep", params)




#: the readings of what the paper leaves unstated or lost, tried next to the defaults
#: (``gpfverify reproduce ungm1d --interpretations all``)
INTERPRETATIONS: tuple[InterpretationSpec, ...] = (
    InterpretationSpec(
        "numpy-rank", {"rank_rule": "numpy"},
        "the paper does not say how rank(Cₓᵧᵐ) is decided; MATLAB's rank() (numpy's matrix_rank) may be its rule. "
        "With a 1 × 1 cross term that rule calls any nonzero value full rank however small against the state's "
        "and the output's spreads (its tolerance is relative to the one singular value itself), so a cross "
        "covariance near zero counts as full rank and its inverse in eq. 35 amplifies the rounding of "
        "μₑᵐ − μₚᵐ; the default, the canonical-correlation rule (τ = √eps), is unit-free and drops such a "
        "correlation"),
    InterpretationSpec(
        "measurement-noise-0.1", {"measurement_noise_var": 0.1},
        "the text's measurement noise shows as '0.1²' with symbols lost: variance 0.01 (default) or 0.1"),
    InterpretationSpec(
        "mahalanobis-root", {"mahalanobis": "root"},
        "eq. 44 cites Deisenroth et al. (2009) for the metric, who use the square-root form |x − x̂|/σ; the squared "
        "form has mean D = 1 for every calibrated filter and ranks filters by calibration more than by accuracy "
        "(read from the saved runs)"),
    InterpretationSpec(
        "rmse", {"metric": "squared-error"},
        "the paper's other metric, the RMSE of eq. 45 (§4.2), which ranks filters by accuracy alone: per-run mean "
        "squared errors compared (read from the saved runs)"),
)
#: the fields that only change how the saved runs are read (summary-only interpretations)
SUMMARY_FIELDS: frozenset[str] = frozenset({"mahalanobis", "metric"})
#: the interpretations every report profile tries: those that only read the saved runs differently
METRIC_INTERPRETATIONS: tuple[str, ...] = tuple(s.name for s in INTERPRETATIONS if set(s.changes) <= SUMMARY_FIELDS)

PROFILES: dict[str, Profile] = {
    # the two noise levels of Figs. 2 and 3, few runs
    "quick": Profile(4, (_setting(Params(sweep=(2.0,))),), METRIC_INTERPRETATIONS),
    "full": Profile(DEFAULT_RUNS, (_setting(Params()),), METRIC_INTERPRETATIONS),
}
