"""Render :class:`~gpfverify.report.document.Section` pages to Markdown files and one
self-contained HTML page (figures embedded as base64 PNG, styles inline, no script, no network).

The report page (:func:`write_report`) has a title, a summary of every verdict per paper (counts
in colour and one mark per verdict, linking to its row), what was run (profile, seed, runs,
machine load), the sections — each opening with its paper and a standard "what was run" table
made from its files — the papers cited in full, and the provenance; a table of contents stays in
view while scrolling (CSS ``position: sticky``)."""

from __future__ import annotations

import base64
import html
import json
import os
import re
from collections.abc import Iterable
from pathlib import Path

from gpfverify.contract.claims import ACCURACY, TIMING, VERDICTS
from gpfverify.contract.interpretations import is_robust, robustness
from gpfverify.contract.papers import PAPERS
from gpfverify.report import cjk_font
from gpfverify.report.document import (CAUTION_MARK, VERDICT_CLASSES, Cell, Chips, Code, Details, Figure, Link,
                                       Paragraph, Section, Table, VerdictCell, anchor_id, claim_anchor, fmt,
                                       unicode_math)
from gpfverify.report.inputs import STATUSES, RunInfo, SectionSummary, VerdictCounts

esc = html.escape
_CODE_SPAN = re.compile(r"`([^`\n]+)`")
_BOLD_SPAN = re.compile(r"\*\*([^*\n]+)\*\*")
#: runs of CJK characters (with the punctuation between them)
_CJK_RUN = re.compile(r"[\u3000-\u303f\u3400-\u4dbf\u4e00-\u9fff\uf900-\ufaff\uff00-\uffef“”]+")
_CJK_IDEOGRAPH = re.compile(r"[\u3400-\u4dbf\u4e00-\u9fff\uf900-\ufaff]")


def inline(text: str) -> str:
    """Markdown text as HTML: escaped, with its `code` and **bold** spans rendered (the Markdown
    pages and the HTML page show the same text, neither with raw backticks), and runs of Chinese
    characters marked ``lang="zh"`` with the embedded CJK font named first
    (:mod:`gpfverify.report.cjk_font`; a page with such characters carries it), then the usual
    system CJK fonts; the papers' citations also give the transliteration beside them."""
    html_text = _BOLD_SPAN.sub(r"<b>\1</b>", _CODE_SPAN.sub(r"<code>\1</code>", esc(text)))
    return _CJK_RUN.sub(lambda m: f'<span lang="zh" class="cjk">{m.group(0)}</span>'
                        if _CJK_IDEOGRAPH.search(m.group(0)) else m.group(0), html_text)


# ---- cells ---------------------------------------------------------------------------------------

def _text(value) -> str:
    return unicode_math(value) if isinstance(value, str) else fmt(value)


#: what starts raw HTML in Markdown (CommonMark): ``<`` before a tag name, ``/``, ``!`` or ``?``, and
#: a character reference ``&name;`` or ``&#...;``
_RAW_HTML = re.compile(r"<(?=[A-Za-z/!?])|&(?=#?\w+;)")


def md_escaped(text: str) -> str:
    """``text`` for a Markdown page with any raw HTML in it shown as text, as the HTML page shows
    it (user-supplied text: a system's name, a run's error, a file name): ``<`` that would open a
    tag and ``&`` that would start a character reference become ``&lt;`` and ``&amp;``, except
    inside `code` spans, which Markdown shows literally. Comparisons such as ``p < 0.05`` are left
    as they are."""
    parts = re.split(r"(`[^`\n]+`)", text)
    return "".join(part if i % 2 else _RAW_HTML.sub(lambda m: "&lt;" if m.group(0) == "<" else "&amp;", part)
                   for i, part in enumerate(parts))


def _md(value) -> str:
    """A value's text on a Markdown page (:func:`md_escaped`)."""
    return md_escaped(_text(value))


def _md_cell(value) -> str:
    if isinstance(value, VerdictCell):
        text = md_escaped(value.verdict + (f" {CAUTION_MARK} " + "; ".join(value.cautions) if value.cautions else ""))
    elif isinstance(value, Cell):
        text = _md(value.value)
    elif isinstance(value, Link):
        text = f"[{_md(value.text)}]({value.slug}/README.md)"
    elif isinstance(value, Chips):
        text = md_escaped(value.text)
    else:
        text = _md(value)
    return text.replace("|", "\\|").replace("\n", " ")


#: a cell with at least this many characters of text is prose: it keeps a readable width (``td.prose``)
PROSE_CHARS = 40


def _labelled(cell: str, label: str) -> str:
    """A ``<td ...>`` with its column's header as ``data-label`` (shown beside the value when the
    table is stacked, :data:`_FIT_SCRIPT`) and the class ``prose`` when it holds a sentence."""
    text = re.sub(r"<[^>]*>", "", cell)
    prose = len(text) >= PROSE_CHARS and " " in text
    if prose and cell.startswith('<td class="'):
        cell = '<td class="prose ' + cell[len('<td class="'):]
    elif prose:
        cell = '<td class="prose"' + cell[3:]
    return "<td" + label + cell[3:]


