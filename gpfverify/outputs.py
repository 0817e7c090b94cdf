"""Output folders: what ``--out DIR`` may touch, and how a command writes it.

The rule (docs/output-and-errors.md): DIR is written only when it does not exist, is empty, or
holds only what gpfverify wrote there before; nothing gpfverify did not write is ever changed or
removed, and a command that fails leaves DIR as it found it.

:func:`output_folder` is the one mechanism every command that writes ``--out DIR`` uses:

1. **Check** (before anything runs): ``DIR`` is not ``''``; if it exists it is a folder whose
   every entry is listed in ``DIR/.gpfverify-files`` (the files gpfverify wrote there, one
   relative POSIX path per line) — otherwise :class:`~gpfverify.errors.InputError` naming the
   first foreign entry.
2. **Stage**: the command writes into a temporary sibling ``.DIR.gpfverify-partial-PID``, which
   starts as a copy of DIR's gpfverify files (``keep=True``: saved runs to resume, report
   sections to keep) or empty (``keep=False``: the command rewrites all of its output).
3. **Commit** on success: the list of files is written into the staging folder, which then
   replaces DIR by ``rename`` (DIR held only gpfverify's files, re-checked just before).
   On an error the staging folder is removed and DIR is as it was. On an interruption
   (Ctrl-C, SIGTERM) or a lost worker process (:class:`~gpfverify.errors.WorkerLost`) the saved
   runs (``manifest.json`` and ``runs/run-*.json`` at any depth, each written whole) are
   committed, so ``--resume`` continues them; nothing else is. After a SIGKILL the staging folder
   stays; the next command on DIR that keeps its files adopts its saved runs and removes it once
   committed.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
from collections.abc import Iterator
from pathlib import Path, PurePosixPath

from gpfverify.errors import InputError, WorkerLost

#: the list of files gpfverify wrote in an output folder (its own entry included)
FILE_LIST = ".gpfverify-files"
#: prefix of the staging and retired siblings of an output folder
PARTIAL = ".gpfverify-partial-"
RETIRED = ".gpfverify-retired-"


def out_path(text: str) -> Path:
    """argparse type of ``--out``: refuses the empty string (``Path('')`` is the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("must name a folder, got an empty string")
    return Path(text)


out_path.__name__ = "folder"  # argparse names the type in "invalid ... value"


def _listed(folder: Path) -> set[str]:
    """The relative paths ``folder/.gpfverify-files`` lists (empty when there is no list)."""
    path = folder / FILE_LIST
    if not path.is_file() or path.is_symlink():
        return set()
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeError):
        return set()
    return {line for line in text.splitlines() if line} | {FILE_LIST}


def _entries(folder: Path) -> Iterator[tuple[str, bool]]:
    """Every entry under ``folder`` as (relative POSIX path, is a real folder), links not followed."""
    for root, dirs, files in os.walk(folder):
        base = Path(root).relative_to(folder)
        for name in dirs:
            path = Path(root) / name
            yield (base / name).as_posix(), not path.is_symlink()
        for name in files:
            yield (base / name).as_posix(), False


def foreign_entry(folder: Path) -> str | None:
    """The first entry of an existing ``folder`` that gpfverify did not write (None if none):
    files must be listed, folders must lead to a listed file."""
    listed = _listed(folder)
    parents = {str(p) for entry in listed for p in PurePosixPath(entry).parents if str(p) != "."}
    entries = sorted(_entries(folder), key=lambda e: e[1])  # files first: the most telling name
    return next((entry for entry, is_folder in entries
                 if entry not in listed and not (is_folder and entry in parents)), None)


def check_out(out: Path) -> None:
    """Refuse ``out`` unless gpfverify may write it (see the module docstring)."""
    if str(out) == "":
        raise InputError("--out must name a folder, got an empty string")
    if out.exists() and out.is_dir() and Path.cwd().resolve().is_relative_to(out.resolve()):
        raise InputError(f"--out {out} is the current folder or contains it; name a folder inside it")
    if out.is_symlink() or (out.exists() and not out.is_dir()):
        raise InputError(f"--out {out} exists and is not a folder")
    if out.exists():
        foreign = foreign_entry(out)
        if foreign is not None:
            raise InputError(f"--out {out} holds {foreign}, which gpfverify did not write; choose a new "
                             "or empty folder (gpfverify never changes files it did not write)")


