"""Contract of the ``moments`` experiment: exact moment matching of a GP at a Gaussian input
(seed 000 §2.2, eq. 8–11 and 20, after Deisenroth et al. 2009) checked against two independent
oracles — tensor Gauss–Hermite quadrature and Monte Carlo — that use only predictions at
deterministic inputs (law of total covariance; :mod:`gpfverify.gp.reference`).

One run draws, for every case (D inputs, E outputs), a training set x ~ U[−r, r]^D with targets
sin(x·wₐ) + noise for each output a, fits a SE-ARD GP by evidence maximisation, draws an input
mean μ ~ U[−m, m]^D and an input covariance Σ = s (AAᵀ/D + 0.2 I) with A standard normal (D × D),
then compares the closed-form moments E[f], Cov[f], Cov[x, f] with both oracles. It also draws a
one-dimensional illustration (a GP through noisy sin x + ½ sin 2.5x, its moment-matched prediction
at one uncertain input, and a Monte Carlo histogram of f(x)) for the report's figure.

The computation is :mod:`gpfverify.papers.fusion.moments_experiment`.
"""

from __future__ import annotations

from dataclasses import dataclass

from gpfverify.contract.experiment import Profile, Setting
from gpfverify.contract.methods import Method
from gpfverify.contract.params import Params as ParamsBase
from gpfverify.contract.params import option
from gpfverify.errors import InputError

NAME = "moments"
PAPER = "seed000"
#: where the paper states the moments
SOURCE_EQUATIONS = "eq. (8)–(11) and (20)"
#: random problem sets of the full profile (the paper states no run count: these are our checks)
DEFAULT_RUNS = 5
#: random problem sets of the quick profile
QUICK_RUNS = 1
#: Monte Carlo samples per case in the quick profile
QUICK_SAMPLES = 20_000
#: Monte Carlo samples per case in the full profile (the default)
FULL_SAMPLES = 400_000
#: the largest input dimension: tensor quadrature grows as order^D
MAX_INPUT_DIM = 4
#: the three routes to the moments, as keys of ``time_per_run``
CLOSED_FORM = Method("closed-form")
QUADRATURE = Method("Gauss-Hermite")
MONTE_CARLO = Method("Monte-Carlo")
ROUTES: tuple[Method, ...] = (CLOSED_FORM, QUADRATURE, MONTE_CARLO)
#: the moments compared, as fields of :class:`Moments`
MOMENTS: tuple[str, ...] = ("mean", "cov", "cross_cov")
#: the illustration's input x ~ N(ILLUSTRATION_MEAN, ILLUSTRATION_VAR), training points, grid
ILLUSTRATION_MEAN = 0.8
ILLUSTRATION_VAR = 0.35
ILLUSTRATION_POINTS = 40
ILLUSTRATION_RANGE = 5.0
ILLUSTRATION_GRID = 400
ILLUSTRATION_BINS = 80


@dataclass(frozen=True)
class CaseShape:
    """A case: input dimension D and output dimension E."""

    input_dim: int
    output_dim: int

    @property
    def label(self) -> str:
        return f"D = {self.input_dim}, E = {self.output_dim}"


