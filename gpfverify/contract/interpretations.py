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

from gpfverify.contract.claims import ClaimRecord


@dataclass(frozen=True)
class InterpretationSpec:
    """A named reading of the paper: ``changes`` maps ``Params`` field names to values."""

    name: str
    changes: dict[str, Any]
    why: str


def robustness(claim: ClaimRecord) -> str:
    """The verdict across the main run and the interpretations tried, in words ("" when none was
    tried)."""
    if not claim.interpretations:
        return ""
    verdicts = [claim.verdict, *(i.verdict for i in claim.interpretations)]
    tried = len(verdicts)
    if len(set(verdicts)) == 1:
        return f"{claim.verdict} under all {tried} interpretations tried"
    groups: dict[str, list[str]] = {}
    for name, verdict in (("as run", claim.verdict), *((i.name, i.verdict) for i in claim.interpretations)):
        groups.setdefault(verdict, []).append(name)
    return "depends on the interpretation: " + "; ".join(
        f"{verdict} under {', '.join(names)}" for verdict, names in groups.items())
