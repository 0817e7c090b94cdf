"""Report page: the kernel-checked proofs and the casadi cross-checks, from their certificates
(``certificates.json``, written by the command layer or by ``gpfverify prove``)."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from gpfverify.report.document import VERDICT_CLASSES, Cell, Details, Paragraph, Section, Table, VerdictCell, fmt
from gpfverify.report.inputs import STATUSES, CertificateInfo, SectionInput
from gpfverify.report.render import certificate_anchor

SLUG = "proofs"
TITLE = "Kernel-checked proofs and a second implementation"


def render_section(data: SectionInput) -> Section:
    """The page from the section's certificates."""
    return render(list(data.certificates))


def _controls(c: CertificateInfo) -> Cell:
    if not c.negative_controls:
        return Cell("none", "zero")
    failed = [m.mutant for m in c.negative_controls if not (m.rejected and m.false_on_instance)]
    if failed:
        return Cell(f"FAILED {len(failed)} of {len(c.negative_controls)}: " + "; ".join(failed), "v-not-held")
    return Cell(f"all {len(c.negative_controls)} refused and refuted: " + "; ".join(m.mutant
                                                                                  for m in c.negative_controls),
                "controls")


def _status(c: CertificateInfo) -> Cell | VerdictCell:
    """The status, coloured; a statement meant to be refuted says so (its record's ``expected``), and one
    that did not get the status it was meant to, or a failed check, is marked FAILED."""
    if c.holds is False or (c.expected and not c.as_intended):
        meant = f" (meant to be {c.expected})" if c.expected and not c.as_intended else ""
        return Cell(f"{c.status}{meant} — FAILED", "v-not-held")
    if c.as_intended:
        return Cell(c.status_text, VERDICT_CLASSES[c.status],
                    f"meant to be {c.expected}: a false variant of a theorem, whose {c.expected} status is the result")
    return VerdictCell(c.status)


def render(certificates: list[dict], out_dir: Path | None = None) -> Section:
    """The page for a list of certificate dicts (``certificates.json``); ``out_dir`` is unused
    (the page has no figures) and accepted for the common ``render(results, dir)`` shape."""
    infos = [CertificateInfo.of(c) for c in certificates]
    counts = Counter(c.status for c in infos)
    section = Section(SLUG, TITLE)
    section.add(
        Paragraph("A statement is a formal object (matrices of symbolic sizes, hypotheses, a conclusion); the "
                  "statement, scope and assumptions shown are rendered from it, and a title in words is shown "
                  "apart. It is proved when the kernel (gpfverify/kernel, docs/proofs.md) accepts its certificate "
                  "and an exact witness satisfies every hypothesis; refuted when the kernel evaluates an exact "
                  "counterexample that satisfies every hypothesis; checked when identities hold at listed sizes or "
                  "two implementations agree within a stated tolerance — checked is not a proof. Each negative "
                  "control is a mutated statement that the kernel must refuse and refute on an exact instance. A "
                  "statement whose record says it is meant to be refuted (a false variant of a theorem, such as "
                  "\"full column rank is necessary\") shows \"refuted, as intended\": its refutation is the result. "
                  "`gpfverify prove --check certificates.json` derives every status and statement again with the "
                  "kernel alone. Totals: " + ", ".join(f"{counts[s]} {s}" for s in STATUSES) + "."),
        Table(["claim", "status", "title", "statement", "scope", "method", "negative controls", "seconds"],
              [[c.claim, _status(c), c.title or "—", c.statement, c.scope or "not stated", c.method, _controls(c),
                fmt(c.seconds, 3)] for c in infos],
              "Certificates", tuple(certificate_anchor(c.claim) for c in infos), "certificates"),
    )
    for c in infos:
        section.add(Details(f"{c.claim} ({c.status}): what was shown", c.detail))
    return section
