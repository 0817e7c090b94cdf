"""Contract types shared by the fusion paper's two experiments (:mod:`gpfverify.papers.fusion.ct2d_contract`,
:mod:`gpfverify.papers.fusion.ungm1d_contract`; Liao et al. 2019 §4): the parameters both take
(:class:`FusionParams`), the twelve methods as :class:`~gpfverify.contract.methods.Method` values,
and the typed record of one Monte Carlo run (:class:`FusionRun`), which
:mod:`gpfverify.papers.fusion.run` computes and summarises.

Per step and method a run records ‖x − x̂‖² (for the RMSE, eq. 45) and the squared Mahalanobis
distance (x − x̂)ᵀC⁻¹(x − x̂) (eq. 44 as written), and each method's own computation time; for the
equivalence analysis the singular values of every local cross covariance C_xy^m, the rank decision,
the DMF − CMF gaps and the audit of every step on which the rank condition failed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from gpfverify.contract.methods import Method
from gpfverify.contract.params import Params, option
from gpfverify.errors import InputError
from gpfverify.fusion.exactness import DEFAULT_RANK_RULE, parse_rank_rule

#: the paper (a key of :data:`gpfverify.contract.papers.PAPERS`)
PAPER = "seed000"
#: the filter families the fusion paper runs every rule on
FAMILIES: tuple[str, ...] = ("GP-ADF", "GP-UKF")
#: the fusion rules besides the sensors' own filters, in the order of the paper's figures
FUSION_RULES: tuple[str, ...] = ("CMF", "DMF", "RCC-CI", "CW")
#: the number of sensors in both experiments
SENSORS = 2
#: what a NEES outside its χ² band means on the fusion pages (stated there; the same on every page:
#: a consistency finding, never a failed health gate, :mod:`gpfverify.contract.health_records`)
NEES_POLICY = (
    "NEES outside its χ² band is a consistency finding, reported apart from the health gates and never a reason "
    "to withhold a verdict on errors: the paper's GP-ADF and GP-UKF (and the fusion rules built on them) are "
    "optimistic as the paper specifies them — moments of GP models learned from κ training samples with no "
    "inflation for model error, sigma points through those models, and the start the paper prescribes; our "
    "implementations of the moments and of eq. 35 are certified separately (proofs page) — and covariance "
    "intersection (RCC-CI) and the convex combination may be pessimistic by design")


def family_methods(family: str) -> tuple[Method, ...]:
    """The six methods of one family: each sensor's filter, then CMF, DMF, RCC-CI, CW."""
    return (*(Method.sensor_filter(m, family) for m in range(1, SENSORS + 1)),
            *(Method(rule, family) for rule in FUSION_RULES))


#: the twelve methods of the paper's figures (keys as in CONTRACT.md)
METHODS: tuple[Method, ...] = tuple(m for family in FAMILIES for m in family_methods(family))
#: the local filters whose cross covariances C_xy^m decide Proposition 1
LOCAL_FILTERS: tuple[Method, ...] = tuple(m for m in METHODS if m.is_sensor)
#: the fusion methods (everything but the sensors' own filters)
FUSION_METHODS: tuple[Method, ...] = tuple(m for m in METHODS if not m.is_sensor)


#: the rank rule eq. 35 is run with unless another is given: the project's one default (unit-free)
DEFAULT_RULE = DEFAULT_RANK_RULE.name


@dataclass(frozen=True)
class FusionParams(Params):
    """Options both fusion experiments take: GP fitting, RCC-CI, the rank tolerance of eq. 35 and
    the sigma points of GP-UKF."""

    restarts: int = option(1, "evidence-maximisation restarts of the GP hyperparameter fit", minimum=1)
    fit_points: int = option(100, "at most this many training samples (evenly spaced) for the hyperparameter "
                             "fit; the GP then conditions on all of them", minimum=3)
    rcc_size: float | None = option(None, "RCC-CI ellipsoid size c (none: the chi-square 0.99 quantile with D "
                                    "degrees of freedom)", above=0)
    rcc_on_empty: Literal["enlarge", "error"] = option(
        "enlarge", "RCC-CI when the local ellipsoids do not intersect: enlarge c to twice the smallest "
        "intersecting size (the step is counted), or fail the run")
    rank_tol: float | None = option(None, "absolute singular-value tolerance for rank(C_xy^m) in eq. 35, the same "
                                    "as --rank-rule absolute:TOL (none: --rank-rule decides)", minimum=0)
    rank_rule: str = option(
        DEFAULT_RULE, "how eq. 35 decides rank(C_xy^m), as in check and audit: canonical[:TAU], numpy or "
        "absolute:TOL. Default canonical — canonical correlations of state and sensor output above τ (default "
        "√eps): unit-free, the project's one rule, which Proposition 1's verdicts are judged under. numpy — "
        "singular values of C_xy^m above σ_max · max(D, l) · eps (numpy's and MATLAB's rank(), perhaps the "
        "paper's; it depends on units and calls any nonzero scalar cross term full rank: the interpretation "
        "'numpy-rank'). absolute:TOL — singular values above TOL")
    alpha: float = option(1.0, "sigma-point α of GP-UKF", above=0)
    beta: float = option(0.0, "sigma-point β of GP-UKF")
    sigma_kappa: float = option(2.0, "sigma-point κ of GP-UKF")
    divergence_bound: float = option(1000.0, "health check: a run diverged when a filter's estimation error "
                                     "‖x − x̂‖ exceeds this (or is not finite) at some step", above=0)
    nees_level: float = option(0.95, "health check: level of the two-sided χ² interval of the ANEES per step",
                               above=0, maximum=0.9999)

    def check(self) -> None:
        try:
            parse_rank_rule(self.rank_rule)
        except InputError as exc:  # the accepted forms, named by the option that took the text
            raise InputError(f"--rank-rule: {exc}") from None
        if self.rank_tol is not None and self.rank_rule != DEFAULT_RULE:
            raise InputError(f"--rank-tol TOL is the rule absolute:TOL; --rank-rule {self.rank_rule} is another "
                             "rule: give one of them")

    @property
    def rank_rule_spec(self) -> str:
        """The rule as :func:`gpfverify.fusion.exactness.parse_rank_rule` reads it ("canonical",
        "absolute:1e-09", "numpy")."""
        return self.rank_rule if self.rank_tol is None else f"absolute:{self.rank_tol!r}"