def _write_list(folder: Path) -> None:
    files = sorted(entry for entry, is_folder in _entries(folder) if not is_folder and entry != FILE_LIST)
    (folder / FILE_LIST).write_text("".join(f"{f}\n" for f in [FILE_LIST, *files]), encoding="utf-8")


def _is_saved_run(relative: PurePosixPath) -> bool:
    return relative.name == "manifest.json" or (relative.parent.name == "runs" and relative.match("run-*.json"))


def _swap_in(stage: Path, out: Path) -> None:
    """Replace ``out`` (absent, empty, or gpfverify's files only) by the finished ``stage``."""
    check_out(out)  # nothing foreign arrived while the command ran
    if not out.exists():
        stage.rename(out)
        return
    retired = out.with_name(f"{RETIRED}{out.name}-{os.getpid()}")
    out.rename(retired)
    try:
        stage.rename(out)
    except OSError:
        retired.rename(out)
        raise
    shutil.rmtree(retired, ignore_errors=True)


def _salvage_runs(stage: Path, out: Path) -> None:
    """After an interruption or a lost worker: move the saved runs of ``stage`` into ``out`` (each replaces only
    its own earlier copy, a file gpfverify wrote) and list them, for ``--resume``."""
    runs = [entry for entry, is_folder in _entries(stage) if not is_folder and _is_saved_run(PurePosixPath(entry))]
    if all(PurePosixPath(entry).name == "manifest.json" for entry in runs):  # no run finished: keep nothing
        return
    check_out(out)
    listed = _listed(out) - {FILE_LIST}
    for entry in runs:
        target = out / entry
        target.parent.mkdir(parents=True, exist_ok=True)
        os.replace(stage / entry, target)
    files = sorted(listed | set(runs))
    tmp = out / f"{FILE_LIST}.{os.getpid()}"
    tmp.write_text("".join(f"{f}\n" for f in [FILE_LIST, *files]), encoding="utf-8")
    os.replace(tmp, out / FILE_LIST)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # exists, owned by someone else
        return True
    return True


def _orphans(out: Path) -> list[Path]:
    """Staging folders of ``out`` left by a command that was killed (its process is gone)."""
    found = []
    for sibling in out.parent.glob(f"{PARTIAL}{out.name}-*"):
        pid = sibling.name.rsplit("-", 1)[-1]
        if pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid)) and sibling.is_dir():
            found.append(sibling)
    return sorted(found)


def _adopt_runs(orphan: Path, stage: Path) -> None:
    """Copy the saved runs of a killed command's staging folder into ``stage``."""
    for entry, is_folder in _entries(orphan):
        if not is_folder and _is_saved_run(PurePosixPath(entry)):
            (stage / entry).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(orphan / entry, stage / entry)


@contextlib.contextmanager
def output_folder(out: Path, keep: bool = True) -> Iterator[Path]:
    """Yield the staging folder a command writes its outputs to; commit it as ``out`` when the
    block ends normally, discard it when the block raises (keeping the saved runs when it was
    interrupted or lost a worker). ``keep``: start from a copy of ``out``'s files (runs to resume, sections to
    keep) rather than from an empty folder."""
    check_out(Path(out))
    out = Path(out).absolute()
    parent = out.absolute().parent
    if not parent.is_dir():
        parent.mkdir(parents=True)
    stage = parent / f"{PARTIAL}{out.name}-{os.getpid()}"
    if stage.exists():
        shutil.rmtree(stage)
    try:
        if keep and out.is_dir():
            shutil.copytree(out, stage, symlinks=True)
        else:
            stage.mkdir()
        orphans = _orphans(out) if keep else []
        for orphan in orphans:  # runs saved before a SIGKILL: --resume continues them
            _adopt_runs(orphan, stage)
        yield stage
        _write_list(stage)
        _swap_in(stage, out)
        for orphan in orphans:
            shutil.rmtree(orphan, ignore_errors=True)
    except (KeyboardInterrupt, WorkerLost):  # interrupted, or a worker lost: the saved runs are kept
        with contextlib.suppress(OSError, InputError):
            if stage.exists():
                _salvage_runs(stage, out)
        raise
    finally:
        if stage.exists():
            shutil.rmtree(stage, ignore_errors=True)


def final_path(path: Path, stage: Path, out: Path) -> Path:
    """Where ``path`` (inside the staging folder) will be once the folder is committed as ``out``:
    for messages and records that name output files."""
    return Path(out) / Path(path).relative_to(stage)
