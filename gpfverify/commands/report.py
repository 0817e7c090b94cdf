"""``gpfverify report``: run the experiments of every section (the runner, seeded and resumable)
and the proofs, then render the verification report from the files they wrote
(:mod:`gpfverify.report` only reads and renders).

Progress is one line per event with the elapsed time, on a terminal or not (``make report``, CI
logs): each setting started, every tenth run saved (and at least every ten seconds), each proof,
each page rendered; a heartbeat line says what is still running after
:data:`HEARTBEAT_SECONDS` without news. Once this build has timed two runs of an experiment, its
run lines end with the time that experiment's runs have left, from the pace measured (:class:`Eta`);
nothing is estimated before that. The command ends with where the report is and the verdict
counts."""

from __future__ import annotations

import argparse
import importlib
import json
import shutil
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from gpfverify.cli import non_negative_int, positive_int
from gpfverify.errors import InputError
from gpfverify.contract.experiment import RunEntry, SectionRuns
from gpfverify.outputs import add_wait_argument, final_path, out_path, output_folder
from gpfverify.full_report import SECTIONS, build_report, papers_title
from gpfverify.report.inputs import VerdictCounts, write_runs
from gpfverify.report.render import read_summaries
from gpfverify.streams import result

#: report section -> the experiments it renders (names as in gpfverify.papers.EXPERIMENTS)
SECTION_EXPERIMENTS: dict[str, tuple[str, ...]] = {
    "moments": ("moments",),
    "gpadf-scalar": ("gpadf-scalar",),
    "ungm1d": ("ungm1d",),
    "ct2d": ("ct2d",),
    "tbd": ("tbd",),
    "particle-flow": ("pff1d", "bearing"),
    "sins-gps": ("sins-gps",),
}
#: the mapping as help texts and docs show it
SECTION_MAP_TEXT = "; ".join(f"{slug} = {' + '.join(names)}" for slug, names in SECTION_EXPERIMENTS.items()
                             if names != (slug,))
#: the profile name a page rendered from one reproduce folder records
REPRODUCED = "reproduce"
#: the section whose "runs" are the symbolic proofs and cross-checks
PROOFS = "proofs"
CERTIFICATES = "certificates.json"
#: the longest silence before a line saying what is still running
HEARTBEAT_SECONDS = 20.0
#: a run line at least this often while runs are being saved (besides every tenth run)
RUN_LINE_SECONDS = 10.0
def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--full", action="store_true",
                        help="the papers' run counts (hours) instead of the quick profile (minutes)")
    parser.add_argument("--out", type=out_path, default=None,
                        help="output folder (default reports/quick or reports/full)")
    add_wait_argument(parser)
    parser.add_argument("--seed", type=non_negative_int, default=1, help="root seed, an integer >= 0 (default 1)")
    parser.add_argument("--workers", type=positive_int, default=1,
                        help="worker processes for experiments (>= 1; results do not depend on it)")
    parser.add_argument("--only", nargs="+", metavar="SECTION", choices=list(SECTIONS),
                        help=f"build (or rebuild) only these sections, keeping the others already in "
                             f"the output folder: {', '.join(SECTIONS)} (a section renders the experiments "
                             f"reproduce names: {SECTION_MAP_TEXT})")
    parser.add_argument("--from", dest="from_dir", type=Path, default=None, metavar="DIR",
                        help="render one 'gpfverify reproduce NAME --out DIR' folder as a page instead of "
                             "running anything (into --out, default DIR-report)")


