"""Report page: the symbolic proofs (sympy) and the casadi cross-checks, from their certificates."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

from gpfverify.report.document import Paragraph, Section, Table, fmt

SLUG = "proofs"
TITLE = "Symbolic proofs and second implementation"


def render(certificates: list[dict], out_dir: Path | None = None) -> Section:
    """The page for a list of certificate dicts (``certificates.json``); ``out_dir`` is unused
    (the page has no figures) and accepted for the common ``render(results, dir)`` shape."""
    counts = Counter(c["status"] for c in certificates)
    section = Section(SLUG, TITLE)
    section.add(
        Paragraph("Each claim is checked by exact symbolic computation (status 'proved', or 'refuted' with an "
                  "exact counterexample) or by numerical agreement of two independent implementations within a "
                  "stated tolerance ('checked'). Statements the toolkit expects to be false are kept and shown "
                  "as refuted. Totals: " + ", ".join(f"{counts[s]} {s}" for s in ("proved", "refuted", "checked"))
                  + "."),
        Table(["claim", "status", "method", "seconds"],
              [[c["claim"], c["status"], c["method"], fmt(float(c.get("seconds", 0.0)), 3)] for c in certificates],
              "Certificates"),
    )
    for c in certificates:
        section.add(Paragraph(f"{c['claim']} ({c['status']}): {c.get('statement', '')}. {c['detail']}"))
    return section


def build(ctx) -> Section:
    from gpfverify.symbolic.claims import run_claims
    from gpfverify.symbolic.crosscheck import run_crosschecks

    size = "small" if ctx.quick else "large"
    certificates = [c.to_json() for c in run_claims(size) + run_crosschecks(size, seed=ctx.seed)]
    (ctx.section_dir(SLUG) / "certificates.json").write_text(json.dumps(certificates, indent=2), encoding="utf-8")
    return render(certificates, ctx.section_dir(SLUG))
