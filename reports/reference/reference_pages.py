"""Steps shared by the scripts that render the committed reference pages from saved runs.

The per-run files stay where the runs were made; ``results.json`` is recomputed from them with the
current summaries and copied, with its manifest, next to the page that shows it.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Sequence
from pathlib import Path

from gpfverify.contract.claims import read_claims
from gpfverify.contract.interpretations import robustness
from gpfverify.experiments.sensitivity import merge_saved
from gpfverify.report.document import Paragraph, Section
from gpfverify.report.render import to_markdown


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


def provenance_paragraph(page_dir: Path) -> Paragraph:
    """Which commit made the runs of every ``manifest.json`` committed under ``page_dir``."""
    made = {}
    for manifest_path in sorted(page_dir.rglob("manifest.json")):
        provenance = json.loads(manifest_path.read_text(encoding="utf-8"))["provenance"]
        where = manifest_path.parent.relative_to(page_dir).as_posix()
        made[provenance["git_commit"][:12] + ("" if where == "." else f" ({where})")] = None
    return Paragraph("Runs made at commit " + "; ".join(made)
                     + " (each folder's manifest.json has the full provenance).")


#: words by which a claim's caveat reports a failed health check (divergence, NEES, particle degeneracy)
HEALTH_WORDS = ("health", "NEES", "diverge", "N_eff")


def not_held_paragraph(results: Sequence[dict]) -> Paragraph | None:
    """Each NOT held verdict with the readings it was tried under (:func:`robustness`) and the
    health caveats it carries; None when no verdict is NOT held."""
    said = []
    for claim in (c for r in results for c in read_claims(r) if c.verdict == "NOT held"):
        tried = robustness(claim) or "no other documented reading was tried"
        health = [c for c in claim.caveats if any(w in c for w in HEALTH_WORDS)]
        said.append(f"{claim.claim}{f' ({claim.setting})' if claim.setting else ''}: {tried}; "
                    + ("health: " + " / ".join(health) if health else "its record carries no failed health check"))
    if not said:
        return None
    return Paragraph("NOT held verdicts, the readings each was tried under and the health of the filters compared "
                     "(from the claim records): " + "; ".join(f"({i}) {s}" for i, s in enumerate(said, 1)) + ".")


def write_page(section: Section, page_dir: Path, results: Sequence[dict] = ()) -> Path:
    """The page as ``README.md`` in ``page_dir``, with the NOT held verdicts' readings and health
    (from ``results``) and the commit its runs were made at."""
    if (paragraph := not_held_paragraph(results)) is not None:
        section.add(paragraph)
    section.add(provenance_paragraph(page_dir))
    path = page_dir / "README.md"
    path.write_text(to_markdown(section, page_dir), encoding="utf-8")
    return path