class Eta:
    """The time each experiment's runs have left in this build, from the pace this build measured:
    the seconds between two runs of the experiment saved one after the other, times the runs of it
    still to make (every setting's, with the interpretations' that run). A batch's first run is not
    timed (it carries the start of the workers and the compilation of kernels), so an experiment has
    an estimate from its second run saved on and none before: a guess is never shown. Runs reused
    from an earlier build are runs not left."""

    def __init__(self, planned: dict[str, tuple[str, int]], clock: Callable[[], float] = time.monotonic):
        #: item (an experiment's setting) -> its experiment, and its runs still to make
        self.experiment = {item: experiment for item, (experiment, _) in planned.items()}
        self.runs_left = {item: runs for item, (_, runs) in planned.items()}
        self.clock = clock
        self.timed: dict[str, list[float]] = {}  # experiment -> [seconds timed, runs timed]
        self.last: dict[str, float | None] = {}  # experiment -> when its last run was saved in this batch

    def batch(self, experiment: str) -> None:
        """A batch of the experiment's runs starts: its first run will not be timed."""
        self.last[experiment] = None

    def ran(self, item: str) -> None:
        """A run of ``item`` was saved."""
        experiment = self.experiment[item]
        now, last = self.clock(), self.last.get(experiment)
        if last is not None:
            timed = self.timed.setdefault(experiment, [0.0, 0])
            timed[0] += now - last
            timed[1] += 1
        self.last[experiment] = now
        self.runs_left[item] = max(0, self.runs_left[item] - 1)

    def finished(self, item: str) -> None:
        """``item`` is over: what was not run of it was reused."""
        self.runs_left[item] = 0

    def seconds_per_run(self, experiment: str) -> float | None:
        """The measured pace, or None before two runs of the experiment were saved in one batch."""
        seconds, runs = self.timed.get(experiment, (0.0, 0))
        return seconds / runs if runs else None

    def seconds_left(self, experiment: str) -> float | None:
        """The experiment's runs still to make at its measured pace, or None before it has one."""
        pace = self.seconds_per_run(experiment)
        if pace is None:
            return None
        return pace * sum(runs for item, runs in self.runs_left.items() if self.experiment[item] == experiment)

    def suffix(self, item: str) -> str:
        """`` (ct2d: about 3 min 10 s of runs left)`` for a progress line, or nothing yet."""
        experiment = self.experiment[item]
        left = self.seconds_left(experiment)
        return "" if left is None else f" ({experiment}: about {_duration(left)} of runs left)"


def plan(ctx: ReportContext, selected: list[str]) -> dict[str, tuple[str, int]]:
    """The runs of a build (:class:`Eta`): per setting, its experiment and its runs with those of
    its interpretations that run (a summary-only one reads the main runs)."""
    from gpfverify.papers import EXPERIMENTS
    from gpfverify.experiments.sensitivity import select, summary_only

    work: dict[str, tuple[str, int]] = {}
    for slug in selected:
        if slug == PROOFS:
            continue
        for name in SECTION_EXPERIMENTS[slug]:
            module = importlib.import_module(EXPERIMENTS[name])
            profile = module.PROFILES[ctx.profile]
            with_runs = 1
            if profile.interpretations:
                specs = select(module, ",".join(profile.interpretations))
                with_runs += sum(not summary_only(module, spec) for spec in specs)
            for setting in profile.settings:
                work[f"{name}-{setting.tag}"] = (name, profile.runs * with_runs)
    return work