# -- one run ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class SensorAuditRecord:
    """One sensor of an audited step (:func:`gpfverify.audit.case.audit_case`): the rank of its cross
    covariance C_xy^m with ``cols`` columns, its singular values, the rank tolerance, the largest
    gap per unit of lost component, and whether eq. 35 is still exact for it. ``index`` from 0."""

    index: int
    rank: int
    cols: int
    tol: float
    singular_values: tuple[float, ...]
    gap_gain_norm: float
    exact: bool


@dataclass(frozen=True)
class AuditEntry:
    """A step (numbered from 1) on which a rank condition failed: the DMF − CMF gap from the same
    central prediction, the closed-form gap, their difference and the size of the CMF correction."""

    step: int
    family: str
    condition_holds: bool
    exact: bool
    gap_norm: float
    predicted_gap_norm: float
    gap_error: float
    correction_norm: float
    sensors: tuple[SensorAuditRecord, ...]


@dataclass(frozen=True)
class FamilyRun:
    """One family's six methods over the test steps of a run. Per-method series are keyed by
    :attr:`Method.key`; per-sensor series by the sensor filter's key."""

    #: ‖x − x̂‖² per method and step
    sq_err: dict[str, tuple[float, ...]]
    #: (x − x̂)ᵀC⁻¹(x − x̂) per method and step
    maha: dict[str, tuple[float, ...]]
    #: singular values of C_xy^m per sensor and step, largest first
    singular_values: dict[str, tuple[tuple[float, ...], ...]]
    #: C_xy^m has full column rank at eq. 35's tolerance, per sensor and step
    full_rank: dict[str, tuple[bool, ...]]
    #: that tolerance, per sensor and step
    rank_tol: dict[str, tuple[float, ...]]
    #: ‖μ_DMF − μ_CMF‖ of the two recursive filters, per step
    recursive_gap: tuple[float, ...]
    #: ‖eq. 35 − CMF‖ from the same central prediction, per step
    one_step_gap: tuple[float, ...]
    #: that gap relative to the size of the CMF correction ‖μ_CMF − μ_p‖
    one_step_gap_rel: tuple[float, ...]
    #: every C_xy^m had full column rank (Proposition 1's condition), per step
    condition_holds: tuple[bool, ...]
    #: that gap whitened by the central prior, ‖L_p⁻¹(μ_DMF − μ_CMF)‖ in prior standard deviations
    #: (unit-free; :func:`gpfverify.fusion.exactness.gap_size`), per step
    gap_size: tuple[float, ...]
    #: its rounding bound in the same units, what the audit calls the step's "gap_bound"
    #: (:func:`gpfverify.fusion.exactness.equivalence_tolerance`), per step
    gap_bound: tuple[float, ...]
    audit: tuple[AuditEntry, ...]
    #: RCC-CI steps on which the ellipsoids had to be enlarged
    rcc_enlarged: int
    #: ‖Δμ_e‖ of one CMF step for a rounding-level nudge of the prior mean
    rounding_sensitivity: float
    #: each method's own computation time per step
    seconds: dict[str, tuple[float, ...]]
    #: CMF's and DMF's update alone (once the measurements arrive), per step
    online_seconds: dict[str, tuple[float, ...]]
    #: canonical correlations ρ of state and sensor output per sensor and step, largest first, when
    #: the canonical rule decided the rank (empty otherwise)
    correlations: dict[str, tuple[tuple[float, ...], ...]] = field(default_factory=dict)


@dataclass(frozen=True)
class GPHyperparameters:
    """A fitted GP stack: lengthscales (E, D), signal and noise variances (E,)."""

    lengthscales: tuple[tuple[float, ...], ...]
    signal_var: tuple[float, ...]
    noise_var: tuple[float, ...]


@dataclass(frozen=True)
class FittedModels:
    transition: GPHyperparameters
    sensors: tuple[GPHyperparameters, ...]


@dataclass(frozen=True)
class FusionRun:
    """One run of one setting: both families (keyed by family name), the GP training time and the
    fitted hyperparameters."""

    families: dict[str, FamilyRun]
    training_seconds: float
    hyperparameters: FittedModels
