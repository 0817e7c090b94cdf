"""Claims under several interpretations: each interpretation is a run of its own, and every claim
of the main results records its verdict under each."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gpfverify import cli
from gpfverify.contract import ClaimRecord, Interpretation, read_claims
from gpfverify.contract.interpretations import robustness
from gpfverify.experiments import EXPERIMENTS

HERE = Path(__file__).parent


@pytest.fixture()
def toy(monkeypatch):
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setitem(EXPERIMENTS, "toy", "toy_experiment")


def test_every_claim_records_its_verdict_under_each_interpretation(toy, tmp_path):
    out = tmp_path / "run"
    args = ["reproduce", "toy", "--runs", "20", "--seed", "2", "--out", str(out), "--interpretations", "all"]
    assert cli.main(args) == 0
    claim = read_claims(json.loads((out / "results.json").read_text()))[0]
    shifted = json.loads((out / "interpretations" / "shifted" / "results.json").read_text())
    assert shifted["params"]["shift"] == 10.0
    assert claim.verdict == "held"
    assert [(i.name, i.params, i.verdict) for i in claim.interpretations][0] == ("shifted", {"shift": 10.0}, "NOT held")
    assert claim.id == "toy/mean-below-1"
    assert claim.interpretations[0].statistic == read_claims(shifted)[0].statistic
    assert claim.interpretations[1].name == "wide"
    assert robustness(claim).startswith("depends on the interpretation: held under as run")


def test_unknown_interpretation_is_refused_before_any_run(toy, tmp_path, capsys):
    out = tmp_path / "run"
    assert cli.main(["reproduce", "toy", "--out", str(out), "--interpretations", "sideways"]) == 2
    assert "unknown" in capsys.readouterr().err and not out.exists()


def test_robustness_in_words():
    base = ClaimRecord("c", "s", "NOT held", 1.0, 0.0, 10, "e")
    assert robustness(base) == ""
    same = ClaimRecord("c", "s", "NOT held", 1.0, 0.0, 10, "e", interpretations=tuple(
        Interpretation(f"i{k}", {}, "NOT held", 1.0) for k in range(5)))
    assert robustness(same) == "NOT held under all 6 interpretations tried"


def test_timing_claims_are_kept_apart_as_a_timing_field(toy, tmp_path):
    from gpfverify.experiments.runner import without_timing

    out = tmp_path / "run"
    assert cli.main(["reproduce", "toy", "--runs", "3", "--seed", "2", "--out", str(out)]) == 0
    results = json.loads((out / "results.json").read_text())
    assert "timing_claims" in results["timing_keys"] and "timing_claims" not in without_timing(results)
    assert [c.id for c in read_claims(results)] == ["toy/mean-below-1", "toy/time"]
    assert [c["id"] for c in results["claims"]] == ["toy/mean-below-1"]
