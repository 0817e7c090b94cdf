"""Every table of the real pages — the report of every section, the check page and the audit page —
fits a 1024 px window, wrapping or stacked, with no sentence squeezed into a sliver: measured in a
headless browser (a Chromium on PATH or playwright's; Debian: ``apt-get install -y chromium``).
The summary table's layout rules (its CSS) are checked without a browser too. Markdown
code spans render as HTML, never as raw backticks. Chinese text renders with the CJK font the
page embeds: its subset covers every CJK character of gpfverify's sources (read with fontTools),
and a browser loads it."""

import base64
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from gpfverify.commands.report import render_reproduced
from gpfverify.report import cjk_font
from gpfverify.report.document import Paragraph, Section
from gpfverify.report.render import _STYLE, inline, to_html

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))  # the suite imports in importlib mode: the helper beside it
import layout_pages  # noqa: E402

pytestmark = pytest.mark.slow  # renders real pages and measures them in a browser

WINDOW = 1024  # px
REM = 16  # px, the browsers' default root font size
BROWSER = layout_pages.browser()
needs_browser = pytest.mark.skipif(BROWSER is None, reason="no headless browser (chromium, chromium-browser, "
                                   "google-chrome on PATH, or playwright's); Debian: apt-get install -y chromium")
#: a cell holding a sentence is at least this wide (px): 7.5 rem, about fifteen characters a line
READABLE = 7.5 * REM


@pytest.fixture(scope="module")
def page(tmp_path_factory) -> Path:
    source = tmp_path_factory.mktemp("reproduced") / "ungm1d"
    source.mkdir()
    shutil.copy(HERE / "fixtures" / "ungm1d" / "results.json", source / "results.json")
    return render_reproduced(source, source.with_name("page"))


def _rule(selector: str, css: str = _STYLE) -> str:
    match = re.search(r"(?:^|[}\n])" + re.escape(selector) + r"\{([^}]*)\}", css)
    assert match, f"no CSS rule for {selector}"
    return match.group(1)


def _rem(declarations: str, prop: str) -> float:
    match = re.search(rf"(?:^|;){prop}:([\d.]+)rem", declarations)
    assert match, f"{prop} not in rem in {declarations!r}"
    return float(match.group(1))


def test_the_summary_tables_layout_rules_fit_a_1024_px_window(page):
    html = page.read_text(encoding="utf-8")
    assert 'class="summary"' in html  # the rules below are the ones the page uses
    narrow = re.search(r"@media \(max-width:(\d+)px\)\{\.layout\{grid-template-columns:([\d.]+)rem", _STYLE)
    assert narrow and int(narrow.group(1)) >= WINDOW, "at 1024 px the contents column must be narrowed"
    toc = float(narrow.group(2)) * REM
    main = _STYLE[narrow.end():].split("}}", 1)[0]
    padding = 2 * float(re.search(r"main\{padding:[\d.]+rem ([\d.]+)rem", main).group(1)) * REM
    column = WINDOW - toc - padding
    assert _rule("table.summary") == "width:100%"  # the table takes the column, no more
    headers = _rule("table.summary th")
    assert "overflow-wrap:anywhere" in headers  # long headers wrap instead of widening their columns
    assert "white-space:nowrap" not in _rule("table.summary td,table.summary th")
    # the widest the columns are forced to be: the declared minimum widths, plus the other
    # columns at two characters each (headers wrap anywhere; cells hold counts)
    minimums = [_rem(_rule("table.summary td:nth-child(2)"), "min-width"),
                _rem(_rule("table.summary td.paper"), "min-width"),
                _rem(_rule("table.summary td.chips"), "min-width")]
    header_count = len(re.search(r'<table class="summary">.*?<thead><tr>(.*?)</tr>', html, re.S).group(1)
                       .split("<th>")) - 1
    forced = sum(minimums) * REM + (header_count - len(minimums)) * 2 * 0.74 * REM
    assert forced <= column, (forced, column)


