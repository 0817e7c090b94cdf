"""Sensitivity of a paper's claims to the interpretations of what it leaves unstated
(:mod:`gpfverify.contract.interpretations`): the experiment is run once per interpretation in
``DIR/interpretations/<name>/`` (same seed, same run count, the runner's usual saving and
resuming), and every claim of the main ``DIR/results.json`` gains the verdict and statistic it
has under each — matched by the claim's ``id``.

An interpretation that changes only how the runs are *read* — parameters the experiment lists in
``SUMMARY_FIELDS`` (a detection definition, an error metric) — needs no runs of its own: its
``results.json`` is the summary of the main run's saved runs under the changed parameters
(:func:`summary_results`), at the main run's count whenever it is recomputed. Likewise a reading
that combines another interpretation's changes with summary fields (a birth proposal read with
another detection definition) reads that interpretation's runs (:func:`runs_source`)."""

from __future__ import annotations

import dataclasses
import functools
import json
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from pathlib import Path
from types import ModuleType

from gpfverify.contract.claims import AS_RUN, ClaimRecord, Interpretation, read_claims
from gpfverify.contract.interpretations import InterpretationSpec
from gpfverify.contract.params import Params
from gpfverify.contract.serial import to_json
from gpfverify.errors import InputError
from gpfverify.outputs import record_written


def select(module: ModuleType, wanted: str) -> tuple[InterpretationSpec, ...]:
    """The interpretations named in ``wanted`` ("all" or comma-separated names) among the
    experiment's ``INTERPRETATIONS``, each reading of another interpretation's runs after that
    interpretation (added when not named: :func:`runs_source`)."""
    declared: tuple[InterpretationSpec, ...] = getattr(module, "INTERPRETATIONS", ())
    if not declared:
        raise InputError(f"{module.NAME} declares no interpretations to try")
    by_name = {s.name: s for s in declared}
    chosen = list(by_name) if wanted.strip() == "all" else [n.strip() for n in wanted.split(",") if n.strip()]
    unknown = [n for n in chosen if n not in by_name]
    if unknown or not chosen:
        raise InputError(f"--interpretations: unknown {unknown or wanted!r}; choose 'all' or from {list(by_name)}")
    ordered: list[str] = []
    for name in chosen:
        source = runs_source(module, by_name[name])
        ordered += [n for n in (source, name) if n and n not in ordered]
    return tuple(by_name[n] for n in ordered)


def runs_source(module: ModuleType, spec: InterpretationSpec) -> str | None:
    """Whose saved runs answer ``spec``: "" the main run's (``spec`` changes only parameters the
    summary reads, the experiment's ``SUMMARY_FIELDS``), the name of the declared interpretation whose
    changes are exactly ``spec``'s other changes (``spec`` reads that interpretation's runs another
    way), or None: ``spec`` needs runs of its own."""
    fields = frozenset(getattr(module, "SUMMARY_FIELDS", ()))
    run_changes = {k: v for k, v in spec.changes.items() if k not in fields}
    if len(run_changes) == len(spec.changes):
        return None
    if not run_changes:
        return ""
    return next((s.name for s in getattr(module, "INTERPRETATIONS", ()) if s.changes == run_changes), None)


def summary_only(module: ModuleType, spec: InterpretationSpec) -> bool:
    """Does ``spec`` change only parameters the summary reads (the experiment's ``SUMMARY_FIELDS``)?
    Then the main run's saved runs answer it."""
    return runs_source(module, spec) == ""


def summary_results(module: ModuleType, run_dir: Path, spec: InterpretationSpec) -> dict:
    """The ``results.json`` of an interpretation that reads saved runs (:func:`runs_source`): the
    main run's runs in ``run_dir`` — or those of the interpretation it reads, in
    ``run_dir/interpretations/<source>`` — summarised under its parameters changed by ``spec``,
    written to ``run_dir/interpretations/<name>/results.json`` and returned."""
    from gpfverify.experiments.runner import _atomic_write_json, read_manifest, results_of

    source = runs_source(module, spec)
    runs_dir = Path(run_dir) / "interpretations" / source if source else Path(run_dir)
    manifest = read_manifest(runs_dir)
    changed = module.Params.from_json(manifest["params"]).replace(**spec.changes)
    results = results_of(module, runs_dir, {**manifest, "params": changed.to_json()})
    folder = Path(run_dir) / "interpretations" / spec.name
    folder.mkdir(parents=True, exist_ok=True)
    _atomic_write_json(folder / "results.json", results)
    return results


