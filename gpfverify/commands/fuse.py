"""``gpfverify fuse CASE.json --method M [--json]``: fuse one fusion step (methods in
:mod:`gpfverify.fusion.methods`, names in :mod:`gpfverify.fusion.names`)."""

from __future__ import annotations

import argparse
import json

import numpy as np

from gpfverify.cli import fusion_rule
from gpfverify.errors import InputError
from gpfverify.fusion.case import load_case
from gpfverify.fusion.methods import fuse_case
from gpfverify.fusion.names import CHOICES_TEXT


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("case", help="fusion-case JSON file (format in docs/fusion-case-format.md)")
    parser.add_argument("--method", required=True, type=fusion_rule, metavar="RULE",
                        help=f"fusion rule: {CHOICES_TEXT}")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    parser.add_argument("--criterion", choices=("trace", "det"), default="trace",
                        help="CI/ICI weight criterion (default trace)")
    parser.add_argument("--rcc-size", "--c", dest="rcc_size", type=float, default=None, metavar="C",
                        help="RCC-CI ellipsoid size c (default: the chi-square 0.99 quantile with D degrees "
                             "of freedom); the same option as reproduce's")
    parser.add_argument("--rcc-on-empty", "--on-empty", dest="rcc_on_empty", choices=("enlarge", "error"),
                        default="enlarge",
                        help="RCC-CI when the ellipsoids do not intersect: enlarge (default, as in reproduce "
                             "and check: c becomes twice the smallest intersecting size and the output says "
                             "'enlarged: True') or error")


def _text(result: dict) -> str:
    lines = [f"method: {result['method']}", "mean: " + " ".join(f"{x:.6g}" for x in result["mean"]), "cov:"]
    lines += ["  " + " ".join(f"{x:12.6g}" for x in row) for row in result["cov"]]
    for key in ("weights", "c", "criterion", "enlarged", "primal_dual_discrepancy", "condition_holds", "exact"):
        if key in result:
            lines.append(f"{key}: {result[key]}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    if args.rcc_size is not None and not args.rcc_size > 0:
        raise InputError(f"--rcc-size must be > 0, got {args.rcc_size}")
    result = fuse_case(load_case(args.case), args.method, args.criterion, args.rcc_size, args.rcc_on_empty)
    if not all(np.isfinite(result[key]).all() for key in ("mean", "cov")):
        raise InputError(f"{args.method} gave a non-finite result on this case: its numbers are too "
                         "large or too small in combination")
    print(json.dumps(result) if args.json else _text(result))
    return 0
