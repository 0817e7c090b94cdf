"""The claims the committed reference runs leave open, and the command that would decide each.

Read from the committed reference pages' records (``reports/reference/**/results.json`` with their
``manifest.json``), never typed: every claim whose verdict is undecided — as run, or under an
interpretation — with a runs-needed estimate (:attr:`~gpfverify.contract.claims.ClaimRecord.runs_to_decide`,
were the mean and spread seen the true ones) of at most :data:`LIMIT` runs, and every claim the runs
could not judge for want of data they did not keep (``needs``). Claims that one command would decide
are grouped under it: the experiment at the page's parameters (:func:`page_fields` given explicitly),
under a reading with ``--interpretation NAME`` (its changes applied, so that the reading runs as a
main run with the same seed — the same runs an interpretation run makes), at :func:`planned` runs. A
reading whose own run is committed under the page's folder (:func:`reading_of`) is judged by that
run.

    python -m gpfverify.undecided            # writes docs/undecided-claims.md from the records

A test checks that the committed file is what the records give.
"""

from __future__ import annotations

import dataclasses
import importlib
import json
import math
from dataclasses import dataclass
from pathlib import Path

from gpfverify.contract.claims import AS_RUN, ClaimRecord, read_claims
from gpfverify.papers import EXPERIMENTS
from gpfverify.reference_pages import reading_name, timed_alike
from gpfverify.report.document import Paragraph, Section, Table
from gpfverify.report.render import to_markdown

#: the largest runs-needed estimate (per setting) whose command is listed
LIMIT = 20_000
#: the committed reference pages and the file this module writes, from the repository root
REFERENCE = Path("reports") / "reference"
DOC = Path("docs") / "undecided-claims.md"


def planned(estimate: int, runs: int) -> int:
    """The runs a command plans for a verdict estimated to need ``estimate`` runs: twice the
    estimate (where the Monte Carlo tolerance is 1/√2 of the margin seen, so the verdict is decided
    unless the true margin is below 0.71 of it), at least the runs made, rounded up to a hundred."""
    return int(math.ceil(max(2 * estimate, runs) / 100.0) * 100)


@dataclass(frozen=True)
class OpenClaim:
    """One open verdict: the claim, the reading it is open under (:data:`AS_RUN` or an
    interpretation's name), the runs it rests on, the runs-needed estimate (None for a claim not
    judged for want of data, with what it ``needs``)."""

    claim: ClaimRecord
    reading: str
    verdict: str
    runs: int
    estimate: int | None
    needs: str = ""


@dataclass(frozen=True)
class Command:
    """A command and the open verdicts it would decide."""

    page: str
    reading: str
    text: str
    runs: int
    decides: tuple[OpenClaim, ...]


def _command(experiment: str, options: list[str], reading: str, runs: int, seed: int, out: str,
             timed: bool = False) -> str:
    chosen = [] if reading == AS_RUN else ["--interpretation", reading]
    one_by_one = ["--batch", "1"] if timed else []  # a batch's runs share its time: no independent ratios
    return " ".join(["gpfverify", "reproduce", experiment, *options, *chosen, "--runs", str(runs), "--seed", str(seed),
                     *one_by_one, "--out", out])


def open_claims(results: dict, limit: int = LIMIT, readings: bool = True) -> list[OpenClaim]:
    """The open verdicts of one ``results.json``: undecided (as run or, with ``readings``, under an
    interpretation) with an estimate of at most ``limit`` runs, or not judged for want of data."""
    out = []
    for claim in read_claims(results):
        if claim.needs:
            out.append(OpenClaim(claim, AS_RUN, claim.verdict, claim.n, None, claim.needs))
        elif claim.verdict == "undecided" and claim.runs_to_decide and claim.runs_to_decide <= limit:
            out.append(OpenClaim(claim, AS_RUN, claim.verdict, claim.n, claim.runs_to_decide))
        for i in claim.interpretations if readings else ():
            if i.name != AS_RUN and i.verdict == "undecided" and i.runs_to_decide and i.runs_to_decide <= limit:
                out.append(OpenClaim(claim, i.name, i.verdict, i.n or claim.n, i.runs_to_decide))
    return out


