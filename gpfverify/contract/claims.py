"""Claims as data: every verdict of a reproduction is a :class:`ClaimRecord` in ``results.json``
(CONTRACT.md, "Claims as records"), computed by the experiment and rendered by the report.

A record says what the paper claims (``claim``, ``paper``, ``source``: equation / figure /
table), the verdict, the statistic it rests on and the threshold it was compared with, how many
runs (``n``) against the paper's own count (``paper_n``), the evidence in words, caveats, whether
it rests on wall-clock timing, and — for sensitivity studies — the verdict under each
interpretation tried. Verdicts:

* ``held`` / ``NOT held`` — decided by the statistic against the threshold;
* ``undecided`` — the Monte Carlo interval contains the threshold: more runs would decide;
* ``not decidable`` — the experiment cannot decide it as run (e.g. the filter failed its health
  checks, or the setting the claim needs is not in this profile).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from gpfverify.contract.serial import from_json, to_json
from gpfverify.tolerances import MONTE_CARLO_SIGMAS, monte_carlo_atol

Verdict = Literal["held", "NOT held", "undecided", "not decidable"]
VERDICTS: tuple[Verdict, ...] = ("held", "NOT held", "undecided", "not decidable")


def verdict_of(held: bool | None) -> Verdict:
    """True -> held, False -> NOT held, None -> undecided."""
    return "undecided" if held is None else "held" if held else "NOT held"


def combine(verdicts: list[Verdict]) -> Verdict:
    """A claim made of parts: NOT held if any part is, held if all are, else undecided (or not
    decidable when a part is)."""
    if "NOT held" in verdicts:
        return "NOT held"
    if "not decidable" in verdicts:
        return "not decidable"
    return "held" if verdicts and all(v == "held" for v in verdicts) else "undecided"


#: the name of the entry holding the claim's verdict as run on the interpretations' run count
#: (its first n runs, the same seeds), when the main run has more runs than they do
AS_RUN = "as run"


@dataclass(frozen=True)
class Interpretation:
    """The claim's verdict under one interpretation of an unstated or lost detail, on ``n`` runs
    (None: as many as the main run). The entry named :data:`AS_RUN` (``params`` empty) is no
    interpretation: it is the verdict as run on the first ``n`` runs, what the interpretations run
    on fewer runs than the main run are compared with."""

    name: str
    params: dict[str, Any]
    verdict: Verdict
    statistic: float | None
    n: int | None = None
    #: for an undecided verdict, about how many runs would decide it under this interpretation
    runs_to_decide: int | None = None


@dataclass(frozen=True)
class ClaimRecord:
    """One checked claim (see the module docstring). ``statistic`` and ``threshold`` are in the
    unit the evidence states; ``statistic`` is None only when nothing was measured."""

    claim: str
    source: str
    verdict: Verdict
    statistic: float | None
    threshold: float | None
    n: int
    evidence: str
    caveats: tuple[str, ...] = ()
    interpretations: tuple[Interpretation, ...] = ()
    #: stable identifier, "experiment/slug" (e.g. "ct2d/dmf-equals-cmf/GP-ADF")
    id: str = ""
    #: the paper, a key of gpfverify.contract.papers.PAPERS
    paper: str = ""
    #: the experiment setting the verdict belongs to ("κ = 300, Ω = 2π/90"), "" for one setting
    setting: str = ""
    #: the paper's own run count for this claim, when it states one
    paper_n: int | None = None
    #: the verdict compares wall-clock times (which depend on the machine and its load)
    timing: bool = False
    #: for an undecided Monte Carlo verdict: about how many runs would decide it, were the
    #: observed mean and spread the true ones (:attr:`PairedDifference.runs_to_decide`)
    runs_to_decide: int | None = None

    def to_json(self) -> dict[str, Any]:
        return to_json(self)

    @classmethod
    def from_json(cls, data: Any) -> ClaimRecord:
        return from_json(cls, data, "claim")

    def _repr_html_(self) -> str:
        """In a notebook: the report's claims table with this record (:func:`gpfverify.notebook.claims_html`)."""
        from gpfverify.notebook import claims_html

        return claims_html([self])

    @property
    def cautions(self) -> list[str]:
        """Why a reader should hold this verdict loosely: fewer runs than the paper, wall-clock."""
        out = []
        if self.paper_n is not None and self.n < self.paper_n:
            out.append(f"rests on {self.n} run{'s' if self.n != 1 else ''}; the paper used {self.paper_n}")
        if self.timing:
            out.append("rests on wall-clock timing, which depends on the machine and its load")
        return out


def read_claims(results: dict) -> list[ClaimRecord]:
    """The claim records of a ``results.json``: ``"claims"`` and then ``"timing_claims"`` (those
    resting on wall-clock times, kept apart because they differ between executions); an empty
    list when it has none."""
    return [ClaimRecord.from_json(c) for key in ("claims", "timing_claims") for c in results.get(key, [])]


@dataclass(frozen=True)
class PairedDifference:
    """Is method A's per-run error below method B's? d = a − b over runs (paired): held if
    mean(d) < −atol, NOT held if mean(d) > atol, undecided otherwise, with atol =
    :func:`~gpfverify.tolerances.monte_carlo_atol` (std d, runs)."""

    verdict: Verdict
    mean: float
    atol: float | None  # None with fewer than two runs
    n: int

    @property
    def runs_to_decide(self) -> int | None:
        """For an undecided verdict, the run count n' at which the same mean would lie outside
        ±atol: atol scales as 1/√n, so n' = ⌈n (atol / |mean|)²⌉ (None when decided, when the mean
        is exactly zero or with fewer than two runs)."""
        if self.verdict != "undecided" or self.atol is None or self.mean == 0.0:
            return None
        return int(np.ceil(self.n * (self.atol / abs(self.mean)) ** 2))

    @classmethod
    def of(cls, a: Any, b: Any) -> PairedDifference:
        d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
        if d.size < 2:
            return cls("undecided", float(np.mean(d)) if d.size else 0.0, None, int(d.size))
        atol = float(monte_carlo_atol(np.std(d, ddof=1), d.size))
        mean = float(np.mean(d))
        held = True if mean < -atol else False if mean > atol else None
        return cls(verdict_of(held), mean, atol, int(d.size))


def paired_evidence(d: PairedDifference, unit: str = "") -> str:
    """A paired difference in words: "+0.012 s ± 0.004 (5 standard errors, 60 runs)"."""
    unit = f" {unit}" if unit else ""
    spread = "no standard error (fewer than two runs)" if d.atol is None else \
        f"± {d.atol:.2g}{unit} ({MONTE_CARLO_SIGMAS:g} standard errors, {d.n} runs)"
    return f"{d.mean:+.3g}{unit} {spread}"
