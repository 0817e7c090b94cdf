"""Claims as data: every verdict of a reproduction is a :class:`ClaimRecord` in ``results.json``
(CONTRACT.md, "Claims as records"), computed by the experiment and rendered by the report.

A record says what is claimed (``claim``, ``paper``, ``source``: section and equation / figure /
table located exactly, ``quote``: the paper's own words), whose claim it is (``kind``: a claim the
paper makes, or a ``"diagnostic"`` — a check of the toolkit's own that the paper does not make), the
verdict, the statistic it rests on and the threshold it was compared with, how many runs (``n``)
against the paper's own count (``paper_n``), the evidence in words, caveats, the health of every
filter it compares (``health``: the checks run of each, :mod:`gpfverify.contract.health_records`),
the group it is counted in (:attr:`ClaimRecord.group`) and — for sensitivity studies — the verdict
under each interpretation tried. Verdicts:

* ``held`` / ``NOT held`` — decided by the statistic against the threshold;
* ``undecided`` — the Monte Carlo interval contains the threshold: more runs would decide;
* ``not decidable`` — the experiment cannot decide it as run: a filter it compares failed a health
  gate (``would_be`` keeps the verdict the runs gave), or the runs did not keep what it needs
  (``needs`` says what).

Every word a page says about a claim — its kind, source, health, the group it is counted in — is
rendered from these fields, never from the text of a caveat.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from gpfverify.contract.health_records import FilterHealth, filter_health
from gpfverify.contract.serial import from_json, to_json
from gpfverify.errors import InputError
from gpfverify.tolerances import MONTE_CARLO_SIGMAS, monte_carlo_atol
from gpfverify.views import HtmlView

Verdict = Literal["held", "NOT held", "undecided", "not decidable"]
VERDICTS: tuple[Verdict, ...] = ("held", "NOT held", "undecided", "not decidable")
#: a claim the paper makes, or a check of the toolkit's own (a comparison the paper does not make)
Kind = Literal["claim", "diagnostic"]


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
#: the group of the paper's claims that are neither a theorem's nor on computation time: the headline
ACCURACY = "accuracy"
#: the group of the claims on computation time that hold by construction of the implementation
#: (more λ-steps take more time): reported, never counted as evidence
BY_CONSTRUCTION = "by construction"
#: the group of the toolkit's own checks, which the paper does not make
DIAGNOSTIC = "diagnostic"
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
    #: "claim": the paper makes it (``quote`` or ``source`` locates where); "diagnostic": the toolkit's own
    kind: Kind = "claim"
    #: the paper's words that make the claim (its language; see docs/claims.md for the conventions)
    quote: str = ""
    #: every filter the verdict compares, with the health checks run of it (none: no checks run)
    health: tuple[FilterHealth, ...] = ()
    #: for a verdict withheld by a failed health gate: the verdict the runs gave
    would_be: Verdict | None = None
    #: why the claim holds by construction of the implementation (a timing claim that measures no
    #: property of the methods): such a verdict is reported and never counted as evidence
    by_construction: str = ""
    #: for a claim the runs could not judge: what a judgement needs that they did not keep
    needs: str = ""
    #: the health gate was applied comparison by comparison (a comparison of filters that failed a
    #: gate withheld, the others deciding), not to the claim as a whole
    parts_gated: bool = False

    def __post_init__(self):
        name = self.id or self.claim
        if self.timing and self.theorem:
            raise InputError(f"claim {name!r}: a claim on computation time checks no theorem")
        if self.would_be is not None and self.verdict != "not decidable":
            raise InputError(f"claim {name!r}: only a withheld ('not decidable') verdict has a 'would_be'")
        if self.needs and self.verdict != "not decidable":
            raise InputError(f"claim {name!r}: a claim the runs could not judge is 'not decidable'")

    @property
    def group(self) -> str:
        """The group the verdict is counted in: :data:`DIAGNOSTIC` for the toolkit's own checks,
        :data:`BY_CONSTRUCTION` for a claim on computation time that holds by construction,
        :data:`TIMING` for the other claims on computation time, the theorem's name for a claim
        checking one, else :data:`ACCURACY` (the headline)."""
        if self.kind == "diagnostic":
            return DIAGNOSTIC
        if self.by_construction:
            return BY_CONSTRUCTION
        return TIMING if self.timing else self.theorem or ACCURACY

    @property
    def gated(self) -> bool:
        """Does a failed health gate of a compared filter withhold the whole verdict? Yes, except for
        a theorem checked step by step from the same prediction (eq. 35 against CMF), which stands
        whatever the filters' health, and a claim gated comparison by comparison (``parts_gated``)."""
        return not self.theorem and not self.parts_gated

    @property
    def failed_filters(self) -> tuple[FilterHealth, ...]:
        """The compared filters that failed a health gate."""
        return tuple(h for h in self.health if h.failed)

    def checked(self, subjects, checks) -> ClaimRecord:
        """This record with the health of the filters it compares (``subjects``, each with its
        checks among ``checks``; :func:`~gpfverify.contract.health_records.filter_health`) and the
        health gate applied: when a compared filter failed a gate, the verdict is withheld
        ("not decidable", the verdict the runs gave kept in ``would_be``) — unless the record is
        not :attr:`gated`."""
        health = filter_health(subjects, checks)
        record = dataclasses.replace(self, health=health)
        if not record.gated or not record.failed_filters or record.verdict == "not decidable":
            return record
        return dataclasses.replace(record, verdict="not decidable", would_be=self.verdict, runs_to_decide=None)

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


