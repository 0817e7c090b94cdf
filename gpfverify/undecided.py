"""The claims the committed reference runs leave open, and the command that would decide each.

Read from the committed reference pages' records (``reports/reference/**/results.json`` with their
``manifest.json``), never typed: every claim whose verdict is undecided — as run, or under an
interpretation — with a runs-needed estimate (:attr:`~gpfverify.contract.claims.ClaimRecord.runs_to_decide`,
were the mean and spread seen the true ones) of at most :data:`LIMIT` runs, and every claim the runs
could not judge for want of data they did not keep (``needs``). Claims that one command would decide
are grouped under it: the experiment at the page's parameters (an interpretation's changes applied,
so that its reading runs as a main run with the same seed — the same runs an interpretation run
makes), at :func:`planned` runs.

    python -m gpfverify.undecided            # writes docs/undecided-claims.md from the records

A test checks that the committed file is what the records give.
"""

from __future__ import annotations

import importlib
import json
import math
from dataclasses import dataclass
from pathlib import Path

from gpfverify.contract.claims import AS_RUN, ClaimRecord, read_claims
from gpfverify.papers import EXPERIMENTS
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


def _command(experiment: str, options: list[str], runs: int, seed: int, out: str) -> str:
    return " ".join(["gpfverify", "reproduce", experiment, *options, "--runs", str(runs), "--seed", str(seed),
                     "--out", out])


def open_claims(results: dict, limit: int = LIMIT) -> list[OpenClaim]:
    """The open verdicts of one ``results.json``: undecided (as run or under an interpretation) with
    an estimate of at most ``limit`` runs, or not judged for want of data."""
    out = []
    for claim in read_claims(results):
        if claim.needs:
            out.append(OpenClaim(claim, AS_RUN, claim.verdict, claim.n, None, claim.needs))
        elif claim.verdict == "undecided" and claim.runs_to_decide and claim.runs_to_decide <= limit:
            out.append(OpenClaim(claim, AS_RUN, claim.verdict, claim.n, claim.runs_to_decide))
        for i in claim.interpretations:
            if i.name != AS_RUN and i.verdict == "undecided" and i.runs_to_decide and i.runs_to_decide <= limit:
                out.append(OpenClaim(claim, i.name, i.verdict, i.n or claim.n, i.runs_to_decide))
    return out


def commands(reference: Path = REFERENCE, limit: int = LIMIT) -> list[Command]:
    """One command per page and reading with open verdicts, each at the runs its most demanding
    verdict plans (:func:`planned`; a claim not judged for want of data: the runs the page made)."""
    out = []
    for path in sorted(reference.rglob("results.json")):
        manifest_path = path.parent / "manifest.json"
        if not manifest_path.is_file():
            continue
        results = json.loads(path.read_text(encoding="utf-8"))
        manifest = json.loads(manifest_path.read_text(encoding="utf-8"))
        module = importlib.import_module(EXPERIMENTS[manifest["experiment"]])
        params = module.Params.from_json(manifest["params"])
        specs = {s.name: s for s in getattr(module, "INTERPRETATIONS", ())}
        page = path.parent.relative_to(reference).as_posix()
        by_reading: dict[str, list[OpenClaim]] = {}
        for item in open_claims(results, limit):
            by_reading.setdefault(item.reading, []).append(item)
        for reading, items in by_reading.items():
            changed = params if reading == AS_RUN else params.replace(**specs[reading].changes)
            runs = max(planned(i.estimate, i.runs) if i.estimate else i.runs for i in items)
            tag = page.replace("/", "-") + ("" if reading == AS_RUN else f"-{reading}")
            out.append(Command(page, reading, _command(manifest["experiment"], changed.cli_options(), runs,
                                                       manifest["seed"], f"OUT/{tag}"), runs, tuple(items)))
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
        "its parameters, an interpretation's changes applied (the same seeds: its first runs are the committed "
        "ones), at twice the largest estimate of the verdicts it decides (there the tolerance is 1/√2 of the "
        "margin seen), at least the runs made, rounded up to a hundred; a claim not judged for want of data is "
        "decided by the page's own runs made again with the current code, which keeps what it needs. The "
        "interpretations' verdicts are then read by running the page's command with `--interpretations`, or by "
        "reading these runs on their own."))
    page.add(Table(["page", "reading", "runs", "command", "open verdicts it would decide"],
                   [[c.page, c.reading, c.runs, f"`{c.text}`", _decides(c.decides)] for c in found],
                   f"{len(found)} commands, {sum(len(c.decides) for c in found)} open verdicts"))
    return page


def markdown(reference: Path = REFERENCE) -> str:
    """docs/undecided-claims.md as the records give it."""
    return to_markdown(section(commands(reference)), reference)


if __name__ == "__main__":
    DOC.write_text(markdown(), encoding="utf-8")
