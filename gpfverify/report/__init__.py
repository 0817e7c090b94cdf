"""The verification report: one page per section, Markdown + PNG, plus one HTML page.

Sections are modules listed in :data:`SECTIONS`; each defines
``render_section(data: SectionInput) -> Section``, rendering from the files the command layer
wrote (:mod:`gpfverify.report.inputs`). A section that still defines only ``build(ctx)`` runs its
own experiment (being phased out).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path

from gpfverify.report.document import Section
from gpfverify.report.render import write_report

#: section slug -> module; order is the order of the report.
SECTIONS: dict[str, str] = {
    "moments": "gpfverify.report.sections.moments",
    "gpadf-scalar": "gpfverify.report.sections.gpadf_scalar",
    "ungm1d": "gpfverify.report.sections.fusion_ungm1d",
    "ct2d": "gpfverify.report.sections.fusion_ct2d",
    "tbd": "gpfverify.report.sections.tbd",
    "particle-flow": "gpfverify.report.sections.particle_flow",
    "sins-gps": "gpfverify.report.sections.sins_gps",
    "proofs": "gpfverify.report.sections.proofs",
}


#: the papers each section reproduces (added to the papers its claim records name)
SECTION_PAPERS: dict[str, tuple[str, ...]] = {
    "moments": ("seed000",),
    "ungm1d": ("seed000",),
    "ct2d": ("seed000",),
    "tbd": ("seed004",),
    "particle-flow": ("seed003",),
    "sins-gps": ("seed001",),
}

TITLE = "Verification report: Gaussian-process filters and multisensor fusion, four papers reproduced"
PREAMBLE = ("Each section reruns one paper's experiments (or checks its algebra) with this toolkit and "
            "records every claim it checks as a verdict computed from the runs; nothing on these pages "
            "is typed in by hand. The summary counts them; each section opens with the runs it rests on.")


@dataclass(frozen=True)
class ReportContext:
    """What a section needs: where to write, how big a run to make, a seed."""

    out_dir: Path
    profile: str  # "quick" (minutes, few runs) or "full" (the papers' run counts)
    seed: int = 1
    workers: int = 1

    @property
    def quick(self) -> bool:
        return self.profile == "quick"

    def section_dir(self, slug: str) -> Path:
        path = self.out_dir / slug
        path.mkdir(parents=True, exist_ok=True)
        return path


def build_report(ctx: ReportContext, only: list[str] | None = None, progress=print) -> Path:
    """Render the sections (all, or ``only``) from the files in ``ctx.out_dir`` and write the
    report there (:func:`~gpfverify.report.render.write_report`); returns the HTML page's path."""
    unknown = sorted(set(only or []) - set(SECTIONS))
    if unknown:
        from gpfverify.errors import InputError

        raise InputError(f"unknown section(s) {unknown}; choose from {list(SECTIONS)}")
    from gpfverify import provenance
    from gpfverify.report.inputs import SectionSummary, load_section, summarize_section

    if ctx.out_dir.exists() and not ctx.out_dir.is_dir():
        from gpfverify.errors import InputError

        raise InputError(f"--out {ctx.out_dir} exists and is not a folder")
    sections: list[Section] = []
    summaries = {}
    for slug, module in SECTIONS.items():
        if only and slug not in only:
            continue
        progress(f"{slug}: rendering the page")
        section_module = importlib.import_module(module)
        if hasattr(section_module, "render_section"):
            data = load_section(ctx.out_dir, slug)
            section = section_module.render_section(data)
            summaries[slug] = summarize_section(data, section.title, SECTION_PAPERS.get(slug, ()))
        else:  # legacy: the section runs its own experiment
            section = section_module.build(ctx)
            summaries[slug] = SectionSummary(slug, section.title, ctx.profile, ctx.seed, SECTION_PAPERS.get(slug, ()))
        sections.append(section)
    progress("writing the report pages (Markdown and one HTML file)")
    # --only rebuilds its sections and keeps the others already in the folder
    return write_report(sections, ctx.out_dir, TITLE, PREAMBLE, order=list(SECTIONS),
                        provenance=provenance.current(), summaries=summaries)


def run_for_report(ctx: ReportContext, slug: str, module, params: dict, runs: int) -> dict:
    """Run an experiment for a report section into ``<out>/<slug>/run``, reusing the runs saved
    there when they were made with the same settings, and return its results."""
    import json
    import shutil

    from gpfverify.experiments.runner import make_executor, run_experiment

    run_dir = ctx.section_dir(slug) / "run"
    manifest = run_dir / "manifest.json"
    if manifest.exists():
        try:
            old = json.loads(manifest.read_text(encoding="utf-8"))
            same = (old.get("seed"), old.get("runs"), old.get("params")) == \
                (ctx.seed, runs, json.loads(json.dumps(params)))
        except (ValueError, AttributeError, RecursionError):  # damaged: start this run afresh
            same = False
        if not same:
            shutil.rmtree(run_dir)
    with make_executor(ctx.workers) as executor:
        return run_experiment(module, params, runs, ctx.seed, run_dir, resume=True, executor=executor)