@dataclass(frozen=True)
class Statement:
    """Where a claim comes from, as a paper's catalogue of claims states it: ``kind`` (the paper's
    claim or the toolkit's diagnostic), ``source`` (section and figure / table / equation, exactly),
    ``quote`` (the paper's words; empty only where a figure or table alone makes the claim) and, for
    a timing claim that holds by construction of the implementation, why."""

    kind: Kind
    source: str
    quote: str = ""
    by_construction: str = ""

    def __post_init__(self):
        if self.kind == "claim" and not self.quote and not any(w in self.source for w in ("Fig", "Table", "eq.")):
            raise InputError(f"a paper's claim names its sentence (quote) or its figure, table or equation: "
                             f"{self.source!r}")

    def applied(self, record: ClaimRecord) -> ClaimRecord:
        """``record`` said to come from this statement."""
        return dataclasses.replace(record, kind=self.kind, source=self.source, quote=self.quote,
                                   by_construction=self.by_construction)


#: how caveats written by the health gate of earlier versions began; the gate's words are now
#: rendered from a record's health records, so a carried record drops them (:func:`carry`)
_OLD_GATE_CAVEATS = ("health of the filters compared:", "verdict withheld (would be")


def carry(fresh: Iterable[ClaimRecord], stored: Iterable[ClaimRecord],
          summary_fields: Iterable[str] = ()) -> list[ClaimRecord]:
    """The claims of ``fresh`` (what the current code judges from a stored ``results.json`` body)
    with what only the runs could give carried over from ``stored`` (the records of that file,
    judged from the runs when they were made), matched by id:

    * a fresh record that could not be judged from the body (its ``needs`` says why) is replaced by
      the stored record, said to come from the fresh record's statement (kind, source, quote, by
      construction) and re-checked against the fresh record's health records (the gate applied);
      without a stored record it stays as it is ("not decidable", with what it needs);
    * a fresh record judged from the body keeps the stored record's verdicts under the
      interpretations tried (they rest on runs the body does not hold).

    Stored claims the current code no longer makes are dropped. A timing claim keeps no verdict of
    an interpretation that only reads the same runs another way (every parameter it changes is in
    ``summary_fields``): its CPU times are the main run's, so that is one verdict, not another."""
    by_id = {c.id: c for c in stored}
    reads_only = frozenset(summary_fields)
    out = []
    for record in fresh:
        old = by_id.get(record.id)
        if old is None:
            out.append(record)
            continue
        tried = tuple(i for i in old.interpretations
                      if not (record.timing and i.name != AS_RUN and i.params and set(i.params) <= reads_only))
        if record.needs:
            kept = dataclasses.replace(
                old, kind=record.kind, source=record.source, quote=record.quote,
                by_construction=record.by_construction, interpretations=tried,
                caveats=tuple(c for c in old.caveats if not c.startswith(_OLD_GATE_CAVEATS)))
            if kept.verdict == "not decidable" and kept.would_be is None and not kept.needs:
                raise InputError(f"claim {record.id!r}: a stored verdict withheld by the earlier gate cannot be "
                                 "carried (the verdict it would have been is not recorded); make its runs again")
            out.append(kept.checked([h.subject for h in record.health],
                                    [c for h in record.health for c in h.checks]))
        else:
            out.append(dataclasses.replace(record, interpretations=tried))
    return out


