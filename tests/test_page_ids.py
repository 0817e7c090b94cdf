"""Every page gpfverify writes, and every committed HTML page, has each id once, and every link inside
a page lands on an element that exists; a summary mark lands on the row of its own claim and setting
(ct2d shows the same claims at κ = 30 and κ = 300 on one page: their rows once shared ids, so a
κ = 30 mark jumped to the κ = 300 row). Notebook outputs, many of which share one document, carry
no ids at all."""

from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))  # the suite imports in importlib mode: the helpers beside it
import layout_pages  # noqa: E402
from html_dom import Node, parse  # noqa: E402

pytestmark = pytest.mark.slow  # renders every kind of page (the report of every section, a check, an audit)


def _ids(page: Node) -> Counter:
    return Counter(node.attrs["id"] for node in page.iter() if "id" in node.attrs)


def _assert_ids_unique_and_links_land(page: Node, where: str) -> None:
    ids = _ids(page)
    assert ids, f"{where}: no ids at all (not a page?)"
    repeated = {i: n for i, n in ids.items() if n > 1}
    assert not repeated, f"{where}: ids used more than once: {repeated}"
    targets = [a.attrs["href"][1:] for a in page.find_all("a") if a.attrs.get("href", "").startswith("#")]
    assert targets, f"{where}: no links inside the page"
    dangling = sorted({t for t in targets if t not in ids})
    assert not dangling, f"{where}: links to no element: {dangling}"


@pytest.fixture(scope="module")
def pages(tmp_path_factory) -> dict[str, Path]:
    """The report of every section (stored results of the quick report's settings; ct2d with two
    settings), a check page, an audit page and a page of one reproduce folder."""
    from gpfverify.commands.report import render_reproduced

    folder = tmp_path_factory.mktemp("pages")
    (folder / "report").mkdir()
    reproduced = folder / "ct2d"
    reproduced.mkdir()
    (reproduced / "results.json").write_bytes((HERE / "fixtures" / "ct2d" / "k12-w0.0698.json").read_bytes())
    return {"report": layout_pages.report_page(folder / "report"), "check": layout_pages.check_page(folder / "check"),
            "audit": layout_pages.audit_page(folder / "audit"),
            "reproduce": render_reproduced(reproduced, folder / "ct2d-page")}


@pytest.mark.parametrize("kind", ["report", "check", "audit", "reproduce"])
def test_every_id_of_a_written_page_is_unique_and_every_link_lands(pages, kind):
    _assert_ids_unique_and_links_land(parse(pages[kind].read_text(encoding="utf-8")), kind)


def test_every_committed_page_has_unique_ids_and_links_that_land():
    committed = sorted((ROOT / "reports").rglob("*.html"))
    assert committed, "no committed page found under reports/"
    for path in committed:
        _assert_ids_unique_and_links_land(parse(path.read_text(encoding="utf-8")), str(path.relative_to(ROOT)))


def _chips_and_rows(page: Node) -> list[tuple[str, str]]:
    """(the mark's tooltip, the text of the first cell of the row it links to) for every summary mark
    that links to a claim's row."""
    rows = {node.attrs["id"]: node for node in page.find_all("tr") if "id" in node.attrs}
    out = []
    for chip in page.find_all("a", cls="chip"):
        row = rows.get(chip.attrs["href"][1:])
        if row is not None and chip.attrs["href"].startswith("#claim-"):
            out.append((chip.attrs["title"], row.find_all("td")[0].text))
    return out


def test_each_summary_mark_lands_on_the_row_of_its_own_claim_and_setting(pages):
    """A mark's tooltip is "<claim> (<setting>): <verdict>"; the row it links to shows
    "<claim> (<setting>)" — for the two ct2d settings of the page alike."""
    page = parse(pages["report"].read_text(encoding="utf-8"))
    pairs = _chips_and_rows(page)
    assert len(pairs) >= 20
    for title, row in pairs:
        assert title.startswith(row + ":"), (title, row)
    ct2d_settings = {row.rsplit(" (", 1)[-1] for _, row in pairs if "Ω" in row}
    assert len(ct2d_settings) == 2, ct2d_settings  # both settings' marks, each on its own rows


def test_notebook_outputs_carry_no_ids():
    """Two records shown in one notebook would repeat every id of the page they render: a notebook
    fragment has none (and so no in-page links)."""
    from gpfverify.model_fusion import run_fusion
    from gpfverify.systems import load_system

    model = load_system(f"{ROOT / 'examples' / 'three_sensor_system.py'}:tracker")
    _, ys = model.simulate(4, np.random.default_rng(0))
    fused = run_fusion(model, ys, family="ukf", methods=("cmf", "dmf"))
    fragment = parse(fused._repr_html_())
    assert fragment.find_all("section") and not _ids(fragment)
    assert not [a for a in fragment.find_all("a") if a.attrs.get("href", "").startswith("#")]
