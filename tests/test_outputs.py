"""Output folders (docs/output-and-errors.md): ``--out ''`` is refused; a folder holding anything
gpfverify did not write is refused before anything runs, and left byte for byte as it was; a
command that fails leaves the folder as it found it; an interrupted run keeps its saved runs for
``--resume``; ``check --out`` writes run files that ``audit`` reads. One test per command."""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gpfverify import cli
from gpfverify.papers import EXPERIMENTS
from gpfverify.audit.runfile import write_run
from gpfverify.outputs import FILE_LIST, PARTIAL, sibling
from gpfverify.fusion.synthetic import random_case
from gpfverify.tolerances import algebra_rtol
from gpfverify.usercode import forget_interrupts

pytestmark = pytest.mark.slow  # each test runs commands in subprocesses, some killed mid-run

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))  # the suite imports in importlib mode: the helper beside it
from processes import pool_workers  # noqa: E402
from system_files import LINEAR_SYSTEM, MEASURING_SYSTEM  # noqa: E402


@pytest.fixture
def toy(monkeypatch):
    monkeypatch.syspath_prepend(str(HERE))
    monkeypatch.setitem(EXPERIMENTS, "toy", "toy_experiment")
    sys.modules.pop("toy_experiment", None)


def _main(argv, capsys):
    """(exit status, stdout, stderr) of the command line, usage errors included."""
    try:
        code = cli.main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _run_file(tmp_path: Path) -> Path:
    rng = np.random.default_rng(0)
    return write_run(tmp_path / "RUN.jsonl", [random_case(rng, 2, (2, 2)) for _ in range(3)])


def _system(tmp_path: Path) -> str:
    path = tmp_path / "linear.py"
    path.write_text(LINEAR_SYSTEM)
    return f"{path}:system"


def _commands(tmp_path: Path) -> dict[str, list]:
    """Every command that writes --out, with arguments that make it quick; the folder goes last."""
    return {
        "audit": ["audit", _run_file(tmp_path)],
        "check": ["check", _system(tmp_path), "--steps", "3", "--methods", "cmf,dmf"],
        "reproduce": ["reproduce", "toy", "--runs", "2"],
        "prove": ["prove", "--size", "small", "--only", "full-rank-needs-l-le-D"],
        "report": ["report", "--only", "moments"],
        "props": ["props"],
    }


@pytest.mark.parametrize("command", ["audit", "check", "reproduce", "prove", "report", "props"])
def test_an_empty_out_is_refused_and_the_current_folder_untouched(command, toy, tmp_path, capsys,
                                                                    monkeypatch):
    argv = _commands(tmp_path)[command]
    work = tmp_path / "work"
    (work / "figures").mkdir(parents=True)
    (work / "README.md").write_text("the user's notes")
    (work / "figures" / "x.png").write_bytes(b"user figure")
    before = _snapshot(work)
    monkeypatch.chdir(work)
    code, out, err = _main([*argv, "--out", ""], capsys)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert "empty" in err
    assert _snapshot(work) == before and sorted(os.listdir(work)) == ["README.md", "figures"]


@pytest.mark.parametrize("command", ["audit", "check", "reproduce", "prove", "report", "props"])
def test_a_folder_with_a_file_gpfverify_did_not_write_is_refused(command, toy, tmp_path, capsys):
    argv = _commands(tmp_path)[command]
    out_dir = tmp_path / "out"
    (out_dir / "figures").mkdir(parents=True)
    (out_dir / "figures" / "x.png").write_bytes(b"user figure")
    before = _snapshot(out_dir)
    code, out, err = _main([*argv, "--out", out_dir], capsys)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert "figures/x.png" in err and "did not write" in err
    assert _snapshot(out_dir) == before
    assert sorted(os.listdir(tmp_path)) == sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith("."))


@pytest.mark.parametrize("through", ["nosuch/..", "nosuch/../work"])
@pytest.mark.parametrize("command", ["audit", "check", "reproduce", "prove", "report", "props"])
def test_an_out_through_a_missing_folder_and_back_is_refused_and_makes_nothing(command, through, toy, tmp_path,
                                                                               capsys, monkeypatch):
    """``--out nosuch/..`` (the current folder, once nosuch exists) and ``nosuch/../work`` (a
    folder of the user's): refused before any folder is made, where nosuch/ was left behind."""
    argv = _commands(tmp_path)[command]
    work = tmp_path / "work"
    work.mkdir()
    (work / "notes.txt").write_text("the user's")
    monkeypatch.chdir(tmp_path)
    before = sorted(os.listdir(tmp_path))
    code, out, err = _main([*argv, "--out", through], capsys)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert "nosuch, which is not a folder that exists" in err, err
    assert sorted(os.listdir(tmp_path)) == before and os.listdir(work) == ["notes.txt"]


def test_audit_rewrites_its_own_folder_and_lists_every_file(tmp_path, capsys):
    run, out_dir = _run_file(tmp_path), tmp_path / "out"
    assert _main(["audit", run, "--out", out_dir], capsys)[0] == 0
    listed = set((out_dir / FILE_LIST).read_text().split())
    assert listed == set(_snapshot(out_dir))
    assert {"audit.json", "README.md", "report.html"} <= listed
    assert _main(["audit", run, "--out", out_dir], capsys)[0] == 0  # its own files: rewritten
    (out_dir / "figures" / "mine.png").write_bytes(b"user figure")  # now a foreign file
    code, _, err = _main(["audit", run, "--out", out_dir], capsys)
    assert code == 2 and "figures/mine.png" in err
    assert (out_dir / "figures" / "mine.png").read_bytes() == b"user figure"