def _html_cell(value) -> str:
    if isinstance(value, VerdictCell):
        caution = ""
        if value.cautions:
            reasons = "; ".join(value.cautions)
            caution = f'<div class="caution" title="{esc(reasons)}">{CAUTION_MARK} {esc(reasons)}</div>'
        css = VERDICT_CLASSES.get(value.verdict, "")
        return f'<td class="verdict {css}"><span class="verdict-text">{esc(value.verdict)}</span>{caution}</td>'
    if isinstance(value, Cell):
        title = f' title="{esc(value.title)}"' if value.title else ""
        css = f' class="{esc(value.css)}"' if value.css else ""
        return f"<td{css}{title}>{inline(_text(value.value))}</td>"
    if isinstance(value, Link):
        return f'<td><a href="#{esc(value.anchor or value.slug)}">{esc(_text(value.text))}</a></td>'
    if isinstance(value, Chips):
        marks = "".join(
            f'<a class="chip {VERDICT_CLASSES.get(verdict, "")}{" cautioned" if cautioned else ""}" '
            f'href="#{esc(anchor)}" title="{esc(tooltip)}">{CAUTION_MARK if cautioned else ""}</a>'
            for verdict, tooltip, anchor, cautioned in value.chips)
        return f'<td class="chips">{marks}</td>'
    return f"<td>{inline(_text(value))}</td>"


# ---- blocks --------------------------------------------------------------------------------------

def to_markdown(section: Section, page_dir: Path) -> str:
    return "\n".join([f"# {_md(section.title)}", "", *_markdown_lines(section.blocks, page_dir)])


def _markdown_lines(blocks, page_dir: Path) -> list[str]:
    lines = []
    for block in blocks:
        if isinstance(block, Paragraph):
            lines += [_md(block.text), ""]
        elif isinstance(block, Table):
            if block.caption:
                lines += [f"**{_md(block.caption)}**", ""]
            lines.append("| " + " | ".join(_md_cell(h) for h in block.headers) + " |")
            lines.append("|" + "---|" * len(block.headers))
            lines += ["| " + " | ".join(_md_cell(c) for c in row) + " |" for row in block.rows]
            lines.append("")
        elif isinstance(block, Figure):
            rel = os.path.relpath(block.path, page_dir)
            lines += [f"![{_md(block.caption)}]({rel})", "", f"*{_md(block.caption)}*", ""]
        elif isinstance(block, Code):
            fence = "`" * max(3, 1 + max((len(run) for run in re.findall("`+", block.text)), default=0))
            lines += [fence, block.text, fence, ""]  # longer than any run of backticks in it: it cannot end early
        elif isinstance(block, Details):
            lines += [f"**{_md(block.summary)}** {_md(block.text)}", ""]
        else:
            raise TypeError(f"unknown block {type(block).__name__}")
    return lines


def _html_block(block, ids: bool = True) -> str:
    """One block as HTML; ``ids`` False leaves out the rows' anchors (a notebook holds many outputs in one
    document, where they would repeat)."""
    if isinstance(block, Paragraph):
        return f"<p>{inline(_text(block.text))}</p>"
    if isinstance(block, Table):
        head = "".join(f"<th>{inline(_text(h))}</th>" for h in block.headers)
        labels = [f' data-label="{esc(_text(h))}"' for h in block.headers]
        row_ids = list(block.row_ids) if ids else []
        row_ids += [""] * (len(block.rows) - len(row_ids))
        body = "".join((f'<tr id="{esc(row_id)}">' if row_id else "<tr>")
                       + "".join(_labelled(_html_cell(c), label) for c, label in zip(row, labels)) + "</tr>"
                       for row, row_id in zip(block.rows, row_ids))
        cap = f"<caption>{inline(_text(block.caption))}</caption>" if block.caption else ""
        css = f' class="{esc(block.css)}"' if block.css else ""
        return (f'<div class="table-wrap"><table{css}>{cap}<thead><tr>{head}</tr></thead>'
                f"<tbody>{body}</tbody></table></div>")
    if isinstance(block, Figure):
        data = base64.b64encode(Path(block.path).read_bytes()).decode("ascii")
        return (f'<figure><img alt="{esc(_text(block.caption))}" src="data:image/png;base64,{data}">'
                f"<figcaption>{inline(_text(block.caption))}</figcaption></figure>")
    if isinstance(block, Code):
        return f"<pre>{esc(block.text)}</pre>"
    if isinstance(block, Details):
        return (f"<details><summary>{inline(_text(block.summary))}</summary>"
                f"<p>{inline(_text(block.text))}</p></details>")
    raise TypeError(f"unknown block {type(block).__name__}")


