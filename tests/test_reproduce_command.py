"""``gpfverify reproduce``: the quick profile by default and the paper's count on request, progress
lines off a terminal, each claim's verdict at the end; ``gpfverify report --from DIR`` renders
one reproduce folder as a page."""

import json
import re
import shutil
from pathlib import Path

import pytest

from gpfverify.cli import main
from gpfverify.commands.reproduce import PROGRESS_FRACTION, interpretation_lines, progress_lines
from gpfverify.papers import EXPERIMENTS

HERE = Path(__file__).parent


def _run(argv, capsys):
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def toy(monkeypatch):
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setitem(EXPERIMENTS, "toy", "toy_experiment")
    import toy_experiment

    return toy_experiment


def test_quick_profile_by_default_then_the_verdicts(toy, tmp_path, capsys):
    out = tmp_path / "quick"
    code, stdout, stderr = _run(["reproduce", "toy", "--out", str(out)], capsys)
    assert code == 0
    results = json.loads((out / "results.json").read_text())
    assert results["runs"] == toy.PROFILES["quick"].runs != toy.DEFAULT_RUNS
    assert f"--paper-scale for the paper's {toy.DEFAULT_RUNS}" in stderr
    # off a terminal (captured): a line once the first run is saved, and the last one at 100 %
    assert "first run took" in stderr and f"{results['runs']} of {results['runs']} runs saved (100 %)" in stderr
    for claim in results["claims"]:  # every verdict as results.json records it
        assert f"{claim['verdict']:<14} {claim['claim']}" in stdout
    assert f"page: gpfverify report --from {out}" in stdout


def test_paper_scale_runs_the_papers_count_and_excludes_runs(toy, tmp_path, capsys):
    out = tmp_path / "paper"
    assert _run(["reproduce", "toy", "--paper-scale", "--out", str(out)], capsys)[0] == 0
    assert json.loads((out / "results.json").read_text())["runs"] == toy.DEFAULT_RUNS
    code, stdout, stderr = _run(["reproduce", "toy", "--paper-scale", "--runs", "2", "--out", str(tmp_path / "x")],
                                capsys)
    assert code == 2 and stdout == "" and len(stderr.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()


def test_progress_lines_every_few_percent_with_the_time_left():
    lines, now = [], [0.0]
    on_run = progress_lines("exp", lines.append, clock=lambda: now[0])
    total = 200
    for saved in range(1, total + 1):
        now[0] = 2.0 * saved  # two seconds a run: the time left is known exactly
        on_run(saved, total)
    assert lines[0] == f"exp: first run took 2 s; estimated time left for the other {total - 1}: 6 min 38 s"
    assert lines[-1].startswith(f"exp: {total} of {total} runs saved (100 %)")
    # one line per PROGRESS_FRACTION of the runs (the first line included), never one per run
    assert len(lines) == round(1 / PROGRESS_FRACTION) + 1
    assert "exp: 100 of 200 runs saved (50 %), about 3 min 20 s left" in lines


def test_progress_after_resume_counts_only_this_commands_runs():
    lines, now = [], [0.0]
    on_run = progress_lines("exp", lines.append, clock=lambda: now[0])
    for saved in (51, 52):  # 50 runs saved by an earlier command
        now[0] += 10.0
        on_run(saved, 100)
    assert lines[0].endswith("estimated time left for the other 49: 8 min 10 s")


def test_report_from_renders_one_reproduce_folder(tmp_path, capsys):
    source = tmp_path / "ungm1d"
    source.mkdir()
    shutil.copy(HERE / "fixtures" / "ungm1d" / "results.json", source / "results.json")
    code, stdout, _ = _run(["report", "--from", str(source)], capsys)
    assert code == 0
    page = tmp_path / "ungm1d-report" / "report.html"
    assert f"The page: {page}" in stdout
    html = page.read_text()
    assert "gpfverify reproduce ungm1d" in html and "one paper reproduced" in html
    results = json.loads((source / "results.json").read_text())
    assert all(c["claim"].replace("&", "&amp;").split(" (")[0][:40] in html for c in results["claims"])


def test_report_from_refuses_a_folder_reproduce_did_not_write(tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    code, stdout, stderr = _run(["report", "--from", str(empty)], capsys)
    assert code == 2 and stdout == "" and len(stderr.strip().splitlines()) == 1 and "results.json" in stderr
    assert not (tmp_path / "empty-report").exists()


@pytest.mark.parametrize("experiment", sorted(set(EXPERIMENTS) - {"toy"}))
def test_help_shows_no_sphinx_markup(experiment, capsys):
    code, out, _ = _run(["reproduce", experiment, "--help"], capsys)
    assert code == 0 and "--paper-scale" in out
    assert not re.search(r":(mod|func|class|meth|data|attr):`|``", out), out


def test_progress_of_each_interpretation_names_it_and_times_its_own_runs():
    """The interpretations run one after the other, each counting its runs from one again: its
    lines name it, and its first run's time is its own, not the time since the first one started."""
    lines, now = [], [0.0]
    on_run = interpretation_lines("exp", lines.append, clock=lambda: now[0])
    for name, seconds_per_run in (("fast", 2.0), ("slow", 60.0)):  # the second thirty times slower
        for saved in range(1, 11):
            now[0] += seconds_per_run
            on_run(name, saved, 10)
    firsts = [line for line in lines if "first run took" in line]
    assert firsts == ["exp, interpretation fast: first run took 2 s; estimated time left for the other 9: 18 s",
                      "exp, interpretation slow: first run took 1 min 0 s; estimated time left for the other 9: "
                      "9 min 0 s"]
    assert all(line.startswith(("exp, interpretation fast: ", "exp, interpretation slow: ")) for line in lines)
    assert lines[-1] == "exp, interpretation slow: 10 of 10 runs saved (100 %), about 0 s left"
