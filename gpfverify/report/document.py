"""A tiny document model for report pages, rendered to Markdown and to self-contained HTML.

Sections are built from data (``results.json`` and verification numbers), never from prose
templates with numbers pasted in.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from gpfverify.contract.claims import AS_RUN, ClaimRecord, group_order
from gpfverify.contract.interpretations import robustness


@dataclass(frozen=True)
class Paragraph:
    text: str


@dataclass(frozen=True)
class Table:
    """Rows of cells: plain values (numbers formatted with :func:`fmt`), or :class:`Cell`,
    :class:`VerdictCell` and :class:`Link` for colour, cautions and links. ``row_ids`` (optional,
    one per row, "" for none) become HTML anchors; ``css`` is the table's HTML class."""

    headers: list[str]
    rows: list[list]
    caption: str = ""
    row_ids: tuple[str, ...] = ()
    css: str = ""


@dataclass(frozen=True)
class Cell:
    """A table cell with an HTML class (colour) and a tooltip; Markdown shows the value alone."""

    value: object
    css: str = ""
    title: str = ""


class VerdictCell(str):
    """A verdict ("held", "NOT held", "undecided", "not decidable", or a certificate status
    "proved", "refuted", "checked"), coloured in HTML, with the reasons to hold it loosely
    (:attr:`gpfverify.contract.ClaimRecord.cautions`) shown as one caution mark. It is the
    verdict's string (``VerdictCell("held") == "held"``), so tables compare as before."""

    cautions: tuple[str, ...]

    def __new__(cls, verdict: str, cautions: tuple[str, ...] | list[str] = ()) -> VerdictCell:
        cell = super().__new__(cls, verdict)
        cell.cautions = tuple(cautions)
        return cell

    @property
    def verdict(self) -> str:
        return str(self)

    def __repr__(self) -> str:
        return f"VerdictCell({str(self)!r}, {self.cautions!r})"


@dataclass(frozen=True)
class Link:
    """A link to another place of the report: ``slug`` (a section) and an optional ``anchor``
    inside the HTML page; Markdown links to the section's page."""

    text: str
    slug: str
    anchor: str = ""


#: verdict or status -> HTML class (colours in :mod:`gpfverify.report.render`)
VERDICT_CLASSES = {"held": "v-held", "NOT held": "v-not-held", "undecided": "v-undecided",
                   "not decidable": "v-not-decidable", "proved": "v-proved", "refuted": "v-refuted",
                   "checked": "v-checked"}
#: the warning sign that marks a caution, on the page and in Markdown
CAUTION_MARK = "\u26a0"


def anchor_id(text: str) -> str:
    """``text`` as an HTML id: its letters and digits (Greek ones too, so that κ = 30 and κ = 300 stay
    apart), '_', and '-' for every run of anything else."""
    return re.sub(r"[^\w-]+", "-", text).strip("-") or "x"


@dataclass(frozen=True)
class Figure:
    path: Path  # a PNG inside the report folder
    caption: str


@dataclass(frozen=True)
class Code:
    text: str


@dataclass(frozen=True)
class Details:
    """Long text a reader opens on demand (HTML ``<details>``; Markdown: a bold line and the text)."""

    summary: str
    text: str


@dataclass(frozen=True)
class Chips:
    """A row of small coloured marks, one per verdict, each linking to its claim's row (the
    summary table); Markdown shows ``text`` instead."""

    chips: tuple[tuple[str, str, str, bool], ...]  # (verdict, tooltip, anchor, cautioned)
    text: str = ""


@dataclass(frozen=True)
class Claim:
    """One claim of a paper checked against our numbers: ``held`` is True, False, or None when
    the run was too small to decide."""

    claim: str
    held: bool | None
    evidence: str


#: words by which a claim's caveat reports a failed health check (divergence, NEES, particle degeneracy)
HEALTH_WORDS = ("health", "NEES", "diverge", "N_eff")


def not_held_note(record: ClaimRecord) -> str:
    """What a NOT held verdict is read with: the interpretations it was tried under
    (:func:`~gpfverify.contract.interpretations.robustness`) and the health of the filters it
    compares (whether its caveats report a failed check)."""
    tried = robustness(record) or "no other documented reading was tried"
    failed = any(word in caveat for caveat in record.caveats for word in HEALTH_WORDS)
    health = ("a failed health check of the filters compared is among its caveats" if failed else
              "no failed health check is recorded for the filters compared" if record.group != "timing" else
              "a claim on CPU times, which no filter health gates")
    return f"NOT held — interpretations tried: {tried}; health: {health}"