_STYLE = """
:root{--held:#d7f0dc;--held-ink:#14532d;--not:#fbd9d9;--not-ink:#8b1a1a;--und:#fdecc2;--und-ink:#7a4b00;
--nd:#e4e6e9;--nd-ink:#3b4148;--proved:#c9ecd2;--refuted:#e6def5;--refuted-ink:#3f2a7a;--checked:#d3ebf3;--checked-ink:#114b5f;
--line:#c8ccd2;--muted:#5a6270}
*{box-sizing:border-box}
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,"Noto Sans","DejaVu Sans",sans-serif;margin:0;
line-height:1.45;color:#1d232b;background:#fff}
.layout{display:grid;grid-template-columns:15rem minmax(0,1fr)}
nav.toc{position:sticky;top:0;align-self:start;height:100vh;overflow-y:auto;padding:1rem .9rem;
background:#f5f6f8;border-right:1px solid var(--line);font-size:.88rem}
nav.toc h2{font-size:.95rem;margin:.2rem 0 .6rem}
nav.toc ol{list-style:none;margin:0;padding:0}
nav.toc li{margin:.15rem 0}
nav.toc a{display:block;padding:.2rem .4rem;border-radius:4px;color:#1d3d6b;text-decoration:none}
nav.toc a:hover{background:#e3e8f0}
nav.toc .toc-counts{display:block;margin-top:.1rem}
.mini{display:inline-block;min-width:1.3rem;padding:0 .25rem;margin-right:.15rem;border-radius:3px;
font-size:.72rem;text-align:center}
main{padding:1rem 2rem 4rem;max-width:78rem;min-width:0}
main > header h1{margin:.4rem 0 .2rem;font-size:1.7rem}
.subtitle{color:var(--muted);margin-top:0}
h2{margin-top:2.2rem;border-bottom:2px solid #e3e6ea;padding-bottom:.2rem}
section,tr[id]{scroll-margin-top:1rem}
.paper-line{color:var(--muted);margin-top:-.3rem}
.table-wrap{overflow-x:auto}
td.prose{min-width:8rem}
table.stacked,table.stacked tbody,table.stacked tr,table.stacked td{display:block;width:auto;min-width:0}
table.stacked thead{display:none}table.stacked caption{display:block}
table.stacked tr{border:1px solid var(--line);border-radius:4px;margin:.5rem 0}
table.stacked td{display:grid;grid-template-columns:minmax(6rem,28%) minmax(0,1fr);gap:.6rem;border:0;
border-bottom:1px solid #eef0f3;overflow-wrap:anywhere}
table.stacked td::before{content:attr(data-label);font-weight:600;color:var(--muted)}
table.stacked td.chips{display:block}table.stacked td.chips::before{display:block}
table{border-collapse:collapse;margin:.8rem 0;font-size:.92rem}
td,th{border:1px solid var(--line);padding:.25rem .5rem;text-align:left;vertical-align:top}
th{background:#eef0f3}
caption{font-weight:bold;text-align:left;padding:.2rem 0}
img{max-width:100%}
figure{margin:1rem 0}
pre{background:#f4f4f4;padding:.5rem;overflow-x:auto}
details{margin:.3rem 0}summary{cursor:pointer;color:#1d3d6b}
.v-held{background:var(--held);color:var(--held-ink)}
.v-not-held{background:var(--not);color:var(--not-ink);font-weight:600}
.v-undecided{background:var(--und);color:var(--und-ink)}
.v-not-decidable{background:var(--nd);color:var(--nd-ink)}
.v-proved{background:var(--proved);color:var(--held-ink)}
.v-refuted{background:var(--refuted);color:var(--refuted-ink)}
.v-checked{background:var(--checked);color:var(--checked-ink)}
td.verdict{white-space:nowrap}
.caution{margin-top:.25rem;padding:.1rem .35rem;border:1px solid #b7791f;border-radius:4px;background:#fff7e6;
color:#7a4b00;font-size:.78rem;font-weight:normal;white-space:normal;min-width:9rem}
td.zero{color:#b0b5bc;text-align:center}
td.count{text-align:center;font-weight:600}
td.total{font-weight:700}
td.runs-low{background:#fff7e6}
td.chips{min-width:9rem}
.chip{display:inline-block;width:1.05rem;height:1.05rem;margin:1px;border-radius:3px;border:1px solid #0002;
font-size:.7rem;line-height:1rem;text-align:center;text-decoration:none;color:#7a4b00;vertical-align:middle}
.chip.cautioned{border:1px solid #b7791f;box-shadow:inset 0 0 0 1px #fff7e6}
table.summary{width:100%}
table.summary td,table.summary th{padding:.25rem .3rem}table.summary th{font-size:.74rem;font-weight:600;
overflow-wrap:anywhere;hyphens:auto}
table.summary th:nth-child(n+4):nth-last-child(n+3){writing-mode:vertical-rl;transform:rotate(180deg);
white-space:nowrap;text-align:left;vertical-align:middle;padding:.4rem .15rem}
table.summary td:nth-child(2){min-width:8rem}table.summary td.paper{min-width:5rem;font-weight:600}
table.summary td.chips{min-width:5.5rem}
td.controls{font-size:.82rem}
.totals{display:flex;flex-direction:column;gap:.35rem;margin:.6rem 0}
.group-line{display:flex;flex-wrap:wrap;gap:.4rem;align-items:center}.group-label{min-width:7.5rem;font-weight:600}
table.summary td.group{font-size:.82rem;white-space:nowrap}
.badge{padding:.3rem .6rem;border-radius:6px;font-weight:600;border:1px solid #0001}
.badge.caution-badge{background:#fff7e6;color:#7a4b00;border-color:#b7791f}
ol.refs li{margin:.3rem 0}
.cjk{font-family:"gpfverify-cjk","Noto Sans CJK SC","Source Han Sans SC","PingFang SC","Microsoft YaHei",
"WenQuanYi Micro Hei",sans-serif}
.legend{font-size:.88rem;color:var(--muted)}
@media (max-width:1100px){.layout{grid-template-columns:11rem minmax(0,1fr)}main{padding:1rem 1rem 3rem}}
@media (max-width:900px){.layout{display:block}nav.toc{height:auto;max-height:35vh;z-index:2;
border-right:0;border-bottom:1px solid var(--line)}main{padding:1rem}}
@media print{nav.toc{display:none}.layout{display:block}}
"""


