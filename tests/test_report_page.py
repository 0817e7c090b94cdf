"""The report page rendered from a stored tiny report folder (tests/fixtures/report: two sections
of toy experiments with claim records, and proof certificates; no experiment is run), read back
with the standard library's HTML parser; the command layer's progress lines; and the rule that
the report package imports nothing from gpfverify.experiments."""

from __future__ import annotations

import ast
import io
import json
import re
import shutil
import sys
import types
from pathlib import Path

import pytest

from gpfverify.contract import PAPERS, read_claims
from gpfverify.report.document import Section, claim_records_table, unicode_math
from gpfverify.report.inputs import SectionInput, load_section
from gpfverify.symbolic.claims import run_claim

HERE = Path(__file__).parent
FIXTURE = HERE / "fixtures" / "report"
ROOT = HERE.parent
sys.path.insert(0, str(HERE))  # the suite imports in importlib mode: the helper beside it
from html_dom import parse  # noqa: E402


# ---- the fixture report, rendered ------------------------------------------------------------------

def _toy_section(title: str):
    def render_section(data: SectionInput) -> Section:
        section = Section(data.slug, title)
        for entry, results in zip(data.runs.entries, data.results):
            section.add(claim_records_table(read_claims(results), f"Claims ({entry.setting or 'one setting'})"))
        return section
    return render_section


@pytest.fixture
def report(monkeypatch, tmp_path):
    """The fixture folder rendered by the real build_report with two toy sections and the real
    proofs page; returns (folder, parsed HTML page, every claim record of the fixture)."""
    import gpfverify.full_report as report

    shutil.copytree(FIXTURE, tmp_path / "r")
    out = tmp_path / "r"
    sections = {}
    for slug, title in (("alpha", "Toy fusion"), ("beta", "Toy detection")):
        module = types.ModuleType(f"toy_section_{slug}")
        module.render_section = _toy_section(title)  # type: ignore[attr-defined]
        monkeypatch.setitem(sys.modules, module.__name__, module)
        sections[slug] = module.__name__
    sections["proofs"] = "gpfverify.report.proofs"
    monkeypatch.setattr(report, "SECTIONS", sections)
    lines: list[str] = []
    html_path = report.build_report(out, progress=lines.append)
    assert lines[-1].startswith("writing the report pages")
    records = [c for slug in ("alpha", "beta") for r in load_section(out, slug).results for c in read_claims(r)]
    return out, parse(html_path.read_text(encoding="utf-8")), records


def test_the_fixture_has_what_the_page_must_show():
    records = [c for slug in ("alpha", "beta") for r in load_section(FIXTURE, slug).results for c in read_claims(r)]
    assert {c.verdict for c in records} == {"held", "NOT held", "undecided", "not decidable"}
    assert any(c.paper_n and c.n < c.paper_n for c in records) and any(c.timing for c in records)
    assert any(c.paper_n and c.n < c.paper_n and c.timing for c in records)  # two reasons, one caution
    assert any(c.paper_n and c.n >= c.paper_n and not c.timing for c in records)  # enough runs: none


def test_title_and_sticky_table_of_contents(report):
    _, page, _ = report
    (title,) = page.find_all("title")
    (h1,) = page.find_all("h1")
    assert title.text == h1.text and "Verification report" in h1.text
    (nav,) = page.find_all("nav", cls="toc")
    style = "".join(s.text for s in page.find_all("style"))
    assert "nav.toc{position:sticky;top:0" in style.replace("\n", "")
    targets = [a.attrs["href"] for a in nav.find_all("a")]
    assert targets == ["#summary", "#what-was-run", "#alpha", "#beta", "#proofs", "#references", "#provenance"]
    for target in targets:  # every entry leads somewhere on the page
        assert page.find_all(id=target[1:])
    # one file, works offline: no script or style sheet loaded from elsewhere (the one inline script
    # stacks a table too wide for the window)
    assert not [s for s in page.find_all("script") if "src" in s.attrs] and not page.find_all("link")


