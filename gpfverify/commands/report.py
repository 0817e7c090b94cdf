"""``gpfverify report``: run the experiments of every section (the runner, seeded and resumable)
and render the verification report from the files they wrote (:mod:`gpfverify.report` only
reads and renders)."""

from __future__ import annotations

import argparse
import importlib
import json
import shutil
import sys
import time
from pathlib import Path

from gpfverify.cli import non_negative_int, positive_int
from gpfverify.contract.experiment import RunEntry, SectionRuns
from gpfverify.report import SECTIONS, ReportContext, build_report
from gpfverify.report.inputs import write_runs

#: report section -> the experiments it renders (names as in gpfverify.experiments.EXPERIMENTS)
SECTION_EXPERIMENTS: dict[str, tuple[str, ...]] = {
    "moments": ("moments",),
    "gpadf-scalar": ("gpadf-scalar",),
    "ungm1d": ("ungm1d",),
    "ct2d": ("ct2d",),
    "tbd": ("tbd",),
    "particle-flow": ("pff1d", "bearing"),
    "sins-gps": ("sins-gps",),
}


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


class Progress:
    """One line per event with the elapsed time, on a terminal or not (CI logs, ``make report``)."""

    def __init__(self, stream=None):
        self.stream = stream or sys.stdout
        self.started = time.monotonic()

    def __call__(self, message: str) -> None:
        elapsed = time.monotonic() - self.started
        print(f"[report {int(elapsed // 60):2d}:{int(elapsed % 60):02d}] {message}", file=self.stream, flush=True)


def _experiments_have_profiles(slug: str) -> bool:
    from gpfverify.experiments import EXPERIMENTS

    return all(hasattr(importlib.import_module(EXPERIMENTS[name]), "PROFILES")
               for name in SECTION_EXPERIMENTS.get(slug, ()))


def run_section(ctx: ReportContext, slug: str, progress) -> SectionRuns:
    """Run every setting of the section's experiments at the report's profile into
    ``<out>/<slug>/<experiment>-<tag>/run`` (reusing runs saved there with the same settings) and
    write the section's ``runs.json``."""
    from gpfverify.experiments import EXPERIMENTS
    from gpfverify.experiments.runner import make_executor, run_experiment

    entries = []
    for name in SECTION_EXPERIMENTS[slug]:
        module = importlib.import_module(EXPERIMENTS[name])
        profile = module.PROFILES[ctx.profile]
        for i, setting in enumerate(profile.settings, 1):
            folder = f"{name}-{setting.tag}"
            run_dir = ctx.out_dir / slug / folder / "run"
            _discard_other_settings(run_dir, ctx.seed, profile.runs, setting.params.to_json())
            where = f"{slug}: {name} {setting.label or 'default setting'} ({i} of {len(profile.settings)})"
            progress(f"{where}: {profile.runs} run{'s' if profile.runs != 1 else ''}")
            step = max(1, profile.runs // 10)

            def on_run(done: int, total: int, where: str = where, step: int = step) -> None:
                if done == total or done % step == 0:
                    progress(f"{where}: run {done} of {total} saved")

            with make_executor(ctx.workers) as executor:
                run_experiment(module, setting.params, profile.runs, ctx.seed, run_dir, resume=True,
                               executor=executor, show_progress=False, on_run=on_run)
            entries.append(RunEntry(name, setting.label, setting.tag, f"{folder}/run/results.json"))
    runs = SectionRuns(slug, ctx.profile, ctx.seed, tuple(entries))
    write_runs(ctx.out_dir, runs)
    return runs


def _discard_other_settings(run_dir: Path, seed: int, runs: int, params: dict) -> None:
    """Remove saved runs made with other settings (a report folder holds one profile's runs)."""
    manifest = run_dir / "manifest.json"
    if not manifest.exists():
        return
    try:
        old = json.loads(manifest.read_text(encoding="utf-8"))
        same = (old.get("seed"), old.get("runs"), old.get("params")) == (seed, runs, json.loads(json.dumps(params)))
    except (ValueError, AttributeError, RecursionError):  # damaged: start afresh
        same = False
    if not same:
        shutil.rmtree(run_dir)


def run(args: argparse.Namespace) -> int:
    profile = "full" if args.full else "quick"
    out = args.out or Path("reports") / profile
    progress = Progress()
    ctx = ReportContext(out, profile, args.seed, args.workers)
    selected = [s for s in SECTIONS if not args.only or s in args.only]
    progress(f"building the {profile} report in {out} (seed {args.seed}, {args.workers} worker(s)): "
             f"{', '.join(selected)}")
    for slug in selected:
        if slug in SECTION_EXPERIMENTS and _experiments_have_profiles(slug):
            run_section(ctx, slug, progress)
    html_path = build_report(ctx, args.only, progress)
    progress(f"report written: {out / 'README.md'} and {html_path}")
    return 0