def read_claims(results: dict) -> list[ClaimRecord]:
    """The claim records of a ``results.json``: ``"claims"`` and then ``"timing_claims"`` (those
    resting on measured times, kept apart because they differ between executions); an empty list
    when it has none."""
    return [ClaimRecord.from_json(c) for key in ("claims", "timing_claims") for c in results.get(key, [])]


def group_order(groups: Iterable[str]) -> list[str]:
    """Groups in the order a summary shows them: accuracy (the headline), each theorem in order of
    first appearance, timing, timing by construction, the toolkit's diagnostics."""
    seen = list(dict.fromkeys(groups))
    fixed = (ACCURACY, TIMING, BY_CONSTRUCTION, DIAGNOSTIC)
    theorems = [g for g in seen if g not in fixed]
    return [g for g in (ACCURACY, *theorems, *fixed[1:]) if g in seen]


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
        is exactly zero or with fewer than two runs, whose spread is unknown)."""
        if self.verdict != "undecided" or self.atol is None or not np.isfinite(self.atol) or self.mean == 0.0:
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
class Band:
    """Does a quantity lie within [``low``, ``high``] (a two-sided claim: "about 0.5 dB", "similar
    time")? From its estimate ``value`` and Monte Carlo tolerance ``atol``: held when
    [value − atol, value + atol] lies inside the band, NOT held when it lies wholly outside,
    undecided otherwise (a one-sided claim is a band with an infinite side)."""

    verdict: Verdict
    value: float
    atol: float | None
    low: float
    high: float
    n: int

    @property
    def margin(self) -> float:
        """The distance from ``value`` to the nearer edge: positive inside the band, negative outside."""
        return min(self.value - self.low, self.high - self.value)

    @property
    def runs_to_decide(self) -> int | None:
        """For an undecided verdict, the run count at which the same margin would exceed the
        tolerance (the tolerance scales as 1/√n, :attr:`PairedDifference.runs_to_decide`)."""
        if self.verdict != "undecided" or self.atol is None or self.margin == 0.0:
            return None
        return int(np.ceil(self.n * (self.atol / abs(self.margin)) ** 2))

    @classmethod
    def of(cls, value: float, atol: float | None, low: float, high: float, n: int) -> Band:
        if not low < high:
            raise ValueError(f"a band needs low < high, got [{low}, {high}]")
        margin = min(value - low, high - value)
        held = None if atol is None else True if margin > atol else False if margin < -atol else None
        return cls(verdict_of(held), float(value), atol, float(low), float(high), int(n))


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

    def within(self, low: float, high: float) -> Band:
        """The ratio judged two-sided: is it between ``low`` and ``high`` (on the log scale, with the
        same tolerance as the one-sided verdict)? :class:`Band` of log(ratio)."""
        centre = float(np.log(self.ratio)) if np.isfinite(self.ratio) and self.ratio > 0 else float("nan")
        return Band.of(centre, self.log_difference.atol, float(np.log(low)), float(np.log(high)), self.n)

    def evidence(self, a: str, b: str) -> str:
        """The ratio in words: "A / B = 0.82 (geometric mean of 1000 paired per-run ratios; [0.80, 0.84] at 5
        standard errors of the log ratio), held below 1, NOT held above it"."""
        interval = ("no interval (fewer than two runs)" if self.log_difference.atol is None else
                    f"[{self.low:.3g}, {self.high:.3g}] at {MONTE_CARLO_SIGMAS:g} standard errors of the log ratio")
        dropped = f"; {self.dropped} run(s) left out: a time below the clock's resolution" if self.dropped else ""
        return (f"CPU time per run {a} / {b} = {self.ratio:.3g} (geometric mean of {self.n} paired per-run ratios; "
                f"{interval}{dropped}; held when the interval lies below {self.bound:g}, NOT held when above it, "
                "undecided otherwise)")
