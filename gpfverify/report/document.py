"""A tiny document model for report pages, rendered to Markdown and to self-contained HTML.

Sections are built from data (``results.json`` and verification numbers), never from prose
templates with numbers pasted in.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path


@dataclass(frozen=True)
class Paragraph:
    text: str


@dataclass(frozen=True)
class Table:
    headers: list[str]
    rows: list[list]
    caption: str = ""


@dataclass(frozen=True)
class Figure:
    path: Path  # a PNG inside the report folder
    caption: str


@dataclass(frozen=True)
class Code:
    text: str


@dataclass(frozen=True)
class Claim:
    """One claim of a paper checked against our numbers: ``held`` is True, False, or None when
    the run was too small to decide."""

    claim: str
    held: bool | None
    evidence: str


def claim_records_table(records, caption: str = "Claims checked") -> Table:
    """Claim records (:class:`gpfverify.contract.ClaimRecord`, as stored in ``results.json``) as a
    table: claim, where the paper makes it, verdict, evidence, and the cautions a reader needs
    (fewer runs than the paper, wall-clock timing, the record's own caveats)."""
    rows = []
    for r in records:
        notes = [*r.cautions, *r.caveats]
        rows.append([r.claim + (f" ({r.setting})" if r.setting else ""), r.source, r.verdict, r.evidence,
                     "; ".join(notes)])
    return Table(["claim", "source", "verdict", "evidence", "caution"], rows, caption)


def claims_table(claims: list[Claim], caption: str = "Claims checked") -> Table:
    verdict = {True: "held", False: "NOT held", None: "undecided"}
    return Table(["claim", "verdict", "evidence"],
                 [[c.claim, verdict[c.held], c.evidence] for c in claims], caption)


@dataclass
class Section:
    """One report page: ``slug`` names its folder and file."""

    slug: str
    title: str
    blocks: list = field(default_factory=list)

    def add(self, *blocks) -> Section:
        self.blocks.extend(blocks)
        return self


def fmt(value, digits: int = 4) -> str:
    """Numbers as short strings for tables: floats in ``digits`` significant figures."""
    if isinstance(value, bool) or value is None:
        return str(value)
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def integer_ranges(values, dash: str = "–") -> str:
    """Sorted integers as ranges: [1, 2, 3, 7] -> '1–3, 7' (step indices in report text)."""
    values = [int(v) for v in values]
    parts, start = [], None
    for i, v in enumerate(values):
        if start is None:
            start = v
        if i + 1 == len(values) or values[i + 1] != v + 1:
            parts.append(str(start) if start == v else f"{start}{dash}{v}")
            start = None
    return ", ".join(parts)
