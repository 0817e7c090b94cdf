"""What a report section renders: ``<report>/<section>/runs.json`` (written by the command layer,
:mod:`gpfverify.commands.report`) and the ``results.json`` / ``certificates.json`` files it names.
The report package reads these files and renders; it never runs an experiment."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from gpfverify.contract.experiment import RunEntry, SectionRuns
from gpfverify.errors import InputError

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
    results = tuple(_read(folder / e.results) for e in runs.entries)
    if not all(isinstance(r, dict) for r in results):
        raise InputError(f"{folder}: a results.json named in {RUNS_FILE} is not an object")
    certificates: tuple = ()
    if runs.certificates is not None:
        loaded = _read(folder / runs.certificates)
        if not isinstance(loaded, list):
            raise InputError(f"{folder / runs.certificates} is not a list of certificates")
        certificates = tuple(loaded)
    return SectionInput(slug, folder, runs, results, certificates)


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