def test_summary_table_counts_every_verdict_per_section_and_group(report):
    out, page, records = report
    (table,) = page.find_all("table", cls="summary")
    headers = [th.text for th in table.find_all("th")]
    kinds = ["held", "NOT held", "undecided", "not decidable", "proved", "refuted", "checked"]
    assert headers[2] == "group" and headers[3:10] == kinds
    body = table.find_all("tbody")[0].find_all("tr")
    cells = [[td.text for td in row.find_all("td")] for row in body]
    # a section's name on its first row only; one row per group it has, accuracy first, then the theorem, timing
    sections, section = [], ""
    for row in cells:
        section = row[1] or section
        sections.append((section, row[2]))
    assert sections == [("Toy fusion", "accuracy"), ("Toy fusion", "Proposition 1"), ("Toy fusion", "timing"),
                        ("Toy detection", "accuracy"), ("Kernel-checked proofs and a second implementation", "proofs"),
                        ("every section", "accuracy"), ("every section", "Proposition 1"),
                        ("every section", "timing"), ("every section", "proofs")]
    assert [row[0] for row in cells[:5]] == ["Liao et al. 2019", "", "", "Chen et al. 2015",
                                             "the toolkit's own algebra"]

    def counted(group: str, prefix: str | None) -> list[int]:
        """The counts of one group, computed here from the records (independently of the page)."""
        mine = [c for c in records if prefix is None or c.id.startswith(prefix)]
        mine = [c for c in mine if ("timing" if c.timing else c.theorem or "accuracy") == group]
        return [sum(c.verdict == k for c in mine) for k in kinds[:4]] + [0, 0, 0]

    for (section, group), row in zip(sections, cells):
        counts = [int(v) for v in row[3:10]]
        if group == "proofs":
            assert counts == [0, 0, 0, 0, 1, 1, 1]
        else:
            prefix = {"Toy fusion": "toy-a", "Toy detection": "toy-b", "every section": None}[section]
            assert counts == counted(group, prefix), (section, group)
    # the groups add up to every verdict: none is counted twice or lost
    totals = [[int(v) for v in row[3:7]] for (section, _), row in zip(sections, cells) if section == "every section"]
    assert [sum(col) for col in zip(*totals)] == [sum(c.verdict == k for c in records) for k in kinds[:4]]
    # colour: a non-zero count carries its verdict's class, a zero none
    held_cell = body[0].find_all("td")[3]
    assert "v-held" in held_cell.classes
    assert "zero" in body[0].find_all("td")[7].classes
    # each section's first row links to it
    links = [a.attrs["href"] for a in table.find_all("a") if "chip" not in a.classes]
    assert links == ["#alpha", "#beta", "#proofs"]
    # one mark per verdict and certificate, linking to an existing row
    chips = table.find_all("a", cls="chip")
    assert len(chips) == len(records) + 3
    for chip in chips:
        (row,) = page.find_all("tr", id=chip.attrs["href"][1:])
    # the totals above the table and verdicts.json render the same record, group by group
    (totals_div,) = page.find_all("div", cls="totals")
    lines = [line.text for line in totals_div.find_all("div", cls="group-line")]
    saved = json.loads((out / "verdicts.json").read_text(encoding="utf-8"))
    assert [g["group"] for g in saved["groups"]] == ["accuracy", "Proposition 1", "timing"]
    for g in saved["groups"]:
        assert g["counts"] == dict(zip(kinds[:4], counted(g["group"], None)))
        line = next(text for text in lines if text.startswith(g["group"]))
        assert all(f"{n} {v}" in line for v, n in g["counts"].items())
    assert saved["proofs"] == {"proved": 1, "refuted": 1, "checked": 1}
    assert set(saved["sections"]) == {"alpha", "beta", "proofs"}
    index = (out / "README.md").read_text(encoding="utf-8")
    expected = "; ".join(f"{g}: " + ", ".join(f"{n} {k}" for n, k in zip(counted(g, None), kinds[:4]))
                         for g in ("accuracy", "Proposition 1", "timing"))
    assert expected + "; proofs: 1 proved, 1 refuted, 1 checked" in index