def test_prove_writes_into_an_empty_folder_and_leaves_no_staging_folder(tmp_path, capsys):
    out_dir = tmp_path / "certs"
    out_dir.mkdir()
    code, _, _ = _main(["prove", "--size", "small", "--only", "full-rank-needs-l-le-D", "--out", out_dir], capsys)
    assert code == 0
    assert {"certificates.json", "README.md", FILE_LIST} == set(os.listdir(out_dir))
    assert os.listdir(tmp_path) == ["certs"]


def test_reproduce_that_fails_leaves_the_folder_as_it_found_it(toy, tmp_path, capsys):
    out_dir = tmp_path / "out"
    code, _, err = _main(["reproduce", "toy", "--runs", "1", "--fail-run", "0", "--out", out_dir], capsys)
    assert code == 2 and "every run of toy failed" in err
    assert os.listdir(tmp_path) == []  # no manifest.json, no runs/, no staging folder
    out_dir.mkdir()
    assert _main(["reproduce", "toy", "--runs", "1", "--fail-run", "0", "--out", out_dir], capsys)[0] == 2
    assert os.listdir(out_dir) == [] and os.listdir(tmp_path) == ["out"]


def test_an_interrupted_reproduce_keeps_its_saved_runs_for_resume(toy, tmp_path, capsys):
    out_dir = tmp_path / "out"
    argv = ["reproduce", "toy", "--runs", "3", "--interrupt-run", "2", "--out", out_dir]
    code, _, err = _main(argv, capsys)
    assert code == 130
    assert [line for line in err.splitlines() if line.startswith("gpfverify")] == [  # after the progress lines
        f"gpfverify reproduce: interrupted; 2 of 3 runs had finished; the saved runs are kept in {out_dir}: run the "
        "command again with --resume to continue them"], err
    saved = {"manifest.json", "runs/run-000000.json", "runs/run-000001.json"}
    assert set(_snapshot(out_dir)) == saved | {FILE_LIST}
    assert set((out_dir / FILE_LIST).read_text().split()) == saved | {FILE_LIST}
    assert _main([*argv, "--resume"], capsys)[0] == 130  # accepted as gpfverify's own, interrupted again
    assert os.listdir(tmp_path) == ["out"]


def test_a_resumed_reproduce_adds_to_its_own_runs(toy, tmp_path, capsys):
    out_dir = tmp_path / "out"
    assert _main(["reproduce", "toy", "--runs", "2", "--out", out_dir], capsys)[0] == 0
    first = json.loads((out_dir / "runs" / "run-000000.json").read_text())
    assert _main(["reproduce", "toy", "--runs", "2", "--out", out_dir], capsys)[0] == 2  # no --resume
    assert _main(["reproduce", "toy", "--runs", "2", "--out", out_dir, "--resume"], capsys)[0] == 0
    assert json.loads((out_dir / "runs" / "run-000000.json").read_text()) == first


@pytest.mark.parametrize("runs", [1, 2])
def test_check_writes_run_files_that_audit_reads(tmp_path, capsys, runs):
    out_dir = tmp_path / "out"
    code, _, err = _main(["check", _system(tmp_path), "--steps", "4", "--runs", runs, "--methods", "cmf,dmf",
                          "--out", out_dir], capsys)
    assert code == 0, err
    results = json.loads((out_dir / "results.json").read_text())
    names = ["run.jsonl"] if runs == 1 else [f"run-{i:03d}.jsonl" for i in range(runs)]
    assert sorted(p.name for p in out_dir.glob("run*.jsonl")) == names
    for i, name in enumerate(names):
        code, out, err = _main(["audit", out_dir / name, "--json", "--rank-rule", "canonical"], capsys)
        assert code == 0, err
        audit = json.loads(out)
        assert [s["k"] for s in audit["steps"]] == results["k"]
        check_gaps = np.array(results["gap_norm"][i])
        audit_gaps = np.array([np.linalg.norm(s["gap"]) for s in audit["steps"]])
        scale = max(1.0, float(np.abs(check_gaps).max()))
        np.testing.assert_allclose(audit_gaps, check_gaps, rtol=0, atol=algebra_rtol() * scale)
        # the same rank decisions and exactness per sensor and step as the check recorded
        assert [[x["rank"] for x in s["sensors"]] for s in audit["steps"]] == results["rank"][i]
        assert [[x["exact"] for x in s["sensors"]] for s in audit["steps"]] == results["exact"][i]


def test_the_saved_runs_of_a_killed_command_are_kept_by_the_next_one(toy, tmp_path, capsys):
    """A SIGKILLed command leaves its staging folder unlocked: the next command on the same --out
    keeps its saved runs in --out (as an interruption would have) and removes the rest."""
    done = tmp_path / "done"
    assert _main(["reproduce", "toy", "--runs", "2", "--out", done], capsys)[0] == 0
    out_dir = tmp_path / "out"
    stale = sibling(out_dir, PARTIAL)  # as the killed command left it
    (stale / "runs").mkdir(parents=True)
    for name in ("manifest.json", "runs/run-000000.json"):
        (stale / name).write_bytes((done / name).read_bytes())
    (stale / "report.html").write_text("<html><body>half-writ")
    code, _, err = _main(["reproduce", "toy", "--runs", "2", "--out", out_dir], capsys)
    assert code == 2 and "pass --resume" in err  # refused without --resume, the runs kept for it
    assert not stale.exists() and sorted(os.listdir(tmp_path)) == ["done", "out"]
    assert sorted(_snapshot(out_dir)) == [FILE_LIST, "manifest.json", "runs/run-000000.json"]
    assert _main(["reproduce", "toy", "--runs", "2", "--out", out_dir, "--resume"], capsys)[0] == 0
    # run 0 is the killed command's file (its own timing), run 1 was computed now
    assert (out_dir / "runs" / "run-000000.json").read_bytes() == (done / "runs" / "run-000000.json").read_bytes()
    assert sorted(os.listdir(tmp_path)) == ["done", "out"]


