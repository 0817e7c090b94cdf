"""The report page's summary table fits a 1024 px window: checked by the page's layout rules
(its CSS), and measured in a headless browser when /usr/bin/chromium is installed. Markdown
code spans render as HTML, never as raw backticks."""

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from gpfverify.commands.report import render_reproduced
from gpfverify.report.document import Paragraph, Section
from gpfverify.report.render import _STYLE, inline, to_html

HERE = Path(__file__).parent
WINDOW = 1024  # px
REM = 16  # px, the browsers' default root font size
CHROMIUM = Path("/usr/bin/chromium")


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


@pytest.mark.skipif(not CHROMIUM.exists(), reason="no headless browser at /usr/bin/chromium")
def test_the_summary_table_fits_a_1024_px_window_in_a_browser(page, tmp_path):
    measured = tmp_path / "measured.html"
    probe = ("<script>const t=document.querySelector('table.summary').getBoundingClientRect();"
             "document.title='right='+Math.ceil(t.right)+' width='+window.innerWidth</script>")
    measured.write_text(page.read_text(encoding="utf-8").replace("</body>", probe + "</body>"), encoding="utf-8")
    proc = subprocess.run([str(CHROMIUM), "--headless", "--no-sandbox", "--disable-gpu",
                           f"--window-size={WINDOW},768", "--dump-dom", measured.as_uri()],
                          capture_output=True, text=True, timeout=120)
    found = re.search(r"<title>right=(\d+) width=(\d+)</title>", proc.stdout)
    assert found, proc.stderr[-2000:]
    assert int(found.group(1)) <= int(found.group(2))
    subprocess.run([str(CHROMIUM), "--headless", "--no-sandbox", "--disable-gpu", f"--window-size={WINDOW},900",
                    f"--screenshot={tmp_path / 'summary.png'}", page.as_uri()], capture_output=True, timeout=120)
    assert (tmp_path / "summary.png").stat().st_size > 0


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
    assert re.search(r"\.cjk\{font-family:\"Noto Sans CJK SC\"", html)
    outside = re.sub(r'<span lang="zh" class="cjk">[^<]*</span>', "", html.split("<body>", 1)[-1])
    assert not re.search(r"[\u4e00-\u9fff]", re.sub(r"<style>.*?</style>", "", outside, flags=re.S))
    assert inline("“quoted”") == "“quoted”"  # English quotation marks stay as they are
