"""Contract of the ``bearing`` experiment (Zhou et al. 2020 §3.2: Table 2, Fig. 3): parameters,
profiles, the filters it compares and the per-run record.

``results.json`` (CONTRACT.md): ``"rmse"``, ``"time_per_run"``, ``"mean_rmse"``, ``"diverged"``,
``"run_rmse"``, ``"run_seconds"``: {filter key} with the keys of :attr:`Params.filters` ("PF-N50",
"PF-N200", "IE-PFF-N50" at the paper's particle counts, and "IE-PFF-N200"); ``"large_noise"``: the
same for the trajectory with the larger process noise; ``"health"``: a list of
:class:`~gpfverify.health.HealthCheck` (divergence of every filter, weight collapse of the PFs);
``"significance_level"``; ``"claims"``.

``INTERPRETATIONS``: the flow's λ schedule (exponential spacing with its ratio and number of
steps, a finer Δλ) and the lost noise settings (bearing noise σ, r1 and r2 read as standard
deviations).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from typing import Literal

from gpfverify.contract.experiment import Profile, Setting
from gpfverify.contract.interpretations import InterpretationSpec
from gpfverify.contract.methods import Method
from gpfverify.contract.params import Params as ParamsBase
from gpfverify.contract.params import option
from gpfverify.papers.particle_flow.contract import IE_PFF, PF, Spacing
from gpfverify.errors import InputError

NAME = "bearing"
#: the paper's Monte Carlo runs (§3.2: "200次蒙特卡洛仿真")
PAPER_RUNS = 200
#: x₀ = [x, ẋ, y, ẏ] of the paper (m, m/s)
INITIAL_STATE: tuple[float, float, float, float] = (1000.0, 10.0, 1500.0, 15.0)


@dataclass(frozen=True, order=True)
class SizedFilter:
    """A particle filter with its particle count; :attr:`key` is its name in ``results.json``."""

    method: Method
    particles: int

    @property
    def key(self) -> str:
        """"PF-N200": the method's key and the particle count."""
        return f"{self.method.key}-N{self.particles}"


@dataclass(frozen=True)
class Params(ParamsBase):
    """Parameters of ``bearing``; defaults are the paper's settings and, where its parameter list
    was lost, the interpretations stated in the report."""

    q_pos: float = option(0.05, "process-noise variance of x, y (the paper's r1 = 0.05)", above=0.0)
    q_vel: float = option(0.1, "process-noise variance of ẋ, ẏ (the paper's r2 = 0.1)", above=0.0)
    bearing_std: float = option(0.01, "bearing noise standard deviation in rad (lost in the paper; chosen)",
                                above=0.0)
    prior_std_pos: float = option(10.0, "prior standard deviation of x, y in m", above=0.0)
    prior_std_vel: float = option(1.0, "prior standard deviation of ẋ, ẏ in m/s", above=0.0)
    omega_deg: float = option(5.0, "turn rate in °/s")
    switch_time: float = option(40.0, "start of the turn in s", minimum=0.0)
    duration: int = option(60, "steps of 1 s", minimum=1)
    dlambda: float = option(0.05, "pseudo-time step Δλ of the flow", above=0.0, maximum=1.0)
    spacing: Spacing = option("uniform", "λ-step schedule of the flow (uniform: the paper's)")
    exponential_ratio: float = option(1.2, "ratio of consecutive λ-steps of the exponential schedule", above=0.0)
    exponential_steps: int = option(0, "number of λ-steps of the exponential schedule whatever Δλ (0: round(1/Δλ), "
                                       "as many as the uniform schedule)", minimum=0)
    noise_values: Literal["variance", "std"] = option(
        "variance", "how r1 (--q-pos) and r2 (--q-vel) are read: variances, or standard deviations (variance = value²)")
    divergence_bound: float = option(1e4, "health check: a position error above this (m) at any step counts the run "
                                          "as diverged (as does a non-finite estimate)", above=0.0)
    pf_small: int = option(50, "particles of the smaller bootstrap PF", minimum=2)
    pf_large: int = option(200, "particles of the larger bootstrap PF", minimum=2)
    flow_particles: int = option(50, "particles of the IE-PFF", minimum=2)
    flow_particles_large: int = option(200, "particles of the second IE-PFF (§3.2: more particles do not make the "
                                            "flow more accurate)", minimum=2)
    large_noise_factor: float = option(10.0, "process noise of the second trajectory of every run, as a multiple of "
                                             "r1 and r2 (§3.2: Table 2's rows at larger process noise, whose values "
                                             "were lost)", above=1.0)
    initial_state: tuple[float, float, float, float] = option(
        INITIAL_STATE, "the target's initial state x₀ = [x, ẋ, y, ẏ] (m, m/s), the filters' prior mean",
        cli=False)

    @property
    def process_variances(self) -> tuple[float, float]:
        """(position, velocity) process-noise variances under :attr:`noise_values`."""
        if self.noise_values == "variance":
            return self.q_pos, self.q_vel
        return self.q_pos ** 2, self.q_vel ** 2

    def check(self) -> None:
        if self.pf_small == self.pf_large:
            raise InputError(f"--pf-small and --pf-large must differ, both are {self.pf_small}")
        if self.flow_particles == self.flow_particles_large:
            raise InputError(f"--flow-particles and --flow-particles-large must differ, both are "
                             f"{self.flow_particles}")

    @property
    def filters(self) -> tuple[SizedFilter, SizedFilter, SizedFilter, SizedFilter]:
        """The filters compared, in the paper's order: PF (small N), PF (large N), IE-PFF, then the
        IE-PFF with more particles."""
        return (SizedFilter(PF, self.pf_small), SizedFilter(PF, self.pf_large),
                SizedFilter(IE_PFF, self.flow_particles), SizedFilter(IE_PFF, self.flow_particles_large))

    @property
    def large_noise_filters(self) -> tuple[SizedFilter, SizedFilter, SizedFilter]:
        """The filters run on the trajectory with the larger process noise: Table 2's three."""
        return self.filters[:3]