# ---- folders that cannot be written, two commands on one folder, long names, a killed page ---------

def _read_only(path: Path) -> None:
    """``chmod -R a-w path``."""
    for entry in [path, *path.rglob("*")]:
        entry.chmod(entry.stat().st_mode & ~0o222)


def _writable(path: Path) -> None:
    """``chmod -R u+w path`` (so that the test's folder can be removed)."""
    for entry in [path, *path.rglob("*")]:
        entry.chmod(entry.stat().st_mode | 0o200)


@pytest.mark.parametrize("previous", ["empty", "its own output"])
@pytest.mark.parametrize("command", ["audit", "check", "reproduce", "prove", "report", "props"])
def test_a_read_only_folder_is_refused_never_replaced(command, previous, toy, tmp_path, capsys):
    argv = {**_commands(tmp_path), "props": ["props", "-k", "resampl"],  # quick ones, to write a first output
            "report": ["report", "--from", _reproduced(tmp_path)]}[command]
    out_dir = tmp_path / "out"
    if previous == "empty":
        out_dir.mkdir()
    else:
        code, _, err = _main([*argv, "--out", out_dir], capsys)
        assert code == 0, err
    _read_only(out_dir)
    before, modes = _snapshot(out_dir), {p: p.stat().st_mode for p in [out_dir, *out_dir.rglob("*")]}
    try:
        code, out, err = _main([*argv, "--out", out_dir], capsys)
        assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
        assert "is read-only" in err and "never replaces" in err
        assert _snapshot(out_dir) == before and {p: p.stat().st_mode for p in modes} == modes
        assert sorted(os.listdir(tmp_path)) == sorted(n for n in os.listdir(tmp_path) if not n.startswith("."))
    finally:
        _writable(out_dir)


def _reproduced(tmp_path: Path) -> Path:
    """A folder as ``gpfverify reproduce ungm1d --out DIR`` writes it (its results.json)."""
    source = tmp_path / "ungm1d"
    source.mkdir(exist_ok=True)
    (source / "results.json").write_bytes((HERE / "fixtures" / "ungm1d" / "results.json").read_bytes())
    return source


def test_a_read_only_file_in_a_previous_output_is_refused_by_name(tmp_path, capsys):
    out_dir, run = tmp_path / "out", _run_file(tmp_path)
    assert _main(["audit", run, "--out", out_dir], capsys)[0] == 0
    (out_dir / "README.md").chmod(0o444)
    before = _snapshot(out_dir)
    code, _, err = _main(["audit", run, "--out", out_dir], capsys)
    assert code == 2 and "holds README.md, which is read-only" in err and _snapshot(out_dir) == before


def test_a_folder_that_cannot_hold_the_output_is_refused_before_anything_is_made(tmp_path, capsys):
    parent = tmp_path / "locked"
    parent.mkdir()
    _read_only(parent)
    try:
        code, _, err = _main(["audit", _run_file(tmp_path), "--out", parent / "new" / "out"], capsys)
        assert code == 2 and f"the folder {parent} that would hold it is read-only" in err
        assert list(parent.iterdir()) == []
    finally:
        _writable(parent)


@pytest.mark.parametrize("bad", [["--seed", "-1"], ["--runs", "0"], ["every run fails"]],
                         ids=["seed", "runs", "failing"])
