"""The commit of an output folder against someone else's files (docs/output-and-errors.md, "Output
folders"): a folder that appears at ``--out DIR`` while a command runs is never replaced, a file
that arrives in DIR while it is replaced is never removed, and gpfverify removes only what its list
names. Each case is made to happen at the exact moment in-process (the rename wrapped), then a
timed sweep races a second process against real commands."""

from __future__ import annotations

import contextlib
import os
import random
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from gpfverify import cli, outputs
from gpfverify.audit.runfile import write_run
from gpfverify.fusion.synthetic import random_case

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))  # the suite imports in importlib mode: the helper beside it
from processes import sweep_trials  # noqa: E402


def _run_file(folder: Path) -> Path:
    rng = np.random.default_rng(0)
    return write_run(folder / "RUN.jsonl", [random_case(rng, 2, (2, 2)) for _ in range(3)])


def _audit(run: Path, out: Path, capsys) -> tuple[int, list[str]]:
    code = cli.main(["audit", str(run), "--out", str(out)])
    return code, capsys.readouterr().err.splitlines()


def _siblings(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith(".gpfverify-"))


def _before_first_rename(monkeypatch, act) -> None:
    """Run ``act()`` just before the commit's first rename (after its last check)."""
    real = outputs.rename_noreplace
    calls = []

    def rename(source, target):
        if not calls:
            act()
        calls.append((source, target))
        return real(source, target)

    monkeypatch.setattr(outputs, "rename_noreplace", rename)


@pytest.mark.parametrize("renameat2", [True, False], ids=["renameat2", "fallback"])
def test_a_folder_that_appears_at_out_while_the_command_runs_is_never_replaced(tmp_path, capsys, monkeypatch,
                                                                                renameat2):
    run, out = _run_file(tmp_path), tmp_path / "out"
    if not renameat2:
        monkeypatch.setattr(outputs, "_renameat2", lambda: None)

    def user_makes_the_folder():
        out.mkdir()
        (out / "mine.txt").write_text("the user's")

    _before_first_rename(monkeypatch, user_makes_the_folder)
    code, err = _audit(run, out, capsys)
    assert code == 2 and len(err) == 1 and "was made by another program while the command ran" in err[0], err
    assert sorted(os.listdir(out)) == ["mine.txt"] and (out / "mine.txt").read_text() == "the user's"
    assert _siblings(tmp_path) == []


def test_a_file_that_arrives_in_its_own_folder_before_it_is_replaced_is_kept(tmp_path, capsys, monkeypatch):
    run, out = _run_file(tmp_path), tmp_path / "out"
    assert _audit(run, out, capsys)[0] == 0
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    _before_first_rename(monkeypatch, lambda: (out / "mine.txt").write_text("the user's"))
    code, err = _audit(run, out, capsys)
    assert code == 2 and len(err) == 1 and "gained mine.txt, which gpfverify did not write" in err[0], err
    after = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert after == {**before, Path("mine.txt"): b"the user's"}  # the folder as it was, the user's file in it
    assert _siblings(tmp_path) == []


def test_a_file_that_arrives_in_the_replaced_folder_stays_there(tmp_path, capsys, monkeypatch):
    """Written through a handle on the old folder after it was set aside (a shell whose current
    folder it is): only the listed files are removed; the file stays, and a note says where."""
    run, out = _run_file(tmp_path), tmp_path / "out"
    assert _audit(run, out, capsys)[0] == 0
    real = outputs._remove_listed

    def remove(folder):
        (folder / "late.txt").write_text("the user's, late")
        return real(folder)

    monkeypatch.setattr(outputs, "_remove_listed", remove)
    code, err = _audit(run, out, capsys)
    retired = outputs.sibling(out, outputs.RETIRED)
    assert code == 0 and err == [f"note: late.txt arrived in {out} while it was being replaced; it is kept in "
                                 f"{retired}"], err
    assert os.listdir(retired) == ["late.txt"] and (retired / "late.txt").read_text() == "the user's, late"
    assert outputs.foreign_entry(out) is None  # the new output, complete


