"""Contract of the fusion paper's 2-D constant-turn experiment (Liao et al. 2019 §4.2, Figs. 5–15):
its parameters, report profiles and run record (computed by :mod:`gpfverify.papers.fusion.ct2d_experiment`).

Model (eq. 46–47): xₖ₊₁ = F(Ω)xₖ + w, w ~ N(0, 5 I); two range–bearing sensors,
yᵐ = [‖x − zₘ‖, arctan((x₂ − zₘ₂)/(x₁ − zₘ₁))] + vᵐ, vᵐ ~ N(0, diag(5, (0.1π/180)²)); κ training
samples from x ~ N(0, I), then 50 test steps.

Interpretations (each a parameter; :data:`INTERPRETATIONS` lists the readings tried besides the
defaults): sensor positions z₁ = [−200, 200], z₂ = [200, 200] (a minus
sign was lost in the text); each sensor's filter starts at the polar→Cartesian conversion of its
first test observation plus a per-coordinate N(b, 1) perturbation (b = 10 for κ = 300, 20 for κ =
30, 60, as the paper states) with initial covariance (b² + 1) I — the perturbation's second moment,
which the paper does not give; the fused filters start at the mean of the sensors' starts with the
same covariance.
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

NAME = "ct2d"
#: the paper's run count (M = 1000 for every figure of §4.2)
DEFAULT_RUNS = 1000
#: the small turn rate of the paper, 2π/90 rad/s
OMEGA_SMALL = 2 * math.pi / 90
#: κ at and above which the paper's start perturbation is N(10, 1) (below: N(20, 1))
LARGE_TRAINING = 300
#: the interpretation of the lost sign: z₁ = [−200, 200], z₂ = [200, 200]
SENSOR_POSITIONS: tuple[tuple[float, float], ...] = ((-200.0, 200.0), (200.0, 200.0))


def default_perturbation_mean(kappa: int) -> float:
    """The paper's b of the N(b, 1) start perturbation: 10 for κ = 300, 20 for κ = 30, 60."""
    return 10.0 if kappa >= LARGE_TRAINING else 20.0


def omega_label(omega: float) -> str:
    """Ω as the paper writes it: "2π/90" for 2π/90 (and its 4-digit rounding 0.0698), else the number."""
    if math.isclose(omega, OMEGA_SMALL, rel_tol=1e-3):
        return "2π/90"
    return f"{omega:g}"


def omega_tag(omega: float) -> str:
    return f"{omega:.4f}"


@dataclass(frozen=True)
class Params(FusionParams):
    """The constant-turn experiment's parameters (see the module docstring); the defaults are the
    paper's headline setting κ = 300, Ω = 2π/90."""

    kappa: int = option(300, "training samples κ (paper: 300, 30, 60); --kappa, the paper's symbol, is the same "
                        "option", minimum=3, flag="train-points", aliases=("kappa",))
    omega: float = option(OMEGA_SMALL, "turn rate Ω in rad/s (paper: 2π/90 ≈ 0.0698 and 0.5)")
    test_steps: int = option(50, "test steps filtered after the training samples", minimum=1)
    sensor_positions: tuple[tuple[float, float], ...] = option(
        SENSOR_POSITIONS, "sensor positions zₘ in m (interpretation: the sign of z₁'s first coordinate was lost)",
        cli=False)
    process_noise_var: float = option(5.0, "variance of each coordinate of the process noise w (Q = q I)", above=0)
    range_noise_var: float = option(5.0, "range noise variance of each sensor, m²", above=0)
    bearing_noise_var: float = option((0.1 * math.pi / 180.0) ** 2, "bearing noise variance of each sensor, rad²",
                                      above=0)
    training_start_var: float = option(1.0, "the training trajectory starts at x ~ N(0, v I); this is v", above=0)
    local_start: Literal["first-observation"] = option(
        "first-observation", "each sensor's filter starts at the polar→Cartesian conversion of its first test "
        "observation (on the origin's side of the sensor) plus the start perturbation")
    perturbation_mean: float | None = option(
        None, "mean b of the N(b, σ²) start perturbation per coordinate (none: the paper's 10 for κ ≥ 300, "
        "else 20)")
    perturbation_std: float = option(1.0, "standard deviation σ of the start perturbation", minimum=0)
    initial_cov_scale: float | None = option(
        None, "initial covariance s I of every filter (none: b² + σ², the perturbation's second moment; "
        "the paper does not give it)", above=0)
    fused_start: Literal["mean-of-sensor-starts"] = option(
        "mean-of-sensor-starts", "the fused filters start at the mean of the sensors' starts, same covariance")

    divergence_bound: float = option(1000.0, "health check: a run diverged when a filter's position error exceeds "
                                     "this many metres (or is not finite) at some step (the sensors are 200–300 m "
                                     "from the origin)", above=0)

    def check(self) -> None:
        super().check()
        if len(self.sensor_positions) != SENSORS:
            raise InputError(f"sensor_positions must hold {SENSORS} positions, got {len(self.sensor_positions)}")

    @property
    def start_mean(self) -> float:
        """b used: the given perturbation mean, else the paper's for κ."""
        return default_perturbation_mean(self.kappa) if self.perturbation_mean is None else self.perturbation_mean

    @property
    def start_cov_scale(self) -> float:
        """s used: the given initial covariance scale, else b² + σ²."""
        if self.initial_cov_scale is not None:
            return self.initial_cov_scale
        return self.start_mean ** 2 + self.perturbation_std ** 2

    @property
    def label(self) -> str:
        """The setting as the page names it: "κ = 300, Ω = 2π/90"."""
        return f"κ = {self.kappa}, Ω = {omega_label(self.omega)}"

    @property
    def tag(self) -> str:
        """The setting's folder name: "k300-w0.0698"."""
        return f"k{self.kappa}-w{omega_tag(self.omega)}"


