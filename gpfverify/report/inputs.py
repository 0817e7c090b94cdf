"""What a report section renders: ``<report>/<section>/runs.json`` (written by the command layer,
:mod:`gpfverify.commands.report`) and the ``results.json`` / ``certificates.json`` files it names.
The report package reads these files and renders; it never runs an experiment."""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gpfverify.contract.claims import ACCURACY, VERDICTS, ClaimRecord, group_order, read_claims
from gpfverify.contract.experiment import RunEntry, SectionRuns
from gpfverify.contract.serial import from_json, to_json
from gpfverify.errors import InputError

if TYPE_CHECKING:
    from gpfverify.report.document import Section

RUNS_FILE = "runs.json"


@dataclass(frozen=True)
class SectionInput:
    """A section's runs index and the results it names (``results[i]`` belongs to
    ``runs.entries[i]``); figures are written into ``folder``."""

    slug: str
    folder: Path
    runs: SectionRuns
    results: tuple[dict, ...]
    certificates: tuple[dict, ...] = ()

    def of(self, experiment: str) -> list[tuple[RunEntry, dict]]:
        """(entry, results) of one experiment, in run order."""
        return [(e, r) for e, r in zip(self.runs.entries, self.results) if e.experiment == experiment]

    def render_single(self, experiment: str, title: str,
                      render: Callable[[dict, Path], Section]) -> Section:
        """The page of a one-experiment section: ``render(results, folder)`` of its first run, or
        a page saying that the report folder holds no run of ``experiment``."""
        from gpfverify.report.document import Paragraph, Section

        runs = self.of(experiment)
        if not runs:
            return Section(self.slug, title, [Paragraph(f"No {experiment} run was found in this report folder.")])
        return render(runs[0][1], self.folder)

    def by_setting(self, experiment: str) -> dict[str, dict]:
        """``{setting label: results}`` of one experiment, in run order."""
        return {e.setting: r for e, r in self.of(experiment)}


def _read(path: Path) -> object:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from None
    except ValueError as exc:
        raise InputError(f"{path} is not valid JSON ({exc})") from None


def has_runs(out_dir: Path, slug: str) -> bool:
    return (Path(out_dir) / slug / RUNS_FILE).is_file()


def load_section(out_dir: Path, slug: str) -> SectionInput:
    """The section ``slug`` of the report in ``out_dir`` as written by the command layer."""
    folder = Path(out_dir) / slug
    runs = SectionRuns.from_json(_read(folder / RUNS_FILE))
    results: list[dict] = []
    for entry in runs.entries:
        loaded = _read(folder / entry.results)
        if not isinstance(loaded, dict):
            raise InputError(f"{folder / entry.results} is not a results object")
        results.append(loaded)
    certificates: tuple = ()
    if runs.certificates is not None:
        listed = _read(folder / runs.certificates)
        if not isinstance(listed, list) or not all(isinstance(c, dict) for c in listed):
            raise InputError(f"{folder / runs.certificates} is not a list of certificates")
        certificates = tuple(listed)
    return SectionInput(slug, folder, runs, tuple(results), certificates)


def write_runs(out_dir: Path, runs: SectionRuns) -> Path:
    """Write ``<out>/<section>/runs.json`` (atomically)."""
    import os

    folder = Path(out_dir) / runs.section
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / RUNS_FILE
    tmp = path.with_name(path.name + f".tmp{os.getpid()}")
    tmp.write_text(json.dumps(runs.to_json(), indent=1), encoding="utf-8")
    os.replace(tmp, path)
    return path


# ---- what the page summarises: runs, verdicts and certificates of a section -------------------------

#: certificate statuses (gpfverify.symbolic.certificate), in the order the page counts them
STATUSES = ("proved", "refuted", "checked")


@dataclass(frozen=True)
class RunInfo:
    """What was run for one setting of an experiment (read from its ``results.json``)."""

    experiment: str
    setting: str
    runs: int
    runs_ok: int
    seed: int | None
    #: the paper's run counts stated by the setting's claim records (usually one)
    paper_n: tuple[int, ...] = ()
    #: 1-, 5- and 15-minute load averages when results.json was written, and the core count
    load_average: tuple[float, ...] = ()
    cpus: int | None = None
    git_commit: str | None = None
    created: str | None = None


@dataclass(frozen=True)
class Control:
    """A negative control of a certificate: a mutated statement the proof must reject."""

    mutant: str
    rejected: bool
    false_on_instance: bool | None = None


