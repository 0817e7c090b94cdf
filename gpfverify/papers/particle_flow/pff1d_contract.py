"""Contract of the ``pff1d`` experiment (Zhou et al. 2020 §3.1: Table 1, Figs. 1–2): parameters,
profiles, the per-run record and the summary records the report reads back.

``results.json`` (CONTRACT.md): ``"rmse"``, ``"time_per_run"``, ``"diverged"``: {"PF", "UPF",
"EDH", "IE-PFF"} at the gamma case's main R (``"main_case"``); ``"table1"``: a list of
:class:`Table1Row`; ``"gamma"``: {R: {variant label: :class:`GammaEntry`}}; ``"divergences"``: a
list of :class:`DivergenceCount`; ``"health"``: a list of :class:`~gpfverify.health.HealthCheck`
(divergence of every filter, weight collapse of PF and UPF, per cell); ``"significance_level"`` of
the paired tests; ``"claims"``.

``INTERPRETATIONS`` are the readings the sensitivity study tries: the λ schedule of the flows
(exponentially spaced as in the particle-flow literature, with its ratio and number of steps), the
unstated noise settings (the grid's Q and R read as standard deviations) and the lost measurement
function (a one-to-one y = x in place of y = x²/20); those not about the schedule use the stable
uniform Δλ = 0.001 (:data:`STABLE_DLAMBDA`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from gpfverify.contract.experiment import Profile, Setting
from gpfverify.contract.interpretations import InterpretationSpec
from gpfverify.contract.methods import Method
from gpfverify.contract.params import Params as ParamsBase
from gpfverify.contract.params import option
from gpfverify.papers.particle_flow.contract import EDH, IE_PFF, PF, UPF, Spacing, Variant
from gpfverify.errors import InputError

NAME = "pff1d"
#: the paper's Monte Carlo runs (§3.1: "30 次蒙特卡洛仿真")
PAPER_RUNS = 30
#: methods of Table 1 (Gaussian noise) and of Fig. 2 (gamma noise)
TABLE_METHODS: tuple[Method, ...] = (PF, EDH, IE_PFF)
GAMMA_METHODS: tuple[Method, ...] = (PF, UPF, EDH, IE_PFF)

#: the 1-D model of the Table-1 grid: the UNGM, or the van der Merwe et al. (2000) benchmark of the
#: gamma case with Gaussian process noise
TableModel = Literal["ungm", "vdm"]
#: a run's cases: the Table-1 grid on its model, and the gamma case
Case = Literal["ungm", "vdm", "gamma"]
#: each Table-1 model by name (health subjects, the claims' settings, the report; vdM-Gaussian: the van der
#: Merwe et al. (2000) benchmark with Gaussian process noise)
TABLE_MODEL_NAMES: dict[str, str] = {"ungm": "UNGM", "vdm": "vdM-Gaussian"}
#: how the grid's noise values are read: as variances (the default) or as standard deviations
NoiseReading = Literal["variance", "std"]


@dataclass(frozen=True)
class Prior:
    """A scalar Gaussian prior N(mean, var) of x₀ (the truth's and every filter's)."""

    mean: float
    var: float


@dataclass(frozen=True)
class Params(ParamsBase):
    """Parameters of ``pff1d``; defaults are the paper's settings (N = 50, T = 50, the Table-1 grid)
    and, where the paper is silent, the interpretations stated in the report."""

    particles: int = option(50, "particles per filter", minimum=2)
    steps: int = option(50, "time steps T", minimum=1)
    table_q: tuple[float, ...] = option((0.1, 1.0, 10.0), "process-noise variances Q of the Table-1 grid",
                                        above=0.0)
    table_r: tuple[float, ...] = option((0.1, 1.0), "measurement-noise variances R of the Table-1 grid",
                                        above=0.0)
    dlambda: tuple[float, ...] = option((0.1, 0.01, 0.001), "pseudo-time steps Δλ of the flows (Table-1 grid)",
                                        above=0.0, maximum=1.0)
    spacings: tuple[Spacing, ...] = option(("uniform", "exponential"),
                                           "λ-step schedules of the flows; the first is the main one")
    exponential_ratio: float = option(1.2, "ratio of consecutive λ-steps of the exponential schedule", above=0.0)
    exponential_steps: int = option(0, "number of λ-steps of the exponential schedule whatever Δλ (0: round(1/Δλ), "
                                       "as many as the uniform schedule)", minimum=0)
    table_model: TableModel = option(
        "ungm", "1-D model of the Table-1 grid (the paper's model text is lost): 'ungm' the univariate growth "
                "model, 'vdm' the van der Merwe et al. (2000) benchmark of the gamma case with Gaussian process "
                "noise N(0, Q)")
    noise_values: NoiseReading = option("variance", "how the Q and R values of the grid and of the gamma case's R are "
                                                    "read: variances, or standard deviations (variance = value²)")
    ungm_measurement: Literal["quadratic", "linear"] = option(
        "quadratic", "measurement function of the Gaussian (UNGM) cases: 'quadratic' y = x²/20 (Kitagawa's, "
                     "two-peaked posterior), 'linear' the one-to-one y = x (the paper's model text is lost)")
    divergence_bound: float = option(1e3, "health check: an absolute state error above this at any step counts the "
                                          "run as diverged (as does a non-finite estimate)", above=0.0)
    gamma_r: tuple[float, ...] = option((0.01, 0.1, 1.0), "measurement-noise variances R of the gamma case (Fig. 2)",
                                        above=0.0)
    gamma_main_r: float = option(0.1, "R of the gamma case reported under the 'rmse' key", above=0.0)
    gamma_dlambda: float = option(0.01, "Δλ of the flows in the gamma case", above=0.0, maximum=1.0)
    gamma_shape: float = option(3.0, "shape of the gamma process noise Γ(shape, rate)", above=0.0)
    gamma_rate: float = option(2.0, "rate of the gamma process noise Γ(shape, rate)", above=0.0)
    ungm_prior: Prior = option(Prior(0.0, 1.0), "prior N(mean, var) of x₀ in the UNGM cases", cli=False)
    gamma_prior: Prior = option(Prior(1.0, 0.75), "prior N(mean, var) of x₀ on the van der Merwe benchmark (the "
                                                  "gamma cases, and the Table-1 grid under table-model 'vdm')",
                                cli=False)

    def check(self) -> None:
        for name in ("table_q", "table_r", "dlambda", "spacings", "gamma_r"):
            values = getattr(self, name)
            if not values:
                raise InputError(f"--{name.replace('_', '-')} needs at least one value")
            if len(set(values)) != len(values):
                raise InputError(f"--{name.replace('_', '-')} has a repeated value: {list(values)}")
        if self.gamma_main_r not in self.gamma_r:
            raise InputError(f"--gamma-main-r {self.gamma_main_r:g} must be one of --gamma-r {list(self.gamma_r)}")
        for name in ("ungm_prior", "gamma_prior"):
            if not getattr(self, name).var > 0:
                raise InputError(f"{name} variance must be positive, got {getattr(self, name).var}")
        if self.table_model != "ungm" and self.ungm_measurement != "quadratic":
            raise InputError(f"--ungm-measurement {self.ungm_measurement} applies to the UNGM only, not to "
                             f"--table-model {self.table_model}")

    @property
    def main_spacing(self) -> Spacing:
        return self.spacings[0]

    def variance(self, value: float) -> float:
        """The noise variance a grid value stands for under :attr:`noise_values`."""
        return value if self.noise_values == "variance" else value * value


#: quick profile: the grid's extreme process noises at one R, two Δλ, the gamma case at its main R
QUICK_PARAMS = Params(table_q=(0.1, 10.0), table_r=(1.0,), dlambda=(0.1, 0.01), gamma_r=(0.1,))

#: a uniform λ schedule under which IE-PFF diverged in none of the runs of the UNGM grid (at
#: Δλ = 0.1 it diverged in every run at R = 0.1; at 0.002 still in some runs at Q = 10, R = 0.1):
#: explicit Euler is stable only for steps below about 4R/(P₀H²), and the interpretations that are
#: not about the schedule use this one, so that a divergence of the integrator decides nothing
STABLE_DLAMBDA = (0.001,)
INTERPRETATIONS: tuple[InterpretationSpec, ...] = (
    InterpretationSpec(
        "exponential-1.2", {"spacings": ("exponential",), "dlambda": (0.1,)},
        "particle flows in the literature integrate λ in exponentially growing steps (ratio 1.2: Daum & Huang; "
        "Li & Coates 2017), small where the flow is stiff (λ ≈ 0); 10 steps, as many as Δλ = 0.1 gives"),
    InterpretationSpec(
        "exponential-1.5", {"spacings": ("exponential",), "dlambda": (0.1,), "exponential_ratio": 1.5},
        "a steeper geometric schedule: 10 steps, the first far smaller than 1/10"),
    InterpretationSpec(
        "li-coates-29", {"spacings": ("exponential",), "dlambda": (0.1,), "exponential_steps": 29},
        "the schedule of Li & Coates (2017) after Daum & Huang: 29 exponentially spaced λ-steps, ratio 1.2, "
        "in place of the Δλ = 0.1 grid (and of the gamma case's Δλ)"),
    InterpretationSpec(
        "noise-as-std", {"noise_values": "std", "dlambda": STABLE_DLAMBDA, "spacings": ("uniform",)},
        "the lost model listing may give Q and R as standard deviations: variances Q ∈ {0.01, 1, 100}, "
        "R ∈ {0.01, 1} (gamma case R ∈ {1e-4, 0.01, 1}); uniform λ-steps of the stable Δλ = 0.001"),
    InterpretationSpec(
        "measurement-linear", {"ungm_measurement": "linear", "dlambda": STABLE_DLAMBDA, "spacings": ("uniform",)},
        "the model text is lost; y = x²/20 cannot tell x from −x, so the UNGM posterior is two-peaked, which a flow "
        "with one linear gain for all particles cannot represent and a PF can: the same dynamics with the "
        "one-to-one y = x, uniform λ-steps of the stable Δλ = 0.001"),
    InterpretationSpec(
        "vdm-gaussian", {"table_model": "vdm", "spacings": ("uniform",)},
        "the model text is lost, and §3.1 runs its gamma case on the van der Merwe et al. (2000) benchmark: the "
        "whole Table-1 grid (every Q, R and Δλ) on that model with Gaussian process noise N(0, Q), the paper's "
        "uniform λ-steps; it bears on the Table-1 and Fig. 1 claims (the gamma case is the same as run)",
        bears_on=(f"{NAME}/ie-pff-beats-pf-and-edh-fig1b/", f"{NAME}/ie-pff-beats-pf-and-edh-at-large-q/")),
)

#: the interpretations every profile tries, each at the profile's run count, so that every verdict of
#: the report states whether it survives them
TRIED: tuple[str, ...] = tuple(s.name for s in INTERPRETATIONS)
PROFILES: dict[str, Profile] = {
    "quick": Profile(2, (Setting("reduced grid", "reduced", QUICK_PARAMS),), TRIED),
    "full": Profile(PAPER_RUNS, (Setting("the paper's grid", "paper", Params()),), TRIED),
}


# ----------------------------------------------------------------------------- per run

@dataclass(frozen=True)
class VariantRun:
    """One filter variant on one case's trajectory: the squared error per step (None when the
    filter diverged) and the CPU seconds it took."""

    case: Case
    q: float
    r: float
    variant: Variant
    sq_err: tuple[float, ...] | None
    seconds: float
    #: N_eff/N of the weighted set per step (PF and UPF; None for the flows and when diverged)
    ess_fraction: tuple[float, ...] | None = None


@dataclass(frozen=True)
class RunRecord:
    """One Monte Carlo run: every (case, Q, R) × variant, in a fixed order."""

    records: tuple[VariantRun, ...]


# ----------------------------------------------------------------------------- summary

@dataclass(frozen=True)
class Table1Row:
    """One cell × variant of the Table-1 grid on its model (``results.json`` "table1")."""

    Q: float
    R: float
    method: str
    dlambda: float | None
    spacing: Spacing | None
    #: the RMSE curve averaged over time
    mean_rmse: float
    diverged: int
    runs: int
    time_per_run: float
    #: RMSE per step over the runs that did not diverge
    rmse: tuple[float, ...]
    #: per run √(mean over steps of err²), None where the filter diverged
    run_rmse: tuple[float | None, ...]
    #: per run the filter's CPU seconds in this cell (what the timing claims compare; empty in a
    #: summary made before they were kept)
    run_seconds: tuple[float, ...] = ()

    @property
    def variant(self) -> Variant:
        return Variant(Method.parse(self.method), self.dlambda, self.spacing)


@dataclass(frozen=True)
class GammaEntry:
    """One variant at one R of the gamma case (``results.json`` "gamma"[R][label])."""

    method: str
    dlambda: float | None
    spacing: Spacing | None
    rmse: tuple[float, ...]
    mean_rmse: float
    diverged: int
    time_per_run: float
    run_rmse: tuple[float | None, ...]

    @property
    def variant(self) -> Variant:
        return Variant(Method.parse(self.method), self.dlambda, self.spacing)


@dataclass(frozen=True)
class DivergenceCount:
    """How often a flow variant diverged over the whole Table-1 grid (cells × runs)."""

    method: str
    dlambda: float
    spacing: Spacing
    diverged: int
    total: int


def gamma_entries(results: dict) -> dict[str, dict[str, GammaEntry]]:
    """``results.json``'s "gamma" read back as typed entries."""
    from gpfverify.contract.serial import from_json

    return from_json(dict[str, dict[str, GammaEntry]], results["gamma"], "gamma")


def table1_rows(results: dict) -> list[Table1Row]:
    """``results.json``'s "table1" read back as typed rows."""
    from gpfverify.contract.serial import from_json

    return from_json(list[Table1Row], results["table1"], "table1")
