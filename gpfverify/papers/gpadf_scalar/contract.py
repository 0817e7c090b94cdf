"""Contract of the ``gpadf-scalar`` experiment (the scalar benchmark of Deisenroth, Huber and
Hanebeck, ICML 2009; reference [7] of Liao et al. 2019 and SPEC §4): parameters, run profiles,
the per-run record and the summary rows the report reads.

    x₁ = 0.5x₀ + 25x₀/(1 + x₀²) + w,  w ~ N(0, 0.2²);   y₁ = 5 sin(2x₁) + v,  v ~ N(0, 0.01²);
    x₀ ~ N(μ₀, 0.5²), μ₀ ~ U[−10, 10]; one predict–update step per test case.

The computation is :mod:`gpfverify.papers.gpadf_scalar.experiment`.
"""

from __future__ import annotations

from dataclasses import dataclass

from gpfverify.contract.experiment import Profile, Setting
from gpfverify.contract.methods import Method
from gpfverify.contract.params import Params as ParamsBase
from gpfverify.contract.params import option

NAME = "gpadf-scalar"
#: the benchmark's paper: the GP-ADF filter whose moments the fusion paper (seed 000) builds on,
#: its reference [7] (SPEC §4)
PAPER = "deisenroth2009"
#: the run count of the full profile (20 independent training sets and test sets)
DEFAULT_RUNS = 20
#: runs of the quick report profile
QUICK_RUNS = 5
#: the four filters, in table order: UKF and EKF on the true model, GP-UKF and GP-ADF on learned GPs
METHODS: tuple[Method, ...] = tuple(Method(family) for family in ("UKF", "EKF", "GP-UKF", "GP-ADF"))
#: the method whose claims the paper makes
GP_ADF = Method("GP-ADF")
#: P(|z| > 2) for z ~ N(0, 1): the ±2σ exceedance of a calibrated Gaussian posterior
CALIBRATED_EXCEEDANCE = 0.04550026389635842


@dataclass(frozen=True)
class Params(ParamsBase):
    """The benchmark's numbers (defaults: Deisenroth et al. 2009) and the filters' settings."""

    train_points: int = option(100, "training points per GP", minimum=2)
    test_points: int = option(200, "test cases (prior means μ₀) per run", minimum=2)
    prior_std: float = option(0.5, "standard deviation of each test case's prior N(μ₀, σ₀²)", above=0.0)
    system_noise_std: float = option(0.2, "standard deviation of the transition noise w", above=0.0)
    measurement_noise_std: float = option(0.01, "standard deviation of the measurement noise v", above=0.0)
    domain: float = option(10.0, "training inputs and prior means on [-domain, domain]", above=0.0)
    restarts: int = option(3, "evidence-maximisation restarts per GP", minimum=1)
    alpha: float = option(1.0, "sigma-point spread α (UKF, GP-UKF)", above=0.0)
    beta: float = option(0.0, "sigma-point β (prior-knowledge weight of the centre point)")
    kappa: float = option(2.0, "sigma-point κ; the scalar state needs α²(1 + κ) > 0, i.e. κ > -1",
                          above=-1.0, flag="sigma-kappa", deprecated=("kappa",))


PROFILES: dict[str, Profile] = {
    "quick": Profile(QUICK_RUNS, (Setting("", "default", Params()),)),
    "full": Profile(DEFAULT_RUNS, (Setting("", "default", Params()),)),
}


@dataclass(frozen=True)
class Scores:
    """Per test case (each tuple has ``test_points`` entries): NLL = −log N(x₁ | μₑ, σₑ²) in nats,
    Mahalanobis distance |x₁ − μₑ|/σₑ and squared error (x₁ − μₑ)²."""

    nll: tuple[float, ...]
    maha: tuple[float, ...]
    sq_err: tuple[float, ...]


@dataclass(frozen=True)
class Posterior:
    """A filter's posterior N(mean, std²) per test case."""

    mean: tuple[float, ...]
    std: tuple[float, ...]


@dataclass(frozen=True)
class Cases:
    """The test cases of a run: prior means μ₀, true states x₁, measurements y₁."""

    prior_mean: tuple[float, ...]
    x1: tuple[float, ...]
    y1: tuple[float, ...]


@dataclass(frozen=True)
class Hyperparameters:
    """A fitted scalar GP: lengthscale ℓ, signal variance α², noise variance σ²."""

    lengthscale: float
    signal_var: float
    noise_var: float


@dataclass(frozen=True)
class FittedGPs:
    transition: Hyperparameters
    measurement: Hyperparameters


@dataclass(frozen=True)
class RunRecord:
    """One run: scores and posteriors per filter (keys: :data:`METHODS`' keys), the filters'
    wall-clock seconds, GP fitting seconds, the test cases and the fitted GPs."""

    scores: dict[str, Scores]
    posteriors: dict[str, Posterior]
    seconds: dict[str, float]
    fit_seconds: float
    cases: Cases
    gps: FittedGPs


@dataclass(frozen=True)
class TableRow:
    """One filter over the pooled test cases of all runs (``results.json`` ``"table"``): mean and
    standard error of NLL, Mahalanobis distance, NEES (its square); RMSE with its delta-method
    s.e.; NEES sample standard deviation; the fraction of cases outside μₑ ± 2σₑ; the number of
    cases; the s.e. of the NLL and Mahalanobis over per-run means (seed-to-seed spread)."""

    nll: float
    nll_se: float
    maha: float
    maha_se: float
    rmse: float
    rmse_se: float
    nees: float
    nees_se: float
    nees_std: float
    outside_2sigma: float
    cases: int
    nll_se_runs: float
    maha_se_runs: float


@dataclass(frozen=True)
class PerRun:
    """Per-run means of one filter (``results.json`` ``"per_run"``)."""

    nll: tuple[float, ...]
    maha: tuple[float, ...]
    rmse: tuple[float, ...]


@dataclass(frozen=True)
class Example:
    """The first run's cases and posteriors (``results.json`` ``"example"``), for the figure."""

    cases: Cases
    posteriors: dict[str, Posterior]