@dataclass(frozen=True)
class CertificateInfo:
    """A certificate (``certificates.json``, CONTRACT.md) as the page shows it: every word here was
    derived by the kernel from the record's formal content (:mod:`gpfverify.kernel.verdict`), except
    the title, which is shown apart from the statement."""

    claim: str
    statement: str
    method: str
    status: str
    detail: str
    seconds: float = 0.0
    scope: str = ""
    negative_controls: tuple[Control, ...] = ()
    title: str = ""
    #: a numerical check that failed (False), or None for a kernel record
    holds: bool | None = None
    #: the status the record is meant to get ("refuted" for a false variant of a theorem), or ""
    expected: str = ""

    @property
    def as_intended(self) -> bool:
        """A status its record says it is meant to get (a refutation that is the result)."""
        return bool(self.expected) and self.expected == self.status

    @property
    def status_text(self) -> str:
        """The status as the pages show it: "refuted, as intended" for a statement meant to be refuted."""
        return f"{self.status}, as intended" if self.as_intended else self.status

    @classmethod
    def of(cls, record: dict) -> CertificateInfo:
        """From one record of ``certificates.json`` (fields such as ``formal`` or ``provenance`` are
        not shown), re-checked by the kernel: a record the kernel does not confirm is shown as
        "checked", its detail starting with what the kernel found."""
        from gpfverify.kernel.verdict import check_record, derive

        try:
            controls = tuple(Control(str(c["mutant"]), bool(c["rejected"]),
                                     None if c.get("false_on_instance") is None else bool(c["false_on_instance"]))
                             for c in record.get("negative_controls", ()))
            status, detail = str(record["status"]), str(record.get("detail", ""))
            statement, method, scope = (str(record.get(k, "")) for k in ("statement", "method", "scope"))
            problems = check_record(record)
            if problems:  # none of the record's own words stands: the statement is the kernel's rendering
                status, detail = "checked", "REJECTED by the kernel: " + "; ".join(problems) + ". " + detail
                statement = derive(record)["statement"] if record.get("formal") else statement
                method, scope = "not confirmed by the kernel", "not proved"
            return cls(str(record["claim"]), statement, method, status, detail, float(record.get("seconds", 0.0)),
                       scope, controls, str(record.get("title", "")),
                       None if record.get("holds") is None else bool(record["holds"]), str(record.get("expected", "")))
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"malformed certificate {str(record)[:80]!r}: {exc}") from None


@dataclass(frozen=True)
class SectionSummary:
    """A section as the report's summary, "what was run" table and table of contents see it; kept
    in ``<section>/section.json`` so that a later ``--only`` build still counts it."""

    slug: str
    title: str
    profile: str
    seed: int | None
    #: keys of gpfverify.contract.PAPERS the section reproduces
    papers: tuple[str, ...]
    claims: tuple[ClaimRecord, ...] = ()
    certificates: tuple[CertificateInfo, ...] = ()
    runs: tuple[RunInfo, ...] = ()

    def to_json(self) -> dict[str, Any]:
        return to_json(self)

    @classmethod
    def from_json(cls, data: Any) -> SectionSummary:
        return from_json(cls, data, "section summary")

    @property
    def verdicts(self) -> VerdictCounts:
        """This section's counts (:class:`VerdictCounts`)."""
        return VerdictCounts.of(self.claims, [c.status for c in self.certificates])

    @property
    def cautioned(self) -> int:
        """How many verdicts carry a caution (fewer runs than the paper, measured times)."""
        return self.verdicts.cautioned


def run_info(entry: RunEntry, results: dict) -> RunInfo:
    """One setting's line of the "what was run" table."""
    def integer(value: Any) -> int | None:
        return value if isinstance(value, int) and not isinstance(value, bool) else None

    claims = read_claims(results)
    load = results.get("machine_load") or {}
    average = load.get("load_average") if isinstance(load, dict) else None
    prov = results.get("provenance") or {}
    runs = integer(results.get("runs")) or 0
    runs_ok = integer(results.get("runs_ok"))
    return RunInfo(entry.experiment, entry.setting, runs, runs if runs_ok is None else runs_ok,
                   integer(results.get("seed")),
                   tuple(sorted({c.paper_n for c in claims if c.paper_n is not None})),
                   tuple(float(v) for v in average) if isinstance(average, list) else (),
                   integer(load.get("cpus")) if isinstance(load, dict) else None,
                   prov.get("git_commit") if isinstance(prov, dict) else None,
                   prov.get("created") if isinstance(prov, dict) else None)