class Progress:
    """One line per event with the elapsed time, on a terminal or not (CI logs, ``make report``).

    Used as a context manager it also watches for silence: after ``heartbeat`` seconds without a
    line it prints one saying what is still running (the last event) and for how long."""

    def __init__(self, stream: TextIO | None = None, heartbeat: float = HEARTBEAT_SECONDS,
                 clock: Callable[[], float] = time.monotonic):
        self.stream = stream or result()
        self.clock = clock
        self.started = self.last = clock()
        self.heartbeat = heartbeat
        self.current = "starting"
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _stamp(self) -> str:
        elapsed = self.clock() - self.started
        return f"[report {int(elapsed // 60):2d}:{int(elapsed % 60):02d}]"

    def __call__(self, message: str) -> None:
        with self._lock:
            print(f"{self._stamp()} {message}", file=self.stream, flush=True)
            self.current = message
            self.last = self.clock()

    def beat(self) -> None:
        """A heartbeat line when nothing was said for ``heartbeat`` seconds."""
        with self._lock:
            quiet = self.clock() - self.last
            if quiet < self.heartbeat:
                return
            print(f"{self._stamp()} ... still working ({quiet:.0f} s since the last line: {self.current})",
                  file=self.stream, flush=True)
            self.last = self.clock()

    def __enter__(self) -> Progress:
        def watch() -> None:
            while not self._stop.wait(min(1.0, self.heartbeat / 4)):
                self.beat()

        self._thread = threading.Thread(target=watch, name="gpfverify-report-heartbeat", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()


@dataclass(frozen=True)
class ReportContext:
    """What the command runs: where to write, which profile ("quick": minutes, few runs; "full":
    the papers' run counts), the root seed and the worker processes."""

    out_dir: Path
    profile: str
    seed: int = 1
    workers: int = 1

    @property
    def quick(self) -> bool:
        return self.profile == "quick"


def run_section(ctx: ReportContext, slug: str, progress: Callable[[str], None], eta: Eta) -> SectionRuns:
    """Run every setting of the section's experiments at the report's profile into
    ``<out>/<slug>/<experiment>-<tag>/run`` (reusing runs saved there with the same settings), with
    the profile's interpretations in ``run/interpretations/<name>``, and write the section's
    ``runs.json``."""
    from gpfverify.papers import EXPERIMENTS
    from gpfverify.experiments.runner import make_executor, run_experiment
    from gpfverify.experiments.sensitivity import run_interpretations, select

    entries = []
    for name in SECTION_EXPERIMENTS[slug]:
        module = importlib.import_module(EXPERIMENTS[name])
        profile = module.PROFILES[ctx.profile]
        for i, setting in enumerate(profile.settings, 1):
            folder = f"{name}-{setting.tag}"
            run_dir = ctx.out_dir / slug / folder / "run"
            _discard_other_settings(run_dir, ctx.seed, profile.runs, setting.params.to_json())
            where = slug if name == slug else f"{slug}/{name}"
            where += f", {setting.label}" if setting.label else ""
            if len(profile.settings) > 1:
                where += f" (setting {i} of {len(profile.settings)})"
            progress(f"{where}: {profile.runs} run{'s' if profile.runs != 1 else ''}")
            step = max(1, profile.runs // 10)
            last = [time.monotonic(), 0.0]  # time of the last line, runs saved now

            def on_run(done: int, total: int, where: str = where, step: int = step, last: list = last,
                       item: str = folder) -> None:
                now = time.monotonic()
                last[1] += 1
                eta.ran(item)
                if done == total or done % step == 0 or now - last[0] >= RUN_LINE_SECONDS:
                    progress(f"{where}: run {done} of {total} saved{eta.suffix(item)}")
                    last[0] = now

            with make_executor(ctx.workers) as executor:
                eta.batch(name)
                run_experiment(module, setting.params, profile.runs, ctx.seed, run_dir, resume=True,
                               executor=executor, show_progress=False, on_run=on_run)
                if profile.interpretations:
                    progress(f"{where}: interpretations {', '.join(profile.interpretations)}")
                    current = [""]

                    def named(spec: str, done: int, total: int, where: str = where, current: list = current,
                              name: str = name) -> None:
                        if spec != current[0]:  # a new batch: the summary of the last one is not a run's time
                            current[0] = spec
                            eta.batch(name)
                        on_run(done, total, where=f"{where}, interpretation {spec}")

                    run_interpretations(module, setting.params, select(module, ",".join(profile.interpretations)),
                                        profile.runs, ctx.seed, run_dir, executor, on_run=named)
            eta.finished(folder)
            if not last[1]:
                progress(f"{where}: every run saved by an earlier build with the same settings, reused")
            entries.append(RunEntry(name, setting.label, setting.tag, f"{folder}/run/results.json"))
    runs = SectionRuns(slug, ctx.profile, ctx.seed, tuple(entries))
    write_runs(ctx.out_dir, runs)
    return runs


def run_proofs(ctx: ReportContext, progress: Callable[[str], None]) -> SectionRuns:
    """The symbolic proofs and casadi cross-checks (small problems in the quick profile, large in
    the full one) into ``<out>/proofs/certificates.json`` (each record with its provenance, as
    ``gpfverify prove`` writes it), and the section's ``runs.json`` naming that file."""
    from gpfverify.provenance import current
    from gpfverify.symbolic.claims import run_claims
    from gpfverify.symbolic.crosscheck import run_crosschecks

    size = "small" if ctx.quick else "large"

    def say(text: str) -> None:
        progress(f"{PROOFS}: {text.removeprefix('[prove] ')}")

    certificates = run_claims(size, progress=say) + run_crosschecks(size, seed=ctx.seed, progress=say)
    record = current()
    folder = ctx.out_dir / PROOFS
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / CERTIFICATES
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps([{**c.to_json(), "provenance": record} for c in certificates], indent=2),
                   encoding="utf-8")
    tmp.replace(path)
    runs = SectionRuns(PROOFS, ctx.profile, ctx.seed, (), certificates=CERTIFICATES)
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


def _duration(seconds: float) -> str:
    minutes, rest = divmod(int(round(seconds)), 60)
    return f"{minutes} min {rest} s" if minutes else f"{rest} s"


def build(ctx: ReportContext, only: list[str] | None, progress: Progress) -> Path:
    """Run what the selected sections render, then render the report; returns the HTML path."""
    selected = [s for s in SECTIONS if not only or s in only]
    eta = Eta(plan(ctx, selected))
    for number, slug in enumerate(selected, 1):
        progress(f"section {number} of {len(selected)}: {slug}")
        if slug == PROOFS:
            run_proofs(ctx, progress)
        else:
            run_section(ctx, slug, progress, eta)
    progress("rendering the pages")
    return build_report(ctx.out_dir, only, progress)


def section_of(experiment: str) -> str:
    """The report section that renders ``experiment`` (a reproduce name)."""
    for slug, names in SECTION_EXPERIMENTS.items():
        if experiment in names:
            return slug
    raise InputError(f"no report section renders the experiment {experiment!r}")


def render_reproduced(source: Path, out: Path, wait: bool = False) -> Path:
    """Render the folder of one ``gpfverify reproduce NAME --out DIR`` run (``source``) as a page
    in ``out``: its results (and interpretations) copied as the section's only run, nothing run.
    Returns the HTML page's path."""
    results_path = source / "results.json"
    if not results_path.is_file():
        raise InputError(f"--from {source}: no results.json; give the folder 'gpfverify reproduce NAME --out DIR' "
                         "wrote")
    try:
        results = json.loads(results_path.read_text(encoding="utf-8"))
    except ValueError as exc:
        raise InputError(f"--from {source}: results.json is not valid JSON ({exc})") from None
    if not isinstance(results, dict) or not isinstance(results.get("experiment"), str):
        raise InputError(f"--from {source}: results.json names no experiment (not a reproduce folder)")
    name = results["experiment"]
    slug = section_of(name)
    with output_folder(out, keep=False, wait=wait) as stage:  # the page is rendered whole every time
        folder = f"{name}-{REPRODUCED}"
        shutil.copytree(source, stage / slug / folder / "run", ignore=shutil.ignore_patterns("runs", ".*"))
        write_runs(stage, SectionRuns(slug, REPRODUCED, int(results.get("seed", 0)),
                                      (RunEntry(name, "", REPRODUCED, f"{folder}/run/results.json"),)))
        title = papers_title([slug]).replace("Verification report", f"gpfverify reproduce {name}")
        html = final_path(build_report(stage, [slug], progress=lambda text: None, title=title), stage, out)
    return html


def run(args: argparse.Namespace) -> int:
    if args.from_dir is not None:
        if args.full or args.only:
            raise InputError("--from renders a folder that reproduce wrote: not together with --full or --only")
        out = args.out or Path(str(args.from_dir).rstrip("/\\") + "-report")
        html_path = render_reproduced(args.from_dir, out, args.wait)
        print(f"The page: {html_path} (one self-contained page; open it in a browser)\n"
              f"          {out / 'README.md'} (Markdown)")
        return 0
    profile = "full" if args.full else "quick"
    out = args.out or Path("reports") / profile
    selected = [s for s in SECTIONS if not args.only or s in args.only]
    with output_folder(out, keep=True, wait=args.wait) as stage, Progress() as progress:
        progress(f"building the {profile} report in {out} (seed {args.seed}, {args.workers} worker(s)): "
                 f"{', '.join(selected)}")
        ctx = ReportContext(stage, profile, args.seed, args.workers)
        html_path = final_path(build(ctx, args.only, progress), stage, out)
        summaries = read_summaries(stage, list(SECTIONS))
        progress(f"done in {_duration(time.monotonic() - progress.started)}")
    counts = VerdictCounts.total(s.verdicts for s in summaries)
    print(f"\nThe report: {html_path} (one self-contained page; open it in a browser)\n"
          f"            {out / 'README.md'} (Markdown pages, one per section)\n"
          f"Verdicts:   {counts.line()}", flush=True)
    return 0