def to_html(sections: list[Section], title: str) -> str:
    """A plain self-contained page of ``sections`` (with a sticky table of contents)."""
    listed = {s.slug: (s.title, _fragment(s)) for s in sections}
    return _page(title, "", listed, {}, None)


#: rules of the page's frame (the contents column, the main column, the title), left out of a fragment
_FRAME = ("*", "body", ".layout", "nav", "main", ".subtitle", ".mini", "section,tr[id]")


def fragment_style() -> str:
    """The page's styles for a fragment: its colours and font on the fragment's ``div``, and every rule
    of its content (tables, verdicts, figures, captions, code, details) scoped to that ``div``; the
    page's frame (contents column, layout, window widths) left out."""
    css = re.sub(r"@media[^{]*\{(?:[^{}]*\{[^{}]*\})*[^{}]*\}", "", _STYLE)
    rules = re.findall(r"([^{}]+)\{([^{}]*)\}", css)
    root = next(body for selector, body in rules if selector.strip() == ":root")
    font = next(body for selector, body in rules if selector.strip() == "body")
    out = [f".gpfverify-report{{{root};{font}}}"]
    for selector, body in rules:
        selector = selector.strip()
        if selector == ":root" or selector.startswith(_FRAME):
            continue
        scoped = ",".join(f".gpfverify-report {part.strip()}" for part in selector.split(","))
        out.append(f"{scoped}{{{body}}}")
    return "".join(out)


def to_fragment(sections: list[Section]) -> str:
    """``sections`` as one HTML fragment for a notebook's output cell: the page's blocks and words,
    styled as the page (:func:`fragment_style`, scoped to the fragment: the notebook keeps its own
    styles), without ids (a notebook holds many outputs in one document)."""
    return (f"<div class=\"gpfverify-report\"><style>{fragment_style()}</style>"
            + "".join(_fragment(s, ids=False) for s in sections) + "</div>")


def _fragment(section: Section, ids: bool = True) -> str:
    """A section as HTML, anchored by its slug and its rows' ids unless ``ids`` is False."""
    anchor = f' id="{esc(section.slug)}"' if ids else ""
    return (f"<section{anchor}><h2>{inline(_text(section.title))}</h2>"
            + "".join(_html_block(b, ids) for b in section.blocks) + "</section>")


# ---- provenance, papers, what was run, summary -----------------------------------------------------

def provenance_table(record: dict) -> Table:
    """The provenance record (CONTRACT.md, "Provenance") as a table for a report page."""
    packages = ", ".join(f"{k} {v}" for k, v in sorted(record.get("packages", {}).items()))
    rows: list[list] = [["gpfverify", record.get("gpfverify")], ["git commit", record.get("git_commit") or "unknown"],
            ["Python", record.get("python")], ["platform", record.get("platform")],
            ["libraries", packages], ["created (UTC)", record.get("created")],
            ["command", " ".join(record.get("command", []))]]
    return Table(["provenance", ""], rows, "What produced this page")


def provenance_section(record: dict | None = None) -> Section:
    """A closing "Provenance" section for a single-page report (default: the running command's
    record, :func:`gpfverify.provenance.current`)."""
    if record is None:
        from gpfverify import provenance

        record = provenance.current()
    return Section("provenance", "Provenance", [provenance_table(record)])


def paper_name(key: str) -> str:
    paper = PAPERS.get(key)
    return paper.short if paper else key


def section_title(summary: SectionSummary | None, title: str) -> str:
    """The title as the page shows it: naming the section's paper(s) unless it already does."""
    if summary is None:
        return title
    missing = [paper_name(k) for k in summary.papers if paper_name(k) not in title]
    return f"{title} — {', '.join(missing)}" if missing else title


def _load(run: RunInfo) -> str:
    if not run.load_average:
        return "not recorded"
    text = " / ".join(f"{v:.2f}" for v in run.load_average)
    if run.cpus:
        text += f" on {run.cpus} CPU{'s' if run.cpus != 1 else ''}"
        if run.load_average[0] > run.cpus:
            text += " (busy: timings unreliable)"
    return text


