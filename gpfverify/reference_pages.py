"""Steps shared by the scripts that render the committed reference pages from saved runs.

The per-run files stay where the runs were made; ``results.json`` is recomputed from them with the
current summaries and copied, with its manifest, next to the page that shows it.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

from gpfverify.contract.claims import ClaimRecord, carry, read_claims
from gpfverify.experiments.batching import batching_caveat, with_batching_caveat
from gpfverify.experiments.runner import read_manifest, results_of
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
