"""Report page: the symbolic proofs (sympy) and the casadi cross-checks, from their certificates
(``certificates.json``, written by the command layer or by ``gpfverify prove``)."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from gpfverify.report.document import Cell, Details, Paragraph, Section, Table, VerdictCell, fmt
from gpfverify.report.inputs import STATUSES, CertificateInfo, SectionInput
from gpfverify.report.render import certificate_anchor

SLUG = "proofs"
TITLE = "Symbolic proofs and a second implementation"


def render_section(data: SectionInput) -> Section:
    """The page from the section's certificates."""
    return render(list(data.certificates))


def _controls(c: CertificateInfo) -> Cell:
    if not c.negative_controls:
        return Cell("none", "zero")
    accepted = [m.mutant for m in c.negative_controls if not m.rejected]
    if accepted:
        return Cell(f"ACCEPTED {len(accepted)} of {len(c.negative_controls)}: " + "; ".join(accepted), "v-not-held")
    return Cell(f"all {len(c.negative_controls)} rejected: " + "; ".join(m.mutant for m in c.negative_controls),
                "controls")


def render(certificates: list[dict], out_dir: Path | None = None) -> Section:
    """The page for a list of certificate dicts (``certificates.json``); ``out_dir`` is unused
    (the page has no figures) and accepted for the common ``render(results, dir)`` shape."""
    infos = [CertificateInfo.of(c) for c in certificates]
    counts = Counter(c.status for c in infos)
    section = Section(SLUG, TITLE)
    section.add(
        Paragraph("A statement is proved when the proof engine accepts it: every rule the proof applies was "
                  "issued by a declaration (and checked on exact instances) or derived, every hypothesis it rests "
                  "on is written into the statement, and its scope is what the proof covers (any dimension, or "
                  "the sizes listed). It is refuted by an exact counterexample, and checked when it holds on exact "
                  "instances or two independent implementations agree within a stated tolerance — checked is not "
                  "a proof (the detail says why). A proof must also reject its negative controls — deliberately "
                  "wrong variants of the statement (a sign, a transpose, a dropped term, a dropped hypothesis, a "
                  "rule no declaration issued) — or it is demoted; a stated fact (checked, not proved) is listed. "
                  "Statements expected to be false are kept and shown as refuted. Totals: "
                  + ", ".join(f"{counts[s]} {s}" for s in STATUSES) + "."),
        Table(["claim", "status", "statement", "scope", "stated facts (used, not proved)", "method",
               "negative controls", "seconds"],
              [[c.claim, VerdictCell(c.status), c.statement, c.scope or "not stated",
                "; ".join(c.stated_facts) or "none", c.method, _controls(c), fmt(c.seconds, 3)] for c in infos],
              "Certificates", tuple(certificate_anchor(c.claim) for c in infos), "certificates"),
    )
    for c in infos:
        section.add(Details(f"{c.claim} ({c.status}): what was shown", c.detail))
    return section
