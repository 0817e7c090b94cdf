"""Command-line contract: user errors exit 2 with one line on stderr; reproduce dispatches."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from gpfverify import cli
from gpfverify.papers import EXPERIMENTS

HERE = Path(__file__).parent


def _run(*args):
    return subprocess.run([sys.executable, "-m", "gpfverify", *args], capture_output=True, text=True,
                          timeout=120)


@pytest.mark.parametrize("args", [["bogus"], ["report", "--only", "nope"], ["reproduce"],
                                  ["reproduce", "no-such-experiment", "--out", "x"]])
def test_usage_errors_exit_2_with_one_line(args):
    proc = _run(*args)
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert proc.stdout == ""


def test_version_and_help():
    assert _run("--version").stdout.startswith("gpfverify ")
    proc = _run("--help")
    assert proc.returncode == 0 and "report" in proc.stdout


def test_reproduce_runs_an_experiment_and_refuses_to_overwrite(monkeypatch, tmp_path, capsys):
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setitem(EXPERIMENTS, "toy", "toy_experiment")
    out = tmp_path / "run"
    assert cli.main(["reproduce", "toy", "--runs", "3", "--seed", "4", "--out", str(out)]) == 0
    capsys.readouterr()  # the progress lines of the first command
    results = json.loads((out / "results.json").read_text())
    assert (results["experiment"], results["runs"], results["seed"]) == ("toy", 3, 4)
    assert results["params"] == {"scale": 1.0, "shift": 0.0, "fail_run": -1, "interrupt_run": -1,
                                 "limit": 1.0}
    assert cli.main(["reproduce", "toy", "--runs", "3", "--seed", "4", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--resume" in err[0]
    assert cli.main(["reproduce", "toy", "--runs", "3", "--seed", "4", "--out", str(out), "--resume"]) == 0