@dataclass(frozen=True)
class Params(ParamsBase):
    """The random test problems, the oracles' settings and the sample count."""

    cases: tuple[CaseShape, ...] = option(
        (CaseShape(1, 1), CaseShape(2, 3), CaseShape(3, 2)),
        "the (input dimension D, output dimension E) of each test problem", cli=False)
    samples: int = option(FULL_SAMPLES, "Monte Carlo samples of x per case", minimum=100)
    quadrature_rtol: float = option(
        1e-10, "Gauss–Hermite order raised (×1.5 from 10) until two successive rules agree to this, relative "
        "to the largest covariance entry", above=0.0)
    quadrature_max_nodes: int = option(300_000, "largest tensor Gauss–Hermite grid (nodes) per case", minimum=1000)
    train_points: int = option(60, "training points per test problem", minimum=2)
    train_range: float = option(3.0, "training inputs x ~ U[-r, r]^D", above=0.0)
    train_noise_std: float = option(0.05, "standard deviation of the training targets' noise", above=0.0)
    restarts: int = option(2, "evidence-maximisation restarts per GP", minimum=1)
    mean_range: float = option(1.0, "input means μ ~ U[-m, m]^D", minimum=0.0)
    input_cov_scale: float = option(0.3, "input covariance Σ = s (AAᵀ/D + 0.2 I)", above=0.0)

    def check(self) -> None:
        if not self.cases:
            raise InputError("cases must name at least one (D, E)")
        for case in self.cases:
            if not 1 <= case.input_dim <= MAX_INPUT_DIM or case.output_dim < 1:
                raise InputError(f"cases: D must be 1..{MAX_INPUT_DIM} and E at least 1, got {case.label}")


PROFILES: dict[str, Profile] = {
    "quick": Profile(QUICK_RUNS, (Setting("", "default", Params(samples=QUICK_SAMPLES)),)),
    "full": Profile(DEFAULT_RUNS, (Setting("", "default", Params(samples=FULL_SAMPLES)),)),
}


@dataclass(frozen=True)
class Moments:
    """Moments of f(x) for x ~ N(μ, Σ): ``mean`` (E,), ``cov`` (E × E, latent, no noise) and
    ``cross_cov`` = Cov[x, f(x)] (D × E); or their Monte Carlo standard errors, entry by entry."""

    mean: tuple[float, ...]
    cov: tuple[tuple[float, ...], ...]
    cross_cov: tuple[tuple[float, ...], ...]


@dataclass(frozen=True)
class CaseRecord:
    """One case of one run: the three routes' moments, the quadrature's last order and its own
    error estimate (the relative change between its last two rules)."""

    shape: CaseShape
    closed_form: Moments
    quadrature: Moments
    quadrature_order: int
    quadrature_change: float
    monte_carlo: Moments
    monte_carlo_se: Moments


@dataclass(frozen=True)
class Illustration:
    """A 1-D GP (training data, predictive mean and latent variance on a grid), the input
    x ~ N(input_mean, input_var), its moment-matched Gaussian N(matched_mean, matched_var) and a
    Monte Carlo histogram of f(x) (density per bin, ``bins + 1`` edges, ``samples`` draws)."""

    train_x: tuple[float, ...]
    train_y: tuple[float, ...]
    grid: tuple[float, ...]
    grid_mean: tuple[float, ...]
    grid_var: tuple[float, ...]
    input_mean: float
    input_var: float
    matched_mean: float
    matched_var: float
    histogram_edges: tuple[float, ...]
    histogram_density: tuple[float, ...]
    samples: int


@dataclass(frozen=True)
class RunRecord:
    """One run: every case, the illustration, and the wall-clock seconds of each route (keys:
    :data:`ROUTES`' keys, summed over cases)."""

    cases: tuple[CaseRecord, ...]
    illustration: Illustration
    seconds: dict[str, float]


@dataclass(frozen=True)
class CaseSummary:
    """One case over all runs (``results.json`` ``"cases"``): the quadrature's largest grid (nodes)
    and largest change between its last two rules; per moment, the largest relative error of the
    closed form against quadrature (max |closed − quadrature| / max |quadrature|); the closed
    form's error in the scale of the quadrature's convergence estimate (/ max |Cov|) and the
    allowance it is compared with (that estimate plus the rounding tolerance), both of the run
    where their ratio is largest; the largest |closed − Monte Carlo| / s.e. over entries and runs."""

    label: str
    input_dim: int
    output_dim: int
    quadrature_nodes: int
    quadrature_change: float
    rel_err: dict[str, float]
    quadrature_error: float
    quadrature_allowance: float
    max_z: float
