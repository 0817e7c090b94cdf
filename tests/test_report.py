"""Report rendering and the moments page, end to end."""

import re

from gpfverify.report import ReportContext, build_report
from gpfverify.report.document import Claim, Paragraph, Section, Table, claims_table
from gpfverify.report.render import to_html, to_markdown


def test_markdown_and_html_escape_and_render_every_block(tmp_path):
    section = Section("demo", "Demo <page>").add(
        Paragraph("a < b & c"),
        Table(["x | y", "z"], [[1.23456789, "p|q"]], "cap"),
        claims_table([Claim("claim A", True, "1 < 2"), Claim("claim B", False, "3 > 4"),
                      Claim("claim C", None, "too few runs")]),
    )
    md = to_markdown(section, tmp_path)
    assert "| x \\| y | z |" in md and "1.235" in md and "p\\|q" in md
    assert "NOT held" in md and "undecided" in md
    page = to_html([section], "t")
    assert "a &lt; b &amp; c" in page and "Demo &lt;page&gt;" in page


def test_moments_page_is_built_with_numbers_and_an_embedded_figure(tmp_path):
    html_path = build_report(ReportContext(tmp_path, "quick", seed=3), only=["moments"], progress=lambda _: None)
    page = (tmp_path / "moments" / "README.md").read_text()
    assert (tmp_path / "moments" / "moment_matching.png").stat().st_size > 10_000
    rows = [line for line in page.splitlines() if line.startswith("| D=")]
    assert len(rows) == 3
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        quad_change, quad_errors = float(cells[2]), [float(c) for c in cells[3:6]]
        mc_z = float(cells[6])
        assert quad_change <= 1e-10  # the oracle converged ...
        assert max(quad_errors) < 1e-6  # ... and the closed form agrees with it
        assert mc_z < 5.0  # and with Monte Carlo within 5 standard errors
    assert re.search(r"data:image/png;base64,[A-Za-z0-9+/]{1000}", html_path.read_text())


def _fake_sections(monkeypatch, built: list):
    """Three cheap sections standing in for the real ones."""
    import sys
    import types

    import gpfverify.report as report

    sections = {}
    for slug in ("first", "second", "third"):
        module = types.ModuleType(f"fake_section_{slug}")

        def build(ctx, slug=slug):
            built.append(slug)
            return Section(slug, f"Page {slug} (seed {ctx.seed})").add(Paragraph(f"body of {slug}"))

        module.build = build
        monkeypatch.setitem(sys.modules, module.__name__, module)
        sections[slug] = module.__name__
    monkeypatch.setattr(report, "SECTIONS", sections)


def test_only_updates_its_sections_and_keeps_the_rest_of_the_index(monkeypatch, tmp_path):
    built: list = []
    _fake_sections(monkeypatch, built)
    build_report(ReportContext(tmp_path, "quick", seed=1), progress=lambda _: None)
    build_report(ReportContext(tmp_path, "quick", seed=2), only=["second"], progress=lambda _: None)
    assert built == ["first", "second", "third", "second"]
    index = (tmp_path / "README.md").read_text()
    links = re.findall(r"- \[(.*?)\]\((.*?)/README.md\)", index)
    assert links == [("Page first (seed 1)", "first"), ("Page second (seed 2)", "second"),
                     ("Page third (seed 1)", "third")]  # report order, the rebuilt one updated
    page = (tmp_path / "report.html").read_text()
    assert [m for m in re.findall(r'<section id="(\w+)"', page)] == ["first", "second", "third"]
    assert "body of first" in page and "Page second (seed 2)" in page and "seed 1)</h1>" in page