def test_one_caution_per_low_count_or_timing_verdict(report):
    _, page, records = report
    cautioned = [c for c in records if c.cautions]
    assert 0 < len(cautioned) < len(records)
    # in the section tables: exactly one caution mark in each cautioned verdict's cell, none elsewhere
    marks = page.find_all(cls="caution")
    assert len(marks) == len(cautioned)
    from gpfverify.report.document import claim_anchor

    for record in records:
        (row,) = page.find_all("tr", id=claim_anchor(record))
        (verdict,) = row.find_all("td", cls="verdict")
        assert verdict.find_all("span", cls="verdict-text")[0].text == record.verdict
        found = verdict.find_all(cls="caution")
        assert len(found) == (1 if record.cautions else 0)
        if record.paper_n is not None and record.n < record.paper_n:
            assert f"the paper used {record.paper_n}" in found[0].text
        if record.timing:
            assert "CPU times" in found[0].text
    # in the summary: one marked chip per cautioned verdict, and the count
    (table,) = page.find_all("table", cls="summary")
    assert len(table.find_all("a", cls="cautioned")) == len(cautioned)
    assert f"{len(cautioned)} with a caution" in page.find_all("div", cls="totals")[0].text


def test_verdict_cells_are_coloured(report):
    _, page, records = report
    colour = {"held": "v-held", "NOT held": "v-not-held", "undecided": "v-undecided",
              "not decidable": "v-not-decidable"}
    cells = [td for td in page.find_all("td", cls="verdict") if td.ancestor("table").attrs.get("class") == "claims"]
    assert len(cells) == len(records)
    for td in cells:
        verdict = td.find_all("span", cls="verdict-text")[0].text
        assert colour[verdict] in td.classes
    style = "".join(s.text for s in page.find_all("style"))
    assert ".v-held{background:var(--held)" in style and "--held:#d7f0dc" in style


def test_what_was_run_and_provenance(report):
    _, page, _ = report
    run_tables = page.find_all("table", cls="runs")
    assert len(run_tables) == 2  # alpha and beta open with what was run; proofs with a sentence
    rows = run_tables[0].find_all("tbody")[0].find_all("tr")
    cells = [[td.text for td in row.find_all("td")] for row in rows]
    assert [c[:2] for c in cells] == [["toy-a", "κ = 300"], ["toy-a", "κ = 30"]]
    assert cells[0][2] == "5 ⚠ fewer than the paper" and cells[0][3] == "100"  # 5 runs, paper 100
    assert cells[1][2].startswith("4 of 5")  # one run failed
    assert cells[0][4] == "1" and cells[0][5] == "1.50 / 1.20 / 1.00 on 2 CPUs"
    assert "busy: timings unreliable" in cells[1][5]  # load 3.1 on 2 CPUs
    assert cells[0][6].startswith("0123456789ab")
    (what,) = page.find_all("section", id="what-was-run")
    assert "Profile quick" in what.text and "root seed 1" in what.text and "3 settings" in what.text
    (prov,) = page.find_all("section", id="provenance")
    assert "What produced this page" in prov.text and "git commit" in prov.text


def test_papers_are_cited_in_full(report):
    _, page, _ = report
    (refs,) = page.find_all("section", id="references")
    items = refs.find_all("li")
    assert [li.attrs["id"] for li in items] == [f"ref-{k}" for k in PAPERS]
    for li, paper in zip(items, PAPERS.values()):
        assert paper.citation in li.text and paper.authors in li.text
    (alpha,) = page.find_all("section", id="alpha")
    assert "Liao et al. 2019" in alpha.find_all("h2")[0].text
    assert PAPERS["seed000"].title_en in alpha.text


def test_proof_certificates_are_a_table(report):
    _, page, _ = report
    (table,) = page.find_all("table", cls="certificates")
    assert [th.text for th in table.find_all("th")] == ["claim", "status", "title", "statement", "scope", "method",
                                                        "negative controls", "seconds"]
    rows = {tr.attrs["id"]: [td.text for td in tr.find_all("td")] for tr in table.find_all("tbody")[0].find_all("tr")}
    proved = rows["cert-full-rank-needs-l-le-D"]
    title = unicode_math(run_claim("full-rank-needs-l-le-D", "small").title)
    assert proved[:3] == ["full-rank-needs-l-le-D", "proved", title]
    assert proved[3].startswith("l ≤ D (for all sizes D, l ≥ 0; all A ∈ ℝ^(D×l)) — assuming: A has full column rank")
    assert proved[4] == "any dimension" and proved[5].startswith("kernel-checked certificate")
    assert proved[6].startswith("all 3 refused and refuted: l_m + 1 ≤ D")
    assert rows["cert-dmf-exact-without-condition"][4].startswith("counterexample at D = 2")
    assert rows["cert-dmf-exact-without-condition"][6] == "none"
    status = table.find_all("tr", id="cert-dmf-exact-without-condition")[0].find_all("td")[1]
    assert "v-refuted" in status.classes and "v-not-held" not in status.classes
    # the record says the statement is meant to be refuted: the page says so, in the table and on its mark
    assert status.text == "refuted, as intended" and status.attrs["title"].startswith("meant to be refuted")
    (chip,) = [a for a in page.find_all("a", cls="chip") if a.attrs["href"] == "#cert-dmf-exact-without-condition"]
    assert chip.attrs["title"] == "dmf-exact-without-condition: refuted, as intended"
    assert rows["cert-full-rank-needs-l-le-D"][1] == "proved"  # no record meant to be proved says more