def test_removing_an_old_output_removes_only_what_its_list_names(tmp_path):
    folder = tmp_path / "old"
    (folder / "figures").mkdir(parents=True)
    (folder / "figures" / "a.png").write_bytes(b"png")
    (folder / "figures" / "yours.txt").write_text("yours")
    (folder / "results.json").write_text("{}")
    (folder / "empty-folder-of-yours").mkdir()
    outputs._save_list(folder, {"figures/a.png", "results.json"})
    left = outputs._remove_listed(folder)
    assert left is not None
    assert sorted(str(p.relative_to(folder)) for p in folder.rglob("*")) == [
        "empty-folder-of-yours", "figures", "figures/yours.txt"]


# ---- the timed sweep -----------------------------------------------------------------------------

#: trials of the sweep (GPFVERIFY_SWEEP_TRIALS for more)
TRIALS = sweep_trials(6)


def _racer(out: Path, stage: Path, holds_it_open: bool, created: dict, stop: threading.Event) -> None:
    """A user's program timed on the commit. With ``holds_it_open`` it has made ``out``, an empty
    folder, before the command commits and holds it open (as a shell whose current folder it is);
    otherwise ``out`` does not exist. Once the command has written its file list into its staging
    folder (what it does just before the commit) it makes ``out`` (if need be) and writes files
    into it as fast as it can until ``stop``: through its handle on the folder, or by path. Every
    file it wrote is recorded with its content."""
    handle = os.open(out, os.O_RDONLY | os.O_DIRECTORY) if holds_it_open else None
    listed = stage / outputs.FILE_LIST
    try:
        while not listed.exists() and not stop.is_set():
            pass  # a busy wait: the commit follows within a millisecond
        if handle is None:
            with contextlib.suppress(FileExistsError):
                out.mkdir()
        i = 0
        while not stop.is_set() and i < 3000:
            name = f"user-{i:04d}.txt"
            try:
                fd = os.open(name if handle is not None else out / name, os.O_WRONLY | os.O_CREAT | os.O_EXCL,
                             dir_fd=handle)
                os.write(fd, f"file {i}".encode())
                os.close(fd)
                created[name] = f"file {i}"
            except (FileNotFoundError, NotADirectoryError):
                pass  # the folder was set aside or gone at that instant: the program was told
            i += 1
    finally:
        if handle is not None:
            os.close(handle)


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the race is timed on Linux")
def test_files_written_while_commands_commit_are_never_removed(tmp_path):
    """Commands on a folder that does not exist or is empty, raced by a program that writes files
    into it from the moment the command is about to commit (:func:`_racer`): every command ends
    with 0 or 2 and one line at most, no staging folder is left, and every file the program wrote
    is in the folder or, written into the old folder while it was being replaced, kept beside it
    with a note saying so."""
    run = _run_file(tmp_path)
    command = [sys.executable, "-m", "gpfverify", "audit", str(run), "--out"]
    rng = random.Random(0)
    outcomes = []
    for trial in range(TRIALS):
        folder = tmp_path / f"trial-{trial}"
        folder.mkdir()
        out = folder / "out"
        holds_it_open = rng.random() < 0.5
        if holds_it_open:
            out.mkdir()
        created: dict[str, str] = {}
        stop = threading.Event()
        racer = threading.Thread(target=_racer, args=(out, outputs.sibling(out, outputs.PARTIAL), holds_it_open,
                                                      created, stop))
        racer.start()
        proc = subprocess.run([*command, str(out)], capture_output=True, text=True, timeout=300)
        time.sleep(0.05)
        stop.set()
        racer.join()
        lines = proc.stderr.splitlines()
        assert proc.returncode in (0, 2) and len(lines) <= 1 and "Traceback" not in proc.stderr, proc.stderr
        retired = outputs.sibling(out, outputs.RETIRED)
        assert [name for name in _siblings(folder) if name != retired.name] == [], (trial, os.listdir(folder))
        missing = [name for name, text in created.items()
                   if not any((where / name).is_file() and (where / name).read_text() == text
                              for where in (out, retired))]
        assert not missing, (trial, holds_it_open, proc.returncode, lines, len(missing), len(created))
        if retired.exists():  # files arrived in the folder while it was replaced: kept, and the line says where
            assert lines and f"it is kept in {retired}" in lines[0], lines
        outcomes.append((holds_it_open, proc.returncode, len(created), retired.exists()))
    print(f"{TRIALS} trials (held open, exit status, files written, kept aside): {outcomes}")