@pytest.fixture(scope="module")
def real_pages(tmp_path_factory) -> dict[str, Path]:
    """The three kinds of page as the commands write them (the report from stored results)."""
    folder = tmp_path_factory.mktemp("pages")
    (folder / "report").mkdir()
    return {"report": layout_pages.report_page(folder / "report"), "check": layout_pages.check_page(folder / "check"),
            "audit": layout_pages.audit_page(folder / "audit")}


@needs_browser
@pytest.mark.parametrize("kind", ["report", "check", "audit"])
def test_every_table_of_every_page_fits_a_1024_px_window(real_pages, kind, tmp_path):
    """Each table ends within the main column (no sideways scroll), no cell's text overflows it,
    and a cell holding a sentence keeps a readable width (the claim column was 85 px once)."""
    measured = layout_pages.measure(BROWSER, real_pages[kind], WINDOW, tmp_path)
    assert measured["window"] == WINDOW
    tables = measured["tables"]
    assert len(tables) >= {"report": 40, "check": 3, "audit": 2}[kind]  # every table of the page is measured
    for table in tables:
        where = (kind, table["i"], table["caption"])
        assert table["right"] <= table["limit"] and not table["scroll"], (where, table["right"], table["limit"])
        assert not [c["text"] for c in table["cells"] if c["over"]], where
        squeezed = [(c["w"], c["text"]) for c in table["cells"] if c["chars"] >= 40 and " " in c["text"]
                    and c["w"] < READABLE]
        assert not squeezed, (where, squeezed)


def _assert_figures_readable(measured: dict, html_text: str, where: str) -> None:
    """Every image is a figure gpfverify.report.figures.save wrote (it records the smallest font, in
    the PNG's pixels, and the legends over data), whose smallest text is at least MIN_TEXT_PX as the
    browser shows it (that font times the shown width over the PNG's own), with no legend over data."""
    from gpfverify.report.figures import MIN_TEXT_PX

    records, images = layout_pages.figures_shown(html_text), measured["images"]
    assert len(records) == len(images) and images, (where, len(records), len(images))
    for record, image in zip(records, images):
        assert record, (where, image["i"], "a figure not written by gpfverify.report.figures.save")
        shown_px = record["min_font_px"] * image["shown"] / image["natural"]
        assert shown_px >= MIN_TEXT_PX, (where, image, record, round(shown_px, 2))
        assert record["legends_over_data"] == 0, (where, image, record)


@needs_browser
@pytest.mark.parametrize("kind", ["report", "check", "audit"])
def test_every_text_of_every_figure_is_at_least_9_px_at_a_1024_px_window(real_pages, kind, tmp_path):
    page = real_pages[kind]
    measured = layout_pages.measure(BROWSER, page, WINDOW, tmp_path)
    _assert_figures_readable(measured, page.read_text(encoding="utf-8"), kind)


@needs_browser
def test_every_committed_reference_figure_is_readable_at_a_1024_px_window(tmp_path):
    """The committed reference pages' figures (regenerated by each page's command), shown as the
    report shows figures."""
    pngs = sorted((layout_pages.ROOT / "reports" / "reference").rglob("*.png"))
    assert len(pngs) >= 20
    page = layout_pages.figures_page(pngs, tmp_path)
    measured = layout_pages.measure(BROWSER, page, WINDOW, tmp_path)
    _assert_figures_readable(measured, page.read_text(encoding="utf-8"), "reports/reference")
    fusion_page = layout_pages.ROOT / "reports" / "reference" / "fusion-paper.html"
    measured = layout_pages.measure(BROWSER, fusion_page, WINDOW, tmp_path)
    _assert_figures_readable(measured, fusion_page.read_text(encoding="utf-8"), "fusion-paper.html")


@needs_browser
def test_a_table_too_wide_for_the_window_is_stacked_and_one_that_fits_is_not(real_pages, tmp_path):
    """The check page's per-sensor table is stacked at 1024 px (one block per sensor, each value
    beside its column's name) and is a table again at 1600 px; the page's tables are the same
    elements either way."""
    narrow = layout_pages.measure(BROWSER, real_pages["check"], WINDOW, tmp_path)["tables"]
    wide = layout_pages.measure(BROWSER, real_pages["check"], 1600, tmp_path)["tables"]
    assert "stacked" in narrow[0]["cls"] and "stacked" not in wide[0]["cls"]
    assert [t["caption"] for t in narrow] == [t["caption"] for t in wide]


