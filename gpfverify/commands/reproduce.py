"""``gpfverify reproduce NAME``: run one of the papers' experiments into ``--out DIR``."""

from __future__ import annotations

import argparse
import importlib
import sys

from gpfverify.experiments import EXPERIMENTS
from gpfverify.outputs import check_out, out_path, output_folder


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("experiment", choices=sorted(EXPERIMENTS), help="which experiment")
    # experiment-specific options are added once the name is known (see run)
    parser.add_argument("rest", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)


def add_common_arguments(parser: argparse.ArgumentParser, default_runs: int) -> None:
    from gpfverify.cli import non_negative_int, positive_int

    parser.add_argument("--runs", type=positive_int, default=default_runs,
                        help=f"Monte Carlo runs (default {default_runs}, the paper's)")
    parser.add_argument("--seed", type=non_negative_int, default=1, help="root seed, an integer >= 0 (default 1)")
    parser.add_argument("--out", type=out_path, required=True, help="output folder")
    parser.add_argument("--resume", action="store_true", help="continue the runs saved in --out")
    parser.add_argument("--workers", type=positive_int, default=1,
                        help="local worker processes, >= 1 (BLAS pinned to 1 thread each; default 1); "
                             "results are the same for any number")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="dask.distributed scheduler address (needs gpfverify[cluster])")
    parser.add_argument("--interpretations", default=None, metavar="NAMES",
                        help="also run the experiment under these interpretations of what the paper leaves "
                             "unstated ('all' or comma-separated names), in OUT/interpretations/NAME, and record "
                             "each claim's verdict under each in results.json")


def run(args: argparse.Namespace) -> int:
    from gpfverify.cli import OneLineParser
    from gpfverify.contract.params import add_arguments as add_params_arguments
    from gpfverify.contract.params import from_arguments
    from gpfverify.experiments.runner import make_executor, run_experiment

    module = importlib.import_module(EXPERIMENTS[args.experiment])
    sub = OneLineParser(prog=f"gpfverify reproduce {args.experiment}", description=module.__doc__)
    add_common_arguments(sub, module.DEFAULT_RUNS)
    add_params_arguments(sub, module.Params)  # the options are generated from the experiment's Params
    opts = sub.parse_args(args.rest)
    params = from_arguments(module.Params, opts)
    check_out(opts.out)
    specs = None
    if opts.interpretations is not None:
        from gpfverify.experiments.sensitivity import run_interpretations, select

        specs = select(module, opts.interpretations)  # before any run: a wrong name costs nothing
    with output_folder(opts.out, keep=True) as stage, make_executor(opts.workers, opts.scheduler) as executor:
        results = run_experiment(module, params, opts.runs, opts.seed, stage, opts.resume, executor)
        if specs:
            results = run_interpretations(module, params, specs, opts.runs, opts.seed, stage, executor)
    print(f"{args.experiment}: {results['runs_ok']} of {results['runs']} runs ok -> {opts.out / 'results.json'}",
          file=sys.stderr if results["failed_runs"] else sys.stdout)
    return 0