def test_a_statement_that_misses_the_status_it_is_meant_to_get_is_a_failure():
    """A record meant to be refuted that the kernel proves (or one whose "expected" was edited) is
    shown FAILED in red, is a problem for prove --check, and makes prove exit non-zero."""
    from gpfverify.kernel.verdict import check_record
    from gpfverify.report.proofs import render
    from gpfverify.report.render import to_markdown

    record = json.loads((FIXTURE / "proofs" / "certificates.json").read_text(encoding="utf-8"))[1]
    assert record["claim"] == "dmf-exact-without-condition" and record["expected"] == "refuted"
    assert check_record(record) == []
    edited = {**record, "expected": "proved"}
    assert check_record(edited) == ["dmf-exact-without-condition: meant to be 'proved', the kernel derives 'refuted'"]
    page = to_markdown(render([edited]), FIXTURE)
    assert "| checked (meant to be proved) — FAILED |" in page  # what the kernel rejects is shown as checked
    certificate = run_claim("dmf-exact-without-condition", "small")
    assert certificate.failures == []
    certificate.record["expected"] = "proved"
    assert certificate.failures == ["meant to be proved, the kernel derives refuted"]


def test_markdown_pages_and_index(report):
    out, _, records = report
    index = (out / "README.md").read_text(encoding="utf-8")
    held = sum(c.verdict == "held" for c in records)
    assert f"{held} held" in index and "1 proved, 1 refuted, 1 checked" in index
    assert "[Toy fusion — Liao et al. 2019](alpha/README.md)" in index  # the section list
    assert "[Toy fusion](alpha/README.md)" in index  # the summary table
    assert PAPERS["seed001"].citation in index
    page = (out / "alpha" / "README.md").read_text(encoding="utf-8")
    assert "| NOT held |" in page and "held ⚠ rests on 5 runs; the paper used 100" in page
    assert "DMF equals CMF (xₖ₊₁ = F xₖ)" in page  # pseudo-LaTeX in a claim rendered as Unicode
    assert "About 40 runs would decide it" in page  # the undecided claim's runs_to_decide


def test_only_keeps_the_summary_of_sections_not_rebuilt(report, monkeypatch):
    import gpfverify.full_report as report_package

    out, page, records = report
    html_path = report_package.build_report(out, only=["beta"], progress=lambda _: None)
    again = parse(html_path.read_text(encoding="utf-8"))
    (table,) = again.find_all("table", cls="summary")
    assert len(table.find_all("a", cls="chip")) == len(records) + 3
    from gpfverify.report.render import read_summaries

    assert [s.slug for s in read_summaries(out, ["alpha", "beta", "proofs", "nowhere"])] == ["alpha", "beta", "proofs"]
    # a summary this version cannot read (written by another version): the page is kept, uncounted
    meta = json.loads((out / "alpha" / "section.json").read_text())
    meta["summary"]["claims"][0]["from_the_future"] = 1
    (out / "alpha" / "section.json").write_text(json.dumps(meta))
    assert [s.slug for s in read_summaries(out, ["alpha", "beta", "proofs"])] == ["beta", "proofs"]
    page = parse(report_package.build_report(out, only=["beta"], progress=lambda _: None).read_text())
    assert page.find_all("section", id="alpha") and len(page.find_all("a", cls="chip")) == 2 + 3


