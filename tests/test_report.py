"""Report rendering: blocks to Markdown and HTML, and ``--only`` builds that keep the other sections."""

import re

from gpfverify.contract import SectionRuns
from gpfverify.full_report import build_report
from gpfverify.report.document import (Cell, Claim, Details, Link, Paragraph, Section, Table, VerdictCell,
                                       claims_table)
from gpfverify.report.inputs import write_runs
from gpfverify.report.render import to_html, to_markdown


def test_markdown_and_html_escape_and_render_every_block(tmp_path):
    section = Section("demo", "Demo <page>").add(
        Paragraph("a < b & c"),
        Table(["x | y", "z"], [[1.23456789, "p|q"]], "cap"),
        claims_table([Claim("claim A", True, "1 < 2"), Claim("claim B", False, "3 > 4"),
                      Claim("claim C", None, "too few runs")]),
        Table(["verdict", "cell", "link"], [[VerdictCell("NOT held", ("rests on 2 runs",)), Cell(3, "count"),
                                             Link("Page <b>", "demo")]], row_ids=("row-1",)),
        Details("more <detail>", "x_{k+1} & y"),
    )
    md = to_markdown(section, tmp_path)
    assert "| x \\| y | z |" in md and "1.235" in md and "p\\|q" in md
    assert "NOT held" in md and "undecided" in md
    # what would start raw HTML is shown as text (docs/output-and-errors.md); comparisons are left alone
    assert "| NOT held ⚠ rests on 2 runs | 3 | [Page &lt;b>](demo/README.md) |" in md
    assert "**more &lt;detail>** xₖ₊₁ & y" in md and "# Demo &lt;page>" in md and "a < b & c" in md
    page = to_html([section], "t")
    assert "a &lt; b &amp; c" in page and "Demo &lt;page&gt;" in page
    assert '<tr id="row-1"><td data-label="verdict" class="verdict v-not-held">' in page
    assert '<div class="caution" title="rests on 2 runs">⚠ rests on 2 runs</div>' in page
    assert '<td data-label="cell" class="count">3</td>' in page and '<a href="#demo">Page &lt;b&gt;</a>' in page
    assert "<details><summary>more &lt;detail&gt;</summary><p>xₖ₊₁ &amp; y</p></details>" in page


def _fake_sections(monkeypatch, tmp_path, rendered: list):
    """Three cheap sections rendering from (empty) runs.json files."""
    import sys
    import types

    import gpfverify.full_report as report

    sections = {}
    for slug in ("first", "second", "third"):
        module = types.ModuleType(f"fake_section_{slug}")

        def render_section(data, slug=slug):
            rendered.append(slug)
            return Section(slug, f"Page {slug} (seed {data.runs.seed})").add(Paragraph(f"body of {slug}"))

        module.render_section = render_section
        monkeypatch.setitem(sys.modules, module.__name__, module)
        sections[slug] = module.__name__
    monkeypatch.setattr(report, "SECTIONS", sections)


def test_only_updates_its_sections_and_keeps_the_rest_of_the_index(monkeypatch, tmp_path):
    rendered: list = []
    _fake_sections(monkeypatch, tmp_path, rendered)
    for slug in ("first", "second", "third"):
        write_runs(tmp_path, SectionRuns(slug, "quick", 1, ()))
    build_report(tmp_path, progress=lambda _: None)
    write_runs(tmp_path, SectionRuns("second", "quick", 2, ()))
    build_report(tmp_path, only=["second"], progress=lambda _: None)
    assert rendered == ["first", "second", "third", "second"]
    index = (tmp_path / "README.md").read_text()
    links = re.findall(r"^- \[(.*?)\]\((.*?)/README.md\)", index, re.M)
    assert links == [("Page first (seed 1)", "first"), ("Page second (seed 2)", "second"),
                     ("Page third (seed 1)", "third")]  # report order, the rebuilt one updated
    page = (tmp_path / "report.html").read_text()
    assert [m for m in re.findall(r'<section id="([\w-]+)"', page)] == [
        "summary", "what-was-run", "first", "second", "third", "references", "provenance"]
    assert "body of first" in page and "Page second (seed 2)" in page and "seed 1)</h2>" in page
