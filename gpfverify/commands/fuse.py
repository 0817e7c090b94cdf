"""``gpfverify fuse CASE.json --method M [--json]``: fuse one fusion step (methods in
:mod:`gpfverify.fusion.methods`)."""

from __future__ import annotations

import argparse
import json

import numpy as np

from gpfverify.errors import InputError
from gpfverify.fusion.case import load_case
from gpfverify.fusion.methods import METHODS, fuse_case


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("case", help="fusion-case JSON file (format in docs/fusion-case-format.md)")
    parser.add_argument("--method", required=True, choices=METHODS, help="fusion rule")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    parser.add_argument("--criterion", choices=("trace", "det"), default="trace",
                        help="CI/ICI weight criterion (default trace)")
    parser.add_argument("--c", type=float, default=None,
                        help="RCC-CI ellipsoid size c (default: chi-square 99%% quantile with D dof)")
    parser.add_argument("--on-empty", choices=("error", "enlarge"), default="error",
                        help="RCC-CI when the ellipsoids do not intersect: error (default) or use "
                             "2 x the smallest intersecting size")


def _text(result: dict) -> str:
    lines = [f"method: {result['method']}", "mean: " + " ".join(f"{x:.6g}" for x in result["mean"]), "cov:"]
    lines += ["  " + " ".join(f"{x:12.6g}" for x in row) for row in result["cov"]]
    for key in ("weights", "c", "criterion", "enlarged", "primal_dual_discrepancy", "condition_holds", "exact"):
        if key in result:
            lines.append(f"{key}: {result[key]}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    if args.c is not None and not args.c > 0:
        raise InputError(f"--c must be > 0, got {args.c}")
    result = fuse_case(load_case(args.case), args.method, args.criterion, args.c, args.on_empty)
    if not all(np.isfinite(result[key]).all() for key in ("mean", "cov")):
        raise InputError(f"{args.method} gave a non-finite result on this case: its numbers are too "
                         "large or too small in combination")
    print(json.dumps(result) if args.json else _text(result))
    return 0
