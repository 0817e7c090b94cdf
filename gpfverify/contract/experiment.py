"""What an experiment declares, and how a report finds the results it renders.

An experiment module (listed in :data:`gpfverify.papers.EXPERIMENTS`) defines

* ``NAME`` (as on the command line), ``PAPER`` (a key of :data:`~gpfverify.contract.papers.PAPERS`)
  and ``DEFAULT_RUNS`` (the paper's run count);
* ``Params`` — a :class:`~gpfverify.contract.params.Params` dataclass; the command-line options of
  ``gpfverify reproduce NAME`` are generated from it;
* ``PROFILES`` — ``{"quick": Profile, "full": Profile}``: the settings and run counts the report
  runs;
* ``RunRecord`` — the frozen dataclass one run returns (saved as JSON under ``runs/`` and read
  back through the same type);
* ``run_one(params, seed_sequence) -> RunRecord`` — one independent run (a picklable top-level
  function);
* optionally ``run_batch(params, seed_sequences) -> list[RunRecord]`` — the same runs advancing
  together; ``run_batch(p, seeds)[i]`` is the same bits for every way of splitting the runs into
  batches (``run_batch(p, [seeds[i]])[0]`` included) in every non-timing field, equals ``run_one``
  to :data:`~gpfverify.tolerances.PER_RUN_RTOL`, and each run consumes its own stream in an order that
  does not depend on the batch. The runner then always uses it (``--batch`` never changes a result);
  ``batch_run_bytes(params) -> int``, the working memory of one run in a batch, sets the default
  batch size (:func:`gpfverify.experiments.runner.default_batch`);
* ``summarize(params, records) -> dict`` — the ``results.json`` body from the successful runs, in
  run order, with its ``"claims"`` (a list of :class:`~gpfverify.contract.claims.ClaimRecord` as JSON);
* optionally ``TIMING_KEYS`` — names of measured-time fields that :data:`TIMING_KEY` does not match.

The contract types of an experiment (``Params``, ``RunRecord``, ``PROFILES``, summary records)
live in its paper's contract module (``gpfverify/papers/<paper>/contract.py``, or
``<experiment>_contract.py`` in a paper with several experiments) so that the report section reads
results back through the same types without importing the code that computes them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from gpfverify.contract.params import Params
from gpfverify.contract.serial import from_json, to_json


@dataclass(frozen=True)
class Setting:
    """One configuration an experiment is run at: a page label ("κ = 300, Ω = 2π/90"), a folder
    name (``tag``, letters, digits, '-', '.') and the parameters."""

    label: str
    tag: str
    params: Params


@dataclass(frozen=True)
class Profile:
    """A report profile of one experiment: the settings, each run ``runs`` times, and the names of
    the experiment's ``INTERPRETATIONS`` the report tries at every setting (at the same run count;
    summary-only ones read the setting's own runs, :mod:`gpfverify.experiments.sensitivity`)."""

    runs: int
    settings: tuple[Setting, ...]
    interpretations: tuple[str, ...] = ()


@dataclass(frozen=True)
class RunEntry:
    """One experiment run a report section renders: its ``results.json`` relative to the section
    folder."""

    experiment: str
    setting: str
    tag: str
    results: str


@dataclass(frozen=True)
class SectionRuns:
    """``<report>/<section>/runs.json``: what the command layer ran for a section, in order; the
    report renders a section from this file and the ``results.json`` files it names."""

    section: str
    profile: str
    seed: int
    entries: tuple[RunEntry, ...]
    #: ``certificates.json`` relative to the section folder, for the proofs section
    certificates: str | None = None

    def to_json(self) -> dict[str, Any]:
        return to_json(self)

    @classmethod
    def from_json(cls, data: Any) -> SectionRuns:
        return from_json(cls, data, "runs.json")