@dataclass(frozen=True)
class Run:
    """One committed run: its folder (relative to the reference pages), its ``results.json`` and
    ``manifest.json``, and — for the run of one interpretation committed under its page's folder —
    the page's folder and the interpretation's name (else its own folder and :data:`AS_RUN`)."""

    folder: str
    results: dict
    manifest: dict
    page: str
    reading: str


def reading_of(folder: Path, manifest: dict, reference: Path = REFERENCE) -> tuple[str, str]:
    """(the page's folder, the reading) of a committed run: a run under a page's folder is that
    page's interpretation ``NAME`` when its manifest names it (``reproduce --interpretation NAME``), or
    when the folder is named after one of the experiment's interpretations and its parameters are the
    page's with that interpretation's changes (runs an interpretation made next to the main run);
    any other run is a page of its own, as run."""
    own = folder.relative_to(reference).as_posix()
    parent = next((f for f in folder.parents if (f / "manifest.json").is_file() and reference in f.parents), None)
    if parent is None:
        return own, AS_RUN
    page_manifest = json.loads((parent / "manifest.json").read_text(encoding="utf-8"))
    module = importlib.import_module(EXPERIMENTS[manifest["experiment"]])
    name = reading_name(manifest, page_manifest, module, folder.name)
    if name is None:
        return own, AS_RUN
    return parent.relative_to(reference).as_posix(), name


def committed_runs(reference: Path = REFERENCE) -> list[Run]:
    """Every committed run under ``reference`` with a manifest, each with its page and reading."""
    out = []
    for path in sorted(reference.rglob("results.json")):
        if not (path.parent / "manifest.json").is_file():
            continue
        manifest = json.loads((path.parent / "manifest.json").read_text(encoding="utf-8"))
        page, reading = reading_of(path.parent, manifest, reference)
        out.append(Run(path.parent.relative_to(reference).as_posix(), json.loads(path.read_text(encoding="utf-8")),
                       manifest, page, reading))
    return out


def page_fields(runs: list[Run]) -> dict[str, tuple[str, ...]]:
    """Per experiment, the parameters its commands always give: those in which its pages differ from
    one another or from the defaults (κ and Ω for ct2d), so that a command names the page's setting
    whatever the defaults."""
    out: dict[str, tuple[str, ...]] = {}
    for experiment in dict.fromkeys(r.manifest["experiment"] for r in runs):
        module = importlib.import_module(EXPERIMENTS[experiment])
        pages = [module.Params.from_json(r.manifest["params"]) for r in runs
                 if r.manifest["experiment"] == experiment and r.reading == AS_RUN]
        defaults = module.Params()
        out[experiment] = tuple(f.name for f in dataclasses.fields(module.Params)
                                if any(getattr(p, f.name) != getattr(defaults, f.name) for p in pages))
    return out