def test_unicode_math():
    assert unicode_math(r"x_{k+1} = F x_k, C^{-1}, A^T, \sigma^2 \le \Sigma_{ij}") == \
        "xₖ₊₁ = F x_k, C⁻¹, Aᵀ, σ² ≤ Σᵢⱼ"
    assert unicode_math("results_json and run_for_report") == "results_json and run_for_report"
    assert unicode_math(r"C_{xy} \in \mathbb{R}^{n}") == "C_(xy) ∈ ℝⁿ"
    assert unicode_math("(C_y^m)^{-1} and 10^20") == "(C_yᵐ)⁻¹ and 10^20"


# ---- the command layer -------------------------------------------------------------------------------

def test_progress_lines_and_heartbeat():
    now = [0.0]
    stream = io.StringIO()
    progress = __import__("gpfverify.commands.report", fromlist=["Progress"]).Progress(
        stream, heartbeat=20.0, clock=lambda: now[0])
    progress("ct2d: ct2d κ = 300 (1 of 4): 2 runs")
    now[0] = 15.0
    progress.beat()  # 15 s of silence: nothing yet
    now[0] = 75.5
    progress.beat()
    lines = stream.getvalue().splitlines()
    assert lines == ["[report  0:00] ct2d: ct2d κ = 300 (1 of 4): 2 runs",
                     "[report  1:15] ... still working (76 s since the last line: ct2d: ct2d κ = 300 (1 of 4): 2 runs)"]


def test_the_time_left_comes_from_the_pace_measured_in_this_build_and_none_before():
    """No estimate until two runs of an experiment were saved in one batch (the first run carries the
    workers' start-up: a quick build once opened with "about 48 min left" for 4 min of work); then
    the seconds between runs saved times the experiment's runs still to make — in every setting, the
    pace of the first setting timing the second —; reused runs are runs not left."""
    from gpfverify.commands.report import Eta

    now = [100.0]
    eta = Eta({"a-1": ("a", 4), "a-2": ("a", 6), "b-1": ("b", 5)}, clock=lambda: now[0])
    eta.batch("a")
    now[0] += 40.0  # start-up and the first run
    eta.ran("a-1")
    assert eta.seconds_left("a") is None and eta.suffix("a-1") == ""  # one run saved: nothing timed yet
    now[0] += 3.0
    eta.ran("a-1")  # 3 s a run; 2 + 6 runs of a left
    assert eta.seconds_left("a") == 8 * 3.0 and eta.suffix("a-1") == " (a: about 24 s of runs left)"
    assert eta.seconds_left("b") is None  # b's pace is not a's
    now[0] += 5.0
    eta.ran("a-1")  # (3 + 5) / 2 = 4 s a run
    eta.finished("a-1")  # its last run reused from an earlier build
    assert eta.seconds_left("a") == 6 * 4.0
    eta.batch("a")  # the next setting: its first run (start-up again) is not timed
    now[0] += 60.0
    eta.ran("a-2")
    assert eta.seconds_left("a") == 5 * 4.0