def summarize_section(data: SectionInput, title: str, papers: tuple[str, ...] = ()) -> SectionSummary:
    """The summary of a section rendered from ``data``: its claim records (every ``results.json``
    in run order), its certificates and what was run. ``papers`` are added to the papers its
    claim records name."""
    claims = tuple(c for results in data.results for c in read_claims(results))
    named = [*papers, *(c.paper for c in claims if c.paper)]
    return SectionSummary(data.slug, title, data.runs.profile, data.runs.seed, tuple(dict.fromkeys(named)),
                          claims, tuple(CertificateInfo.of(c) for c in data.certificates),
                          tuple(run_info(e, r) for e, r in zip(data.runs.entries, data.results)))


@dataclass(frozen=True)
class GroupCounts:
    """How many verdicts of one group (:attr:`~gpfverify.contract.claims.ClaimRecord.group`) are
    held, NOT held, undecided and not decidable."""

    group: str
    counts: dict[str, int]

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def text(self) -> str:
        """'3 held, 1 NOT held, 2 undecided, 0 not decidable'."""
        return ", ".join(f"{self.counts.get(v, 0)} {v}" for v in VERDICTS)


@dataclass(frozen=True)
class VerdictCounts:
    """Every count a summary states, computed once from the claim records and certificate statuses
    it covers: the verdicts per group — accuracy (the headline), each theorem checked on the runs
    (Proposition 1), timing —, the certificates per status and the verdicts with a caution. The
    console line, the pages and ``verdicts.json`` render this record; none counts by itself."""

    groups: tuple[GroupCounts, ...]
    proofs: dict[str, int]
    cautioned: int

    @classmethod
    def of(cls, claims: Iterable[ClaimRecord], statuses: Iterable[str] = ()) -> VerdictCounts:
        claims = list(claims)
        by_group: dict[str, Counter[str]] = {}
        for c in claims:
            by_group.setdefault(c.group, Counter())[c.verdict] += 1
        groups = tuple(GroupCounts(g, {v: by_group[g][v] for v in VERDICTS}) for g in group_order(by_group))
        found = Counter(statuses)
        return cls(groups, {s: found[s] for s in STATUSES}, sum(1 for c in claims if c.cautions))

    @classmethod
    def total(cls, parts: Iterable[VerdictCounts]) -> VerdictCounts:
        """The counts of several summaries together."""
        parts = list(parts)
        by_group: dict[str, Counter[str]] = {}
        for part in parts:
            for g in part.groups:
                by_group.setdefault(g.group, Counter()).update(g.counts)
        groups = tuple(GroupCounts(g, {v: by_group[g][v] for v in VERDICTS}) for g in group_order(by_group))
        proofs = {s: sum(part.proofs.get(s, 0) for part in parts) for s in STATUSES}
        return cls(groups, proofs, sum(part.cautioned for part in parts))

    def group(self, name: str) -> GroupCounts:
        """One group's counts (zeros when it has no verdict)."""
        return next((g for g in self.groups if g.group == name), GroupCounts(name, {v: 0 for v in VERDICTS}))

    def groups_text(self) -> str:
        """'accuracy: 8 held, …; Proposition 1: 7 held, …; timing: …' (accuracy always, first)."""
        groups = [self.group(ACCURACY), *(g for g in self.groups if g.group != ACCURACY)]
        return "; ".join(f"{g.group}: {g.text()}" for g in groups)

    def line(self) -> str:
        """'accuracy: 8 held, 12 NOT held, 20 undecided, 6 not decidable; Proposition 1: 7 held, …;
        timing: …; proofs: 6 proved, 2 refuted, 6 checked; 30 verdicts with a caution' — the
        accuracy group always first (the headline, zeros when empty)."""
        text = self.groups_text() + "; proofs: " + ", ".join(f"{self.proofs.get(s, 0)} {s}" for s in STATUSES)
        if self.cautioned:
            text += f"; {self.cautioned} verdict{'s' if self.cautioned != 1 else ''} with a caution"
        return text

    def to_json(self) -> dict[str, Any]:
        return to_json(self)

    @classmethod
    def from_json(cls, data: Any) -> VerdictCounts:
        return from_json(cls, data, "verdict counts")
