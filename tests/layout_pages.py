"""Real pages for the layout tests, made by the real code from stored results (nothing run):
the report of every section from tests/fixtures (the quick report's pages, with the fixtures'
smaller numbers), a check page and a run-audit page; and a headless browser that measures every
table of a page at a given window width."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path

FIXTURES = Path(__file__).parent / "fixtures"
ROOT = Path(__file__).parent.parent
#: each report section's stored runs: (experiment, fixture results.json relative to tests/fixtures)
SECTION_FIXTURES: dict[str, tuple[tuple[str, str], ...]] = {
    "moments": (("moments", "moments/results.json"),),
    "gpadf-scalar": (("gpadf-scalar", "gpadf_scalar/results.json"),),
    "ungm1d": (("ungm1d", "ungm1d/results.json"),),
    "ct2d": (("ct2d", "ct2d/k12-w0.0698.json"), ("ct2d", "ct2d/forced-rank-failure.json")),
    "tbd": (("tbd", "tbd/tbd-small/results.json"),),
    "particle-flow": (("pff1d", "pff1d/results.json"), ("bearing", "bearing/results.json")),
    "sins-gps": (("sins-gps", "sins_gps/sins-gps-small/results.json"),),
}
#: the browsers looked for on PATH, in this order (Debian: apt-get install -y chromium)
BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def report_page(folder: Path) -> Path:
    """``gpfverify report``'s page, rendered by :func:`gpfverify.full_report.build_report` from the
    stored results of every section and the stored proof certificates."""
    from gpfverify.contract.experiment import RunEntry, SectionRuns
    from gpfverify.full_report import build_report
    from gpfverify.report.inputs import write_runs

    for slug, stored in SECTION_FIXTURES.items():
        entries = []
        for index, (experiment, source) in enumerate(stored):
            target = folder / slug / f"{experiment}-{index}" / "results.json"
            target.parent.mkdir(parents=True)
            shutil.copy(FIXTURES / source, target)
            results = json.loads(target.read_text(encoding="utf-8"))
            entries.append(RunEntry(experiment, results.get("setting", "") or f"stored {index}", f"s{index}",
                                    f"{experiment}-{index}/results.json"))
        write_runs(folder, SectionRuns(slug, "quick", 1, tuple(entries)))
    shutil.copytree(FIXTURES / "report" / "proofs", folder / "proofs")
    return build_report(folder, progress=lambda text: None)


def check_page(folder: Path) -> Path:
    """``gpfverify check``'s page of the three-sensor example (simulated, a few steps)."""
    from gpfverify.cli import main

    assert main(["check", f"{ROOT / 'examples' / 'three_sensor_system.py'}:tracker", "--steps", "12",
                 "--out", str(folder)]) == 0
    return folder / "report.html"


def audit_page(folder: Path) -> Path:
    """``gpfverify audit``'s page of the example run file."""
    from gpfverify.cli import main

    assert main(["audit", str(ROOT / "examples" / "tracker-run.jsonl"), "--out", str(folder)]) == 0
    return folder / "report.html"


def browser() -> list[str] | None:
    """The command of a headless browser: a Chromium on PATH, or playwright's when installed."""
    for name in BROWSERS:
        found = shutil.which(name)
        if found:
            return [found]
    try:
        from playwright.sync_api import sync_playwright  # type: ignore[import-not-found]
    except ImportError:
        return None
    with sync_playwright() as p:
        path = p.chromium.executable_path
    return [path] if path and os.path.exists(path) else None


#: measures every table: its right edge against the main column's, its scroll overflow, and each
#: cell's width and whether its text overflows it; and every image: its width as shown and its own
#: (natural) width, in document order; the result as JSON in the page title
PROBE = """<script>addEventListener('load',()=>{
const main=document.querySelector('main')||document.body, mr=main.getBoundingClientRect(),
  pad=parseFloat(getComputedStyle(main).paddingRight)||0;
const tables=[...document.querySelectorAll('table')].map((t,i)=>{
  const r=t.getBoundingClientRect(), wrap=t.parentElement;
  const cells=[...t.querySelectorAll('td')].map(c=>({w:Math.round(c.getBoundingClientRect().width),
    over:c.scrollWidth>c.clientWidth+1, chars:c.textContent.trim().length, text:c.textContent.trim().slice(0,50),
    longest:Math.max(0,...c.textContent.split(/\\s+/).map(s=>s.length)),
    shown:getComputedStyle(c).display!=='none'&&getComputedStyle(c).visibility!=='hidden'}));
  return {i, cls:t.className, caption:(t.caption?t.caption.textContent:'').slice(0,60),
    right:Math.ceil(r.right), limit:Math.floor(mr.right-pad), width:Math.round(r.width),
    scroll:wrap.scrollWidth>wrap.clientWidth+1, cells};});
const images=[...document.querySelectorAll('img')].map((m,i)=>({i, natural:m.naturalWidth,
  shown:m.getBoundingClientRect().width}));
document.title='MEASURED'+JSON.stringify({window:window.innerWidth, tables, images});});
</script>"""


def measure(command: list[str], page: Path, width: int, work: Path) -> dict:
    """Every table and image of ``page`` measured in the headless browser at ``width`` px (:data:`PROBE`)."""
    probe = work / f"measured-{page.parent.name}.html"
    probe.write_text(page.read_text(encoding="utf-8").replace("</body>", PROBE + "</body>"), encoding="utf-8")
    proc = subprocess.run([*command, "--headless", "--no-sandbox", "--disable-gpu", f"--window-size={width},900",
                           "--dump-dom", probe.as_uri()], capture_output=True, text=True, timeout=180)
    found = re.search(r"<title>MEASURED(.*?)</title>", proc.stdout, re.S)
    assert found, proc.stderr[-2000:]
    import html

    return json.loads(html.unescape(found.group(1)))


def figures_shown(html_text: str) -> list[dict]:
    """What :func:`gpfverify.report.figures.save` recorded in each PNG a page embeds, in document order."""
    import base64

    from gpfverify.report.figures import measured

    return [measured(base64.b64decode(data)) for data in re.findall(r'<img [^>]*src="data:image/png;base64,([^"]+)"',
                                                                    html_text)]


def figures_page(pngs: list[Path], folder: Path) -> Path:
    """A page in the report's layout showing ``pngs`` as the report shows its figures."""
    from gpfverify.report.document import Figure, Section
    from gpfverify.report.render import to_html

    section = Section("figures", "Figures", [Figure(png, str(png.relative_to(ROOT))) for png in pngs])
    page = folder / "figures.html"
    page.write_text(to_html([section], "Figures"), encoding="utf-8")
    return page