def test_report_command_runs_a_toy_section_with_progress(monkeypatch, tmp_path, capsys):
    """The command runs a (typed) toy experiment at its quick profile into the section folder,
    prints one line per event, renders the page and ends with where it is and the counts."""
    import gpfverify.commands.report as command
    import gpfverify.full_report as report
    from gpfverify.papers import EXPERIMENTS

    monkeypatch.syspath_prepend(str(FIXTURE))
    import toy_typed_experiment as toy
    monkeypatch.setitem(EXPERIMENTS, "toy-typed", toy.__name__)
    module = types.ModuleType("toy_typed_section")
    module.render_section = _toy_section("Toy typed")  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, module.__name__, module)
    monkeypatch.setattr(report, "SECTIONS", {"toy": module.__name__})
    monkeypatch.setattr(command, "SECTIONS", {"toy": module.__name__})
    monkeypatch.setattr(command, "SECTION_EXPERIMENTS", {"toy": ("toy-typed",)})
    from gpfverify import cli

    assert cli.main(["report", "--out", str(tmp_path), "--seed", "2"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert lines[0].startswith("[report  0:00] building the quick report in")
    assert any("toy/toy-typed, small (setting 1 of 2): 3 runs" in line for line in lines)
    assert any("toy/toy-typed, large (setting 2 of 2): run 3 of 3 saved" in line for line in lines)
    assert any("toy: rendering the page" in line for line in lines)
    # a setting's first run line has no estimate (nothing timed yet); the lines after it have the measured one
    saved = [line for line in lines if " saved" in line]
    assert saved[0].endswith("run 1 of 3 saved")
    assert all(re.search(r"\(toy-typed: about \d+ s of runs left\)$", line) for line in saved[1:3])
    assert not re.search(r"left in all|section \d of \d: .*\(", out)  # no estimate of the whole build
    assert f"The report: {tmp_path / 'report.html'}" in out
    records = [c for r in load_section(tmp_path, "toy").results for c in read_claims(r)]
    held = sum(c.verdict == "held" for c in records)
    assert all(c.group == "accuracy" for c in records)
    assert f"Verdicts:   accuracy: {held} held, {len(records) - held} NOT held, 0 undecided, 0 not decidable; " \
           "proofs: 0 proved, 0 refuted, 0 checked" in out
    assert (tmp_path / "toy" / "toy-typed-small" / "run" / "results.json").is_file()
    # the profile's interpretations: "strict" reads the setting's runs, "shifted" runs its own
    interpretations = tmp_path / "toy" / "toy-typed-small" / "run" / "interpretations"
    assert not (interpretations / "strict" / "runs").exists() and (interpretations / "shifted" / "runs").is_dir()
    for record in records:
        assert [(i.name, i.n) for i in record.interpretations] == [("strict", 3), ("shifted", 3)]
        assert next(i for i in record.interpretations if i.name == "strict").verdict == "NOT held"
    # a second build reuses the saved runs and says so
    assert cli.main(["report", "--out", str(tmp_path), "--seed", "2"]) == 0
    again = capsys.readouterr().out
    assert "toy/toy-typed, small (setting 1 of 2): every run saved by an earlier build" in again
    assert "saved\n" not in again


# ---- the report package only reads and renders --------------------------------------------------------

def test_the_report_package_imports_nothing_from_the_experiments():
    offenders = []
    for path in sorted((ROOT / "gpfverify" / "report").rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module] if node.level == 0 else []
                if node.module == "gpfverify":
                    names += [f"gpfverify.{a.name}" for a in node.names]
            offenders += [f"{path.relative_to(ROOT)}:{node.lineno} imports {n}" for n in names
                          if n == "gpfverify.experiments" or n.startswith("gpfverify.experiments.")]
    assert not offenders, "\n".join(offenders)


def test_summary_says_which_verdicts_survive_every_interpretation():
    from gpfverify.contract import ClaimRecord, Interpretation
    from gpfverify.report.inputs import SectionSummary
    from gpfverify.report.render import summary_table

    def claim(name: str, verdict: str, *others: str) -> ClaimRecord:
        return ClaimRecord(name, "s", verdict, 1.0, 0.0, 10, "e", id=f"x/{name}", paper="seed000",
                           interpretations=tuple(Interpretation(f"i{k}", {}, v, 1.0) for k, v in enumerate(others)))

    claims = (claim("robust", "NOT held", "NOT held", "NOT held"), claim("fragile", "NOT held", "held"),
              claim("untried", "held"))
    table = summary_table([SectionSummary("x", "X", "quick", 1, ("seed000",), claims)])
    column = table.headers.index("same verdict under every interpretation tried")
    assert [row[column].value for row in table.rows] == ["1 of 2", "1 of 2"]
    tips = [chip[1] for chip in table.rows[0][-1].chips]
    assert "NOT held under all 3 interpretations tried" in tips[0]
    assert "depends on the interpretation" in tips[1] and "interpretation" not in tips[2]


def test_a_one_experiment_section_without_its_run_says_so(tmp_path):
    from gpfverify.contract import SectionRuns
    from gpfverify.report.document import Paragraph
    from gpfverify.report.inputs import SectionInput
    from gpfverify.papers.gpadf_scalar import section as gpadf_scalar
    from gpfverify.papers.tbd import section as tbd

    empty = SectionInput("tbd", tmp_path, SectionRuns("tbd", "quick", 1, ()), ())
    for module, name in ((tbd, "tbd"), (gpadf_scalar, "gpadf-scalar")):
        page = module.render_section(empty)
        assert [b.text for b in page.blocks if isinstance(b, Paragraph)] == [
            f"No {name} run was found in this report folder."]