def test_a_refused_check_leaves_no_parent_folder_behind(tmp_path, capsys, bad):
    if bad == ["every run fails"]:
        (tmp_path / "raising.py").write_text(RAISING_SYSTEM)
        argv = ["check", f"{tmp_path / 'raising.py'}:system", "--steps", "5", "--methods", "cmf,dmf"]
    else:
        argv = [*_commands(tmp_path)["check"], *bad]
    before = sorted(os.listdir(tmp_path))
    code, _, err = _main([*argv, "--out", tmp_path / "new" / "deep" / "out"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert sorted(os.listdir(tmp_path)) == before  # no new/, no new/deep/


def test_a_failed_reproduce_removes_the_folders_it_made_to_hold_its_output(toy, tmp_path, capsys):
    code, _, err = _main(["reproduce", "toy", "--runs", "1", "--fail-run", "0", "--out", tmp_path / "a" / "b"], capsys)
    assert code == 2 and "every run of toy failed" in err
    assert os.listdir(tmp_path) == []


def test_a_second_command_on_the_same_folder_is_refused_in_one_line(tmp_path, capsys):
    from gpfverify.errors import InputError
    from gpfverify.outputs import output_folder

    out_dir = tmp_path / "out"
    with output_folder(out_dir, keep=False) as stage:
        (stage / "first.txt").write_text("the first command's")
        with pytest.raises(InputError, match="being written by another gpfverify command"):
            with output_folder(out_dir, keep=True):
                pass  # pragma: no cover - refused on entry
        code, out, err = _main(["audit", _run_file(tmp_path), "--out", out_dir], capsys)
        assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and "--wait" in err, err
    assert (out_dir / "first.txt").read_text() == "the first command's"  # committed, untouched by the second
    assert sorted(os.listdir(tmp_path)) == ["RUN.jsonl", "out"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_second_command_on_a_folder_being_written_is_refused_or_waits(tmp_path):
    """A running check holds --out (its run held until the file ``go`` exists): a second check and
    an audit on the same folder are each refused in one line, changing nothing; ``audit --wait``
    says once that it waits, and writes its report once the check has committed: the folder ends
    as the audit's, and the check's results were complete when it committed."""
    import time

    (tmp_path / "held.py").write_text(HELD_SYSTEM)
    run = _run_file(tmp_path)
    check = [sys.executable, "-m", "gpfverify", "check", "held.py:system", "--steps", "5", "--workers", "2",
             "--methods", "cmf,dmf", "--json", "--out", "out"]
    audit = [sys.executable, "-m", "gpfverify", "audit", str(run), "--json", "--out", "out"]
    first = subprocess.Popen(check, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not pool_workers(first.pid):  # the run is under way
            time.sleep(0.05)
        for argv in (check, audit):
            refused = subprocess.run(argv, cwd=tmp_path, capture_output=True, text=True, timeout=120)
            assert refused.returncode == 2 and refused.stdout == "", refused.stderr
            assert refused.stderr.strip().splitlines() == [
                f"gpfverify {argv[3]}: error: --out {tmp_path / 'out'} is being written by another gpfverify command; "
                "wait for it to finish (or pass --wait), or choose another folder"]
        assert first.poll() is None and not (tmp_path / "out").exists()
        second = subprocess.Popen([*audit, "--wait"], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                  text=True)
        waiting = f"waiting for the other gpfverify command writing {tmp_path / 'out'} to finish\n"
        assert second.stderr.readline() == waiting
    finally:
        (tmp_path / "go").touch()
    out, err = first.communicate(timeout=120)
    assert first.returncode == 0 and json.loads(out)["runs_ok"] == 1, err
    out, err = second.communicate(timeout=120)
    assert second.returncode == 0 and json.loads(out)["summary"], err
    assert (tmp_path / "out" / "audit.json").is_file() and not (tmp_path / "out" / "results.json").exists()
    assert sorted(os.listdir(tmp_path)) == ["RUN.jsonl", "go", "held.py", "out"]


def test_a_240_byte_output_folder_name_works_and_leaves_no_sibling(tmp_path, capsys):
    """(Any name up to 255 bytes: the fuzz test of tests/test_error_boundary.py.)"""
    run, name = _run_file(tmp_path), "n" * 240
    assert len(os.fsencode(sibling(tmp_path / name, PARTIAL).name)) <= 255
    for _ in range(2):  # written, then rewritten
        code, _, err = _main(["audit", run, "--out", tmp_path / name], capsys)
        assert code == 0, err
    assert sorted(os.listdir(tmp_path)) == sorted(["RUN.jsonl", name])


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_sigkilled_report_from_a_folder_renders_again(tmp_path):
    """``report --from DIR --out page`` SIGKILLed while it writes the page (its staging folder left
    behind, unlocked and half-written; the process running the command dies with it), then run
    again, twice: each run writes the page and no hidden folder remains."""
    import signal
    import time

    from processes import alive, descendants

    source = _reproduced(tmp_path)
    argv = [sys.executable, "-m", "gpfverify", "report", "--from", source.name, "--out", "page"]
    killed = subprocess.Popen(argv, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline, processes = time.monotonic() + 120, set()
    while time.monotonic() < deadline and killed.poll() is None and not list(tmp_path.glob(f"{PARTIAL}page-*/*")):
        processes |= descendants(killed.pid)
        time.sleep(0.01)
    processes |= descendants(killed.pid)
    assert killed.poll() is None, "the report finished before it could be killed"
    killed.send_signal(signal.SIGKILL)
    killed.wait(timeout=10)
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline and any(alive(pid) for pid in processes):
        time.sleep(0.05)
    assert processes and not any(alive(pid) for pid in processes)
    assert list(tmp_path.glob(f"{PARTIAL}page-*/*")) and not (tmp_path / "page").exists()
    for _ in range(2):
        rerun = subprocess.run(argv, cwd=tmp_path, capture_output=True, text=True, timeout=300)
        assert rerun.returncode == 0 and "report.html" in rerun.stdout and rerun.stderr == "", rerun.stderr
        assert sorted(os.listdir(tmp_path)) == ["page", "ungm1d"]
    assert (tmp_path / "page" / "report.html").stat().st_size > 0


def test_resuming_onto_a_full_disk_is_one_plain_line(tmp_path, capsys, monkeypatch):
    import shutil

    system, out_dir = _system(tmp_path), tmp_path / "out"
    argv = ["check", system, "--steps", "3", "--methods", "cmf,dmf", "--out", out_dir]
    assert _main(argv, capsys)[0] == 0
    before = _snapshot(out_dir)
    monkeypatch.setattr(shutil, "copy2", _enospc)  # copying the folder into its staging folder fails
    code, _, err = _main([*argv, "--runs", "2", "--resume"], capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert lines[0].startswith("gpfverify check: error: No space left on device: ") and "[(" not in lines[0], err
    assert "could not be copied (and " in lines[0]
    assert _snapshot(out_dir) == before and sorted(os.listdir(tmp_path)) == ["linear.py", "out"]


# ---- a full disk, a failing system, a damaged folder: nothing half-written ----------------------

def _enospc(*_args, **_kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def _fails_after_a_partial_write(original, name):
    """``original(path, ...)`` that, for a file called ``name``, leaves a partial file then fails as
    on a full disk."""
    def write(self_or_path, *args, **kwargs):
        path = Path(self_or_path)
        if path.name == name or path.name.startswith(name + ".tmp"):
            Path(str(path) + f".tmp{os.getpid()}").write_bytes(b"")
            path.write_bytes(b"")
            _enospc()
        return original(self_or_path, *args, **kwargs)
    return write


def _assert_full_disk(code, err, tmp_path, kept):
    last = err.strip().splitlines()[-1]  # after any progress lines
    assert code == 2 and "error: No space left on device" in last and "Traceback" not in err, err
    assert sorted(os.listdir(tmp_path)) == sorted(kept)  # no staging folder, no partial file


def test_reproduce_on_a_full_disk_leaves_no_partial_file(toy, tmp_path, capsys, monkeypatch):
    from gpfverify.experiments import runner

    monkeypatch.setattr(runner, "_atomic_write_json",
                        _fails_after_a_partial_write(runner._atomic_write_json, "results.json"))
    code, _, err = _main(["reproduce", "toy", "--runs", "2", "--out", tmp_path / "out"], capsys)
    _assert_full_disk(code, err, tmp_path, [])


def test_prove_on_a_full_disk_leaves_no_empty_readme(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(Path, "write_text", _fails_after_a_partial_write(Path.write_text, "README.md"))
    code, _, err = _main(["prove", "--size", "small", "--only", "full-rank-needs-l-le-D", "--out",
                          tmp_path / "out"], capsys)
    _assert_full_disk(code, err, tmp_path, [])


def test_audit_on_a_full_disk_leaves_no_empty_folder(tmp_path, capsys, monkeypatch):
    from gpfverify.report import equivalence

    run = _run_file(tmp_path)
    monkeypatch.setattr(equivalence, "to_html", _enospc)
    code, _, err = _main(["audit", run, "--out", tmp_path / "out"], capsys)
    _assert_full_disk(code, err, tmp_path, [run.name])


def test_check_on_a_full_disk_keeps_the_folder_it_found(tmp_path, capsys, monkeypatch):
    from gpfverify.report import equivalence

    system, out_dir = _system(tmp_path), tmp_path / "out"
    argv = ["check", system, "--steps", "3", "--methods", "cmf,dmf", "--out", out_dir]
    assert _main(argv, capsys)[0] == 0
    before = _snapshot(out_dir)
    monkeypatch.setattr(equivalence, "to_html", _enospc)  # results.json written, its report not
    code, _, err = _main([*argv, "--runs", "2", "--resume"], capsys)
    assert code == 2 and "No space left on device" in err
    assert _snapshot(out_dir) == before
    assert sorted(os.listdir(tmp_path)) == ["linear.py", "out"]


RAISING_SYSTEM = '''
import numpy as np
from gpfverify.models import Sensor, StateSpaceModel
calls = [0]
def broken(x):
    calls[0] += 1
    if calls[0] > 4:
        raise RuntimeError("the sensor model broke")
    return x[:, :1]
system = StateSpaceModel(transition=np.eye(2), process_cov=0.1 * np.eye(2),
                         sensors=[Sensor(np.eye(2), np.eye(2)), Sensor(broken, [[1.0]])],
                         prior_mean=[0.0, 0.0], prior_cov=np.eye(2))
'''


def test_a_measurement_function_raising_mid_run_leaves_nothing(tmp_path, capsys):
    (tmp_path / "raising.py").write_text(RAISING_SYSTEM)
    code, out, err = _main(["check", f"{tmp_path / 'raising.py'}:system", "--steps", "5", "--methods", "cmf,dmf",
                            "--out", tmp_path / "out"], capsys)
    assert code == 2 and "the sensor model broke" in err and len(err.strip().splitlines()) == 1, err
    assert sorted(os.listdir(tmp_path)) == ["raising.py"]  # no manifest.json, no runs/


def test_resume_with_a_damaged_manifest_refuses_and_changes_nothing(toy, tmp_path, capsys):
    out_dir = tmp_path / "out"
    assert _main(["reproduce", "toy", "--runs", "2", "--out", out_dir], capsys)[0] == 0
    (out_dir / "manifest.json").write_text('{"experiment": "toy", "se')
    (out_dir / "runs" / "run-000001.json").unlink()
    before = _snapshot(out_dir)
    code, _, err = _main(["reproduce", "toy", "--runs", "2", "--out", out_dir, "--resume"], capsys)
    assert code == 2 and "manifest" in err
    assert _snapshot(out_dir) == before


@pytest.mark.parametrize("damage", ['{"status": "ok"}', "[1, 2]", '{"index": 1, "status": "error"}', "{"])
def test_resume_runs_a_damaged_saved_run_again(toy, tmp_path, capsys, damage):
    out_dir = tmp_path / "out"
    assert _main(["reproduce", "toy", "--runs", "2", "--out", out_dir], capsys)[0] == 0
    first = json.loads((out_dir / "results.json").read_text())
    (out_dir / "runs" / "run-000001.json").write_text(damage)
    assert _main(["reproduce", "toy", "--runs", "2", "--out", out_dir, "--resume"], capsys)[0] == 0
    again = json.loads((out_dir / "results.json").read_text())
    assert again["mean"] == first["mean"] and again["runs_ok"] == 2


def test_props_refusing_its_arguments_writes_nothing_anywhere(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    proc = subprocess.run([sys.executable, "-m", "gpfverify", "props", "--out", "o", "-k", "bad("],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and proc.stdout == "" and len(proc.stderr.strip().splitlines()) == 1
    assert os.listdir(tmp_path) == []  # no .hypothesis/, no o/


# ---- the user's system file cannot end gpfverify or print into its output -------------------------



#: seconds after which a check of the exiting system counts as hung (a few seconds idle; spawning
#: two workers took over 120 s on a 2-core machine at load 20)
HUNG_SECONDS = 300


def _check_system(tmp_path, *extra, **parts):
    parts = {"at_import": "", "in_measurement": "pass", "after": 0, **parts}
    (tmp_path / "system.py").write_text(MEASURING_SYSTEM.format(**parts))
    return subprocess.run([sys.executable, "-m", "gpfverify", "check", "system.py:system", "--steps", "4",
                           "--methods", "cmf,dmf", "--json", "--out", "out", *extra],
                          capture_output=True, text=True, cwd=tmp_path, timeout=HUNG_SECONDS)


@pytest.mark.parametrize("call", ["sys.exit(0)", "os._exit(0)", "sys.exit(3)", "exit()"])
@pytest.mark.parametrize("where", ["at_import", "in_measurement"])
def test_an_exit_in_the_system_file_is_an_error_of_that_file(tmp_path, call, where):
    # in_measurement: after a few calls, i.e. while the runs are under way
    proc = _check_system(tmp_path, **{where: call, "after": 6})
    assert proc.returncode == 2 and proc.stdout == "", proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "the system file system.py called" in lines[0] and "exit(" in lines[0], lines
    assert sorted(os.listdir(tmp_path)) == ["system.py"]  # no manifest.json, no runs/


def test_an_exit_in_a_worker_process_is_an_error_of_the_system_file(tmp_path):
    proc = _check_system(tmp_path, "--workers", "2", "--runs", "2", in_measurement="os._exit(0)", after=6)
    assert proc.returncode == 2 and proc.stdout == ""
    assert "the system file system.py called os._exit(0)" in proc.stderr.strip().splitlines()[-1]
    assert sorted(os.listdir(tmp_path)) == ["system.py"]


@pytest.mark.parametrize("workers", ["1", "2"])
def test_print_in_the_system_file_goes_to_stderr(tmp_path, workers):
    proc = _check_system(tmp_path, "--workers", workers, at_import="print('loading my system')",
                         in_measurement="print('measuring')")
    assert proc.returncode == 0, proc.stderr
    results = json.loads(proc.stdout)  # stdout is the results and nothing else
    assert results["experiment"] == "check"
    assert "loading my system" in proc.stderr and "measuring" in proc.stderr


#: the measurement function's one-line statements, run from its seventh call on (the runs under way)
THREAD_EXIT = "t = __import__('threading').Thread(target=os._exit, args=(0,)); t.start(); t.join()"
POSIX_EXIT = "__import__('posix')._exit(0)"
C_EXIT = "__import__('ctypes').CDLL(None).exit(0)"
POSIX_THREAD_EXIT = THREAD_EXIT.replace("os._exit", "__import__('posix')._exit")


@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_thread_of_the_system_file_calling_os_exit_is_an_error_of_that_file(tmp_path, workers):
    proc = _check_system(tmp_path, "--workers", workers, "--runs", "2", in_measurement=THREAD_EXIT, after=6)
    assert proc.returncode == 2 and proc.stdout == "", proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "the system file system.py called os._exit(0) in a thread it started" in lines[0], lines
    assert sorted(os.listdir(tmp_path)) == ["system.py"]


def test_a_thread_started_at_import_that_ends_the_process_mid_run_is_an_error_of_the_system_file(tmp_path):
    """The thread waits, in the background, until the runs are under way, then calls os._exit(0)
    while the measurement function sleeps."""
    at_import = ("import threading, time\nGO = threading.Event()\n"
                 "threading.Thread(target=lambda: (GO.wait(), os._exit(0)), daemon=True).start()")
    proc = _check_system(tmp_path, "--runs", "3", at_import=at_import, in_measurement="GO.set(); time.sleep(0.2)",
                         after=6)
    assert proc.returncode == 2 and proc.stdout == "", proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "the system file system.py called os._exit(0) in a thread it started" in lines[0], lines
    assert sorted(os.listdir(tmp_path)) == ["system.py"]


@pytest.mark.parametrize("call, where", [(POSIX_EXIT, "at_import"), (POSIX_EXIT, "in_measurement"),
                                         (C_EXIT, "in_measurement"),
                                         (POSIX_THREAD_EXIT, "in_measurement")],
                         ids=["posix-import", "posix-run", "C-exit-run", "posix-thread-run"])
def test_an_exit_gpfverify_cannot_intercept_is_still_an_error_of_the_system_file(tmp_path, call, where):
    """posix._exit, C's exit() and a thread calling either end the process running the command
    with status 0 and no result: the process gpfverify started reports it, exit status 2, and
    removes the staging folder (--out as it was: absent)."""
    proc = _check_system(tmp_path, **{where: call, "after": 6})
    assert proc.returncode == 2 and proc.stdout == "", proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(
        "gpfverify check: error: the system file system.py ended the process (exit status 0) before the command "
        "finished"), lines
    assert lines[0].endswith("; --out was left as it was") == (where == "in_measurement"), lines
    assert sorted(os.listdir(tmp_path)) == ["system.py"]


def test_a_system_file_killing_its_own_process_is_one_line(tmp_path):
    """The process running the command killed: gpfverify's own process does at once what the next
    command on --out would (no run had finished: nothing is kept, no staging folder is left)."""
    proc = _check_system(tmp_path, in_measurement="os.kill(os.getpid(), 9)", after=6)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.strip().splitlines() == [
        "gpfverify check: error: the process running the system file system.py was killed (SIGKILL) before it "
        f"finished; nothing was written to {tmp_path / 'out'}"], proc.stderr
    assert sorted(os.listdir(tmp_path)) == ["system.py"]


@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_thread_the_system_file_leaves_running_does_not_keep_gpfverify_from_ending(tmp_path, workers):
    at_import = "import threading, time\nthreading.Thread(target=time.sleep, args=(3600,), name='forever').start()"
    proc = _check_system(tmp_path, "--workers", workers, at_import=at_import)  # within HUNG_SECONDS: no hang
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["runs_ok"] == 1 and (tmp_path / "out" / "results.json").is_file()
    assert "gpfverify check: note: not waiting for 1 thread(s) still running (forever); they end with gpfverify" \
        in proc.stderr.splitlines(), proc.stderr


@pytest.mark.parametrize("workers", ["1", "2"])
@pytest.mark.parametrize("where", ["at_import", "in_measurement"])
@pytest.mark.parametrize("raised, named", [("raise KeyboardInterrupt('mine')", "raised KeyboardInterrupt (mine)"),
                                           ("raise type('Weird', (BaseException,), {})('boom')", "raised Weird (boom)"),
                                           ("raise GeneratorExit", "raised GeneratorExit")],
                         ids=["KeyboardInterrupt", "BaseException", "GeneratorExit"])
def test_an_exception_that_is_not_an_exception_is_an_error_of_the_system_file(tmp_path, raised, named, where,
                                                                                workers):
    proc = _check_system(tmp_path, "--workers", workers, **{where: raised, "after": 6})
    assert proc.returncode == 2 and proc.stdout == "", proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("gpfverify check: error: the system file system.py " + named), lines
    assert sorted(os.listdir(tmp_path)) == ["system.py"]


@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_system_file_that_changes_folder_moves_no_output(tmp_path, workers):
    (tmp_path / "elsewhere").mkdir()
    proc = _check_system(tmp_path, "--workers", workers, at_import="os.chdir('elsewhere')",
                         in_measurement="os.chdir('/')")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "out" / "results.json").is_file() and os.listdir(tmp_path / "elsewhere") == []
    assert "gpfverify check: the report page: out/report.html" in proc.stderr.splitlines()  # still true


# ---- signals: a second Ctrl-C, a killed worker ---------------------------------------------------

SLOW_SYSTEM = '''
import time
import numpy as np
from gpfverify.models import Sensor, StateSpaceModel
def h(x):
    time.sleep(0.05)
    return x[:, :1]
system = StateSpaceModel(transition=np.eye(2), process_cov=0.1 * np.eye(2),
                         sensors=[Sensor(np.eye(2), np.eye(2)), Sensor(h, [[1.0]])],
                         prior_mean=[0.0, 0.0], prior_cov=np.eye(2))
'''

#: a system whose measurement function, in a worker process, waits until the file ``go`` exists
#: in the folder the check started in: its runs finish only when a test lets them
HELD_SYSTEM = '''
import multiprocessing, os, time
import numpy as np
from gpfverify.models import Sensor, StateSpaceModel
GO = os.path.abspath('go')
def h(x):
    while multiprocessing.parent_process() is not None and not os.path.exists(GO):
        time.sleep(0.02)
    return x[:, :1]
system = StateSpaceModel(transition=np.eye(2), process_cov=0.1 * np.eye(2),
                         sensors=[Sensor(np.eye(2), np.eye(2)), Sensor(h, [[1.0]])],
                         prior_mean=[0.0, 0.0], prior_cov=np.eye(2))
'''


def _slow_check(tmp_path, system=SLOW_SYSTEM, session=False):
    """A check with two workers whose runs take seconds (or, with :data:`HELD_SYSTEM`, wait for
    ``go``), started in its own process (``session``: in a session of its own, as a terminal
    starts it); returns once a worker is running."""
    (tmp_path / "slow.py").write_text(system)
    proc = subprocess.Popen([sys.executable, "-m", "gpfverify", "check", "slow.py:system", "--steps", "400",
                             "--runs", "4", "--workers", "2", "--methods", "cmf,dmf", "--out", "out"],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=session)
    import time

    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and len(pool_workers(proc.pid)) < 2:
        time.sleep(0.1)
    time.sleep(1.0)  # the workers are inside their first runs
    return proc


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_second_ctrl_c_prints_no_traceback(tmp_path):
    import signal
    import time

    proc = _slow_check(tmp_path)
    proc.send_signal(signal.SIGINT)
    time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    _assert_one_true_interrupt_line(err, "gpfverify check: interrupted", tmp_path / "out", 4)


def _assert_one_true_interrupt_line(err, start, out_dir, runs):
    """``err`` is one line starting with ``start`` that says truly what was kept of the runs."""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(start + "; "), err
    kept = sorted((out_dir / "runs").glob("run-*.json")) if out_dir.exists() else []
    if kept:
        assert f"{len(kept)} of {runs} runs had finished; the saved runs are kept in {out_dir}: run the command " \
               "again with --resume" in lines[0], err
    else:
        assert lines[0] == f"{start}; no run had finished; nothing was written to {out_dir}", err
        assert sorted(os.listdir(out_dir.parent)) == ["slow.py"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("signum, to_group", [("SIGINT", True), ("SIGINT", False), ("SIGTERM", False)],
                         ids=["Ctrl-C", "kill-INT", "kill-TERM"])
def test_an_interruption_before_any_run_finished_is_one_true_line(tmp_path, signum, to_group):
    """``check --workers 2`` whose runs cannot finish (they wait for a file never made), stopped by
    Ctrl-C (SIGINT to the whole process group, workers included, as a terminal sends it) or by
    ``kill`` of gpfverify's process: one line, saying nothing was kept, and nothing written."""
    import signal

    proc = _slow_check(tmp_path, HELD_SYSTEM, session=to_group)
    if to_group:
        os.killpg(proc.pid, getattr(signal, signum))
    else:
        proc.send_signal(getattr(signal, signum))
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and out == "", err
    assert err.strip().splitlines() == [
        f"gpfverify check: interrupted; no run had finished; nothing was written to {tmp_path / 'out'}"], err
    assert sorted(os.listdir(tmp_path)) == ["slow.py"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_killed_resource_tracker_costs_one_note_line_at_most(tmp_path):
    """multiprocessing's resource tracker SIGKILLed while the workers run: the check completes
    with its results, and what multiprocessing says about it is one note line, no traceback."""
    import signal
    import time

    from processes import command_line, descendants

    (tmp_path / "slow.py").write_text(SLOW_SYSTEM)
    proc = subprocess.Popen([sys.executable, "-m", "gpfverify", "check", "slow.py:system", "--steps", "30",
                             "--runs", "4", "--workers", "2", "--methods", "cmf,dmf", "--json"],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline, tracker = time.monotonic() + 60, []
    while time.monotonic() < deadline and not (tracker and len(pool_workers(proc.pid)) == 2):
        tracker = [pid for pid in descendants(proc.pid) if "resource_tracker" in command_line(pid)]
        time.sleep(0.05)
    os.kill(tracker[0], signal.SIGKILL)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    assert json.loads(out)["runs_ok"] == 4
    assert "Traceback" not in err and len(err.strip().splitlines()) <= 1, err


def test_from_the_first_interrupt_on_further_ones_are_ignored():
    """The command line's handler: the first SIGINT or SIGTERM raises KeyboardInterrupt and makes
    both signals ignored, so a second one arriving during the clean-up (stopping the workers, moving
    the saved runs into --out) cannot cut it short; a test of the handler itself, because a real
    second Ctrl-C lands in that window only now and then."""
    import signal

    from gpfverify import cli

    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        signal.signal(signal.SIGINT, cli._interrupt)
        signal.signal(signal.SIGTERM, cli._interrupt)
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)  # the handler runs as os.kill returns
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
        assert signal.getsignal(signal.SIGTERM) is signal.SIG_IGN
        os.kill(os.getpid(), signal.SIGINT)  # ignored: nothing raised
        os.kill(os.getpid(), signal.SIGTERM)
    finally:
        for number, handler in saved.items():
            signal.signal(number, handler)
        forget_interrupts()  # the interrupt it counted is not a later test's


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_killed_worker_is_one_line_and_no_leaked_semaphore_warning(tmp_path):
    import signal

    proc = _slow_check(tmp_path)
    os.kill(pool_workers(proc.pid)[0], signal.SIGKILL)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 2 and out == "", err
    assert "leaked" not in err
    _assert_one_true_interrupt_line(err, "gpfverify check: error: a worker process ended abruptly (killed by a "
                                    "signal or out of memory)", tmp_path / "out", 4)


@pytest.mark.parametrize("near", [True, False])
def test_an_error_compiled_code_raised_near_the_memory_limit_keeps_runs_and_leaves_no_staging(tmp_path, monkeypatch,
                                                                                            near):
    """A ``SystemError`` near the address-space limit is memory running out (gpfverify.memory): the
    reserve is given back, the saved runs are kept for ``--resume`` and the staging folder removed.
    Far from the limit the same error is a bug: nothing is kept."""
    from gpfverify import memory, outputs

    released = []
    monkeypatch.setattr(memory, "near_limit", lambda: "its address space reached 379 MB of the 380 MB limit"
                        if near else None)
    monkeypatch.setattr(outputs, "release_reserve", lambda: released.append(True))
    monkeypatch.setattr(outputs, "interrupt_received", lambda: False)  # whatever an earlier test sent this process
    out = tmp_path / "out"
    with pytest.raises(SystemError) as raised:
        with outputs.output_folder(out) as stage:
            (stage / "runs").mkdir()
            (stage / "manifest.json").write_text("{}")
            (stage / "runs" / "run-000000.json").write_text("{}")
            raise SystemError("error return without exception set")
    assert os.listdir(tmp_path) == (["out"] if near else [])
    assert released == ([True] if near else [])
    if near:
        assert set(_snapshot(out)) == {"manifest.json", "runs/run-000000.json", FILE_LIST}
        assert any("--resume" in note for note in raised.value.__notes__)
