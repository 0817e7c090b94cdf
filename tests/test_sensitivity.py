"""Claims under several interpretations: each interpretation is a run of its own, and every claim
of the main results records its verdict under each."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gpfverify import cli
from gpfverify.contract import ClaimRecord, Interpretation, read_claims
from gpfverify.contract.interpretations import robustness
from gpfverify.papers import EXPERIMENTS

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


def test_interpretations_on_fewer_runs_are_compared_with_the_main_run_on_as_many(toy, tmp_path):
    """Main run extended after its interpretations: merge_saved adds the verdict as run on the
    interpretations' run count (the same first runs), and robustness compares like with like."""
    from gpfverify.contract.claims import AS_RUN
    from gpfverify.experiments.runner import results_of, read_manifest
    from gpfverify.experiments.sensitivity import merge_saved

    import toy_experiment

    out = tmp_path / "run"
    assert cli.main(["reproduce", "toy", "--runs", "3", "--seed", "2", "--out", str(out),
                     "--interpretations", "wide"]) == 0
    assert cli.main(["reproduce", "toy", "--runs", "30", "--seed", "2", "--out", str(out), "--resume"]) == 0
    merged = merge_saved(out, toy_experiment)
    claim = next(c for c in read_claims(merged) if c.id == "toy/mean-below-1")
    assert claim.n == 30
    wide = next(i for i in claim.interpretations if i.name == "wide")
    baseline = next(i for i in claim.interpretations if i.name == AS_RUN)
    assert wide.n == baseline.n == 3
    first3 = read_claims(results_of(toy_experiment, out, read_manifest(out), 3))
    assert baseline.statistic == next(c for c in first3 if c.id == claim.id).statistic != claim.statistic
    # the stored file is the merged one
    assert json.loads((out / "results.json").read_text())["claims"] == merged["claims"]


def test_interpretations_on_fewer_runs_from_the_command_line(toy, tmp_path, capsys):
    """--interpretation-runs N: the interpretations run N runs, each claim carries the verdict as
    run on the same first N runs, and the result is that of running them through merge_saved."""
    from gpfverify.contract.claims import AS_RUN
    from gpfverify.experiments.runner import read_manifest, results_of
    from gpfverify.experiments.sensitivity import merge_saved

    import toy_experiment

    out = tmp_path / "run"
    assert cli.main(["reproduce", "toy", "--runs", "30", "--seed", "2", "--out", str(out),
                     "--interpretations", "wide", "--interpretation-runs", "3"]) == 0
    results = json.loads((out / "results.json").read_text())
    assert json.loads((out / "interpretations" / "wide" / "results.json").read_text())["runs"] == 3
    claim = next(c for c in read_claims(results) if c.id == "toy/mean-below-1")
    assert claim.n == 30
    assert {(i.name, i.n) for i in claim.interpretations} == {("wide", 3), (AS_RUN, 3)}
    baseline = next(i for i in claim.interpretations if i.name == AS_RUN)
    first3 = read_claims(results_of(toy_experiment, out, read_manifest(out), 3))
    assert baseline.statistic == next(c for c in first3 if c.id == claim.id).statistic
    assert robustness(claim).startswith("at 3 runs each: ")
    # merge_saved adds the readings of the saved runs the command was not asked for (wide-strict reads wide's)
    again = merge_saved(out, toy_experiment)["claims"]
    assert [{**c, "interpretations": [i for i in c["interpretations"] if i["name"] != "wide-strict"]}
            for c in again] == results["claims"]
    capsys.readouterr()
    # refused before any run: more runs than the main run, or no interpretations to run
    for extra in (["--interpretations", "wide", "--interpretation-runs", "31"], ["--interpretation-runs", "3"]):
        fresh = tmp_path / f"refused-{len(extra)}"
        assert cli.main(["reproduce", "toy", "--runs", "30", "--out", str(fresh), *extra]) == 2
        err = capsys.readouterr().err
        assert "--interpretation-runs" in err and len(err.strip().splitlines()) == 1 and not fresh.exists()


def test_robustness_compares_verdicts_on_equal_run_counts():
    from gpfverify.contract.claims import AS_RUN
    from gpfverify.contract.interpretations import is_robust

    def claim(*entries):
        return ClaimRecord("c", "s", "held", 1.0, 0.0, 1000, "e", interpretations=entries)

    at_60 = [Interpretation(f"i{k}", {"k": k}, "undecided", 0.1, 60) for k in range(3)]
    matched = claim(Interpretation(AS_RUN, {}, "undecided", 0.1, 60), *at_60)
    assert robustness(matched) == "at 60 runs each: undecided under all 4 interpretations tried; as run at 1000 " \
                                  "runs: held"
    assert is_robust(matched)
    flipped = claim(Interpretation(AS_RUN, {}, "held", 0.1, 60), *at_60)
    assert not is_robust(flipped)
    assert robustness(flipped).startswith("at 60 runs each: depends on the interpretation: held under as run; "
                                          "undecided under i0, i1, i2")
    unmatched = claim(*at_60)  # no verdict as run at 60 runs: compared with the 1000-run one, and said so
    assert not is_robust(unmatched)
    assert robustness(unmatched).endswith("(the interpretations at 60 runs, as run at 1000)")
    same_count = claim(*(Interpretation(f"i{k}", {}, "held", 0.1, 1000) for k in range(2)))
    assert robustness(same_count) == "held under all 3 interpretations tried" and is_robust(same_count)
    # several run counts: the full-length ones first, then by run count, the verdict as run on all runs once
    mixed = claim(Interpretation("late", {}, "undecided", 0.1, 200), Interpretation(AS_RUN, {}, "held", 0.1, 200),
                  Interpretation("full", {}, "held", 0.1, 1000), Interpretation(AS_RUN, {}, "undecided", 0.1, 60),
                  *at_60)
    assert robustness(mixed) == (
        "held under all 2 interpretations tried; at 60 runs each: undecided under all 4 interpretations tried; "
        "at 200 runs each: depends on the interpretation: held under as run; undecided under late; "
        "as run at 1000 runs: held")
    assert not is_robust(mixed)