def run_table(summary: SectionSummary) -> Table:
    """The standard "what was run" table that opens every section page."""
    rows: list[list] = []
    for run in summary.runs:
        paper_n = ", ".join(str(n) for n in run.paper_n) or "not stated"
        low = any(run.runs_ok < n for n in run.paper_n)
        done = f"{run.runs_ok} of {run.runs}" if run.runs_ok != run.runs else str(run.runs)
        rows.append([run.experiment, run.setting or "(one setting)",
                     Cell(done + (f" {CAUTION_MARK} fewer than the paper" if low else ""),
                          "runs-low" if low else ""),
                     paper_n, "—" if run.seed is None else run.seed, _load(run),
                     " ".join(x for x in ((run.git_commit or "")[:12], run.created or "") if x) or "unknown"])
    return Table(["experiment", "setting", "runs", "paper's runs", "root seed",
                  "machine load (1, 5, 15 min; median over the runs)", "computed at (commit, UTC)"], rows,
                 f"What was run ({summary.profile} profile)", css="runs")


def verdicts_paragraph(counts: VerdictCounts) -> Paragraph:
    """A page's verdicts counted per group, and what each group present holds."""
    words = {ACCURACY: "the paper's accuracy claims (the headline)", TIMING: "its timing claims (CPU times "
             "compared as paired per-run ratios)"}
    groups = [words.get(g.group, f"{g.group} (the paper's theorem, checked on the runs)") for g in counts.groups]
    return Paragraph(f"Verdicts on this page: {counts.groups_text()}." + (
        f" Counted apart: {'; '.join(groups)}." if len(groups) > 1 else ""))


def header_blocks(summary: SectionSummary) -> list:
    """What every section page opens with: its paper(s) and, for experiments, what was run."""
    blocks: list = []
    papers = [PAPERS[k] for k in summary.papers if k in PAPERS]
    if papers:
        blocks.append(Paragraph("Paper: " + "; ".join(f"{p.short}, “{p.title_en}” ({p.venue}, {p.year})"
                                                      for p in papers) + "."))
    if summary.claims:
        blocks.append(verdicts_paragraph(summary.verdicts))
    if summary.runs:
        blocks.append(run_table(summary))
    if summary.certificates:
        seconds = sum(c.seconds for c in summary.certificates)
        blocks.append(Paragraph(f"What was run: {len(summary.certificates)} certificates (kernel-checked "
                                "proofs and counterexamples, checks by other routes and implementations), "
                                f"{seconds:.0f} s in all."))
    return blocks


def with_header(section: Section, summary: SectionSummary | None) -> Section:
    if summary is None:
        return section
    return Section(section.slug, section_title(summary, section.title), [*header_blocks(summary), *section.blocks])


def _paper_order(summary: SectionSummary) -> int:
    keys = list(PAPERS)
    first = summary.papers[0] if summary.papers else None
    return keys.index(first) if first in keys else len(keys)


def summary_table(summaries: Iterable[SectionSummary]) -> Table:
    """Every verdict of the report per paper, section and group (accuracy — the headline —, each
    theorem checked on the runs, timing; certificates as proofs): counts in colour, one mark per
    verdict (⚠ on those with a caution) linking to its row, and the totals per group."""
    ordered = sorted(summaries, key=_paper_order)  # stable: report order within a paper
    previous = None
    rows: list[list] = []
    total = VerdictCounts.total(s.verdicts for s in ordered)
    robust_total: dict[str, list[int]] = {}
    for s in ordered:
        papers = ", ".join(paper_name(k) for k in s.papers) or ("the toolkit's own algebra" if s.certificates else "—")
        shown, previous = ("" if papers == previous else papers), papers  # a paper once for its sections
        paper_cell = Cell(shown, "paper", "; ".join(PAPERS[k].citation for k in s.papers if k in PAPERS))
        counts = s.verdicts
        first = True
        for group in counts.groups:
            claims = [c for c in s.claims if c.group == group.group]
            tried = [c for c in claims if c.interpretations]
            robust = sum(is_robust(c) for c in tried)
            kept = robust_total.setdefault(group.group, [0, 0])
            kept[0], kept[1] = kept[0] + robust, kept[1] + len(tried)
            cautioned = sum(1 for c in claims if c.cautions)
            section = Link(s.title, s.slug) if first else ""
            rows.append([paper_cell if first else "", section, Cell(group.group, "group"),
                         *[_count_cell(group.counts[v], v) for v in VERDICTS], *[_count_cell(0, k) for k in STATUSES],
                         Cell(f"{CAUTION_MARK} {cautioned}" if cautioned else 0, "count" if cautioned else "zero"),
                         Cell(f"{robust} of {len(tried)}" if tried else "—", "count" if tried else "zero"),
                         Chips(tuple(_chip(c) for c in claims), f"{len(claims)} verdicts")])
            first = False
        if s.certificates:
            rows.append([paper_cell if first else "", Link(s.title, s.slug) if first else "", Cell("proofs", "group"),
                         *[_count_cell(0, v) for v in VERDICTS], *[_count_cell(counts.proofs[k], k) for k in STATUSES],
                         Cell(0, "zero"), Cell("—", "zero"),
                         Chips(tuple((c.status, f"{c.claim}: {c.status_text}", certificate_anchor(c.claim), False)
                                     for c in s.certificates), f"{len(s.certificates)} certificates")])
    for group in total.groups:
        robust, tried_count = robust_total.get(group.group, [0, 0])
        cautioned = sum(1 for s in ordered for c in s.claims if c.group == group.group and c.cautions)
        rows.append([Cell("all", "total"), Cell("every section", "total"), Cell(group.group, "group total"),
                     *[_count_cell(group.counts[v], v, "total") for v in VERDICTS],
                     *[_count_cell(0, k, "total") for k in STATUSES],
                     Cell(f"{CAUTION_MARK} {cautioned}" if cautioned else 0, "count total"),
                     Cell(f"{robust} of {tried_count}" if tried_count else "—", "count total"), ""])
    if any(total.proofs.values()):
        rows.append([Cell("all", "total"), Cell("every section", "total"), Cell("proofs", "group total"),
                     *[_count_cell(0, v, "total") for v in VERDICTS],
                     *[_count_cell(total.proofs[k], k, "total") for k in STATUSES], Cell(0, "zero"), "—", ""])
    return Table(["paper", "section", "group", *VERDICTS, *STATUSES, f"{CAUTION_MARK} caution",
                  "same verdict under every interpretation tried", "each verdict (hover, click)"],
                 rows, "Verdicts per paper, section and group: accuracy (the headline), Proposition 1 (the theorem "
                 "checked on the runs) and timing (CPU-time ratios) are counted apart", css="summary")


