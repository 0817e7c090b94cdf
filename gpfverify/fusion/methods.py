"""Every fusion rule by name, on a :class:`~gpfverify.fusion.case.FusionCase`, with a JSON-able
result (what ``gpfverify fuse --json`` prints).

cmf: centralized update with the stacked y (needs ``y``); dmf: Proposition 1 (eq. 35); cc: convex
combination (also spelled cw; names in :mod:`gpfverify.fusion.names`); ci: covariance
intersection; rcc-ci: relaxed Chebyshev centre CI; ici, ei: inverse covariance / ellipsoidal
intersection. cc, ci, rcc-ci, ici and ei use only the sensors' (mu_e, C_e) and need ``C_e`` in
every local report. The case's angle state components (``circular_state``) are averaged on the
circle by every rule.
"""

from __future__ import annotations

import numpy as np

from gpfverify.errors import CaseFileError, InputError
from gpfverify.filters.records import Gaussian
from gpfverify.fusion.case import FusionCase
from gpfverify.fusion.centralized import cmf_update
from gpfverify.fusion.ci import covariance_intersection, inverse_covariance_intersection
from gpfverify.fusion.convex import convex_combination
from gpfverify.fusion.distributed import DMFResult, dmf_update
from gpfverify.fusion.ellipsoidal import ellipsoidal_intersection
from gpfverify.fusion.estimates import FusedEstimate
from gpfverify.fusion.names import FUSION_RULES, canonical_rule
from gpfverify.fusion.rcc_ci import RccCiResult, rcc_ci
from gpfverify.validate import computed_covariance

METHODS = FUSION_RULES


def _local_estimates(case: FusionCase, method: str) -> list[Gaussian]:
    out = []
    for m, r in enumerate(case.locals):
        if r.C_e is None:
            raise CaseFileError(f"method {method} needs C_e in every local entry; locals[{m}] has none")
        out.append(Gaussian(r.mu_e, r.C_e))
    return out


def fuse_case(case: FusionCase, method: str, criterion: str = "trace", c: float | None = None,
              on_empty: str = "error", rank_rule=None, rcc_metric: str = "euclidean") -> dict:
    """The ``fuse --json`` object for one method (any accepted spelling; the object names the
    canonical one). ``criterion``: the weight criterion of CI and ICI ("trace", which depends on the
    units of the state components, or "det", unit-free). ``rank_rule`` (dmf): a
    :class:`~gpfverify.fusion.exactness.RankRule` or its string, default the case's ``rank_tol``
    (absolute), else canonical; the object names the rule that decided (``"rank_rule"``).
    ``rcc_metric``: RCC-CI's error norm ("euclidean" or "scaled", unit-free)."""
    method = canonical_rule(method)
    extra: dict = {}
    angles = case.circular_state
    fused: Gaussian | FusedEstimate | DMFResult | RccCiResult
    if method == "cmf":
        if case.y is None:
            raise CaseFileError("method cmf needs the stacked measurement 'y' in the case file")
        fused = cmf_update(case.central, case.y)
    elif method == "dmf":
        dmf = dmf_update(case, rank_rule=rank_rule)
        fused = dmf
        assert dmf.rank_rule is not None  # dmf_update records the rule that decided
        extra = {"condition_holds": dmf.condition_holds, "exact": dmf.exact,
                 "rank_rule": {"name": dmf.rank_rule.name, "tol": dmf.rank_rule.tol,
                               "description": dmf.rank_rule.describe()}}
    elif method == "cc":
        fused = convex_combination(_local_estimates(case, method), angles)
    elif method == "ci":
        ci = covariance_intersection(_local_estimates(case, method), criterion, circular_state=angles)
        assert ci.weights is not None  # CI always reports its weights ω
        fused = ci
        extra = {"weights": ci.weights.tolist(), "criterion": criterion}
    elif method == "ici":
        ici = inverse_covariance_intersection(_local_estimates(case, method), criterion, angles)
        fused = ici
        extra = {"weights": [] if ici.weights is None else ici.weights.tolist(), "criterion": criterion}
    elif method == "ei":
        fused = ellipsoidal_intersection(_local_estimates(case, method), angles)
    elif method == "rcc-ci":
        res = rcc_ci(_local_estimates(case, method), c=c, on_empty=on_empty, circular_state=angles, metric=rcc_metric)
        fused = res
        extra = {"weights": res.weights.tolist(), "c": res.c, "enlarged": res.enlarged, "metric": rcc_metric,
                 "primal_mean": res.primal_mean.tolist(), "primal_dual_discrepancy": res.discrepancy}
    else:
        raise InputError(f"unknown method {method!r}")
    cov = computed_covariance(fused.cov, f"the {method} fused covariance")
    return {"method": method, "mean": np.asarray(fused.mean).tolist(), "cov": cov.tolist(), **extra}
