"""The whole verification report: every paper's section and the proofs' page, in order, rendered
into one document (one Markdown page per section with its figures, plus one HTML page).

Sections are modules listed in :data:`SECTIONS` (the papers' ``section`` modules,
:mod:`gpfverify.papers`, and :mod:`gpfverify.report.proofs`); each defines
``render_section(data: SectionInput) -> Section``, rendering from the files the command layer
(:mod:`gpfverify.commands.report`) wrote (:mod:`gpfverify.report.inputs`). This module assembles
and renders; it never runs an experiment. It sits above the papers it assembles, as the notebook
views do above the records they show (docs/architecture.md).
"""


from __future__ import annotations

import importlib
from pathlib import Path

from gpfverify.report.document import Section
from gpfverify.report.render import write_report

#: section slug -> module; order is the order of the report.
SECTIONS: dict[str, str] = {
    "moments": "gpfverify.papers.fusion.moments_section",
    "gpadf-scalar": "gpfverify.papers.gpadf_scalar.section",
    "ungm1d": "gpfverify.papers.fusion.ungm1d_section",
    "ct2d": "gpfverify.papers.fusion.ct2d_section",
    "tbd": "gpfverify.papers.tbd.section",
    "particle-flow": "gpfverify.papers.particle_flow.section",
    "sins-gps": "gpfverify.papers.gpsr_upf.section",
    "proofs": "gpfverify.report.proofs",
}


#: the papers each section reproduces (added to the papers its claim records name)
SECTION_PAPERS: dict[str, tuple[str, ...]] = {
    "moments": ("seed000",),
    "gpadf-scalar": ("deisenroth2009",),
    "ungm1d": ("seed000",),
    "ct2d": ("seed000",),
    "tbd": ("seed004",),
    "particle-flow": ("seed003",),
    "sins-gps": ("seed001",),
}

_NUMBER_WORDS = ("no", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten")


def papers_title(slugs) -> str:
    """The report's title, counting the distinct papers the sections ``slugs`` reproduce."""
    papers = {p for slug in slugs for p in SECTION_PAPERS.get(slug, ())}
    count = _NUMBER_WORDS[len(papers)] if len(papers) < len(_NUMBER_WORDS) else str(len(papers))
    return (f"Verification report: Gaussian-process filters and multisensor fusion, {count} "
            f"paper{'s' if len(papers) != 1 else ''} reproduced")


TITLE = papers_title(SECTIONS)
PREAMBLE = ("Each section reruns one paper's experiments (or checks its algebra) with this toolkit and "
            "records every claim it checks as a verdict computed from the runs; nothing on these pages "
            "is typed in by hand. The summary counts them; each section opens with the runs it rests on.")


def build_report(out_dir: Path, only: list[str] | None = None, progress=print, title: str = TITLE) -> Path:
    """Render the sections (all, or ``only``) from the files the command layer wrote in ``out_dir``
    and write the report there (:func:`~gpfverify.report.render.write_report`); returns the HTML
    page's path. Sections not in ``only`` keep the pages already in ``out_dir``."""
    from gpfverify.errors import InputError

    unknown = sorted(set(only or []) - set(SECTIONS))
    if unknown:
        raise InputError(f"unknown section(s) {unknown}; choose from {list(SECTIONS)}")
    from gpfverify import provenance
    from gpfverify.report.inputs import load_section, summarize_section

    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"--out {out_dir} exists and is not a folder")
    sections: list[Section] = []
    summaries = {}
    for slug, module in SECTIONS.items():
        if only and slug not in only:
            continue
        progress(f"{slug}: rendering the page")
        data = load_section(out_dir, slug)
        section = importlib.import_module(module).render_section(data)
        summaries[slug] = summarize_section(data, section.title, SECTION_PAPERS.get(slug, ()))
        sections.append(section)
    progress("writing the report pages (Markdown and one HTML file)")
    return write_report(sections, out_dir, title, PREAMBLE, order=list(SECTIONS),
                        provenance=provenance.current(), summaries=summaries)