def _chip(c) -> tuple[str, str, str, bool]:
    """A claim's mark in the summary: its verdict, a tooltip, its row's anchor, whether cautioned."""
    tip = f"{c.claim}" + (f" ({c.setting})" if c.setting else "") + f": {c.verdict}"
    if c.cautions:
        tip += f" — {CAUTION_MARK} " + "; ".join(c.cautions)
    if c.interpretations:
        tip += f" — {robustness(c)}"
    return c.verdict, tip, claim_anchor(c), bool(c.cautions)


def _count_cell(n: int, kind: str, extra: str = "") -> Cell:
    css = f"count {VERDICT_CLASSES[kind]}" if n else "zero"
    return Cell(n, f"{css} {extra}".strip())


def certificate_anchor(claim: str) -> str:
    return "cert-" + anchor_id(claim)


def references_blocks() -> list:
    return [Paragraph(f"[{i}] {p.short}: {p.citation}") for i, p in enumerate(PAPERS.values(), 1)]


_LEGEND = ("Colours: held (green) — our runs agree with the paper's claim; NOT held (red) — they contradict "
           "it beyond the Monte Carlo error; undecided (amber) — the Monte Carlo interval contains the "
           "threshold, more runs would decide; not decidable (grey) — the runs as made cannot decide it. "
           "Proofs: proved (a certificate the proof kernel accepts, with an exact witness of its hypotheses), "
           "refuted (violet: an exact counterexample the kernel evaluates; a statement meant to be refuted, a false "
           "variant of a theorem, says so), checked (identities at listed sizes or two "
           f"implementations agreeing to a tolerance — not a proof). {CAUTION_MARK} marks a verdict that rests on "
           "fewer runs than the paper used or on wall-clock timing (which depends on the machine and its "
           "load): hold it loosely.")


def overview_line(summaries: list[SectionSummary]) -> str:
    """Profile, seed, settings, runs and the busiest machine load, in one sentence."""
    runs = [r for s in summaries for r in s.runs]
    profiles = sorted({s.profile for s in summaries if s.runs or s.certificates})
    seeds = sorted({s.seed for s in summaries if s.seed is not None})
    text = (f"Profile {', '.join(profiles) or 'unknown'}"
            + (" (few runs per setting, minutes on a laptop; “gpfverify report --full” runs the papers' counts)"
               if "quick" in profiles else "")
            + f", root seed {', '.join(map(str, seeds)) or 'unknown'}: run i of a setting is seeded by "
            "SeedSequence(seed).spawn(runs)[i], so any run can be repeated alone. ")
    if runs:
        text += (f"{len({r.experiment for r in runs})} experiments in {len(runs)} settings, "
                 f"{sum(r.runs for r in runs)} runs ({sum(r.runs_ok for r in runs)} finished). ")
        loaded = [r for r in runs if r.load_average]
        if loaded:
            busiest = max(loaded, key=lambda r: r.load_average[0])
            text += f"Highest median 1-minute machine load a setting's runs met: {_load(busiest)}."
    return text


# ---- the report folder ---------------------------------------------------------------------------

#: per-section files that let a later ``--only`` build keep the sections it did not rebuild
SECTION_HTML, SECTION_META = "section.html", "section.json"
#: the report's counts (:class:`~gpfverify.report.inputs.VerdictCounts`, with each section's) as JSON
VERDICTS_FILE = "verdicts.json"


