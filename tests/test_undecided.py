"""docs/undecided-claims.md: each command runs what its row says.

Every command of the generated list is read by the real command-line parser of ``gpfverify
reproduce`` and must give the experiment parameters of the page it is listed for, with the changes
of the interpretation it is listed under applied, at the page's seed and the planned runs — a
command that silently ran the default reading (no sensor positions for ``sensors-as-printed``, no
κ for a page at another κ than the default's) fails here. ``reproduce --interpretation`` is checked
on the toy experiment.
"""

from __future__ import annotations

import importlib
import json
import shlex
from pathlib import Path

import pytest

from gpfverify import cli, undecided
from gpfverify.commands.reproduce import experiment_params, experiment_parser
from gpfverify.contract.claims import AS_RUN
from gpfverify.papers import EXPERIMENTS

ROOT = Path(__file__).resolve().parents[1]
HERE = Path(__file__).parent


def test_every_listed_command_runs_its_page_under_its_reading():
    found = undecided.commands(ROOT / undecided.REFERENCE)
    assert found
    for command in found:
        argv = shlex.split(command.text)
        assert argv[:2] == ["gpfverify", "reproduce"], command.text
        module = importlib.import_module(EXPERIMENTS[argv[2]])
        opts = experiment_parser(argv[2]).parse_args(argv[3:])
        manifest = json.loads((ROOT / undecided.REFERENCE / command.page / "manifest.json").read_text(encoding="utf-8"))
        assert manifest["experiment"] == argv[2], command.text
        expected = module.Params.from_json(manifest["params"])
        if command.reading != AS_RUN:
            spec = next(s for s in module.INTERPRETATIONS if s.name == command.reading)
            expected = expected.replace(**spec.changes)
        assert experiment_params(module, opts) == expected, command.text
        assert opts.interpretation == (None if command.reading == AS_RUN else command.reading), command.text
        assert (opts.seed, opts.runs) == (manifest["seed"], command.runs), command.text


def test_a_reading_with_a_committed_run_is_listed_once_under_its_page():
    found = undecided.commands(ROOT / undecided.REFERENCE)
    pairs = [(c.page, c.reading) for c in found]
    assert len(pairs) == len(set(pairs)), pairs
    runs = undecided.committed_runs(ROOT / undecided.REFERENCE)
    second = next(r for r in runs if r.folder == "particle-flow/pff1d/vdm-gaussian")
    assert (second.page, second.reading) == ("particle-flow/pff1d", "vdm-gaussian")


def test_the_pages_own_parameters_are_given_explicitly():
    found = undecided.commands(ROOT / undecided.REFERENCE)
    for command in (c for c in found if c.page.startswith("ct2d/k300-")):
        assert "--train-points 300 " in command.text, command.text


def test_reproduce_runs_one_interpretation_as_the_main_run_and_records_its_name(monkeypatch, tmp_path, capsys):
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setitem(EXPERIMENTS, "toy", "toy_experiment")
    out = tmp_path / "run"
    assert cli.main(["reproduce", "toy", "--interpretation", "shifted", "--runs", "2", "--out", str(out)]) == 0
    for name in ("manifest.json", "results.json"):
        record = json.loads((out / name).read_text(encoding="utf-8"))
        assert record["interpretation"] == "shifted" and record["params"]["shift"] == 10.0, name
    capsys.readouterr()
    # resumed under another reading (the same parameters given by hand) is refused: the runs are one reading's
    assert cli.main(["reproduce", "toy", "--shift", "10", "--runs", "3", "--resume", "--out", str(out)]) == 2
    assert "different settings" in capsys.readouterr().err


@pytest.mark.parametrize("args, message", [
    (["--shift", "3"], "--interpretation shifted sets --shift"),
    (["--interpretations", "all"], "not together with --interpretations"),
])
def test_reproduce_refuses_an_interpretation_that_contradicts_the_options(monkeypatch, tmp_path, capsys, args,
                                                                          message):
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setitem(EXPERIMENTS, "toy", "toy_experiment")
    out = tmp_path / "run"
    assert cli.main(["reproduce", "toy", "--interpretation", "shifted", *args, "--runs", "2", "--out", str(out)]) == 2
    assert message in capsys.readouterr().err
    assert not (out / "manifest.json").exists()


def test_a_readings_own_run_gives_the_page_its_verdict_under_that_reading(monkeypatch, tmp_path, capsys):
    import shutil

    from gpfverify.contract.claims import read_claims
    from gpfverify.reference_pages import reading_commands, readings_into, with_reading_runs

    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setitem(EXPERIMENTS, "toy", "toy_experiment")
    toy = importlib.import_module("toy_experiment")
    monkeypatch.setattr(toy, "judge", lambda params, body, runs: (read_claims(body), []), raising=False)
    runs = tmp_path / "runs"
    assert cli.main(["reproduce", "toy", "--runs", "6", "--interpretations", "shifted", "--interpretation-runs", "2",
                     "--out", str(runs / "toy")]) == 0
    assert cli.main(["reproduce", "toy", "--interpretation", "shifted", "--runs", "6",
                     "--out", str(runs / "toy-shifted")]) == 0
    capsys.readouterr()
    page = tmp_path / "page"
    page.mkdir()
    for name in ("results.json", "manifest.json"):
        shutil.copy(runs / "toy" / name, page / name)
    results = json.loads((page / "results.json").read_text(encoding="utf-8"))
    before = {c.id: {i.name: i.n for i in c.interpretations} for c in read_claims(results)}
    assert before["toy/mean-below-1"]["shifted"] == 2
    assert readings_into(runs, "toy", page, toy) == ["shifted"]
    after = with_reading_runs(results, page, toy)
    entries = {c.id: {i.name: i for i in c.interpretations} for c in read_claims(after)}
    shifted = entries["toy/mean-below-1"]["shifted"]
    alone = next(c for c in read_claims(json.loads((runs / "toy-shifted" / "results.json").read_text())) if
                 c.id == "toy/mean-below-1")
    assert (shifted.n, shifted.verdict, shifted.statistic) == (6, alone.verdict, alone.statistic)
    assert entries["toy/mean-below-1"]["as run"].n == 2  # the main run's first runs, as they were
    assert json.loads((page / "results.json").read_text(encoding="utf-8")) == after  # written back
    said = reading_commands(page, toy, lambda name, n: f"reproduce toy --interpretation {name} --runs {n}")
    assert said.startswith("reproduce toy --interpretation shifted --runs 6 ")
    # a run with fewer runs than the one committed does not replace it
    assert cli.main(["reproduce", "toy", "--interpretation", "shifted", "--runs", "3",
                     "--out", str(tmp_path / "fewer" / "toy-shifted")]) == 0
    assert readings_into(tmp_path / "fewer", "toy", page, toy) == []


def test_a_command_deciding_a_claim_on_computation_time_runs_one_run_at_a_time():
    found = undecided.commands(ROOT / undecided.REFERENCE)
    timed = [c for c in found if any(i.claim.timing for i in c.decides)]
    assert timed
    for command in found:
        assert (" --batch 1 " in command.text) == (command in timed), command.text
