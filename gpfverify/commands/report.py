"""``gpfverify report``: build the verification report."""

from __future__ import annotations

import argparse
from pathlib import Path

from gpfverify.cli import non_negative_int, positive_int
from gpfverify.report import SECTIONS, ReportContext, build_report


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--full", action="store_true",
                        help="the papers' run counts (hours) instead of the quick profile (minutes)")
    parser.add_argument("--out", type=Path, default=None,
                        help="output folder (default reports/quick or reports/full)")
    parser.add_argument("--seed", type=non_negative_int, default=1, help="root seed, an integer >= 0 (default 1)")
    parser.add_argument("--workers", type=positive_int, default=1,
                        help="worker processes for experiments (>= 1; results do not depend on it)")
    parser.add_argument("--only", nargs="+", metavar="SECTION", choices=list(SECTIONS),
                        help=f"build (or rebuild) only these sections, keeping the others already in "
                             f"the output folder: {', '.join(SECTIONS)}")


def run(args: argparse.Namespace) -> int:
    profile = "full" if args.full else "quick"
    out = args.out or Path("reports") / profile
    html_path = build_report(ReportContext(out, profile, args.seed, args.workers), args.only)
    print(f"report written: {out / 'README.md'} and {html_path}")
    return 0