def write_report(sections: list[Section], out_dir: Path, title: str, preamble: str,
                 order: list[str] | None = None, provenance: dict | None = None,
                 summaries: dict[str, SectionSummary] | None = None) -> Path:
    """Write ``out_dir/<slug>/README.md`` per section, ``out_dir/README.md`` as the index and
    ``out_dir/report.html`` with everything embedded. Returns the HTML path.

    With ``order`` (every slug of the full report, in report order), the index and the HTML list
    every section of ``order`` whose page exists in ``out_dir`` — the ones built now and those
    kept from earlier builds (each section also leaves ``<slug>/section.html`` and
    ``<slug>/section.json``, which holds its summary) — so building a few sections updates them
    and keeps the rest. Without ``order`` only ``sections`` are listed. ``summaries`` (slug ->
    :class:`SectionSummary`) give each page its header (paper, what was run) and feed the summary
    of verdicts. ``provenance`` (the record of :mod:`gpfverify.provenance`) is added at the end of
    every page written and to the index."""
    out_dir.mkdir(parents=True, exist_ok=True)
    summaries = dict(summaries or {})
    built = {}
    for section in sections:
        summary = summaries.get(section.slug)
        section = with_header(section, summary)
        if provenance is not None:
            section = Section(section.slug, section.title, [*section.blocks, provenance_table(provenance)])
        page_dir = out_dir / section.slug
        page_dir.mkdir(parents=True, exist_ok=True)
        (page_dir / "README.md").write_text(to_markdown(section, page_dir), encoding="utf-8")
        fragment = _fragment(section)
        (page_dir / SECTION_HTML).write_text(fragment, encoding="utf-8")
        meta = {"slug": section.slug, "title": section.title, "provenance": provenance,
                "summary": None if summary is None else summary.to_json()}
        (page_dir / SECTION_META).write_text(json.dumps(meta), encoding="utf-8")
        built[section.slug] = (section.title, fragment)
    listed = {}
    for slug in (order if order is not None else list(built)):
        if slug in built:
            listed[slug] = built[slug]
            continue
        try:
            meta = json.loads((out_dir / slug / SECTION_META).read_text(encoding="utf-8"))
            listed[slug] = (str(meta["title"]), (out_dir / slug / SECTION_HTML).read_text(encoding="utf-8"))
        except (OSError, ValueError, KeyError, TypeError):
            continue  # never built here (or damaged): not listed
        summary = _summary_of(meta)
        if summary is not None:
            summaries[slug] = summary
    shown = [summaries[slug] for slug in listed if slug in summaries]
    if shown:  # the counts the index and the page show, for programs
        counts = {**VerdictCounts.total(s.verdicts for s in shown).to_json(),
                  "sections": {s.slug: s.verdicts.to_json() for s in shown}, "provenance": provenance}
        (out_dir / VERDICTS_FILE).write_text(json.dumps(counts, indent=1), encoding="utf-8")
    (out_dir / "README.md").write_text(_index_markdown(title, preamble, listed, shown, provenance, out_dir),
                                       encoding="utf-8")
    html_path = out_dir / "report.html"
    html_path.write_text(_page(title, preamble, listed, {s.slug: s for s in shown}, provenance), encoding="utf-8")
    return html_path


def _index_markdown(title: str, preamble: str, listed: dict, shown: list[SectionSummary],
                    provenance: dict | None, out_dir: Path) -> str:
    lines = [f"# {md_escaped(title)}", "", md_escaped(preamble), ""]
    if shown:
        lines += ["## Summary of verdicts", "", VerdictCounts.total(s.verdicts for s in shown).line() + ".", "",
                  *_markdown_lines([summary_table(shown)], out_dir), _LEGEND, "",
                  "## What was run", "", overview_line(shown), ""]
    lines += ["## Sections", ""]
    lines += [f"- [{page_title}]({slug}/README.md)" for slug, (page_title, _) in listed.items()]
    lines += ["", "## References", ""]
    lines += [f"{i}. **{p.short}**: {p.citation}" for i, p in enumerate(PAPERS.values(), 1)]
    if provenance is not None:
        lines += ["", "## Provenance", "", *_markdown_lines([provenance_table(provenance)], out_dir)]
    return "\n".join(lines).rstrip() + "\n"


def _toc_counts(summary: SectionSummary | None) -> str:
    """The section's headline (accuracy) verdicts and its certificates as small coloured counts."""
    if summary is None:
        return ""
    counts = summary.verdicts
    accuracy = counts.group(ACCURACY).counts
    marks = "".join(f'<span class="mini {VERDICT_CLASSES[k]}" title="{ACCURACY}: {accuracy[k]} {esc(k)}">'
                    f"{accuracy[k]}</span>" for k in VERDICTS if accuracy[k])
    marks += "".join(f'<span class="mini {VERDICT_CLASSES[k]}" title="{counts.proofs[k]} {esc(k)}">'
                     f"{counts.proofs[k]}</span>" for k in STATUSES if counts.proofs[k])
    if summary.cautioned:
        marks += f'<span class="mini caution-mini" title="with a caution">{CAUTION_MARK}{summary.cautioned}</span>'
    return f'<span class="toc-counts">{marks}</span>' if marks else ""


