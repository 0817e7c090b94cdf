"""``gpfverify check SYSTEM.py:NAME``: does DMF reproduce CMF on your system, at every step, and why
(not)? Simulated runs (truth known) or your logged measurements; every step audited.

The system file defines NAME, a gpfverify.models.StateSpaceModel (format: docs/models.md), or Stone
Soup models or filterpy filters, taken as they are (docs/ecosystem.md).
Results go to --out DIR (results.json, the per-run records and the equivalence report) or, with
--json alone, to stdout.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import tempfile
from pathlib import Path

from gpfverify.cli import BATCH_HELP, RANK_RULE_HELP, fusion_rules, positive_seconds, rank_rule_text
from gpfverify.contract.check import Params
from gpfverify.contract.params import add_arguments as add_params_arguments
from gpfverify.filters.families import FAMILY_NAMES
from gpfverify.fusion.names import CHOICES_TEXT
from gpfverify.outputs import add_wait_argument, out_path, output_folder
from gpfverify.streams import diagnostics
from gpfverify.usercode import guarded, system_file, time_limited


#: steps per simulated run unless --steps says otherwise
DEFAULT_STEPS = 50


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("system", metavar="SYSTEM.py:NAME",
                        help="a Python file and the name of the StateSpaceModel it defines (docs/models.md), "
                             "or of its Stone Soup models or filterpy filters (docs/ecosystem.md)")
    parser.add_argument("--filter", default="ukf", choices=[f for f in FAMILY_NAMES if f != "kf"],
                        help="the Gaussian family of every local filter and of the centre (default ukf)")
    parser.add_argument("--steps", type=int, default=None,
                        help="steps per simulated run (default 50; with --measurements the file's row count)")
    parser.add_argument("--runs", type=int, default=1, help="simulated Monte Carlo runs (default 1)")
    parser.add_argument("--seed", type=int, default=1, help="root seed (default 1)")
    parser.add_argument("--measurements", metavar="MEASUREMENTS.npz", default=None,
                        help="filter your logged measurements instead of simulating: an .npz with y (T, L) "
                             "stacked in sensor order and optional truth x (T, D) (docs/check-format.md; not "
                             "an audit run file)")
    parser.add_argument("--training", metavar="TRAIN.npz", default=None,
                        help="GP families: learn from your samples, x (n, D) consecutive states and y (n, L)")
    # the GP options as check's Params declares them (--train-points: one name in every command)
    add_params_arguments(parser, Params, only=("train", "fit_points", "restarts"))
    parser.add_argument("--methods", type=fusion_rules, default=("cmf", "dmf", "cc", "ci"), metavar="RULES",
                        help=f"comma-separated fusion rules among {CHOICES_TEXT}, the same names as fuse's "
                             "(cmf and dmf always; default cmf,dmf,cc,ci)")
    parser.add_argument("--rank-rule", type=rank_rule_text, default="canonical", metavar="RULE",
                        help=RANK_RULE_HELP + " Default canonical, as in audit and reproduce: a user's system "
                             "has its own units, and the canonical rule does not depend on them.")
    add_params_arguments(parser, Params, only=("ci_criterion",))
    parser.add_argument("--out", type=out_path, default=None, help="output folder (results.json, runs/, report)")
    add_wait_argument(parser)
    parser.add_argument("--json", action="store_true", help="print results.json to stdout")
    parser.add_argument("--resume", action="store_true", help="continue the runs saved in --out")
    parser.add_argument("--workers", type=int, default=1, help="local worker processes (default 1)")
    parser.add_argument("--timeout", type=positive_seconds, default=None, metavar="SECONDS",
                        help="stop the command (exit status 2, one line naming the function) when one call of "
                             "your system file's code — loading it and building NAME, or one call of one of its "
                             "functions — has not returned after SECONDS (default: no limit)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="dask.distributed scheduler address (needs gpfverify[cluster])")
    parser.add_argument("--batch", type=int, default=None, metavar="B", help=BATCH_HELP)


def run(args: argparse.Namespace) -> int:
    from gpfverify.errors import InputError
    from gpfverify.contract.check import verdict_sentence
    from gpfverify.experiments import check
    from gpfverify.experiments.runner import (check_batch, check_run_count, check_seed, check_workers, make_executor,
                                              run_experiment)
    from gpfverify.systems import load_system

    if args.measurements is not None and args.steps is not None:
        raise InputError("--measurements filters every row of the file: leave out --steps")
    check_run_count(args.runs)  # everything that can be refused is refused before anything is written
    check_seed(args.seed)
    check_workers(args.workers)
    if args.batch is not None:
        check_batch(args.batch)
    if args.out is None and not args.json:
        raise InputError("give --out DIR (results and report) and/or --json (results on stdout)")
    out_dir = None if args.out is None else args.out.absolute()  # before the system file can change folder
    params = check.params_for(args.system, args.filter, DEFAULT_STEPS if args.steps is None else args.steps,
                              args.measurements,
                              args.training, args.train, args.fit_points, args.restarts, args.methods,
                              args.rank_rule, args.ci_criterion)
    with guarded(system_file(params.system)), \
            time_limited(f"{system_file(params.system)} (loading it and building {params.system.rsplit(':', 1)[1]})"):
        model = load_system(params.system)  # fail before anything is written; print() to stderr, exits reported
    if params.measurements is not None:
        if args.runs != 1:
            raise InputError("--measurements filters one logged run: --runs must be 1")
        _, ys = check.logged_measurements(params.measurements, model)
        params = params.replace(steps=len(ys))  # results.json records the file's step count
    check.check_size_fits(model, params.steps, args.runs, params.methods)
    with contextlib.ExitStack() as stack:
        if out_dir is not None:
            out = stack.enter_context(output_folder(out_dir, keep=True, wait=args.wait))
        else:
            out = Path(stack.enter_context(tempfile.TemporaryDirectory()))
        stack.enter_context(guarded(system_file(params.system)))
        with make_executor(args.workers, args.scheduler) as executor:
            results = run_experiment(check, params, args.runs, args.seed, out, args.resume, executor,
                                     batch=args.batch)
        if args.out is not None:
            check.write_run_files(out, args.runs)
            from gpfverify.report.equivalence import write_equivalence_report

            write_equivalence_report(results, out)
    if results["failed_runs"]:
        first = results["failed_runs"][0]
        print(f"gpfverify check: {len(results['failed_runs'])} run(s) failed; first: {first['error']}",
              file=diagnostics())
    if args.json:
        print(json.dumps(results))
    else:
        print(verdict_sentence(results) + f" Results: {args.out / 'results.json'}; the report page: "
              f"{args.out / 'report.html'}")
    if args.json and args.out is not None:
        print(f"gpfverify check: the report page: {args.out / 'report.html'}", file=diagnostics())
    return 0