def test_a_reading_of_another_interpretations_runs_needs_no_runs_of_its_own(toy, tmp_path):
    """An interpretation that adds summary fields to another's changes reads that interpretation's
    saved runs (at its run count), and naming it alone runs the other first."""
    from gpfverify.contract.claims import AS_RUN
    from gpfverify.contract.serial import from_json
    from gpfverify.experiments.sensitivity import merge_saved, runs_source, select

    import toy_experiment

    assert [s.name for s in select(toy_experiment, "wide-strict")] == ["wide", "wide-strict"]
    assert [runs_source(toy_experiment, s) for s in toy_experiment.INTERPRETATIONS] == [None, None, "wide"]
    out = tmp_path / "run"
    assert cli.main(["reproduce", "toy", "--runs", "8", "--seed", "2", "--out", str(out),
                     "--interpretations", "wide-strict", "--interpretation-runs", "5"]) == 0
    strict_dir = out / "interpretations" / "wide-strict"
    assert not (strict_dir / "runs").exists() and (out / "interpretations" / "wide" / "runs").is_dir()
    strict = json.loads((strict_dir / "results.json").read_text())
    wide_runs = [from_json(toy_experiment.RunRecord, json.loads(p.read_text())["result"])
                 for p in sorted((out / "interpretations" / "wide" / "runs").glob("run-*.json"))]
    expected = toy_experiment.summarize(toy_experiment.Params(scale=3.0, limit=-5.0), wide_runs)
    assert strict["runs"] == 5 and strict["params"]["limit"] == -5.0 and strict["params"]["scale"] == 3.0
    assert next(c for c in read_claims(strict) if c.id == "toy/mean-below-1").statistic == \
        next(c for c in expected["claims"] if c.id == "toy/mean-below-1").statistic
    claim = next(c for c in read_claims(json.loads((out / "results.json").read_text())) if c.id == "toy/mean-below-1")
    assert {(i.name, i.n) for i in claim.interpretations} == {("wide", 5), ("wide-strict", 5), (AS_RUN, 5)}
    again = next(c for c in read_claims(merge_saved(out, toy_experiment)) if c.id == claim.id)
    assert again.interpretations == claim.interpretations


def test_a_reading_is_compared_only_on_the_claims_it_bears_on():
    from gpfverify.contract.interpretations import InterpretationSpec
    from gpfverify.experiments.sensitivity import merge

    def results(*ids):
        return {"runs": 4, "claims": [ClaimRecord("c", "s", "held", 1.0, 0.0, 4, "e", id=i).to_json() for i in ids]}

    ids = ("x/fig1/a", "x/fig1/b", "x/fig2", "x/fig10")
    some = InterpretationSpec("fig1-model", {"m": 1}, "why", bears_on=("x/fig1/", "x/fig2"))
    every = InterpretationSpec("everything", {"n": 1}, "why")
    merged = merge(results(*ids), [(some, results(*ids)), (every, results(*ids))])
    tried = {c.id: [i.name for i in c.interpretations] for c in read_claims(merged)}
    assert tried == {"x/fig1/a": ["fig1-model", "everything"], "x/fig1/b": ["fig1-model", "everything"],
                     "x/fig2": ["fig1-model", "everything"], "x/fig10": ["everything"]}


def test_a_folder_whose_results_were_recomputed_can_still_be_resumed(toy, tmp_path, capsys):
    """merge_saved (a reference page's re-rendering) writes the results of readings the command was
    not asked for into the output folder; the folder stays gpfverify's, so --resume continues it —
    while a file the user added is still refused."""
    from gpfverify.experiments.sensitivity import merge_saved
    from gpfverify.outputs import FILE_LIST

    import toy_experiment

    out = tmp_path / "run"
    assert cli.main(["reproduce", "toy", "--runs", "6", "--seed", "2", "--out", str(out),
                     "--interpretations", "wide", "--interpretation-runs", "3"]) == 0
    strict = out / "interpretations" / "wide-strict" / "results.json"
    assert not strict.exists()
    merge_saved(out, toy_experiment)
    assert strict.is_file() and "interpretations/wide-strict/results.json" in (out / FILE_LIST).read_text()
    capsys.readouterr()
    assert cli.main(["reproduce", "toy", "--runs", "9", "--seed", "2", "--out", str(out), "--resume"]) == 0
    assert json.loads((out / "results.json").read_text())["runs"] == 9
    (out / "notes.txt").write_text("mine")
    assert cli.main(["reproduce", "toy", "--runs", "12", "--seed", "2", "--out", str(out), "--resume"]) == 2
    assert "notes.txt" in capsys.readouterr().err


def test_recording_written_files_leaves_a_folder_without_a_list_alone(tmp_path):
    from gpfverify.outputs import FILE_LIST, record_written

    (tmp_path / "a.json").write_text("{}")
    record_written(tmp_path, [tmp_path / "a.json"])
    assert not (tmp_path / FILE_LIST).exists()
