"""Sensitivity of a paper's claims to the interpretations of what it leaves unstated
(:mod:`gpfverify.contract.interpretations`): the experiment is run once per interpretation in
``DIR/interpretations/<name>/`` (same seed, same run count, the runner's usual saving and
resuming), and every claim of the main ``DIR/results.json`` gains the verdict and statistic it
has under each — matched by the claim's ``id``."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from pathlib import Path
from types import ModuleType

from gpfverify.contract.claims import ClaimRecord, Interpretation
from gpfverify.contract.interpretations import InterpretationSpec
from gpfverify.contract.params import Params
from gpfverify.contract.serial import to_json
from gpfverify.errors import InputError


def select(module: ModuleType, wanted: str) -> tuple[InterpretationSpec, ...]:
    """The interpretations named in ``wanted`` ("all" or comma-separated names) among the
    experiment's ``INTERPRETATIONS``."""
    declared: tuple[InterpretationSpec, ...] = getattr(module, "INTERPRETATIONS", ())
    if not declared:
        raise InputError(f"{module.NAME} declares no interpretations to try")
    if wanted.strip() == "all":
        return declared
    by_name = {s.name: s for s in declared}
    chosen = [n.strip() for n in wanted.split(",") if n.strip()]
    unknown = [n for n in chosen if n not in by_name]
    if unknown or not chosen:
        raise InputError(f"--interpretations: unknown {unknown or wanted!r}; choose 'all' or from {list(by_name)}")
    return tuple(by_name[n] for n in chosen)


def merge(main: dict, tried: Sequence[tuple[InterpretationSpec, dict]]) -> dict:
    """``main`` results with each claim's ``interpretations`` (not the timing claims') set from the results of each
    interpretation (a claim absent under an interpretation gets no entry for it)."""
    claims = []
    for raw in main.get("claims", []):
        claim = ClaimRecord.from_json(raw)
        entries = []
        for spec, results in tried:
            other = next((ClaimRecord.from_json(c) for c in results.get("claims", [])
                          if c.get("id") == claim.id and claim.id), None)
            if other is not None:
                entries.append(Interpretation(spec.name, to_json(spec.changes), other.verdict, other.statistic))
        claims.append(to_json(dataclasses.replace(claim, interpretations=tuple(entries))))
    return {**main, "claims": claims}


def run_interpretations(module: ModuleType, params: Params, specs: Sequence[InterpretationSpec], runs: int,
                        seed: int, out_dir: Path, executor: Executor,
                        on_run: Callable[[int, int], None] | None = None) -> dict:
    """Run every interpretation next to the main run in ``out_dir`` (which must hold its
    ``results.json``) and rewrite that file with the merged claims; returns it."""
    from gpfverify.experiments.runner import _atomic_write_json, run_experiment

    main_path = Path(out_dir) / "results.json"
    if not main_path.is_file():
        raise InputError(f"{main_path} is missing: run the experiment before its interpretations")
    main = json.loads(main_path.read_text(encoding="utf-8"))
    tried = []
    for spec in specs:
        changed = params.replace(**spec.changes)
        results = run_experiment(module, changed, runs, seed, Path(out_dir) / "interpretations" / spec.name,
                                 resume=True, executor=executor, on_run=on_run)
        tried.append((spec, results))
    merged = merge(main, tried)
    _atomic_write_json(main_path, merged)
    return merged
