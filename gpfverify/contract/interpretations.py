"""Interpretations of what a paper leaves unstated or lost, as named parameter changes of an
experiment, and how robust a claim's verdict is across them.

An experiment's contract module may declare ``INTERPRETATIONS``: a tuple of
:class:`InterpretationSpec` (a name, the ``Params`` fields it changes, and why it is a plausible
reading of the paper). ``gpfverify reproduce NAME --interpretations all`` runs the experiment once
per interpretation next to the main run and records, in every claim of the main ``results.json``,
the verdict and statistic under each (:class:`~gpfverify.contract.claims.Interpretation`).
:func:`robustness` says it in words: "NOT held under all 6 interpretations tried" is a finding,
"held only under Q inflated 100×" is another.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from gpfverify.contract.claims import AS_RUN, ClaimRecord, Interpretation, Verdict


@dataclass(frozen=True)
class InterpretationSpec:
    """A named reading of the paper: ``changes`` maps ``Params`` field names to values.
    ``bears_on``: the claim ids (or '/'-ended prefixes of them) the reading is about — a reading of
    one figure's model says nothing about the claims of another figure whose setting it leaves as
    run; empty: every claim."""

    name: str
    changes: dict[str, Any]
    why: str
    bears_on: tuple[str, ...] = ()

    def bears_on_claim(self, claim_id: str | None) -> bool:
        """Is a claim with this id compared under this reading?"""
        return not self.bears_on or any(claim_id == b or (b.endswith("/") and (claim_id or "").startswith(b))
                                        for b in self.bears_on)


def _groups(claim: ClaimRecord) -> list[tuple[int | None, Verdict, list[Interpretation]]]:
    """The interpretations tried, grouped by run count, each with the verdict as run on the same
    count (the claim's own when the counts agree, else its :data:`AS_RUN` entry at that count, else
    the claim's own at its larger count)."""
    tried = [i for i in claim.interpretations if i.name != AS_RUN]
    baselines = {i.n: i.verdict for i in claim.interpretations if i.name == AS_RUN}
    by_count: dict[int | None, list[Interpretation]] = {}
    for i in tried:
        by_count.setdefault(None if i.n in (None, claim.n) else i.n, []).append(i)
    return [(n, claim.verdict if n is None else baselines.get(n, claim.verdict), entries)
            for n, entries in by_count.items()]


def is_robust(claim: ClaimRecord) -> bool:
    """The verdict is the same as run and under every interpretation tried, each compared on the
    same number of runs (see :func:`robustness`)."""
    return all(all(i.verdict == baseline for i in entries) for _, baseline, entries in _groups(claim))


def robustness(claim: ClaimRecord) -> str:
    """The verdict across the main run and the interpretations tried, in words ("" when none was
    tried). Interpretations run on fewer runs than the main run are compared with the verdict as run
    on that many runs (their :data:`AS_RUN` entry): "at 60 runs each: undecided under all 6 readings;
    as run at 1000 runs: held" — not with a verdict that more runs decided. The interpretations run
    as long as the main run come first, then those on fewer runs by run count, and the verdict as
    run on all its runs closes the sentence once."""
    parts = []
    compared_on_fewer = False
    groups = sorted(_groups(claim), key=lambda group: (group[0] is not None, group[0] or 0))
    for n, baseline, entries in groups:
        readings = [("as run", baseline), *((i.name, i.verdict) for i in entries)]
        if len({v for _, v in readings}) == 1:
            said = f"{baseline} under all {len(readings)} interpretations tried"
        else:
            by_verdict: dict[str, list[str]] = {}
            for name, verdict in readings:
                by_verdict.setdefault(verdict, []).append(name)
            said = "depends on the interpretation: " + "; ".join(
                f"{verdict} under {', '.join(names)}" for verdict, names in by_verdict.items())
        if n is not None:
            if any(i.name == AS_RUN and i.n == n for i in claim.interpretations):
                said = f"at {n} runs each: {said}"
                compared_on_fewer = True
            else:
                said = f"{said} (the interpretations at {n} runs, as run at {claim.n})"
        parts.append(said)
    if compared_on_fewer:
        parts.append(f"as run at {claim.n} runs: {claim.verdict}")
    return "; ".join(parts)
