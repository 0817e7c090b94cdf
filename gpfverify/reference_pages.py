"""Steps shared by the scripts that render the committed reference pages from saved runs.

The per-run files stay where the runs were made; ``results.json`` is recomputed from them with the
current summaries and copied, with its manifest, next to the page that shows it.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

from gpfverify.contract.claims import ClaimRecord, Interpretation, carry, read_claims
from gpfverify.contract.serial import to_json
from gpfverify.experiments.batching import batch_option, batching_caveat, runs_batched, with_batching_caveat
from gpfverify.experiments.runner import read_manifest, results_of, rewrite_results
from gpfverify.experiments.sensitivity import merge_saved
from gpfverify.report.document import Paragraph, Section, Table
from gpfverify.report.inputs import VerdictCounts
from gpfverify.report.render import to_markdown, verdicts_paragraph

#: the committed reference pages, relative to the repository root the page scripts run from
#: (``python -m gpfverify.papers.<paper>.page ...``)
REFERENCE = Path("reports") / "reference"


def rejudged(results: dict, module) -> dict:
    """A stored ``results.json`` with its claims judged again by the current code from the stored
    summary (the experiment's ``judge(params, body, runs) -> (claims, timing claims)``) and what only
    the runs could give — a verdict that needs per-run data the summary does not hold, the verdicts
    under the interpretations — carried over from the stored records
    (:func:`gpfverify.contract.claims.carry`); the claims on computation time under
    ``"timing_claims"``. For pages whose per-run files are no longer at hand."""
    params = module.Params.from_json(results["params"])
    claims, timing = module.judge(params, results, results.get("runs_ok", results["runs"]))
    merged = carry([*claims, *timing], read_claims(results), getattr(module, "SUMMARY_FIELDS", ()))
    timed = {c.id for c in timing}
    out = {**results, "claims": [c.to_json() for c in merged if c.id not in timed]}
    if timing or "timing_claims" in results:
        out["timing_claims"] = [c.to_json() for c in merged if c.id in timed]
    return with_batching_caveat(out, batching_caveat(module))


def rejudge_committed(path: Path, module) -> dict:
    """:func:`rejudged` of the committed ``results.json`` at ``path``, written back there."""
    results = rejudged(json.loads(path.read_text(encoding="utf-8")), module)
    path.write_text(json.dumps(results, allow_nan=True), encoding="utf-8")  # as the runner writes it
    return results


def recompute_into(run_dir: Path, module, target: Path) -> dict:
    """``results.json`` recomputed from the runs in ``run_dir`` with the verdicts under the
    interpretations saved there merged into its claims (compared on equal run counts:
    :func:`gpfverify.experiments.sensitivity.merge_saved`), copied with its manifest to ``target``;
    returns it."""
    results = merge_saved(run_dir, module)
    target.mkdir(parents=True, exist_ok=True)
    for name in ("results.json", "manifest.json"):
        shutil.copy(run_dir / name, target / name)
    return results


def reading_name(manifest: dict, page_manifest: dict, module, folder_name: str) -> str | None:
    """The interpretation whose run ``manifest`` describes, as a reading of the page whose run
    ``page_manifest`` describes: the one its manifest names (``gpfverify reproduce NAME
    --interpretation NAME``), else the one the folder is named after — either only when the
    experiment is the page's and the parameters are the page's with that interpretation's changes;
    None for any other run."""
    specs = {s.name: s for s in getattr(module, "INTERPRETATIONS", ())}
    name = manifest.get("interpretation") or folder_name
    if manifest.get("experiment") != page_manifest.get("experiment") or name not in specs:
        return None
    page_params = module.Params.from_json(page_manifest["params"])
    if page_params.replace(**specs[name].changes) != module.Params.from_json(manifest["params"]):
        return None
    return name


def reading_runs(page_dir: Path, module) -> dict[str, Path]:
    """The runs of single interpretations committed in the page's folder: ``<page_dir>/<name>/``
    holding the ``results.json`` and ``manifest.json`` of ``gpfverify reproduce ... --interpretation
    NAME`` at the page's parameters (:func:`reading_name`), by interpretation name."""
    page_manifest = json.loads((page_dir / "manifest.json").read_text(encoding="utf-8"))
    out = {}
    for spec in getattr(module, "INTERPRETATIONS", ()):
        folder = page_dir / spec.name
        if (folder / "results.json").is_file() and (folder / "manifest.json").is_file():
            manifest = json.loads((folder / "manifest.json").read_text(encoding="utf-8"))
            if reading_name(manifest, page_manifest, module, spec.name) == spec.name:
                out[spec.name] = folder
    return out


def readings_into(runs_dir: Path, prefix: str, page_dir: Path, module) -> list[str]:
    """Each interpretation's own run in ``runs_dir/<prefix>-<name>/`` (``gpfverify reproduce ...
    --interpretation NAME`` at the page's parameters) recomputed from its saved runs and copied, with
    its manifest, to ``page_dir/<name>/`` — unless the run committed there has more runs. Returns the
    names copied."""
    page_manifest = json.loads((page_dir / "manifest.json").read_text(encoding="utf-8"))
    copied = []
    for spec in getattr(module, "INTERPRETATIONS", ()):
        source = runs_dir / f"{prefix}-{spec.name}"
        if not (source / "manifest.json").is_file():
            continue
        manifest = read_manifest(source)
        if reading_name(manifest, page_manifest, module, spec.name) != spec.name:
            continue
        target = page_dir / spec.name
        if (target / "manifest.json").is_file() and \
                json.loads((target / "manifest.json").read_text(encoding="utf-8"))["runs"] > manifest["runs"]:
            continue
        rewrite_results(source, module)
        target.mkdir(parents=True, exist_ok=True)
        for name in ("results.json", "manifest.json"):
            shutil.copy(source / name, target / name)
        copied.append(spec.name)
    return copied


def timed_alike(results: dict, other: dict) -> bool:
    """Were the two runs' CPU times measured alike: both one run at a time, or both in batches
    (``machine_load.runs_batched``)? In a batch every run records the batch's time divided by its
    size, so its per-run ratios are the batch's, not independent runs' — and the batched code path
    costs the methods differently — so a claim on computation time is not compared across the two."""
    return runs_batched(results) == runs_batched(other)


def with_reading_runs(results: dict, page_dir: Path, module) -> dict:
    """``results`` (the page's, as committed in ``page_dir``) with each claim's verdict under an
    interpretation taken from that interpretation's own run committed in the page's folder
    (:func:`reading_runs`, judged again by the current code and written back), where that run has at
    least as many runs as the entry rests on; on the claims the interpretation bears on (a timing
    claim keeps no entry of an interpretation that only reads the same runs another way, and keeps
    its own entry where the two runs were not timed alike, :func:`timed_alike`). Written back to
    ``page_dir/results.json`` and returned."""
    runs = {name: rejudge_committed(folder / "results.json", module)
            for name, folder in reading_runs(page_dir, module).items()}
    if not runs:
        return results
    specs = {s.name: s for s in module.INTERPRETATIONS}
    reads_only = frozenset(getattr(module, "SUMMARY_FIELDS", ()))
    out = dict(results)
    for key in ("claims", "timing_claims"):
        if key not in results:
            continue
        claims = []
        for raw in results[key]:
            claim = ClaimRecord.from_json(raw)
            entries = {i.name: i for i in claim.interpretations}
            for name, reading in runs.items():
                spec = specs[name]
                other = next((c for c in read_claims(reading) if c.id == claim.id and claim.id), None)
                if other is None or not spec.bears_on_claim(claim.id) or \
                        (claim.timing and (set(spec.changes) <= reads_only or not timed_alike(results, reading))):
                    continue
                old = entries.get(name)
                if old is not None and (old.n or claim.n) > other.n:
                    continue
                entries[name] = Interpretation(name, to_json(spec.changes), other.verdict, other.statistic,
                                               other.n, other.runs_to_decide)
            claims.append(to_json(dataclasses.replace(claim, interpretations=tuple(entries.values()))))
        out[key] = claims
    (page_dir / "results.json").write_text(json.dumps(out, allow_nan=True), encoding="utf-8")
    return out


def reading_commands(page_dir: Path, module, command: Callable[[str, int], str]) -> str:
    """The commands that made the interpretations' own runs committed in the page's folder:
    ``command(name, runs)`` each, then the copy of its results.json and manifest.json; "" when none."""
    page = json.loads((page_dir / "results.json").read_text(encoding="utf-8"))
    said = []
    for name, folder in reading_runs(page_dir, module).items():
        runs = json.loads((folder / "manifest.json").read_text(encoding="utf-8"))["runs"]
        reading = json.loads((folder / "results.json").read_text(encoding="utf-8"))
        batch = (" " + batch_option(reading)).rstrip()
        said.append(f"{command(name, runs)}{batch} (its results.json and manifest.json "
                    f"in {folder.as_posix()}/"
                    + ("" if timed_alike(page, reading) else "; timed in batches, unlike the setting's runs: its "
                       "claims on computation time are not taken, the setting's own runs under this interpretation "
                       "decide them") + ")")
    return "; ".join(said)


#: the run counts at which a reference page shows each claim's verdict (those below the main run's)
RUN_LADDER = (40, 100, 200, 500)


def verdicts_by_run_count(run_dir: Path, module, runs: int, counts: Sequence[int] = RUN_LADDER
                          ) -> dict[int, list[ClaimRecord]]:
    """Every claim's verdict as run on the first n saved runs of ``run_dir`` (the same seeds), for
    each n of ``counts`` below ``runs``."""
    manifest = read_manifest(run_dir)
    return {n: read_claims(results_of(module, run_dir, manifest, n)) for n in counts if n < runs}


def runs_needed_table(results: dict, by_count: dict[int, list[ClaimRecord]], caption: str) -> Table:
    """Per claim: its verdict on the first n runs for each n of ``by_count`` and on all runs, and the
    runs it needed: between the last of those counts at which the verdict was another and the next
    (from which it is the final one at every larger count); for a verdict still undecided, about how
    many runs would decide it (were the mean and spread seen the true ones), said to exceed the
    paper's count where it does."""
    counts = sorted(by_count)
    rows = []
    for claim in read_claims(results):
        earlier = [next((c for c in by_count[n] if c.id == claim.id), None) for n in counts]
        verdicts = [c.verdict if c is not None else "—" for c in earlier] + [claim.verdict]
        if claim.verdict == "undecided":
            needed = "undecided"
            if claim.runs_to_decide:
                beyond = claim.paper_n is not None and claim.runs_to_decide > claim.paper_n
                needed += (f": about {claim.runs_to_decide} runs would decide it"
                           + (f", more than the paper's {claim.paper_n}" if beyond else ""))
        else:
            steady = len(verdicts) - 1  # the first count from which the verdict stays the final one
            while steady > 0 and verdicts[steady - 1] == claim.verdict:
                steady -= 1
            ladder = [*counts, claim.n]
            needed = (f"{ladder[0]} or fewer" if steady == 0 else
                      f"more than {ladder[steady - 1]}, at most {ladder[steady]}")
        rows.append([claim.claim + (f" ({claim.setting})" if claim.setting else ""), claim.group,
                     *verdicts, needed])
    return Table(["claim", "group", *(f"first {n} runs" for n in counts), f"all {results['runs_ok']} runs",
                  "runs it needed"], rows, caption)


def provenance_paragraph(page_dir: Path) -> Paragraph:
    """Which commit made the runs of every ``manifest.json`` committed under ``page_dir``."""
    made: dict[str, None] = {}
    for manifest_path in sorted(page_dir.rglob("manifest.json")):
        provenance = json.loads(manifest_path.read_text(encoding="utf-8"))["provenance"]
        where = manifest_path.parent.relative_to(page_dir).as_posix()
        made[provenance["git_commit"][:12] + ("" if where == "." else f" ({where})")] = None
    return Paragraph("Runs made at commit " + "; ".join(made)
                     + " (each folder's manifest.json has the full provenance).")


def write_page(section: Section, page_dir: Path, results: Sequence[dict] = ()) -> Path:
    """The page as ``README.md`` in ``page_dir``, opening with its verdicts counted per group
    (accuracy, the theorem checked on the runs, timing: :class:`~gpfverify.report.inputs.VerdictCounts`
    of the claims in ``results``), closing with the commit its runs were made at. (Each NOT held
    verdict's readings and health are in its row: :func:`gpfverify.report.document.not_held_note`.)"""
    claims = [c for r in results for c in read_claims(r)]
    if claims:
        section.blocks.insert(0, verdicts_paragraph(VerdictCounts.of(claims)))
    section.add(provenance_paragraph(page_dir))
    path = page_dir / "README.md"
    path.write_text(to_markdown(section, page_dir), encoding="utf-8")
    return path


#: the option of a page script that draws the page's figures again from its committed results
FIGURES = "--figures"


def redraw_figures(page_dir: Path, results_path: Path, render: Callable[[dict, Path], object]) -> list[Path]:
    """The figures of a committed page drawn again from its committed ``results.json`` (the saved runs
    are not committed): ``render(results, folder)`` renders the page's section with its figures into
    a temporary folder, and every PNG the page already has is replaced by its new drawing; the page's
    text is left as it is. Returns the figures replaced."""
    results = json.loads(results_path.read_text(encoding="utf-8"))
    replaced = []
    with tempfile.TemporaryDirectory(prefix="gpfverify-figures-") as folder:
        render(results, Path(folder))
        for png in sorted(Path(folder).rglob("*.png")):
            target = page_dir / png.relative_to(folder)
            if target.is_file():
                shutil.copyfile(png, target)
                replaced.append(target)
    return replaced
