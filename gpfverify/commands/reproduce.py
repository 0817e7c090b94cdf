"""``gpfverify reproduce NAME --out DIR``: run one of the papers' experiments into ``DIR``.

By default the run count of the report's quick profile (minutes); ``--paper-scale`` runs the
paper's count (hours for some experiments), ``--runs N`` any count. Before the runs: what will
run; after the first runs are saved: the estimated time left. Off a terminal a progress line
every few percent (on a terminal, a progress bar). At the end: each claim's verdict, the rank rule
that decided eq. 35 where the experiment has one, and the command that renders the folder as a
page (``gpfverify report --from DIR``).
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from collections.abc import Callable
from pathlib import Path

from gpfverify.papers import EXPERIMENTS
from gpfverify.outputs import add_wait_argument, out_path, output_folder
from gpfverify.streams import diagnostics

#: a progress line off a terminal every this fraction of the runs
PROGRESS_FRACTION = 0.05
#: ... and at least this often while runs are being saved
PROGRESS_SECONDS = 30.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("experiment", nargs="?", choices=sorted(EXPERIMENTS), help="which experiment")
    # experiment-specific options are added once the name is known (see run)
    parser.add_argument("rest", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)


def quick_runs(module) -> int:
    """The run count of the experiment's quick report profile (its paper's count if it has none)."""
    profiles = getattr(module, "PROFILES", {})
    return profiles["quick"].runs if "quick" in profiles else module.DEFAULT_RUNS


def add_common_arguments(parser: argparse.ArgumentParser, default_runs: int, paper_runs: int | None = None) -> None:
    from gpfverify.cli import BATCH_HELP, non_negative_int, positive_int

    paper_runs = default_runs if paper_runs is None else paper_runs
    parser.add_argument("--runs", type=positive_int, default=None,
                        help=f"Monte Carlo runs (default {default_runs}, the quick profile of the report; "
                             f"--paper-scale: {paper_runs}, the paper's)")
    parser.add_argument("--paper-scale", action="store_true",
                        help=f"run the paper's count, {paper_runs} runs (the estimated time is printed after "
                             "the first runs)")
    parser.add_argument("--seed", type=non_negative_int, default=1, help="root seed, an integer >= 0 (default 1)")
    parser.add_argument("--out", type=out_path, required=True,
                        help="output folder (required: every run is saved there as it ends, so that --resume "
                             "can continue and 'gpfverify report --from DIR' can render it)")
    parser.add_argument("--resume", action="store_true", help="continue the runs saved in --out")
    add_wait_argument(parser)
    parser.add_argument("--workers", type=positive_int, default=1,
                        help="local worker processes, >= 1 (BLAS pinned to 1 thread each; default 1); "
                             "results are the same for any number")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="dask.distributed scheduler address (needs gpfverify[cluster]; docs/cluster.md "
                             "says how to start one)")
    parser.add_argument("--batch", type=positive_int, default=None, metavar="B", help=BATCH_HELP)
    parser.add_argument("--interpretations", default=None, metavar="NAMES",
                        help="also run the experiment under these interpretations of what the paper leaves "
                             "unstated ('all' or comma-separated names), in OUT/interpretations/NAME, and record "
                             "each claim's verdict under each in results.json")
    parser.add_argument("--interpretation-runs", type=positive_int, default=None, metavar="N",
                        help="runs of each interpretation that has runs of its own (default --runs; at most "
                             "--runs): each claim's verdict under it is then compared with the main run's on "
                             "its first N runs; the interpretations the main run's runs answer read all of them")


def duration(seconds: float) -> str:
    """``'3 h 12 min'``, ``'4 min 10 s'``, ``'12 s'``."""
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    if hours:
        return f"{hours} h {minutes} min"
    return f"{minutes} min {secs} s" if minutes else f"{secs} s"


def progress_lines(name: str, say: Callable[[str], None], header: str = "",
                   clock: Callable[[], float] = time.monotonic, started: float | None = None):
    """``on_run(saved, total)`` for the runner: ``header`` (what runs; said once the runs have
    started, so that a refused command prints only its error) and the estimated time left after
    the first saved run, then a line every :data:`PROGRESS_FRACTION` of the runs (and at least every
    :data:`PROGRESS_SECONDS`), each with the time left at the rate so far; the clock starts now or
    at ``started``."""
    started = last_line = clock() if started is None else started
    before: int | None = None  # runs saved before this command (--resume)
    last_share = -1

    def on_run(saved: int, total: int) -> None:
        nonlocal before, last_line, last_share
        now = clock()
        if before is None:
            before = saved - 1
            if header:
                say(header)
        new = saved - before
        left = (total - saved) * (now - started) / max(new, 1)
        share = int(saved / total / PROGRESS_FRACTION)
        if new == 1 and saved < total:
            say(f"{name}: first run took {duration(now - started)}; estimated time left for the other "
                f"{total - saved}: {duration(left)}")
        elif saved == total or share > last_share or now - last_line >= PROGRESS_SECONDS:
            say(f"{name}: {saved} of {total} runs saved ({100 * saved // total} %), "
                f"about {duration(left)} left")
        else:
            return
        last_line, last_share = now, share

    return on_run


def interpretation_lines(name: str, say: Callable[[str], None],
                         clock: Callable[[], float] = time.monotonic) -> Callable[[str, int, int], None]:
    """``on_run(interpretation, saved, total)`` for the interpretations, run one after the other:
    :func:`progress_lines` of each, naming it (``ct2d, interpretation initial-cov-wide: ...``), its
    clock started when the previous one saved its last run (or now, for the first)."""
    lines: dict[str, Callable[[int, int], None]] = {}
    last = [clock()]

    def on_run(interpretation: str, saved: int, total: int) -> None:
        if interpretation not in lines:
            lines[interpretation] = progress_lines(f"{name}, interpretation {interpretation}", say, clock=clock,
                                                   started=last[0])
        lines[interpretation](saved, total)
        last[0] = clock()

    return on_run


def claims_text(results: dict) -> str:
    """Each claim's verdict (and the rank rule of eq. 35 where there is one), one line each, in
    their groups (accuracy, a theorem checked on the runs, timing), and the counts per group."""
    from gpfverify.contract.claims import read_claims
    from gpfverify.report.inputs import VerdictCounts

    claims = read_claims(results)
    lines = []
    if results.get("rank_tolerance"):
        lines.append(f"rank rule of eq. 35: {results['rank_tolerance']} (the default is the canonical rule, as in "
                     "check and audit; --rank-rule to change it)")
    if not claims:
        return "\n".join(lines + ["no claims recorded"])
    runs = results.get("runs_ok", results.get("runs"))
    papers = {c.paper_n for c in claims if c.paper_n}
    lines.append(f"claims at {runs} run(s)" + (f" (the paper: {', '.join(map(str, sorted(papers)))})" if papers
                                                else "") + ":")
    counts = VerdictCounts.of(claims)
    for group in counts.groups:
        lines.append(f" {group.group}:")
        for c in (c for c in claims if c.group == group.group):
            more = (f" (about {c.runs_to_decide} runs would decide)"
                    if c.verdict == "undecided" and c.runs_to_decide else "")
            setting = f" ({c.setting})" if c.setting else ""
            lines.append(f"  {c.verdict:<14} {c.claim}{setting}{more}")
    lines.append("verdicts: " + counts.groups_text())
    return "\n".join(lines)


def experiment_parser(name: str) -> argparse.ArgumentParser:
    """The parser of ``gpfverify reproduce NAME ...``: the common options and the experiment's,
    generated from its Params."""
    from gpfverify.cli import OneLineParser, plain_help
    from gpfverify.contract.params import add_arguments as add_params_arguments

    module = importlib.import_module(EXPERIMENTS[name])
    parser = OneLineParser(prog=f"gpfverify reproduce {name}", description=plain_help(module.__doc__))
    add_common_arguments(parser, quick_runs(module), module.DEFAULT_RUNS)
    declared = [s.name for s in getattr(module, "INTERPRETATIONS", ())]
    if declared:
        parser.add_argument("--interpretation", default=None, choices=declared, metavar="NAME",
                            help="run the experiment under this one interpretation of what the paper leaves "
                                 "unstated: its parameter changes applied to the options given, its name recorded "
                                 f"in manifest.json and results.json (one of {', '.join(declared)})")
    add_params_arguments(parser, module.Params)
    return parser


def experiment_params(module, opts: argparse.Namespace):
    """The experiment's ``Params`` from parsed options: the options given, and, with
    ``--interpretation NAME``, that interpretation's parameter changes applied over them. An option
    given at another value than the interpretation sets is refused (the one reading would be two)."""
    from gpfverify.contract.params import cli_fields, field_flag, from_arguments
    from gpfverify.errors import InputError

    params = from_arguments(module.Params, opts)
    name = getattr(opts, "interpretation", None)
    if name is None:
        return params
    spec = next(s for s in module.INTERPRETATIONS if s.name == name)
    changed = params.replace(**spec.changes)
    defaults = module.Params()
    flags = {f.name: field_flag(f) for f in cli_fields(module.Params)}
    for field in spec.changes:
        given = getattr(params, field)
        if field in flags and given != getattr(defaults, field) and given != getattr(changed, field):
            raise InputError(f"--interpretation {name} sets {flags[field]}; it was given at another value")
    return changed


def run(args: argparse.Namespace) -> int:
    from gpfverify.errors import InputError
    from gpfverify.experiments.runner import check_run_count, make_executor, run_experiment
    from gpfverify.memory import advise

    if args.experiment is None:
        raise InputError(f"name the experiment to run, one of {', '.join(sorted(EXPERIMENTS))} "
                         "(gpfverify reproduce NAME --help for its options)")
    module = importlib.import_module(EXPERIMENTS[args.experiment])
    parser = experiment_parser(args.experiment)
    opts = parser.parse_args(args.rest)
    advise(parser._option_string_actions)  # what to try should memory run out: this experiment's options
    if opts.paper_scale and opts.runs is not None:
        raise InputError("--paper-scale runs the paper's count: not together with --runs")
    runs = module.DEFAULT_RUNS if opts.paper_scale else opts.runs or quick_runs(module)
    interpretation = getattr(opts, "interpretation", None)
    if interpretation is not None and opts.interpretations is not None:
        raise InputError("--interpretation runs one reading as the main run: not together with --interpretations")
    params = experiment_params(module, opts)
    check_run_count(runs)  # refused before anything is written
    specs = None
    if opts.interpretations is not None:
        from gpfverify.experiments.sensitivity import run_interpretations, select

        specs = select(module, opts.interpretations)  # before any run: a wrong name costs nothing
    if opts.interpretation_runs is not None:
        if specs is None:
            raise InputError("--interpretation-runs needs --interpretations")
        if opts.interpretation_runs > runs:
            raise InputError(f"--interpretation-runs {opts.interpretation_runs} is more than the main run's "
                             f"{runs} runs: the verdicts are compared on equal run counts")
    if opts.paper_scale:
        scale = "the paper's count"
    elif opts.runs is None:
        scale = f"the quick profile; --paper-scale for the paper's {module.DEFAULT_RUNS}"
    else:
        scale = f"the paper's: {module.DEFAULT_RUNS}"
    reading = f", interpretation {interpretation}" if interpretation else ""
    header = f"{args.experiment}{reading}: {runs} run(s) ({scale}), {opts.workers} worker(s), into {opts.out}"
    terminal = diagnostics().isatty()  # there the runner draws a progress bar
    with output_folder(opts.out, keep=True, wait=opts.wait) as stage, \
            make_executor(opts.workers, opts.scheduler) as executor:
        results = run_experiment(module, params, runs, opts.seed, stage, opts.resume, executor,
                                 on_run=None if terminal else progress_lines(args.experiment, say, header),
                                 batch=opts.batch, interpretation=interpretation)
        if specs:
            say(f"{args.experiment}: interpretations {', '.join(s.name for s in specs)}")
            results = run_interpretations(module, params, specs, runs, opts.seed, stage, executor,
                                          on_run=None if terminal else interpretation_lines(args.experiment, say),
                                          interpretation_runs=opts.interpretation_runs, batch=opts.batch)
    print(f"{args.experiment}: {results['runs_ok']} of {results['runs']} runs ok -> {opts.out / 'results.json'}",
          file=diagnostics() if results["failed_runs"] else sys.stdout)
    print(claims_text(results))
    print(f"page: gpfverify report --from {_shell_word(opts.out)}")
    return 0


def say(text: str) -> None:
    """A progress line (a diagnostic: stderr, flushed at once)."""
    print(text, file=diagnostics(), flush=True)


def _shell_word(path: Path) -> str:
    import shlex

    return shlex.quote(str(path))
