"""``gpfverify audit FILE [--json]``: rank-condition audit of one fusion step (a case file) or of
every step of a run file (.jsonl, .npz; :mod:`gpfverify.audit.runfile`).

:func:`audit_run_file` returns the run audit, the per-step JSON objects and the summary, for
callers that render them otherwise (e.g. a report).
"""

from __future__ import annotations

import argparse
import contextlib
import json

from gpfverify.audit.case import (RANK_RULE_DEFAULT, RunAudit, audit_case, audit_to_dict, format_audit, parse_rank_rule)
from gpfverify.cli import RANK_RULE_HELP, positive_int, rank_rule_text
from gpfverify.errors import InputError
from gpfverify.audit.runfile import run_format
from gpfverify.runtime import progress_shown
from gpfverify.outputs import add_wait_argument, final_path, out_path, output_folder
from gpfverify.report.document import integer_ranges
from gpfverify.audit.run import copy_out, spool, stream_audit, table_header, table_row
from gpfverify.streams import diagnostics

EPILOG = ("FILE formats: a single fusion case (.json) is described in docs/fusion-case-format.md; "
          "a run of cases, one per step (.jsonl: one case per line with an optional integer \"k\"; "
          ".npz: arrays stacked over the steps), in docs/run-file-format.md. JSON Schemas: "
          "docs/schemas/. A run prints one verdict line, {\"steps\": [...], \"summary\": {...}} with --json, "
          "the per-step table and the summary with --table.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.epilog = EPILOG
    parser.add_argument("case", metavar="FILE",
                        help="a fusion case (.json; docs/fusion-case-format.md) or a run file (.jsonl, "
                             ".npz; docs/run-file-format.md)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    parser.add_argument("--table", action="store_true",
                        help="run files: print the per-step table and the summary instead of the one verdict line "
                             "(the report page of --out has both)")
    parser.add_argument("--rank-tol", type=float, default=None, metavar="TOL",
                        help="absolute singular-value tolerance for the rank of each C_xy^m; overrides "
                             f"the case's 'rank_tol'; default: {RANK_RULE_DEFAULT}")
    parser.add_argument("--rank-rule", type=rank_rule_text, default=None, metavar="RULE",
                        help=RANK_RULE_HELP + " Overrides the case's 'rank_tol'; not together with "
                             "--rank-tol. Default: the case's 'rank_tol' (absolute), else canonical, which "
                             "does not depend on units (as in check and reproduce). The output names the rule "
                             "that decided.")
    parser.add_argument("--out", type=out_path, default=None, metavar="DIR",
                        help="run files: write the report (DIR/report.html, DIR/README.md, figures, "
                             "DIR/audit.json)")
    add_wait_argument(parser)
    parser.add_argument("--workers", type=positive_int, default=1, metavar="N",
                        help="run files: audit blocks of steps in N processes (same output for any N)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="run files: audit blocks on a dask.distributed cluster at ADDRESS")
    parser.add_argument("--sensitivity", action="store_true",
                        help="add each sensor's Jacobian norms of the fused mean (casadi AD) and the "
                             "|G_m C_y^m| / sigma_r bound")


def _resolve_rank_rule(rule):
    """``rule`` as a :class:`~gpfverify.fusion.exactness.RankRule` (strings parsed by
    ``parse_rank_rule``, which raises InputError for a bad one); None stays None."""
    return parse_rank_rule(rule) if isinstance(rule, str) else rule


def _audit(case, rank_tol, rank_rule, sensitivity):
    return audit_case(case, rank_tol, sensitivity=sensitivity, rank_rule=rank_rule)


def audit_run_file(path, rank_rule=None, rank_tol: float | None = None, sensitivity: bool = False,
                   show_progress: bool | None = None):
    """Audit every step of a run file (or a single case file, as one step):
    ``(RunAudit, steps, summary)`` with ``steps[t]`` the ``audit --json`` object of step t plus
    its ``"k"`` and ``summary`` as printed by ``audit --json``. ``rank_rule`` is a rule object or a
    string for ``parse_rank_rule``; ``rank_tol`` (absolute) overrides every case's ``rank_tol``;
    without either, each case's ``rank_tol`` or the audit's default rule decides. Holds the whole
    run: for long runs use :func:`gpfverify.audit.run.stream_audit`. ``show_progress`` draws a
    progress bar (default: on a terminal and in a Jupyter notebook).
    Raises :class:`~gpfverify.errors.CaseFileError` for a malformed file."""
    with _progress(progress_shown() if show_progress is None else show_progress) as progress:
        task = progress.add_task("audit", total=None) if progress is not None else None

        def on_block(done: int, total: int | None) -> None:
            if progress is not None:
                progress.update(task, completed=done, total=total)

        summary, steps, audits = stream_audit(path, None, form="none", rank_rule=_resolve_rank_rule(rank_rule),
                                              rank_tol=rank_tol, sensitivity=sensitivity, on_block=on_block,
                                              keep=True)
    return RunAudit(tuple(audits)), steps, summary


#: ranges of step indices a summary line shows before "…" (every index is in ``--json``)
RANGES_SHOWN = 20


def _steps(ks) -> str:
    """Step indices as ranges for a summary line, at most :data:`RANGES_SHOWN` of them."""
    return integer_ranges(ks, "-", RANGES_SHOWN)


def format_summary(summary: dict) -> str:
    """The summary of a run audit as text (after the per-step table)."""
    rule = summary["rank_rule"]
    rules = [rule] if not isinstance(rule, list) else rule
    text = [r.get("description", str(r)) if isinstance(r, dict) else str(r) for r in rules]
    lines = ["(r/l! : sensor not exact at that step)", "", f"rank rule: {'; '.join(text)}",
             f"steps: {summary['steps']}; Proposition 1 condition held at {summary['condition_held_steps']}; "
             f"DMF exact at {summary['exact_steps']}"]
    if summary["max_gap_norm"] is None:
        lines.append("no step has y: gaps not evaluated")
    else:
        lines.append(f"max |DMF - CMF| = {summary['max_gap_norm']:.3g} at k = {summary['max_gap_k']} "
                     f"({summary['steps_with_y']} step(s) with y)")
    for s in summary["sensors"]:
        if s["rank_lost_steps"]:
            lost = _steps(s["rank_lost_steps"])
            lines.append(f"sensor {s['index']}: lost full column rank at k = {lost}; "
                         f"not exact at " + (f"k = {_steps(s['rank_lost_not_exact_steps'])}"
                                             if s["rank_lost_not_exact_steps"] else "none of them"))
        else:
            lines.append(f"sensor {s['index']}: full column rank at every step")
    return "\n".join(lines)


def verdict_line(summary: dict) -> str:
    """The one line ``audit RUN`` prints: at how many steps DMF was exact and the rank condition
    held, the sensors that lost full column rank (where, and where not exact), the largest gap
    and the rank rule — rendered from the run audit's summary record."""
    total, exact, held = summary["steps"], summary["exact_steps"], summary["condition_held_steps"]
    steps = f"{total} step{'s' if total != 1 else ''}"
    if exact == total:
        line = f"DMF exact at all {steps}"
    else:
        line = f"DMF NOT exact at {total - exact} of {steps}"
    line += f" (the rank condition held at {'all' if held == total else held}"
    for s in summary["sensors"]:
        if s["rank_lost_steps"]:
            bad = s["rank_lost_not_exact_steps"]
            line += (f"; sensor {s['index']} lost full column rank at k = {_steps(s['rank_lost_steps'])}"
                     + (f", not exact at k = {_steps(bad)}" if bad else ", exact anyway"))
    line += ")"
    if summary["max_gap_norm"] is None:
        line += "; no step has y, so the gap is not evaluated"
    else:
        line += (f"; largest |DMF - CMF| {summary['max_gap_norm']:.3g} at k = {summary['max_gap_k']} "
                 f"({summary['steps_with_y']} step(s) with y)")
    rule = summary["rank_rule"]
    rules = rule if isinstance(rule, list) else [rule]
    text = "; ".join(r.get("description", str(r)) if isinstance(r, dict) else str(r) for r in rules)
    return line + f"; rank rule: {text}."


def format_run(steps: list[dict], summary: dict) -> str:
    """Per-step table and summary of a run audit (text output)."""
    return "\n".join([table_header(), *(table_row(s) for s in steps), "", format_summary(summary)])


def _progress(show: bool):
    """A progress bar on stderr (``show``), called as ``update(done, total)``."""
    if not show:
        return contextlib.nullcontext(None)
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    return Progress(TextColumn("audit"), BarColumn(), MofNCompleteColumn(), TextColumn("steps"),
                    TimeElapsedColumn(), transient=True, console=Console(file=diagnostics()))


def _audit_run(args: argparse.Namespace) -> None:
    from gpfverify.experiments.runner import check_workers, make_executor

    check_workers(args.workers)
    rule = _resolve_rank_rule(args.rank_rule)
    form = "json" if args.json else "text" if args.table else "none"
    parallel = args.workers > 1 or args.scheduler is not None
    with contextlib.ExitStack() as stack:
        # the folder first: refused (or locked) before the audit costs anything
        stage = stack.enter_context(output_folder(args.out, keep=False, wait=args.wait)) if args.out else None
        out = stack.enter_context(spool())
        executor = stack.enter_context(make_executor(args.workers, args.scheduler)) if parallel else None
        progress = stack.enter_context(_progress(progress_shown()))
        task = progress.add_task("audit", total=None) if progress is not None else None

        def on_block(done: int, total: int | None) -> None:
            if progress is not None:
                progress.update(task, completed=done, total=total)

        in_flight = 2 * args.workers if args.scheduler is None else 64
        summary, steps, _ = stream_audit(args.case, out, form, rule, args.rank_tol, args.sensitivity, executor,
                                         in_flight, on_block, keep=args.out is not None)
        if form == "text":
            out.write(("\n" + format_summary(summary) + "\n").encode())
        elif form == "none":
            out.write((verdict_line(summary) + "\n").encode())
        if stage is not None:
            from gpfverify.report.equivalence import write_run_audit_report

            html = final_path(write_run_audit_report({"steps": steps, "summary": summary,
                                                      "rank_rule": summary["rank_rule"]}, stage), stage, args.out)
        copy_out(out)
    if args.out is not None:  # after the audit itself; on stderr when stdout carries JSON
        if args.json:
            print(f"gpfverify audit: the report page: {html}", file=diagnostics())
        else:
            print(f"the report page: {html}")


def run(args: argparse.Namespace) -> int:
    if args.rank_tol is not None and not args.rank_tol >= 0:
        raise InputError(f"--rank-tol must be >= 0, got {args.rank_tol}")
    if args.rank_tol is not None and args.rank_rule is not None:
        raise InputError("give --rank-tol or --rank-rule, not both")
    if run_format(args.case) == "json":  # one case: output as it always was
        if args.out is not None:
            raise InputError("--out writes the report of a run file (.jsonl or .npz); a single case has none")
        from gpfverify.fusion.caseblock import load_case

        audit = _audit(load_case(args.case), args.rank_tol, _resolve_rank_rule(args.rank_rule),
                       args.sensitivity)
        print(json.dumps(audit_to_dict(audit)) if args.json else format_audit(audit))
        return 0
    _audit_run(args)
    return 0