def totals_html(counts: VerdictCounts) -> str:
    """The report's totals as coloured badges, one line per group (accuracy first, then each
    theorem, timing, proofs), and the verdicts with a caution."""
    lines = [f'<div class="group-line"><span class="group-label">{esc(g.group)}</span>'
             + "".join(f'<span class="badge {VERDICT_CLASSES[v]}">{g.counts[v]} {esc(v)}</span>' for v in VERDICTS)
             + "</div>" for g in (counts.group(ACCURACY), *(g for g in counts.groups if g.group != ACCURACY))]
    lines.append('<div class="group-line"><span class="group-label">proofs</span>'
                 + "".join(f'<span class="badge {VERDICT_CLASSES[k]}">{counts.proofs[k]} {esc(k)}</span>'
                           for k in STATUSES) + "</div>")
    if counts.cautioned:
        lines.append(f'<span class="badge caution-badge">{CAUTION_MARK} {counts.cautioned} with a caution</span>')
    return "".join(lines)


def _page(title: str, preamble: str, listed: dict, summaries: dict[str, SectionSummary],
          provenance: dict | None) -> str:
    toc = ['<nav class="toc" aria-label="Contents"><h2>Contents</h2><ol>']
    parts = [f"<header><h1>{esc(title)}</h1>"
             + (f'<p class="subtitle">{esc(_text(preamble))}</p>' if preamble else "") + "</header>"]
    if summaries:
        shown = list(summaries.values())
        badges = totals_html(VerdictCounts.total(s.verdicts for s in shown))
        parts.append('<section id="summary"><h2>Summary of verdicts</h2>'
                     f'<div class="totals">{badges}</div>' + _html_block(summary_table(shown))
                     + f'<p class="legend">{esc(_LEGEND)}</p></section>')
        parts.append(f'<section id="what-was-run"><h2>What was run</h2><p>{esc(overview_line(shown))}</p>'
                     "<p>Each section opens with the runs it rests on: settings, run counts against the "
                     "paper's, seed and machine load.</p></section>")
        toc += ['<li><a href="#summary">Summary of verdicts</a></li>',
                '<li><a href="#what-was-run">What was run</a></li>']
    for slug, (page_title, _) in listed.items():
        toc.append(f'<li><a href="#{esc(slug)}">{inline(_text(page_title))}{_toc_counts(summaries.get(slug))}</a></li>')
    parts += [fragment for _, fragment in listed.values()]
    if summaries or provenance is not None:
        parts.append('<section id="references"><h2>References</h2><ol class="refs">'
                     + "".join(f'<li id="ref-{esc(p.key)}"><b>{esc(p.short)}</b>: {inline(p.citation)}</li>'
                               for p in PAPERS.values()) + "</ol></section>")
        toc.append('<li><a href="#references">References</a></li>')
    if provenance is not None:
        parts.append('<section id="provenance"><h2>Provenance</h2>'
                     + _html_block(provenance_table(provenance)) + "</section>")
        toc.append('<li><a href="#provenance">Provenance</a></li>')
    toc.append("</ol></nav>")
    body = f"<body><div class='layout'>{''.join(toc)}<main>{''.join(parts)}</main></div></body></html>"
    style = (cjk_font.font_face_css() if cjk_font.page_needs_font(body) else "") + _STYLE
    return (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
            f"<meta name='viewport' content='width=device-width, initial-scale=1'><title>{esc(title)}</title>"
            f"<style>{style}</style></head>{body.replace('</body>', _FIT_SCRIPT + '</body>')}")


#: tables wrap their text (``td.prose`` keeps a readable width); a table that still does not fit
#: its column is stacked, one block per row with each value beside its column's name, and is
#: measured again whenever the window changes (without scripts it scrolls sideways instead)
_FIT_SCRIPT = ("<script>(function(){function fit(){document.querySelectorAll('.table-wrap').forEach(function(w){"
               "var t=w.querySelector('table');t.classList.remove('stacked');"
               "if(t.getBoundingClientRect().width>w.clientWidth+1)t.classList.add('stacked');});}"
               "addEventListener('load',fit);addEventListener('resize',fit);})();</script>")


def read_summaries(out_dir: Path, order: list[str]) -> list[SectionSummary]:
    """The summaries of the sections of ``order`` listed in the report at ``out_dir`` (from their
    ``section.json``; sections never rendered there, or rendered without one, are left out)."""
    out = []
    for slug in order:
        try:
            meta = json.loads((Path(out_dir) / slug / SECTION_META).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        summary = _summary_of(meta)
        if summary is not None:
            out.append(summary)
    return out


def _summary_of(meta: object) -> SectionSummary | None:
    """The summary kept in a ``section.json`` (None when it has none or one this version cannot
    read: the page is then listed without it)."""
    from gpfverify.errors import InputError

    if not isinstance(meta, dict) or meta.get("summary") is None:
        return None
    try:
        return SectionSummary.from_json(meta["summary"])
    except InputError:
        return None