def test_markdown_code_spans_render_as_html_code():
    html = to_html([Section("s", "A `title`", [Paragraph("System `tracker` and **bold** <b>raw</b>")])], "t")
    assert "<code>tracker</code>" in html and "<b>bold</b>" in html and "<code>title</code>" in html
    assert "&lt;b&gt;raw&lt;/b&gt;" in html  # text stays escaped
    body = html.split("<body>", 1)[-1]
    assert "`" not in re.sub(r"<style>.*?</style>", "", body, flags=re.S)


def test_chinese_names_are_marked_for_cjk_fonts_beside_their_transliteration(page):
    from gpfverify.contract.papers import PAPERS

    html = page.read_text(encoding="utf-8")
    meng = PAPERS["seed001"]
    assert "孟阳" in meng.citation and "Meng Yang" in meng.citation
    assert 'Meng Yang (<span lang="zh" class="cjk">孟阳</span>)' in html  # readable without a CJK font
    assert re.search(r"\.cjk\{font-family:\"gpfverify-cjk\",\"Noto Sans CJK SC\"", html)
    outside = re.sub(r'<span lang="zh" class="cjk">[^<]*</span>', "", html.split("<body>", 1)[-1])
    assert not re.search(r"[\u4e00-\u9fff]", re.sub(r"<style>.*?</style>", "", outside, flags=re.S))
    assert inline("“quoted”") == "“quoted”"  # English quotation marks stay as they are


def test_the_embedded_cjk_font_covers_every_cjk_character_of_the_sources():
    from fontTools.ttLib import TTFont

    font = TTFont(cjk_font.FONT)
    covered = {chr(code) for code in font.getBestCmap()}
    used = cjk_font.characters_used()
    assert "孟" in used and "檢" in used  # the scan finds the citations' and the quotations' characters
    missing = "".join(sorted(used - covered))
    assert not missing, (f"rebuild the subset (see gpfverify/report/cjk_font.py): {missing}")
    assert font["name"].getDebugName(1) == cjk_font.FAMILY  # renamed, as the font's licence asks
    assert "Open Font License" in (cjk_font.FONT.parent / "OFL.txt").read_text(encoding="utf-8")


def test_a_page_embeds_the_cjk_font_only_when_it_shows_cjk_text():
    with_cjk = to_html([Section("s", "S", [Paragraph("Meng Yang (孟阳)")])], "t")
    without = to_html([Section("s", "S", [Paragraph("Meng Yang")])], "t")
    face = '@font-face{font-family:"gpfverify-cjk"'
    assert face in with_cjk and face not in without
    data = re.search(r"data:font/woff;base64,([A-Za-z0-9+/=]+)", with_cjk).group(1)
    assert base64.b64decode(data) == cjk_font.FONT.read_bytes()


@needs_browser
def test_a_browser_loads_the_embedded_cjk_font_for_the_pages_chinese_text(page, tmp_path):
    """The page's face named gpfverify-cjk loads in the browser and every Chinese character on the
    page is among those the browser was asked to draw with it (no system CJK font needed)."""
    measured = tmp_path / "fonts.html"
    probe = ("<script>const text=[...document.querySelectorAll('.cjk')].map(e=>e.textContent).join('');"
             "document.fonts.load('16px \"gpfverify-cjk\"',text).then(faces=>{document.title="
             "'faces='+faces.filter(f=>f.family.replace(/\"/g,'')==='gpfverify-cjk'&&f.status==='loaded').length"
             "+' chars='+text.length;});</script>")
    measured.write_text(page.read_text(encoding="utf-8").replace("</body>", probe + "</body>"), encoding="utf-8")
    proc = subprocess.run([*BROWSER, "--headless", "--no-sandbox", "--disable-gpu", "--virtual-time-budget=5000",
                           "--dump-dom", measured.as_uri()], capture_output=True, text=True, timeout=120)
    found = re.search(r"<title>faces=(\d+) chars=(\d+)</title>", proc.stdout)
    assert found, proc.stderr[-2000:]
    assert int(found.group(2)) > 0 and int(found.group(1)) == 1