def commands(reference: Path = REFERENCE, limit: int = LIMIT) -> list[Command]:
    """One command per page and reading with open verdicts, each at the runs its most demanding
    verdict plans (:func:`planned`; a claim not judged for want of data: the runs the page made).
    A reading with a run of its own committed under the page's folder is judged by that run (its
    verdicts, on the claims the reading bears on), not by the page's entries for it."""
    runs = committed_runs(reference)
    always = page_fields(runs)
    pages = {r.folder: r for r in runs if r.reading == AS_RUN}
    # a reading's own run decides its claims for the page; its claims on computation time only when
    # timed as the page's runs were (timed_alike)
    committed_readings = {(r.page, r.reading): timed_alike(pages[r.page].results, r.results)
                          for r in runs if r.reading != AS_RUN}
    found: dict[tuple[str, str], list[OpenClaim]] = {}  # (page, reading) -> its open verdicts, in order
    for run in runs:
        if run.reading == AS_RUN:
            for item in open_claims(run.results, limit):
                alike = committed_readings.get((run.page, item.reading))
                if alike is None or (item.claim.timing and not alike):
                    found.setdefault((run.page, item.reading), []).append(item)
        else:
            module = importlib.import_module(EXPERIMENTS[run.manifest["experiment"]])
            spec = next(s for s in module.INTERPRETATIONS if s.name == run.reading)
            for item in open_claims(run.results, limit, readings=False):
                if spec.bears_on_claim(item.claim.id) and (not item.claim.timing
                                                           or committed_readings[(run.page, run.reading)]):
                    found.setdefault((run.page, run.reading), []).append(dataclasses.replace(item, reading=run.reading))
    out = []
    for (folder, reading), items in found.items():
        page = pages[folder]
        experiment = page.manifest["experiment"]
        params = importlib.import_module(EXPERIMENTS[experiment]).Params.from_json(page.manifest["params"])
        planned_runs = max(planned(i.estimate, i.runs) if i.estimate else i.runs for i in items)
        tag = folder.replace("/", "-") + ("" if reading == AS_RUN else f"-{reading}")
        text = _command(experiment, params.cli_options(always[experiment]), reading, planned_runs,
                        page.manifest["seed"], f"OUT/{tag}", timed=any(i.claim.timing for i in items))
        out.append(Command(folder, reading, text, planned_runs, tuple(items)))
    return out


def _decides(items: tuple[OpenClaim, ...]) -> str:
    return "; ".join(f"{i.claim.id}{f' ({i.claim.setting})' if i.claim.setting else ''}: "
                     + (f"not judged on {i.runs} runs, needs {i.needs}" if i.needs else
                        f"{i.verdict} on {i.runs} runs, about {i.estimate} would decide it") for i in items)


def section(found: list[Command], limit: int = LIMIT) -> Section:
    """The page: what is listed and why, then one row per command."""
    page = Section("undecided-claims", "Claims the reference runs leave open, and the commands that would decide them")
    page.add(Paragraph(
        "Generated from the committed reference records by `python -m gpfverify.undecided` (a test checks that this "
        "file is what they give). Listed: every claim whose verdict is undecided — as run, or under an "
        f"interpretation — with a runs-needed estimate of at most {limit} runs (the runs at which the margin seen "
        "would exceed the Monte Carlo tolerance, were the mean and spread seen the true ones), and every claim the "
        "runs could not judge because they did not keep what it needs. Each command runs the page's experiment at "
        "its parameters — those in which the experiment's pages differ from one another or from the defaults given "
        "explicitly — and, for a reading, with `--interpretation NAME`, which applies that interpretation's "
        "parameter changes and records its name in the run's manifest.json and results.json (the same seeds: its "
        "first runs are the committed ones; a test parses every command with the command line's own parser and "
        "checks the parameters it gives), at twice the largest estimate of the verdicts it decides (there the "
        "tolerance is 1/√2 of the margin seen), at least the runs made, rounded up to a hundred; a claim not judged "
        "for want of data is decided by the page's own runs made again with the current code, which keeps what it "
        "needs. A command that decides a claim on computation time runs one run at a time (`--batch 1`): in a "
        "batch every run records the batch's time, so its per-run ratios would not be independent runs'. A "
        "reading's run committed under its page's folder (`<page>/<reading>/`, its results.json and "
        "manifest.json) is what the page shows for that reading and what this list reads for it, on the claims the "
        "reading bears on (on the claims on computation time only when it was timed as the page's runs were)."))
    page.add(Table(["page", "reading", "runs", "command", "open verdicts it would decide"],
                   [[c.page, c.reading, c.runs, f"`{c.text}`", _decides(c.decides)] for c in found],
                   f"{len(found)} commands, {sum(len(c.decides) for c in found)} open verdicts"))
    return page


def markdown(reference: Path = REFERENCE) -> str:
    """docs/undecided-claims.md as the records give it."""
    return to_markdown(section(commands(reference)), reference)


if __name__ == "__main__":
    DOC.write_text(markdown(), encoding="utf-8")
