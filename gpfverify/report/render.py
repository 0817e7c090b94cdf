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
    lines = [f"# {section.title}", ""]
    for block in section.blocks:
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
    return "\n".join(lines)


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


def write_report(sections: list[Section], out_dir: Path, title: str, preamble: str) -> Path:
    """Write ``out_dir/<slug>/README.md`` per section, ``out_dir/README.md`` as the index and
    ``out_dir/report.html`` with everything embedded. Returns the HTML path."""
    out_dir.mkdir(parents=True, exist_ok=True)
    index = [f"# {title}", "", preamble, ""]
    for section in sections:
        page_dir = out_dir / section.slug
        page_dir.mkdir(parents=True, exist_ok=True)
        (page_dir / "README.md").write_text(to_markdown(section, page_dir), encoding="utf-8")
        index.append(f"- [{section.title}]({section.slug}/README.md)")
    (out_dir / "README.md").write_text("\n".join(index) + "\n", encoding="utf-8")
    html_path = out_dir / "report.html"
    html_path.write_text(to_html(sections, title), encoding="utf-8")
    return html_path
