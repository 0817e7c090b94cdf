"""The committed reference pages and the current code are on one claim set.

Each committed ``results.json`` under ``reports/reference`` is compared with what the current code
emits for the same experiment and parameters (its committed ``manifest.json``), summarised from one
fresh run: the claim ids must be the same, so a claim added to (or dropped from) an experiment fails
here until the pages are made again. The quick report is rendered from the same ``summarize``, so it
is on the same set. Each page must also state the commit its runs were made at.
"""

from __future__ import annotations

import dataclasses
import importlib
import json
from pathlib import Path

import numpy as np
import pytest

from gpfverify.contract.claims import read_claims
from gpfverify.contract.serial import to_json
from gpfverify.papers import EXPERIMENTS

pytestmark = pytest.mark.slow  # one run of every committed reference experiment

REFERENCE = Path(__file__).resolve().parents[1] / "reports" / "reference"
COMMITTED = sorted(REFERENCE.rglob("results.json"))
#: parameters shortened for the one run here; the claims a run emits do not depend on them
SHORTER = {"sins-gps": {"duration": 150.0}, "pff1d": {"particles": 10, "steps": 10}}


def _page_of(results_path: Path) -> Path:
    """The README.md that renders a committed results.json (the nearest one above it)."""
    for folder in results_path.parents:
        if (folder / "README.md").exists():
            return folder / "README.md"
    raise AssertionError(f"no page renders {results_path}")


def _ids(results: dict) -> set[str]:
    return {c.id for c in read_claims(results)}


def _emitted_ids(manifest: dict) -> set[str]:
    """The claim ids the current code emits for the manifest's experiment and parameters, from one
    run (the ids do not depend on the run count: an undecidable claim is still emitted)."""
    module = importlib.import_module(EXPERIMENTS[manifest["experiment"]])
    params = module.Params.from_json(manifest["params"])
    params = dataclasses.replace(params, **SHORTER.get(manifest["experiment"], {}))
    record = module.run_one(params, np.random.SeedSequence(manifest["seed"]))
    return _ids(to_json(module.summarize(params, [record])))


def test_every_reference_page_has_committed_results():
    pages = {p.parent.name for p in REFERENCE.glob("*/README.md")} - {"proofs"}
    covered = {_page_of(p).parent.name for p in COMMITTED}
    assert pages <= covered


@pytest.mark.parametrize("path", COMMITTED, ids=lambda p: str(p.parent.relative_to(REFERENCE)))
def test_reference_page_is_on_the_code_claim_set(path: Path):
    results = json.loads(path.read_text(encoding="utf-8"))
    manifest = json.loads((path.parent / "manifest.json").read_text(encoding="utf-8"))
    assert _ids(results) == _emitted_ids(manifest)


@pytest.mark.parametrize("path", COMMITTED, ids=lambda p: str(p.parent.relative_to(REFERENCE)))
def test_reference_page_states_its_commit(path: Path):
    manifest = json.loads((path.parent / "manifest.json").read_text(encoding="utf-8"))
    commit = manifest["provenance"]["git_commit"]
    assert commit, f"{path} has no commit in its provenance"
    assert commit[:12] in _page_of(path).read_text(encoding="utf-8")
