"""Claims as data: every verdict of a reproduction is a :class:`ClaimRecord` in ``results.json``
(CONTRACT.md, "Claims as records"), computed by the experiment and rendered by the report.

A record says what the paper claims (``claim``, ``paper``, ``source``: equation / figure /
table), the verdict, the statistic it rests on and the threshold it was compared with, how many
runs (``n``) against the paper's own count (``paper_n``), the evidence in words, caveats, the
group it is counted in (:attr:`ClaimRecord.group`: the paper's accuracy claims — the headline —, a
theorem of the paper checked on the runs, or computation time), and — for sensitivity studies —
the verdict under each interpretation tried. Verdicts:

* ``held`` / ``NOT held`` — decided by the statistic against the threshold;
* ``undecided`` — the Monte Carlo interval contains the threshold: more runs would decide;
* ``not decidable`` — the experiment cannot decide it as run (e.g. the filter failed its health
  checks, or the setting the claim needs is not in this profile).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from gpfverify.contract.serial import from_json, to_json
from gpfverify.errors import InputError
from gpfverify.tolerances import MONTE_CARLO_SIGMAS, monte_carlo_atol
from gpfverify.views import HtmlView

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


#: the group of the claims on computation time (CPU times compared as paired per-run ratios)
TIMING = "timing"
#: the group of every claim that is neither a theorem's nor on computation time: the headline
ACCURACY = "accuracy"
#: the fusion paper's theorem: DMF (eq. 35) equals CMF when every C_xy^m has full column rank
PROPOSITION_1 = "Proposition 1"


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
class ClaimRecord(HtmlView):
    """One checked claim (see the module docstring). ``statistic`` and ``threshold`` are in the
    unit the evidence states; ``statistic`` is None only when nothing was measured. In a notebook it
    shows as the report's claims table with this record (:func:`gpfverify.notebook.claims_html`)."""

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
    #: the verdict compares computation times (CPU times measured on the machine that made the runs)
    timing: bool = False
    #: for an undecided Monte Carlo verdict: about how many runs would decide it, were the
    #: observed mean and spread the true ones (:attr:`PairedDifference.runs_to_decide`)
    runs_to_decide: int | None = None
    #: the paper's theorem the claim checks on the runs (:data:`PROPOSITION_1`), "" for an empirical claim
    theorem: str = ""

    def __post_init__(self):
        if self.timing and self.theorem:
            raise InputError(f"claim {self.id or self.claim!r}: a claim on computation time checks no theorem")

    @property
    def group(self) -> str:
        """The group the verdict is counted in: :data:`TIMING` for a claim on computation time, the
        theorem's name for a claim checking one, else :data:`ACCURACY` (the headline)."""
        return TIMING if self.timing else self.theorem or ACCURACY

    def to_json(self) -> dict[str, Any]:
        return to_json(self)

    @classmethod
    def from_json(cls, data: Any) -> ClaimRecord:
        return from_json(cls, data, "claim")

    @property
    def cautions(self) -> list[str]:
        """Why a reader should hold this verdict loosely: fewer runs than the paper, wall-clock."""
        out = []
        if self.paper_n is not None and self.n < self.paper_n:
            out.append(f"rests on {self.n} run{'s' if self.n != 1 else ''}; the paper used {self.paper_n}")
        if self.timing:
            out.append("rests on CPU times measured on one machine, which depend on the machine (and a little on its "
                       "load, recorded with the runs)")
        return out


def read_claims(results: dict) -> list[ClaimRecord]:
    """The claim records of a ``results.json``: ``"claims"`` and then ``"timing_claims"`` (those
    resting on measured times, kept apart because they differ between executions); an empty list
    when it has none."""
    return [ClaimRecord.from_json(c) for key in ("claims", "timing_claims") for c in results.get(key, [])]


def group_order(groups: Iterable[str]) -> list[str]:
    """Groups in the order a summary shows them: accuracy (the headline), each theorem in order of
    first appearance, timing."""
    seen = list(dict.fromkeys(groups))
    theorems = [g for g in seen if g not in (ACCURACY, TIMING)]
    return [g for g in (ACCURACY, *theorems, TIMING) if g in seen]


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


@dataclass(frozen=True)
class PairedRatio:
    """Does method A cost at most ``bound`` times what method B costs? Each run measures both (the
    same data, the same process, interleaved), so its ratio r = a / b is paired; the ratios are
    compared on the log scale, d = log r − log bound, by the paired rule of :class:`PairedDifference`
    (held when mean(d) < −atol, NOT held when mean(d) > atol, undecided in between). ``ratio`` is the
    geometric mean of the per-run ratios, [``low``, ``high``] = exp(mean(log r) ∓ atol). A ratio,
    unlike a difference of seconds, does not move when the machine runs a whole run slower (a
    busier or a slower machine). Runs in which a time is not positive (below the clock's resolution)
    are left out and counted in ``dropped``."""

    verdict: Verdict
    ratio: float
    low: float
    high: float
    bound: float
    log_difference: PairedDifference
    dropped: int = 0

    @property
    def n(self) -> int:
        return self.log_difference.n

    @property
    def runs_to_decide(self) -> int | None:
        """For an undecided verdict, about how many runs would decide it (on the log scale, as
        :attr:`PairedDifference.runs_to_decide`)."""
        return self.log_difference.runs_to_decide

    @classmethod
    def of(cls, a: Any, b: Any, bound: float = 1.0) -> PairedRatio:
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        if a.shape != b.shape or bound <= 0:
            raise ValueError(f"paired times need equal shapes and a positive bound, got {a.shape}, {b.shape}, {bound}")
        kept = (a > 0) & (b > 0)
        log_ratio = np.log(a[kept]) - np.log(b[kept])
        d = PairedDifference.of(log_ratio - np.log(bound), np.zeros(log_ratio.size))
        centre = float(np.mean(log_ratio)) if log_ratio.size else float("nan")
        spread = np.inf if d.atol is None else d.atol
        return cls(d.verdict, float(np.exp(centre)), float(np.exp(centre - spread)), float(np.exp(centre + spread)),
                   float(bound), d, int(np.sum(~kept)))

    def evidence(self, a: str, b: str) -> str:
        """The ratio in words: "A / B = 0.82 (geometric mean of 1000 paired per-run ratios; [0.80, 0.84] at 5
        standard errors of the log ratio), held below 1, NOT held above it"."""
        interval = ("no interval (fewer than two runs)" if self.log_difference.atol is None else
                    f"[{self.low:.3g}, {self.high:.3g}] at {MONTE_CARLO_SIGMAS:g} standard errors of the log ratio")
        dropped = f"; {self.dropped} run(s) left out: a time below the clock's resolution" if self.dropped else ""
        return (f"CPU time per run {a} / {b} = {self.ratio:.3g} (geometric mean of {self.n} paired per-run ratios; "
                f"{interval}{dropped}; held when the interval lies below {self.bound:g}, NOT held when above it, "
                "undecided otherwise)")
