"""``gpfverify audit FILE [--json]``: rank-condition audit of one fusion step (a case file) or of
every step of a run file (.jsonl, .npz; :mod:`gpfverify.fusion.runfile`).

:func:`audit_run_file` returns the run audit, the per-step JSON objects and the summary, for
callers that render them otherwise (e.g. a report).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from gpfverify.audit import (RANK_RULE_DEFAULT, RunAudit, audit_case, audit_to_dict, format_audit,
                             parse_rank_rule)
from gpfverify.errors import InputError
from gpfverify.fusion.runfile import load_run, run_format
from gpfverify.report.document import integer_ranges

EPILOG = ("FILE formats: a single fusion case (.json) is described in docs/fusion-case-format.md; "
          "a run of cases, one per step (.jsonl: one case per line with an optional integer \"k\"; "
          ".npz: arrays stacked over the steps), in docs/run-file-format.md. JSON Schemas: "
          "docs/schemas/. A run prints {\"steps\": [...], \"summary\": {...}} with --json, a per-step "
          "table and the summary otherwise.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.epilog = EPILOG
    parser.add_argument("case", metavar="FILE",
                        help="a fusion case (.json; docs/fusion-case-format.md) or a run file (.jsonl, "
                             ".npz; docs/run-file-format.md)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    parser.add_argument("--rank-tol", type=float, default=None, metavar="TOL",
                        help="absolute singular-value tolerance for the rank of each C_xy^m; overrides "
                             f"the case's 'rank_tol'; default: {RANK_RULE_DEFAULT}")
    parser.add_argument("--rank-rule", default=None, metavar="RULE",
                        help="how the rank of each C_xy^m is decided: canonical[:TAU] (canonical "
                             "correlations > TAU, unit-free), absolute:TOL (singular values > TOL) or "
                             "numpy; overrides the case's 'rank_tol'; not together with --rank-tol")
    parser.add_argument("--out", type=Path, default=None, metavar="DIR",
                        help="run files: write the report (DIR/report.html, DIR/README.md, figures, "
                             "DIR/audit.json)")
    parser.add_argument("--sensitivity", action="store_true",
                        help="add each sensor's Jacobian norms of the fused mean (casadi AD) and the "
                             "|G_m C_y^m| / sigma_r bound")


def _resolve_rank_rule(rule):
    """``rule`` as a :class:`~gpfverify.fusion.exactness.RankRule` (strings parsed by
    ``parse_rank_rule``, which raises InputError for a bad one); None stays None."""
    return parse_rank_rule(rule) if isinstance(rule, str) else rule


def _audit(case, rank_tol, rank_rule, sensitivity):
    return audit_case(case, rank_tol, sensitivity=sensitivity, rank_rule=rank_rule)


def _run_rank_rule(steps: list[dict]):
    """The run's ``rank_rule``: the steps' common top-level object; with ``"covariance":
    "mixed"`` when only the whitening covariance differs; else the list of distinct objects
    (steps decided by different rules, e.g. per-line ``rank_tol``)."""
    rules = [s["rank_rule"] for s in steps]
    if all(r == rules[0] for r in rules):
        return rules[0]
    if isinstance(rules[0], dict):
        bare = [{k: v for k, v in r.items() if k != "covariance"} for r in rules]
        if all(b == bare[0] for b in bare):
            return {**rules[0], "covariance": "mixed"}
    distinct = []
    for r in rules:
        if r not in distinct:
            distinct.append(r)
    return distinct


def run_summary(run: RunAudit, ks, steps: list[dict]) -> dict:
    """The ``summary`` object of a run audit (docs/run-file-format.md)."""
    gap = run.gap_norm
    with_y = ~np.isnan(gap)
    summary = {
        "steps": len(run.steps),
        "condition_held_steps": int(sum(s.condition_holds for s in run.steps)),
        "exact_steps": int(sum(s.exact for s in run.steps)),
        "steps_with_y": int(with_y.sum()),
        "max_gap_norm": float(gap[with_y].max()) if with_y.any() else None,
        "max_gap_k": int(ks[int(np.nanargmax(gap))]) if with_y.any() else None,
        "sensors": [],
        "rank_rule": _run_rank_rule(steps),
    }
    full, exact = run.full_column_rank, run.exact
    for m in range(full.shape[1]):
        summary["sensors"].append({
            "index": m,
            "rank_lost_steps": [int(ks[t]) for t in np.flatnonzero(~full[:, m])],
            "rank_lost_not_exact_steps": [int(ks[t]) for t in np.flatnonzero(~full[:, m] & ~exact[:, m])],
        })
    return summary


def audit_run_file(path, rank_rule=None, rank_tol: float | None = None, sensitivity: bool = False):
    """Audit every step of a run file (or a single case file, as one step):
    ``(RunAudit, steps, summary)`` with ``steps[t]`` the ``audit --json`` object of step t plus
    its ``"k"`` and ``summary`` as printed by ``audit --json``. ``rank_rule`` is a rule object or a
    string for ``parse_rank_rule``; ``rank_tol`` (absolute) overrides every case's ``rank_tol``;
    without either, each case's ``rank_tol`` or the audit's default rule decides.
    Raises :class:`~gpfverify.errors.CaseFileError` for a malformed file."""
    rule = _resolve_rank_rule(rank_rule)
    run_file = load_run(path)
    audits = tuple(_audit(case, rank_tol, rule, sensitivity) for _, case in run_file.steps)
    steps = [{"k": k, **audit_to_dict(a)} for (k, _), a in zip(run_file.steps, audits)]
    run = RunAudit(audits)
    return run, steps, run_summary(run, run_file.ks, steps)


def format_run(steps: list[dict], summary: dict) -> str:
    """Per-step table and summary of a run audit (text output)."""
    rule = summary["rank_rule"]
    rules = [rule] if not isinstance(rule, list) else rule
    text = [r.get("description", str(r)) if isinstance(r, dict) else str(r) for r in rules]
    lines = [f"rank rule: {'; '.join(text)}", "",
             f"{'k':>6} {'condition':>9} {'exact':>5}  {'rank/cols per sensor':<24} {'|gap|':>10} "
             f"{'|predicted|':>11}"]
    for s in steps:
        ranks = " ".join(f"{x['rank']}/{x['cols']}" + ("" if x["exact"] else "!") for x in s["sensors"])
        gap = f"{s['gap_norm']:.3g}" if "gap_norm" in s else "-"
        pred = f"{float(np.linalg.norm(s['predicted_gap'])):.3g}" if "predicted_gap" in s else "-"
        lines.append(f"{s['k']:>6} {str(s['condition_holds']):>9} {str(s['exact']):>5}  {ranks:<24} "
                     f"{gap:>10} {pred:>11}")
    lines += ["", "(r/l! : sensor not exact at that step)", "",
              f"steps: {summary['steps']}; Proposition 1 condition held at {summary['condition_held_steps']}; "
              f"DMF exact at {summary['exact_steps']}"]
    if summary["max_gap_norm"] is None:
        lines.append("no step has y: gaps not evaluated")
    else:
        lines.append(f"max |DMF - CMF| = {summary['max_gap_norm']:.3g} at k = {summary['max_gap_k']} "
                     f"({summary['steps_with_y']} step(s) with y)")
    for s in summary["sensors"]:
        if s["rank_lost_steps"]:
            lost = integer_ranges(s["rank_lost_steps"], "-")
            lines.append(f"sensor {s['index']}: lost full column rank at k = {lost}; "
                         f"not exact at " + (f"k = {integer_ranges(s['rank_lost_not_exact_steps'], '-')}"
                                             if s["rank_lost_not_exact_steps"] else "none of them"))
        else:
            lines.append(f"sensor {s['index']}: full column rank at every step")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    if args.rank_tol is not None and not args.rank_tol >= 0:
        raise InputError(f"--rank-tol must be >= 0, got {args.rank_tol}")
    if args.rank_tol is not None and args.rank_rule is not None:
        raise InputError("give --rank-tol or --rank-rule, not both")
    if run_format(args.case) == "json":  # one case: output as it always was
        if args.out is not None:
            raise InputError("--out writes the report of a run file (.jsonl or .npz); a single case has none")
        from gpfverify.fusion.case import load_case

        audit = _audit(load_case(args.case), args.rank_tol, _resolve_rank_rule(args.rank_rule),
                       args.sensitivity)
        print(json.dumps(audit_to_dict(audit)) if args.json else format_audit(audit))
        return 0
    _, steps, summary = audit_run_file(args.case, args.rank_rule, args.rank_tol, args.sensitivity)
    if args.out is not None:
        from gpfverify.report.equivalence import write_run_audit_report

        write_run_audit_report({"steps": steps, "summary": summary, "rank_rule": summary["rank_rule"]}, args.out)
    if args.json:
        print(json.dumps({"steps": steps, "summary": summary, "rank_rule": summary["rank_rule"]}))
    else:
        print(format_run(steps, summary))
    return 0
