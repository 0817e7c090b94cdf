"""The words a page says about a claim, each rendered from a field of its record
(:class:`~gpfverify.contract.claims.ClaimRecord`), never from the text of a caveat: where the claim
comes from (``kind``, ``source``, ``quote``), how its verdict came about (``would_be``,
``by_construction``, ``needs``) and the health of the filters it compares (``health``: gates and
consistency findings apart, :mod:`gpfverify.contract.health_records`).
"""

from __future__ import annotations

from collections.abc import Sequence

from gpfverify.contract.claims import ClaimRecord
from gpfverify.contract.health_records import HealthCheck

#: what a record with no health records says: nothing was checked, which is not "none failed"
NO_CHECKS = "no checks run"


def source_words(record: ClaimRecord) -> str:
    """Where the claim comes from: the paper's words quoted and their place, or — for a diagnostic —
    that the paper does not make it."""
    if record.kind == "diagnostic":
        return f"diagnostic (not a claim of the paper): {record.source}"
    return f"{record.source}: “{record.quote}”" if record.quote else record.source


def verdict_note(record: ClaimRecord) -> str:
    """How the verdict came about when it is not simply the runs' decision: withheld by a health
    gate (with the verdict the runs gave), not judged for want of data, or true by construction."""
    notes = []
    if record.would_be is not None:
        failed = ", ".join(f"{h.subject} ({', '.join(c.name for c in h.failed)})" for h in record.failed_filters)
        notes.append(f"withheld: the runs gave '{record.would_be}', but {failed} failed a health gate")
    if record.needs:
        notes.append(f"not judged: needs {record.needs}")
    if record.by_construction:
        notes.append(f"holds by construction ({record.by_construction}): reported, not counted as evidence")
    return "; ".join(notes)


def _names(checks: Sequence[HealthCheck]) -> str:
    return ", ".join(dict.fromkeys(c.name for c in checks))


def health_words(record: ClaimRecord) -> str:
    """The health of the filters the claim compares, from its records: the filters that failed a
    gate (with the check's numbers), those that passed every gate (counted, with the checks' names),
    those with no checks run, and apart the consistency findings (NEES within or outside its χ²
    band, with the mean ANEES; the counts behind each are in the check's detail, on the page's
    health table)."""
    if not record.health:
        return NO_CHECKS
    failed = [h for h in record.health if h.failed]
    passed = [h for h in record.health if h.gates and not h.failed]
    no_gates = [h for h in record.health if h.checks and not h.gates]
    unchecked = [h for h in record.health if not h.checks]
    parts = [f"{h.subject}: FAILED {c.name} — {c.detail}" for h in failed for c in h.failed]
    if passed:
        count = (f"all {len(passed)} compared filters" if len(passed) == len(record.health) else
                 f"{len(passed)} of the {len(record.health)} compared filters")
        parts.append(f"{count} passed every health gate ({_names([c for h in passed for c in h.gates])}): "
                     + ", ".join(h.subject for h in passed))
    if no_gates:
        parts.append("no health gate run of " + ", ".join(h.subject for h in no_gates))
    if unchecked:
        parts.append(f"{NO_CHECKS} of " + ", ".join(h.subject for h in unchecked))
    outside = [(h, c) for h in record.health for c in h.consistency if not c.passed]
    within = [h.subject for h in record.health for c in h.consistency if c.passed]
    if outside or within:
        said = []
        if outside:
            said.append("outside for " + ", ".join(f"{h.subject} (mean ANEES {c.statistic:.3g}, {c.threshold:g} "
                                                   "expected)" for h, c in outside))
        if within:
            said.append("within for " + ", ".join(within))
        parts.append("consistency, not a gate (the ANEES of each step against its χ² band, outside when too many steps "
                     "fall above or below it, whatever the mean): " + "; ".join(said))
    if failed and record.parts_gated:
        parts.append("the gate withheld each comparison of a filter that failed it; the others decided")
    elif failed and not record.gated:
        parts.append("the gates do not withhold this verdict (a theorem checked step by step from the same "
                     "prediction)")
    return "; ".join(parts)


def health_summary(record: ClaimRecord) -> str:
    """One short phrase for a claim's health: "no checks run", "a compared filter failed a health
    gate", or "every compared filter passed its health gates" (with the consistency findings
    counted apart)."""
    if not record.health:
        return NO_CHECKS
    if record.failed_filters:
        return "a compared filter failed a health gate"
    if any(not h.checks for h in record.health):
        return f"{NO_CHECKS} for some compared filters, no gate failed among the others"
    outside = sum(1 for h in record.health for c in h.consistency if not c.passed)
    return ("every compared filter passed its health gates"
            + (f"; {outside} NEES finding{'s' if outside != 1 else ''} outside the χ² band (consistency, not a "
               "gate)" if outside else ""))
