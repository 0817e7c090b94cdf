"""``gpfverify fuse CASE.json --method M [--json]``: fuse one fusion step (methods in
:mod:`gpfverify.fusion.methods`, names in :mod:`gpfverify.fusion.names`)."""

from __future__ import annotations

import argparse
import json

import numpy as np

from gpfverify.cli import RANK_RULE_HELP, fusion_rule, rank_rule_text
from gpfverify.errors import InputError
from gpfverify.fusion.caseblock import load_case
from gpfverify.fusion.methods import fuse_case
from gpfverify.fusion.names import CHOICES_TEXT


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("case", help="fusion-case JSON file (format in docs/fusion-case-format.md)")
    parser.add_argument("--method", required=True, type=fusion_rule, metavar="RULE",
                        help=f"fusion rule: {CHOICES_TEXT}")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    parser.add_argument("--ci-criterion", "--criterion", dest="ci_criterion", choices=("trace", "det"),
                        default="trace",
                        help="CI's and ICI's weight criterion: trace (default; minimises the fused bound's trace, "
                             "which depends on the units of the state components) or det (its determinant: "
                             "unit-free); --criterion is the same option")
    parser.add_argument("--rank-rule", type=rank_rule_text, default=None, metavar="RULE",
                        help=RANK_RULE_HELP + " For --method dmf; default the case's 'rank_tol' (absolute), else "
                             "canonical, as audit and check. The output names the rule that decided.")
    parser.add_argument("--rcc-size", "--c", dest="rcc_size", type=float, default=None, metavar="C",
                        help="RCC-CI ellipsoid size c (default: the chi-square 0.99 quantile with D degrees "
                             "of freedom); the same option as reproduce's")
    parser.add_argument("--rcc-metric", choices=("euclidean", "scaled"), default="euclidean",
                        help="the norm of RCC-CI's Chebyshev centre: euclidean (default, the paper's; depends on "
                             "the units of the state components) or scaled (each component in the scale of the "
                             "local estimates' mean information: unit-free)")
    parser.add_argument("--rcc-on-empty", "--on-empty", dest="rcc_on_empty", choices=("enlarge", "error"),
                        default="enlarge",
                        help="RCC-CI when the ellipsoids do not intersect: enlarge (default, as in reproduce "
                             "and check: c becomes twice the smallest intersecting size and the output says "
                             "'enlarged: True') or error")


def _text(result: dict) -> str:
    lines = [f"method: {result['method']}", "mean: " + " ".join(f"{x:.6g}" for x in result["mean"]), "cov:"]
    lines += ["  " + " ".join(f"{x:12.6g}" for x in row) for row in result["cov"]]
    for key in ("weights", "c", "metric", "criterion", "enlarged", "primal_dual_discrepancy", "condition_holds",
                "exact"):
        if key in result:
            lines.append(f"{key}: {result[key]}")
    if "rank_rule" in result:
        lines.append(f"rank rule: {result['rank_rule']['description']}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    if args.rcc_size is not None and not args.rcc_size > 0:
        raise InputError(f"--rcc-size must be > 0, got {args.rcc_size}")
    if args.rank_rule is not None and args.method != "dmf":
        raise InputError(f"--rank-rule decides eq. 35's ranks: it applies to --method dmf, not {args.method}")
    result = fuse_case(load_case(args.case), args.method, args.ci_criterion, args.rcc_size, args.rcc_on_empty,
                       rank_rule=args.rank_rule, rcc_metric=args.rcc_metric)
    if not all(np.isfinite(result[key]).all() for key in ("mean", "cov")):
        raise InputError(f"{args.method} gave a non-finite result on this case: its numbers are too "
                         "large or too small in combination")
    print(json.dumps(result) if args.json else _text(result))
    return 0
