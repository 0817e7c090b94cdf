"""Contract of ``gpfverify check SYSTEM.py:NAME`` (a user's own system, SPEC §6): its parameters
and the record of one run. The command line is ``gpfverify check``'s own (commands/check.py);
these parameters are what it records in ``results.json``."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Literal

from gpfverify.contract.params import Params as ParamsBase
from gpfverify.contract.params import option
from gpfverify.errors import InputError
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.fusion.names import CHOICES_TEXT, canonical_rules

#: the Gaussian families a check can run (gpfverify.filters.families.FAMILY_NAMES)
FilterName = Literal["kf", "ekf", "ukf", "gp-adf", "gp-ukf"]
#: CI's weight criteria (gpfverify.fusion.ci.CRITERIA)
CiCriterion = Literal["trace", "det"]
#: RCC-CI's error norms (gpfverify.fusion.rcc_ci.METRICS)
RccMetric = Literal["euclidean", "scaled"]


@dataclass(frozen=True)
class Params(ParamsBase):
    """What a check ran: the system, the filter family, the data and the rank rule."""

    system: str = dataclasses.field(default="", metadata={
        "help": "SYSTEM.py:NAME, the file (absolute path) and the StateSpaceModel it defines"})
    filter: FilterName = option(
        "ukf", "the Gaussian family of every local filter and of the centre")
    steps: int = option(50, "steps per simulated run", minimum=1)
    measurements: str | None = option(None, "logged measurements RUN.npz (absolute path) instead of simulating")
    training: str | None = option(None, "GP families: training file TRAIN.npz (absolute path)")
    train: int = option(200, "GP families: samples drawn from the system to learn from", minimum=2,
                        flag="train-points", deprecated=("train",))
    fit_points: int | None = option(200, "GP families: at most this many samples for the evidence maximisation",
                                    minimum=2)
    restarts: int = option(2, "GP families: optimiser starts", minimum=1)
    methods: tuple[str, ...] = option(("cmf", "dmf", "cc", "ci"), "fusion rules run (cmf and dmf always; "
                                      "canonical names, an alias such as cw recorded as cc)")
    rank_rule: str = option("canonical", "rank rule of eq. 35: canonical[:TAU], absolute:TOL or numpy")
    ci_criterion: CiCriterion = option(
        "trace", "the weight criterion of CI (and ICI): trace (depends on the units of the state components) or "
        "det (unit-free)")
    rcc_metric: RccMetric = option(
        "euclidean", "the norm of RCC-CI's Chebyshev centre: euclidean (the paper's; depends on the units of the "
        "state components) or scaled (each component in its own scale: unit-free)")
    sigma_alpha: float | None = option(
        None, "sigma-point α of the ukf and gp-ukf filters for a gpfverify model (none: 1); a Stone Soup or "
        "filterpy system brings its own", above=0.0)
    sigma_beta: float | None = option(
        None, "sigma-point β of the ukf and gp-ukf filters for a gpfverify model (none: 0)")
    sigma_kappa: float | None = option(
        None, "sigma-point κ of the ukf and gp-ukf filters for a gpfverify model (none: 2)")

    def check(self) -> None:
        object.__setattr__(self, "methods", canonical_rules(self.methods))  # InputError for unknown names
        if "cmf" not in self.methods or "dmf" not in self.methods:
            raise InputError(f"--methods must include cmf and dmf (among {CHOICES_TEXT}), got "
                             f"{','.join(self.methods)}")
        self.sigma_params()  # InputError for α, κ that give no sigma points (D + λ ≤ 0 is checked per system)

    @property
    def sigma_given(self) -> bool:
        """Whether any of --sigma-alpha, --sigma-beta, --sigma-kappa was given."""
        return any(v is not None for v in (self.sigma_alpha, self.sigma_beta, self.sigma_kappa))

    def sigma_params(self) -> SigmaParams:
        """The sigma points of a gpfverify model's unscented filters: the given α, β, κ, each
        defaulting to gpfverify's (1, 0, 2)."""
        default = SigmaParams()
        return SigmaParams(default.alpha if self.sigma_alpha is None else self.sigma_alpha,
                           default.beta if self.sigma_beta is None else self.sigma_beta,
                           default.kappa if self.sigma_kappa is None else self.sigma_kappa)


@dataclass(frozen=True)
class RunRecord:
    """One run: whether the truth was known, and one audit entry per step (the fields the
    equivalence report reads; see :func:`gpfverify.experiments.check.run_one`)."""

    truth_known: bool
    steps: tuple[dict[str, Any], ...]


def verdict_sentence(results: dict) -> str:
    """The one plain-words verdict of a check, rendered from results.json's counts only (the console
    line and the report page alike): DMF = CMF to rounding (the one-step gap within the step's
    rounding bound, docs/fusion-definitions.md) at how many steps, how many of those had the rank
    condition and how many were exact, and why not elsewhere; each baseline that failed at some
    steps, with the first failure's step and reason."""
    total, held = results["total_steps"], results["condition_held_steps"]
    reproduced, exact = results["reproduced_steps"], results["exact_steps"]
    inexact = total - exact
    runs = results["runs_ok"]
    where = f"{total} steps" + (f" of {runs} runs" if runs > 1 else "")
    if reproduced == total:
        verdict = f"DMF reproduced CMF at all {where}"
        if held < total and inexact == 0:
            verdict += f" (the rank condition failed at {total - held}, exact anyway)"
        elif inexact:
            verdict += (f" (the rank condition failed at {total - held}; DMF was exact at {exact} of the {total}, "
                        f"and at the {inexact} where it was not the gap stayed within rounding)")
    else:
        reasons = [f"{inexact} not exact"] if inexact else []
        if results["branch_offset_steps"]:
            reasons.append(f"{results['branch_offset_steps']} with an angle branch offset")
        verdict = (f"DMF differed from CMF beyond rounding at {total - reproduced} of {where}"
                   + (f" ({', '.join(reasons)})" if reasons else ""))
    sentence = (f"{verdict}; largest one-step gap {results['max_gap']:.3g} "
                f"({results['max_gap_size']:.3g} prior standard deviations)")
    missing = [(m, n) for m, n in enumerate(results.get("reported_steps") or []) if n < total]
    if missing:  # the rank condition and exactness are over the sensors that reported at each step
        sentence += "; " + ", ".join(f"sensor {m} reported at {n} of {total}" for m, n in missing) + \
            " (each step judged over the sensors that reported)"
    failures = results.get("method_failures") or []
    for method in results.get("failed_methods") or []:
        mine = [f for f in failures if f["method"] == method]
        sentence += (f"; {method} failed at {len(mine)} of {total} steps (first at k = {mine[0]['k']}"
                     + (f" of run {mine[0]['run']}" if runs > 1 else "") + f": {mine[0]['reason']})")
    return sentence + "."
