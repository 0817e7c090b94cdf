"""``gpfverify audit CASE.json [--json]``: rank-condition audit of one fusion step."""

from __future__ import annotations

import argparse
import json

from gpfverify.audit import RANK_RULE_DEFAULT, audit_case, audit_to_dict, format_audit
from gpfverify.fusion.case import load_case


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("case", help="fusion-case JSON file (format in docs/fusion-case-format.md)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    parser.add_argument("--rank-tol", type=float, default=None, metavar="TOL",
                        help="absolute singular-value tolerance for the rank of each C_xy^m; overrides "
                             f"the case's 'rank_tol'; default: {RANK_RULE_DEFAULT}")
    parser.add_argument("--sensitivity", action="store_true",
                        help="add each sensor's Jacobian norms of the fused mean (casadi AD) and the "
                             "|G_m C_y^m| / sigma_r bound")


def run(args: argparse.Namespace) -> int:
    from gpfverify.errors import InputError

    if args.rank_tol is not None and not args.rank_tol >= 0:
        raise InputError(f"--rank-tol must be >= 0, got {args.rank_tol}")
    audit = audit_case(load_case(args.case), args.rank_tol, sensitivity=args.sensitivity)
    print(json.dumps(audit_to_dict(audit)) if args.json else format_audit(audit))
    return 0
