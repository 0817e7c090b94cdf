"""``gpfverify fuse CASE.json --method M [--json]``: fuse one fusion step.

cmf: centralized update with the stacked y (needs "y"); dmf: Proposition 1 (eq. 35); cc:
convex combination (CW); ci: covariance intersection (--criterion); rcc-ci: relaxed Chebyshev
centre CI (--c, --on-empty); ici, ei: inverse covariance / ellipsoidal intersection. cc, ci,
rcc-ci, ici and ei use only the sensors' (mu_e, C_e) and need "C_e" in every local entry.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from gpfverify.errors import CaseFileError, InputError
from gpfverify.filters.records import Gaussian
from gpfverify.fusion.case import FusionCase, load_case

METHODS = ("cmf", "dmf", "cc", "ci", "rcc-ci", "ici", "ei")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("case", help="fusion-case JSON file (format in CONTRACT.md)")
    parser.add_argument("--method", required=True, choices=METHODS, help="fusion rule")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    parser.add_argument("--criterion", choices=("trace", "det"), default="trace",
                        help="CI/ICI weight criterion (default trace)")
    parser.add_argument("--c", type=float, default=None,
                        help="RCC-CI ellipsoid size c (default: chi-square 99%% quantile with D dof)")
    parser.add_argument("--on-empty", choices=("error", "enlarge"), default="error",
                        help="RCC-CI when the ellipsoids do not intersect: error (default) or use "
                             "2 x the smallest intersecting size")


def _local_estimates(case: FusionCase, method: str) -> list[Gaussian]:
    missing = [m for m, r in enumerate(case.locals) if r.C_e is None]
    if missing:
        raise CaseFileError(f"method {method} needs C_e in every local entry; locals[{missing[0]}] has none")
    return [Gaussian(r.mu_e, r.C_e) for r in case.locals]


def fuse_case(case: FusionCase, method: str, criterion: str = "trace", c: float | None = None,
              on_empty: str = "error") -> dict:
    """The ``fuse --json`` object for one method."""
    from gpfverify.fusion import ci, convex, ellipsoidal, rcc_ci
    from gpfverify.fusion.centralized import cmf_update
    from gpfverify.fusion.distributed import dmf_update

    extra = {}
    if method == "cmf":
        if case.y is None:
            raise CaseFileError("method cmf needs the stacked measurement 'y' in the case file")
        fused = cmf_update(case.central, case.y)
    elif method == "dmf":
        fused = dmf_update(case)
    elif method == "cc":
        fused = convex.convex_combination(_local_estimates(case, method))
    elif method == "ci":
        fused = ci.covariance_intersection(_local_estimates(case, method), criterion)
        extra = {"weights": fused.weights.tolist(), "criterion": criterion}
    elif method == "ici":
        fused = ci.inverse_covariance_intersection(_local_estimates(case, method), criterion)
        extra = {"weights": [] if fused.weights is None else fused.weights.tolist(), "criterion": criterion}
    elif method == "ei":
        fused = ellipsoidal.ellipsoidal_intersection(_local_estimates(case, method))
    elif method == "rcc-ci":
        res = rcc_ci.rcc_ci(_local_estimates(case, method), c=c, on_empty=on_empty)
        fused = res
        extra = {"weights": res.weights.tolist(), "c": res.c, "enlarged": res.enlarged,
                 "primal_mean": res.primal_mean.tolist(), "primal_dual_discrepancy": res.discrepancy}
    else:
        raise InputError(f"unknown method {method!r}")
    return {"method": method, "mean": np.asarray(fused.mean).tolist(),
            "cov": np.asarray(fused.cov).tolist(), **extra}


def _text(result: dict) -> str:
    lines = [f"method: {result['method']}", "mean: " + " ".join(f"{x:.6g}" for x in result["mean"]), "cov:"]
    lines += ["  " + " ".join(f"{x:12.6g}" for x in row) for row in result["cov"]]
    for key in ("weights", "c", "criterion", "enlarged", "primal_dual_discrepancy"):
        if key in result:
            lines.append(f"{key}: {result[key]}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    if args.c is not None and not args.c > 0:
        raise InputError(f"--c must be > 0, got {args.c}")
    result = fuse_case(load_case(args.case), args.method, args.criterion, args.c, args.on_empty)
    print(json.dumps(result) if args.json else _text(result))
    return 0
