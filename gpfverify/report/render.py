"""Render :class:`~gpfverify.report.document.Section` pages to Markdown files and one
self-contained HTML page (figures embedded as base64 PNG)."""

from __future__ import annotations

import base64
import html
import os
from pathlib import Path

from gpfverify.report.document import Code, Figure, Paragraph, Section, Table, fmt


def _md_cell(value) -> str:
    return fmt(value).replace("|", "\\|").replace("\n", " ")


def to_markdown(section: Section, page_dir: Path) -> str:
    return "\n".join([f"# {section.title}", "", *_markdown_lines(section.blocks, page_dir)])


def _markdown_lines(blocks, page_dir: Path) -> list[str]:
    lines = []
    for block in blocks:
        if isinstance(block, Paragraph):
            lines += [block.text, ""]
        elif isinstance(block, Table):
            if block.caption:
                lines += [f"**{block.caption}**", ""]
            lines.append("| " + " | ".join(_md_cell(h) for h in block.headers) + " |")
            lines.append("|" + "---|" * len(block.headers))
            lines += ["| " + " | ".join(_md_cell(c) for c in row) + " |" for row in block.rows]
            lines.append("")
        elif isinstance(block, Figure):
            rel = os.path.relpath(block.path, page_dir)
            lines += [f"![{block.caption}]({rel})", "", f"*{block.caption}*", ""]
        elif isinstance(block, Code):
            lines += ["```", block.text, "```", ""]
        else:
            raise TypeError(f"unknown block {type(block).__name__}")
    return lines


def _html_block(block) -> str:
    esc = html.escape
    if isinstance(block, Paragraph):
        return f"<p>{esc(block.text)}</p>"
    if isinstance(block, Table):
        head = "".join(f"<th>{esc(h)}</th>" for h in block.headers)
        body = "".join("<tr>" + "".join(f"<td>{esc(fmt(c))}</td>" for c in row) + "</tr>"
                       for row in block.rows)
        cap = f"<caption>{esc(block.caption)}</caption>" if block.caption else ""
        return f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"
    if isinstance(block, Figure):
        data = base64.b64encode(Path(block.path).read_bytes()).decode("ascii")
        return (f'<figure><img alt="{esc(block.caption)}" src="data:image/png;base64,{data}">'
                f"<figcaption>{esc(block.caption)}</figcaption></figure>")
    if isinstance(block, Code):
        return f"<pre>{esc(block.text)}</pre>"
    raise TypeError(f"unknown block {type(block).__name__}")


_STYLE = """body{font-family:system-ui,sans-serif;max-width:60rem;margin:2rem auto;padding:0 1rem;
line-height:1.45}table{border-collapse:collapse;margin:1rem 0}td,th{border:1px solid #bbb;
padding:.25rem .5rem;text-align:left;vertical-align:top}caption{font-weight:bold;text-align:left}
img{max-width:100%}pre{background:#f4f4f4;padding:.5rem;overflow-x:auto}nav a{margin-right:1rem}"""


def to_html(sections: list[Section], title: str) -> str:
    nav = "".join(f'<a href="#{s.slug}">{html.escape(s.title)}</a>' for s in sections)
    body = "".join(f'<section id="{s.slug}"><h1>{html.escape(s.title)}</h1>'
                   + "".join(_html_block(b) for b in s.blocks) + "</section>" for s in sections)
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{_STYLE}</style></head><body><nav>{nav}</nav>{body}</body></html>")


def provenance_table(record: dict) -> Table:
    """The provenance record (CONTRACT.md, "Provenance") as a table for a report page."""
    packages = ", ".join(f"{k} {v}" for k, v in sorted(record.get("packages", {}).items()))
    rows = [["gpfverify", record.get("gpfverify")], ["git commit", record.get("git_commit") or "unknown"],
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


def _with_provenance(section: Section, record: dict | None) -> Section:
    if record is None:
        return section
    return Section(section.slug, section.title, [*section.blocks, provenance_table(record)])


#: per-section files that let a later ``--only`` build keep the sections it did not rebuild
SECTION_HTML, SECTION_META = "section.html", "section.json"


def write_report(sections: list[Section], out_dir: Path, title: str, preamble: str,
                 order: list[str] | None = None, provenance: dict | None = None) -> Path:
    """Write ``out_dir/<slug>/README.md`` per section, ``out_dir/README.md`` as the index and
    ``out_dir/report.html`` with everything embedded. Returns the HTML path.

    With ``order`` (every slug of the full report, in report order), the index and the HTML list
    every section of ``order`` whose page exists in ``out_dir`` — the ones built now and those
    kept from earlier builds (each section also leaves ``<slug>/section.html`` and
    ``<slug>/section.json``) — so building a few sections updates them and keeps the rest.
    Without ``order`` only ``sections`` are listed. ``provenance`` (the record of
    :mod:`gpfverify.provenance`) is added at the end of every page written and to the index."""
    import json

    out_dir.mkdir(parents=True, exist_ok=True)
    built = {}
    for section in sections:
        section = _with_provenance(section, provenance)
        page_dir = out_dir / section.slug
        page_dir.mkdir(parents=True, exist_ok=True)
        (page_dir / "README.md").write_text(to_markdown(section, page_dir), encoding="utf-8")
        fragment = (f'<section id="{section.slug}"><h1>{html.escape(section.title)}</h1>'
                    + "".join(_html_block(b) for b in section.blocks) + "</section>")
        (page_dir / SECTION_HTML).write_text(fragment, encoding="utf-8")
        (page_dir / SECTION_META).write_text(json.dumps({"slug": section.slug, "title": section.title,
                                                         "provenance": provenance}), encoding="utf-8")
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
    index = [f"# {title}", "", preamble, ""]
    index += [f"- [{page_title}]({slug}/README.md)" for slug, (page_title, _) in listed.items()]
    if provenance is not None:
        index += ["", *_markdown_lines([provenance_table(provenance)], out_dir)]
    (out_dir / "README.md").write_text("\n".join(index).rstrip() + "\n", encoding="utf-8")
    nav = "".join(f'<a href="#{slug}">{html.escape(t)}</a>' for slug, (t, _) in listed.items())
    head = "" if provenance is None else _html_block(provenance_table(provenance))
    page = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{_STYLE}</style></head><body><nav>{nav}</nav><p>{html.escape(preamble)}</p>"
            + "".join(fragment for _, fragment in listed.values()) + head + "</body></html>")
    html_path = out_dir / "report.html"
    html_path.write_text(page, encoding="utf-8")
    return html_path