def claim_records_table(records, caption: str = "Claims checked") -> Table:
    """Claim records (:class:`gpfverify.contract.ClaimRecord`, as stored in ``results.json``) as a
    table: claim, where the paper makes it, verdict (coloured, with one caution mark when it rests
    on fewer runs than the paper or on measured times), evidence and the record's caveats — for a
    NOT held verdict also the interpretations it was tried under and the health of the filters it
    compares (:func:`not_held_note`). Rows are anchored by the record's ``id`` so that the summary
    links to them."""
    rows, ids = [], []
    for r in records:
        evidence = r.evidence
        if r.verdict == "undecided" and r.runs_to_decide:
            evidence += (f" About {r.runs_to_decide} runs would decide it, were the mean and spread seen "
                         "here the true ones.")
        notes = [*r.caveats, *((not_held_note(r),) if r.verdict == "NOT held" else ())]
        rows.append([r.claim + (f" ({r.setting})" if r.setting else ""), r.source,
                     VerdictCell(r.verdict, tuple(r.cautions)), evidence, "; ".join(notes)])
        ids.append(claim_anchor(r))
    headers = ["claim", "source", "verdict", "evidence", "caveats"]
    if not any(row[-1] for row in rows):  # no empty column
        headers, rows = headers[:-1], [row[:-1] for row in rows]
    return Table(headers, rows, caption, tuple(ids), "claims")


#: what each group's table says under its caption
GROUP_WORDS = {"accuracy": "accuracy and behaviour (the headline)",
               "timing": "computation time: CPU times of the methods compared as paired per-run ratios, counted "
                         "apart from the accuracy claims"}


def claim_tables(records, caption: str = "Claims checked") -> list[Table]:
    """Claim records as one :func:`claim_records_table` per group (accuracy, each theorem checked on
    the runs, timing; :attr:`~gpfverify.contract.claims.ClaimRecord.group`), so that a page shows
    them apart as its summary counts them; one table with ``caption`` alone when every record is an
    accuracy claim."""
    groups = group_order(r.group for r in records)
    if groups in ([], ["accuracy"]):
        return [claim_records_table(records, caption)]
    return [claim_records_table([r for r in records if r.group == g],
                                f"{caption} — {GROUP_WORDS.get(g, f'{g}, the theorem checked on the runs')}")
            for g in groups]


def claim_anchor(record) -> str:
    """The HTML id of a claim record's row: its ``id`` (else its claim) and its setting, for a page
    shows the same claim once per setting (ct2d at κ = 30 and at κ = 300)."""
    return "claim-" + anchor_id("-".join(part for part in (record.id or record.claim, record.setting) if part))


def claims_table(claims: list[Claim], caption: str = "Claims checked") -> Table:
    verdict = {True: "held", False: "NOT held", None: "undecided"}
    return Table(["claim", "verdict", "evidence"],
                 [[c.claim, VerdictCell(verdict[c.held]), c.evidence] for c in claims], caption, css="claims")


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


def integer_ranges(values, dash: str = "–", limit: int | None = None) -> str:
    """Sorted integers as ranges: [1, 2, 3, 7] -> '1–3, 7' (step indices in report text). With
    ``limit``, at most that many ranges, then '…' and how many integers there are in all (read
    lazily: ``values`` may be a long sequence that is never held as a list)."""
    parts: list[str] = []
    start = previous = None
    for v in map(int, values):
        if previous is not None and v != previous + 1:
            parts.append(str(start) if start == previous else f"{start}{dash}{previous}")
            start = None
            if limit is not None and len(parts) == limit:
                return ", ".join(parts) + f", … ({len(values)} in all)"
        if start is None:
            start = v
        previous = v
    if previous is not None:
        parts.append(str(start) if start == previous else f"{start}{dash}{previous}")
    return ", ".join(parts)


# ---- maths as Unicode ------------------------------------------------------------------------------

_SUB = dict(zip("0123456789+-=()aehijklmnoprstuvx", "₀₁₂₃₄₅₆₇₈₉₊₋₌₍₎ₐₑₕᵢⱼₖₗₘₙₒₚᵣₛₜᵤᵥₓ"))
_SUP = dict(zip("0123456789+-=()T", "⁰¹²³⁴⁵⁶⁷⁸⁹⁺⁻⁼⁽⁾ᵀ"))
_SUP.update(zip("abcdefghijklmnoprstuvwxyz", "ᵃᵇᶜᵈᵉᶠᵍʰⁱʲᵏˡᵐⁿᵒᵖʳˢᵗᵘᵛʷˣʸᶻ"))
_SUP["−"] = "⁻"
_SUB["−"] = "₋"
_COMMANDS = {
    "alpha": "α", "beta": "β", "gamma": "γ", "delta": "δ", "epsilon": "ε", "varepsilon": "ε", "zeta": "ζ",
    "eta": "η", "theta": "θ", "kappa": "κ", "lambda": "λ", "mu": "μ", "nu": "ν", "xi": "ξ", "pi": "π",
    "rho": "ρ", "sigma": "σ", "tau": "τ", "phi": "φ", "varphi": "φ", "chi": "χ", "psi": "ψ", "omega": "ω",
    "Gamma": "Γ", "Delta": "Δ", "Theta": "Θ", "Lambda": "Λ", "Xi": "Ξ", "Pi": "Π", "Sigma": "Σ", "Phi": "Φ",
    "Psi": "Ψ", "Omega": "Ω", "sum": "Σ", "prod": "Π", "int": "∫", "partial": "∂", "nabla": "∇",
    "le": "≤", "leq": "≤", "ge": "≥", "geq": "≥", "ne": "≠", "neq": "≠", "approx": "≈", "sim": "~",
    "times": "×", "cdot": "·", "pm": "±", "in": "∈", "infty": "∞", "to": "→", "rightarrow": "→",
    "mapsto": "↦", "sqrt": "√", "top": "ᵀ", "|": "‖", "ldots": "…", "dots": "…", "otimes": "⊗",
    "subseteq": "⊆", "propto": "∝",
}
_BLACKBOARD = {"R": "ℝ", "N": "ℕ", "Z": "ℤ", "Q": "ℚ", "C": "ℂ", "E": "𝔼"}