#: one run's record
RunRecord = FusionRun


def setting(kappa: int, omega: float) -> Setting:
    params = Params(kappa=kappa, omega=omega)
    return Setting(params.label, params.tag, params)


#: the paper's four settings (κ, Ω): Figs. 5–9 (κ = 300, both Ω), 10–15 (κ = 30, 60)
PAPER_SETTINGS: tuple[tuple[int, float], ...] = ((300, OMEGA_SMALL), (300, 0.5), (30, OMEGA_SMALL), (60, OMEGA_SMALL))



#: the readings of what the paper leaves unstated or lost, tried next to the defaults
#: (``gpfverify reproduce ct2d --interpretations all``)
INTERPRETATIONS: tuple[InterpretationSpec, ...] = (
    InterpretationSpec(
        "numpy-rank", {"rank_rule": "numpy"},
        "the paper does not say how rank(Cₓᵧᵐ) is decided; MATLAB's rank() (numpy's matrix_rank) may be its rule. "
        "That rule depends on units (a bearing column in m·rad is ≈ 1/280 of the range column, and its tolerance "
        "is relative to the largest singular value); the default, the canonical-correlation rule (τ = √eps), "
        "does not"),
    InterpretationSpec(
        "initial-cov-perturbation", {"initial_cov_scale": 1.0},
        "the paper gives no initial covariance; the filters may be told only the perturbation's spread, "
        "N(b, 1) → I, ignoring its bias b (over-confident start)"),
    InterpretationSpec(
        "initial-cov-wide", {"initial_cov_scale": 1000.0},
        "the paper gives no initial covariance; a vague start, 1000 I (≈ 10× the perturbation's second moment at "
        "κ = 300, 2.5× at κ = 30, 60)"),
    InterpretationSpec(
        "sensors-z1-below", {"sensor_positions": ((200.0, -200.0), (200.0, 200.0))},
        "the text prints z₁ = [200, 200]ᵀ = z₂: the lost minus sign may belong to z₁'s second coordinate "
        "(sensors at [200, −200] and [200, 200]) instead of its first"),
    InterpretationSpec(
        "sensors-as-printed", {"sensor_positions": ((200.0, 200.0), (200.0, 200.0))},
        "the sensor positions exactly as printed: both sensors at [200, 200] (the same geometry, independent "
        "noise)"),
)

#: the interpretations every profile tries, each at the profile's run count, so that every verdict of
#: the report states whether it survives them
TRIED: tuple[str, ...] = tuple(s.name for s in INTERPRETATIONS)
PROFILES: dict[str, Profile] = {
    # the headline setting and one small-training setting, few runs
    "quick": Profile(3, (setting(300, OMEGA_SMALL), setting(30, OMEGA_SMALL)), TRIED),
    "full": Profile(DEFAULT_RUNS, tuple(setting(k, w) for k, w in PAPER_SETTINGS), TRIED),
}