INTERPRETATIONS: tuple[InterpretationSpec, ...] = (
    InterpretationSpec("exponential-1.2", {"spacing": "exponential"},
                       "λ-steps growing by 1.2 as in the particle-flow literature (Daum & Huang; Li & Coates 2017), "
                       "as many as Δλ gives"),
    InterpretationSpec("li-coates-29", {"spacing": "exponential", "exponential_steps": 29},
                       "Li & Coates (2017): 29 exponentially spaced λ-steps, ratio 1.2"),
    InterpretationSpec("dlambda-0.01", {"dlambda": 0.01},
                       "a five times finer uniform Euler step (the paper's Δλ for this example is not stated)"),
    InterpretationSpec("bearing-std-0.005", {"bearing_std": 0.005},
                       "the lost bearing noise at Gordon, Salmond & Smith's (1993) bearings-only value, 0.005 rad"),
    InterpretationSpec("bearing-std-0.05", {"bearing_std": 0.05}, "a coarse bearing sensor, 0.05 rad (about 3°)"),
    InterpretationSpec("noise-as-std", {"noise_values": "std"},
                       "r1 = 0.05, r2 = 0.1 read as process-noise standard deviations (variances 0.0025, 0.01)"),
)

#: the interpretations every profile tries, each at the profile's run count, so that every verdict of
#: the report states whether it survives them
TRIED: tuple[str, ...] = tuple(s.name for s in INTERPRETATIONS)
PROFILES: dict[str, Profile] = {
    "quick": Profile(20, (Setting("", "paper", Params()),), TRIED),
    "full": Profile(PAPER_RUNS, (Setting("", "paper", Params()),), TRIED),
}


@dataclass(frozen=True)
class FilterRun:
    """One filter on one run: squared position error per step (None when it diverged) and CPU seconds."""

    sq_pos_err: tuple[float, ...] | None
    seconds: float
    #: N_eff/N of the weighted set per step (PFs; None for the flow and when diverged)
    ess_fraction: tuple[float, ...] | None = None


@dataclass(frozen=True)
class RunRecord:
    """One Monte Carlo run: every filter of :attr:`Params.filters`, by key; and on a second
    trajectory with the process noise × :attr:`Params.large_noise_factor`, the filters of
    :attr:`Params.large_noise_filters`."""

    filters: dict[str, FilterRun]
    large_noise: dict[str, FilterRun] = field(default_factory=dict)