def merge(main: dict, tried: Sequence[tuple[InterpretationSpec, dict]], as_run: Sequence[dict] = ()) -> dict:
    """``main`` results with each claim's ``interpretations`` (the timing claims' too) set from the
    results of each interpretation, with its run count (a claim absent under an interpretation gets
    no entry for it). ``as_run``: the main run's results on fewer runs (its first n, the count the
    interpretations ran), each added as the claim's :data:`~gpfverify.contract.claims.AS_RUN` entry
    at that count, so that verdicts are compared on equal run counts."""
    def entry(claim: ClaimRecord, name: str, params: dict, results: dict) -> Interpretation | None:
        other = next((c for c in read_claims(results) if c.id == claim.id and claim.id), None)
        return None if other is None else Interpretation(name, params, other.verdict, other.statistic, other.n,
                                                         other.runs_to_decide)

    counts = {results.get("runs") for _, results in tried} - {main.get("runs")}
    merged = {}
    for key in ("claims", "timing_claims"):
        claims = []
        for raw in main.get(key, []):
            claim = ClaimRecord.from_json(raw)
            entries = [entry(claim, spec.name, to_json(spec.changes), results) for spec, results in tried
                       if spec.bears_on_claim(claim.id)]
            entries += [entry(claim, AS_RUN, {}, results) for results in as_run if results.get("runs") in counts]
            claims.append(to_json(dataclasses.replace(claim, interpretations=tuple(e for e in entries if e))))
        if key in main:
            merged[key] = claims
    return {**main, **merged}


def merge_saved(run_dir: Path, module: ModuleType) -> dict:
    """``run_dir/results.json`` recomputed from its saved runs with the verdicts under every
    interpretation saved in ``run_dir/interpretations/<name>/`` (each recomputed too) merged into
    its claims, and — where the interpretations ran fewer runs than the main run — the verdicts as
    run on that many runs; written back and returned (for extending a main run after its
    interpretations, e.g. a reference page)."""
    from gpfverify.experiments.runner import _atomic_write_json, read_manifest, results_of, rewrite_results

    manifest = read_manifest(Path(run_dir))
    main = results_of(module, Path(run_dir), manifest)  # written once, merged, below
    tried = []
    for spec in getattr(module, "INTERPRETATIONS", ()):
        folder = Path(run_dir) / "interpretations" / spec.name
        source = runs_source(module, spec)
        if source == "" or source and (Path(run_dir) / "interpretations" / source / "manifest.json").exists():
            tried.append((spec, summary_results(module, Path(run_dir), spec)))
        elif source is None and (folder / "manifest.json").exists():
            tried.append((spec, rewrite_results(folder, module)))
    merged = _merged_on_equal_counts(module, Path(run_dir), main, tried)
    _atomic_write_json(Path(run_dir) / "results.json", merged)
    record_written(Path(run_dir), [Path(run_dir) / "interpretations" / spec.name / "results.json"
                                   for spec, _ in tried])
    return merged


def _merged_on_equal_counts(module: ModuleType, run_dir: Path, main: dict,
                            tried: Sequence[tuple[InterpretationSpec, dict]]) -> dict:
    """:func:`merge` of ``tried`` into ``main``, with the main run's results on the first n runs
    for every count n of runs an interpretation ran that is smaller than the main run's."""
    from gpfverify.experiments.runner import read_manifest, results_of

    fewer = sorted({r["runs"] for _, r in tried if r["runs"] < main["runs"]})
    manifest = read_manifest(run_dir) if fewer else {}
    return merge(main, tried, [results_of(module, run_dir, manifest, n) for n in fewer])


def run_interpretations(module: ModuleType, params: Params, specs: Sequence[InterpretationSpec], runs: int,
                        seed: int, out_dir: Path, executor: Executor,
                        on_run: Callable[[str, int, int], None] | None = None,
                        interpretation_runs: int | None = None, batch: int | None = None) -> dict:
    """Run every interpretation next to the main run in ``out_dir`` (which must hold its
    ``results.json``; a summary-only one reads the main run's runs, :func:`summary_results`) and
    rewrite that file with the merged claims; returns it. ``interpretation_runs``: the runs of each
    interpretation with runs of its own (default ``runs``); on fewer runs than the main run, each
    claim's verdict under it is compared with the main run's on as many (its first) runs. ``batch``:
    runs advanced together (:func:`~gpfverify.experiments.runner.run_experiment`).
    ``on_run(name, saved, runs)`` after every run saved, with the interpretation's name."""
    from gpfverify.experiments.runner import _atomic_write_json, run_experiment

    main_path = Path(out_dir) / "results.json"
    if not main_path.is_file():
        raise InputError(f"{main_path} is missing: run the experiment before its interpretations")
    main = json.loads(main_path.read_text(encoding="utf-8"))
    tried = []
    for spec in specs:  # an interpretation whose runs another reads comes first (select)
        if runs_source(module, spec) is not None:
            tried.append((spec, summary_results(module, Path(out_dir), spec)))
            continue
        changed = params.replace(**spec.changes)
        results = run_experiment(module, changed, interpretation_runs or runs, seed,
                                 Path(out_dir) / "interpretations" / spec.name, resume=True, executor=executor,
                                 on_run=None if on_run is None else functools.partial(on_run, spec.name),
                                 batch=batch)
        tried.append((spec, results))
    merged = _merged_on_equal_counts(module, Path(out_dir), main, tried)
    _atomic_write_json(main_path, merged)
    return merged