def _script(text: str, table: dict[str, str], marker: str) -> str:
    if all(ch in table for ch in text):
        return "".join(table[ch] for ch in text)
    return f"{marker}({text})" if len(text) > 1 else f"{marker}{text}"


def unicode_math(text: str) -> str:
    """Pseudo-LaTeX in report text as Unicode, legible offline without a maths renderer:
    ``x_{k+1}`` → xₖ₊₁, ``C^{-1}`` → C⁻¹, ``A^T`` → Aᵀ, ``\\sigma^2`` → σ², ``\\Sigma`` → Σ,
    ``\\le`` → ≤, ``\\mathbb{R}`` → ℝ, ``C_y^m`` → C_yᵐ. Only braced scripts (``_{...}``,
    ``^{...}``), one-character superscripts and backslash commands are converted, so identifiers such as
    ``results_json`` (and the readable ``P_m``) are left alone; a script with a character that
    Unicode has no sub/superscript for stays readable as ``C_(xy)``."""
    if "\\" not in text and "_{" not in text and "^" not in text:
        return text
    text = re.sub(r"\\mathbb\{(\w)\}", lambda m: _BLACKBOARD.get(m.group(1), m.group(1)), text)
    text = re.sub(r"\\(?:mathrm|text|mathbf|operatorname)\{([^{}]*)\}", r"\1", text)
    text = re.sub(r"\\([A-Za-z]+|\|)", lambda m: _COMMANDS.get(m.group(1), m.group(0)), text)
    text = re.sub(r"_\{([^{}]*)\}", lambda m: _script(m.group(1).replace(" ", ""), _SUB, "_"), text)
    text = re.sub(r"\^\{([^{}]*)\}", lambda m: _script(m.group(1).replace(" ", ""), _SUP, "^"), text)
    return re.sub(r"\^([0-9Ta-pr-z])(?![0-9A-Za-z])", lambda m: _SUP[m.group(1)], text)


def interpretations_table(claims: Sequence[ClaimRecord], caption: str) -> Table | None:
    """Per claim: the verdict as run and under each interpretation tried (with its statistic), the
    robustness sentence and, for undecided verdicts, the runs that would decide; None when no claim
    was run under an interpretation."""
    tried = [c for c in claims if c.interpretations]
    if not tried:
        return None
    names = list(dict.fromkeys(i.name for c in tried for i in c.interpretations))
    if AS_RUN in names:  # the verdict as run on the interpretations' run count, next to the main one
        names.insert(0, names.pop(names.index(AS_RUN)))
    rows = []
    for c in tried:
        by_name = {i.name: i for i in c.interpretations}
        cells: list = [c.claim + (f" ({c.setting})" if c.setting else ""),
                       VerdictCell(c.verdict, tuple(c.cautions))]
        for name in names:
            i = by_name.get(name)
            shown = "—" if i is None else i.verdict + ("" if i.statistic is None else f" ({fmt(i.statistic, 3)})")
            cells.append(shown if i is None else Cell(shown, "", str(i.params)))
        cells += [robustness(c), c.runs_to_decide if c.runs_to_decide else ""]
        rows.append(cells)
    return Table(["claim", "as run", *(_column(name, tried) for name in names), "robustness",
                  "runs that would decide (as run)"], rows, caption)


def _column(name: str, claims: Sequence[ClaimRecord]) -> str:
    """A column of the interpretations table: the interpretation's name, with its run count when it
    ran fewer runs than the main run ("as run" there: the main run's first runs)."""
    counts = {i.n for c in claims for i in c.interpretations if i.name == name and i.n is not None and i.n != c.n}
    if not counts:
        return name
    runs = ", ".join(str(n) for n in sorted(counts))
    return f"as run, first {runs} runs" if name == AS_RUN else f"{name} ({runs} runs)"
