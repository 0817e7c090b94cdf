"""Output folders: what ``--out DIR`` may touch, and how a command writes it.

The rule (docs/output-and-errors.md): DIR is written only when it does not exist, is empty, or
holds only what gpfverify wrote there before, all of it writable; nothing gpfverify did not write
is ever changed or removed, and a command that fails leaves DIR as it found it.

:func:`output_folder` is the one routine every command that writes ``--out DIR`` uses, entered
before the command's work begins:

1. **Check**, before anything is created: ``DIR`` is not ``''``, not the current folder nor one
   containing it, and a ``..`` in it follows folders that exist (:func:`canonical`: ``nosuch/..``
   is refused, never made); if it exists it is a folder whose every entry is listed in
   ``DIR/.gpfverify-files`` (the files gpfverify wrote there, one relative POSIX path per line);
   DIR, everything in it and the folder that will hold it are writable by their permissions (a
   folder or file made read-only is refused, never replaced — also for root, whom the operating
   system would let through). Otherwise :class:`~gpfverify.errors.InputError`, one line naming the
   first entry at fault.
2. **Lock**: the command's staging folder, the hidden sibling ``.gpfverify-partial-NAME-HASH``
   (NAME: DIR's name cut to :data:`NAME_CHARS` characters, HASH: 8 hex digits of the whole name,
   so that a long DIR name still leaves room for its siblings), is created and locked with
   ``flock`` for as long as the command runs. A second command on DIR is refused in one line, or
   with ``wait`` waits for the first. An unlocked staging folder was left by a command that was
   killed (SIGKILL, a power cut; the kernel releases a dead process's locks): its saved runs are
   moved into DIR as an interruption would have moved them, the rest is removed.
3. **Stage**: the staging folder starts as a copy of DIR's files (``keep=True``: saved runs to
   resume, report sections to keep) or empty (``keep=False``: the command rewrites all of it).
4. **Commit** on success: the list of files is written into the staging folder, which then
   takes DIR's place by a rename that never replaces anything (:func:`rename_noreplace`:
   ``renameat2(RENAME_NOREPLACE)`` on Linux). DIR held only gpfverify's files, re-checked just
   before; a previous DIR is first set aside as the hidden sibling ``.gpfverify-retired-NAME-HASH``,
   checked again there (an entry that arrived meanwhile puts it back and fails the command), and
   then only what its list names is removed. A folder that appears at DIR while the command runs
   (someone else's) is never replaced: the command fails and that folder is untouched. On an
   error the staging folder is removed, and so are the folders made to hold DIR: everything is as
   it was. A Ctrl-C that other code swallowed still stops the command before it commits. On an
   interruption (Ctrl-C, SIGTERM), a lost worker process
   (:class:`~gpfverify.errors.WorkerLost`) or memory running out (``MemoryError``,
   :class:`~gpfverify.errors.OutOfMemory`, or an error compiled code raised near the address-space
   limit: :func:`gpfverify.memory.out_of_memory`) the saved runs (``manifest.json`` and
   ``runs/run-*.json`` at any depth, each written whole) are moved into DIR, so ``--resume``
   continues them, and a note on the exception says so; nothing else is kept.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import hashlib
import os
import shutil
import stat
import traceback
from collections.abc import Iterable, Iterator
from pathlib import Path, PurePosixPath

from gpfverify import streams, supervise
from gpfverify.errors import InputError, WorkerLost
from gpfverify.memory import out_of_memory, release_reserve
from gpfverify.usercode import Interrupted, interrupt_received

#: the list of files gpfverify wrote in an output folder (its own entry included)
FILE_LIST = ".gpfverify-files"
#: prefixes of the staging and retired siblings of an output folder
PARTIAL = ".gpfverify-partial-"
RETIRED = ".gpfverify-retired-"
#: characters of DIR's name kept in its siblings' names (the hash stands for the whole name)
NAME_CHARS = 40


def out_path(text: str) -> Path:
    """argparse type of ``--out``: refuses the empty string (``Path('')`` is the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("must name a folder, got an empty string")
    return Path(text)


out_path.__name__ = "folder"  # argparse names the type in "invalid ... value"


def add_wait_argument(parser: argparse.ArgumentParser) -> None:
    """``--wait``, for every command that writes ``--out``."""
    parser.add_argument("--wait", action="store_true",
                        help="when another gpfverify command is writing the same --out, wait for it to finish "
                             "(default: refuse at once)")


def sibling(out: Path, prefix: str) -> Path:
    """The hidden sibling of ``out`` with ``prefix`` (:data:`PARTIAL`, :data:`RETIRED`): short
    whatever the length of ``out``'s name (module docstring)."""
    digest = hashlib.sha1(os.fsencode(out.name)).hexdigest()[:8]
    return out.with_name(f"{prefix}{out.name[:NAME_CHARS]}-{digest}")


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


def _permits_writing(path: Path) -> bool:
    """Whether ``path``'s permissions let this user write it (and, a folder, enter it): the
    permission bits that apply to this user (owner, group or others), whatever the operating
    system would allow root, and :func:`os.access` (a read-only file system, ACLs)."""
    info = os.lstat(path)
    if stat.S_ISLNK(info.st_mode):
        return True  # a link is never written through; what it is, is checked elsewhere
    if info.st_uid == os.geteuid():
        bits = stat.S_IWUSR | (stat.S_IXUSR if stat.S_ISDIR(info.st_mode) else 0)
    elif info.st_gid == os.getegid() or info.st_gid in os.getgroups():
        bits = stat.S_IWGRP | (stat.S_IXGRP if stat.S_ISDIR(info.st_mode) else 0)
    else:
        bits = stat.S_IWOTH | (stat.S_IXOTH if stat.S_ISDIR(info.st_mode) else 0)
    return (info.st_mode & bits) == bits and os.access(path, os.W_OK)


def _existing_ancestor(path: Path) -> Path:
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def canonical(out: Path) -> Path:
    """``out`` as an absolute path without ``..``: the part up to its last ``..`` resolved by the
    system (so it must exist: ``nosuch/..`` is refused, never made), the rest as given. Creates
    nothing."""
    parts = Path(out).absolute().parts
    if ".." not in parts:
        return Path(out).absolute()
    last = len(parts) - 1 - parts[::-1].index("..")
    try:
        base = Path(*parts[:last + 1]).resolve(strict=True)
    except (OSError, RuntimeError):  # a missing folder before the '..', or a loop of links
        raise InputError(f"--out {out} goes through {Path(*parts[:last])}, which is not a folder that exists; name "
                         "the folder without '..' or through folders that exist") from None
    return base.joinpath(*parts[last + 1:])


def check_out(out: Path) -> None:
    """Refuse ``out`` unless gpfverify may write it (step 1 of the module docstring); creates
    nothing."""
    if str(out) == "":
        raise InputError("--out must name a folder, got an empty string")
    out = canonical(out)
    if out.exists() and out.is_dir() and Path.cwd().resolve().is_relative_to(out.resolve()):
        raise InputError(f"--out {out} is the current folder or contains it; name a folder inside it")
    if out.is_symlink() or (out.exists() and not out.is_dir()):
        raise InputError(f"--out {out} exists and is not a folder")
    if out.exists():
        foreign = foreign_entry(out)
        if foreign is not None:
            raise InputError(f"--out {out} holds {foreign}, which gpfverify did not write; choose a new "
                             "or empty folder (gpfverify never changes files it did not write)")
        read_only = next((entry for entry, _ in [(".", True), *_entries(out)]
                          if not _permits_writing(out / entry)), None)
        if read_only is not None:
            what = "is read-only" if read_only == "." else f"holds {read_only}, which is read-only"
            raise InputError(f"--out {out} {what}: gpfverify never replaces what cannot be written; make it "
                             "writable or choose another folder")
    holder = _existing_ancestor(Path(out).absolute().parent)
    if not holder.is_dir() or not _permits_writing(holder):
        raise InputError(f"--out {out} cannot be written: the folder {holder} that would hold it is "
                         f"{'not a folder' if not holder.is_dir() else 'read-only'}")


def _write_list(folder: Path) -> None:
    _save_list(folder, {entry for entry, is_folder in _entries(folder) if not is_folder})


def _save_list(folder: Path, files: set[str]) -> None:
    """``folder``'s list of the files gpfverify wrote: its own entry first, then ``files`` sorted
    (written whole: a reader never sees half a list)."""
    path = folder / FILE_LIST
    tmp = path.with_name(f"{FILE_LIST}.tmp{os.getpid()}")
    tmp.write_text("".join(f"{f}\n" for f in [FILE_LIST, *sorted(files - {FILE_LIST})]), encoding="utf-8")
    os.replace(tmp, path)


def record_written(folder: Path, written: Iterable[Path]) -> None:
    """Add ``written`` (files under ``folder``) to ``folder``'s list when gpfverify wrote the folder
    (it has a list): a routine that writes into an output folder after its command ended (results
    recomputed from the saved runs to render a page) leaves it gpfverify's, so that a later command
    on it (``--resume``) is not refused. A folder without a list is the user's, left as it is."""
    path = folder / FILE_LIST
    if not path.is_file() or path.is_symlink():
        return
    listed = _listed(folder)
    added = {Path(w).relative_to(folder).as_posix() for w in written} - listed
    if added:
        _save_list(folder, listed | added)


def _is_saved_run(relative: PurePosixPath) -> bool:
    return relative.name == "manifest.json" or (relative.parent.name == "runs" and relative.match("run-*.json"))


def _make_parents(folder: Path) -> list[Path]:
    """Create ``folder`` and its missing parents; the ones created, outermost first."""
    missing = []
    while not folder.exists():
        missing.append(folder)
        folder = folder.parent
    for path in reversed(missing):
        with contextlib.suppress(FileExistsError):
            path.mkdir()
    return missing[::-1]


def _remove_made(made: list[Path]) -> None:
    """Remove the folders :func:`_make_parents` made, innermost first, as long as they are empty."""
    for path in reversed(made):
        try:
            path.rmdir()
        except OSError:  # something else arrived in it: it stays
            return


class _Busy(Exception):
    """The staging folder is locked by another command."""


def _lock(stage: Path, out: Path, wait: bool) -> int:
    """Create ``stage`` if need be, lock it and return the descriptor holding the lock
    (:class:`_Busy` when another command holds it and ``wait`` is false)."""
    import fcntl

    said = False
    while True:
        with contextlib.suppress(FileExistsError):
            stage.mkdir()
        try:
            fd = os.open(stage, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0) | getattr(os, "O_NOFOLLOW", 0))
        except FileNotFoundError:  # committed or removed by its owner meanwhile
            continue
        except OSError as exc:
            if exc.errno in (errno.ELOOP, errno.ENOTDIR):
                raise InputError(f"--out {out}: {stage} exists and is not a staging folder gpfverify made; "
                                 "remove it") from None
            raise
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                if not wait:
                    raise _Busy from None
                if not said:
                    print(f"waiting for the other gpfverify command writing {out} to finish",
                          file=streams.diagnostics())
                    said = True
                fcntl.flock(fd, fcntl.LOCK_EX)
            try:  # still the folder at that name (its owner may have committed it as DIR or removed it)
                same = os.path.samestat(os.fstat(fd), os.lstat(stage))
            except FileNotFoundError:
                same = False
            if same:
                return fd
        except BaseException:
            os.close(fd)
            raise
        os.close(fd)


def _salvage_runs(stage: Path, out: Path) -> int:
    """Move the saved runs of ``stage`` into ``out`` (each replaces only its own earlier copy, a file
    gpfverify wrote) and list them, for ``--resume``; the number of finished runs moved (none is
    moved when no run finished)."""
    runs = [entry for entry, is_folder in _entries(stage) if not is_folder and _is_saved_run(PurePosixPath(entry))]
    finished = sum(PurePosixPath(entry).name != "manifest.json" for entry in runs)
    if not finished:
        return 0
    check_out(out)
    listed = _listed(out) - {FILE_LIST}
    for entry in runs:
        target = out / entry
        target.parent.mkdir(parents=True, exist_ok=True)
        os.replace(stage / entry, target)
    _save_list(out, listed | set(runs))
    return finished


def _clear(folder: Path) -> None:
    """Empty ``folder``, a staging folder (gpfverify's own, all of it)."""
    for entry in folder.iterdir():
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry)
        else:
            entry.unlink()


def _remove_listed(folder: Path) -> str | None:
    """Remove what ``folder``'s list names (files, and the folders that only held them), then
    ``folder`` itself when nothing is left; never anything the list does not name. The first entry
    left (one that arrived while the folder was being replaced), or None."""
    listed = _listed(folder)
    for entry in sorted(listed - {FILE_LIST}) + [FILE_LIST]:
        path = folder / entry
        if path.is_symlink() or path.is_file():
            path.unlink(missing_ok=True)
    parents = {p for entry in listed for p in PurePosixPath(entry).parents if str(p) != "."}
    for parent in sorted(parents, key=lambda p: len(p.parts), reverse=True):
        with contextlib.suppress(OSError):  # not empty: something the list does not name is in it
            (folder / parent).rmdir()
    try:
        folder.rmdir()
    except OSError:
        return next((entry for entry, _ in _entries(folder)), folder.name)
    return None


def _recover(stage: Path, out: Path) -> int:
    """Under the lock: finish what a killed command left — its saved runs into DIR, its other files
    removed; a previous DIR set aside for a commit that did not happen put back, or removed (what
    its list names) when the commit happened. The number of finished runs moved into DIR."""
    retired = sibling(out, RETIRED)
    if retired.exists():
        if out.exists():
            _remove_listed(retired)
        else:
            rename_noreplace(retired, out)
    finished = 0
    if any(stage.iterdir()):
        finished = _salvage_runs(stage, out)
        _clear(stage)
    return finished


def _copy_absent(src: str, dst: str) -> None:
    if not os.path.lexists(dst):
        shutil.copy2(src, dst)


#: renameat2's flag: fail with EEXIST rather than replace what is at the destination (Linux ≥ 3.15)
RENAME_NOREPLACE = 1
#: openat's "the current folder" for renameat2
AT_FDCWD = -100


def _renameat2():
    """The C library's ``renameat2``, or None where there is none (not Linux, an old C library)."""
    import ctypes

    try:
        function = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return None
    function.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    function.restype = ctypes.c_int
    return function


def rename_noreplace(source: Path, target: Path) -> None:
    """Rename the folder ``source`` to ``target`` unless something is at ``target``
    (:class:`FileExistsError` then), atomically: ``renameat2(RENAME_NOREPLACE)`` where the system
    has it. Elsewhere (or on a file system without the flag) a check, then ``rename``, which for a
    folder replaces at most an *empty* folder made between the two, never a file or a folder that
    holds anything: nothing of anyone's can be lost."""
    import ctypes

    function = _renameat2()
    if function is not None:
        if function(AT_FDCWD, os.fsencode(source), AT_FDCWD, os.fsencode(target), RENAME_NOREPLACE) == 0:
            return
        number = ctypes.get_errno()
        if number not in (errno.ENOSYS, errno.EINVAL):  # EINVAL: the file system does not take the flag
            raise OSError(number, os.strerror(number), str(source), None, str(target))
    if os.path.lexists(target):
        raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), str(source), None, str(target))
    os.rename(source, target)


def _swap_in(stage: Path, out: Path) -> str | None:
    """Replace ``out`` (absent, empty, or gpfverify's files only) by the finished ``stage``, never
    removing what ``out``'s list does not name: a folder that appears at ``out`` while this runs is
    not replaced (the command fails, that folder untouched), and an entry that arrives in the old
    ``out`` while it is replaced stays (returned, with the folder it is kept in)."""
    check_out(out)  # nothing foreign arrived while the command ran
    if not os.path.lexists(out):
        try:
            rename_noreplace(stage, out)
        except FileExistsError:
            raise InputError(f"--out {out} was made by another program while the command ran; its results were "
                             "not written there (gpfverify never replaces a folder it did not make)") from None
        return None
    retired = sibling(out, RETIRED)
    rename_noreplace(out, retired)
    foreign = foreign_entry(retired)  # arrived between the check above and the rename
    if foreign is not None:
        with contextlib.suppress(OSError):
            rename_noreplace(retired, out)
        where = out if not retired.exists() else retired
        raise InputError(f"--out {out} gained {foreign}, which gpfverify did not write, while the command was "
                         f"writing it; the folder is as it was ({where}) and the command's results were not written")
    try:
        rename_noreplace(stage, out)
    except OSError:
        with contextlib.suppress(OSError):
            rename_noreplace(retired, out)
        raise
    left = _remove_listed(retired)
    return None if left is None else f"{left} arrived in {out} while it was being replaced; it is kept in {retired}"


def kept_note(out: Path, finished: int) -> str:
    """What an interrupted (or failed) command kept of its runs, for its one line."""
    if finished:
        return f"the saved runs are kept in {out}: run the command again with --resume to continue them"
    return f"nothing was written to {out}"


@contextlib.contextmanager
def output_folder(out: Path, keep: bool = True, wait: bool = False) -> Iterator[Path]:
    """Yield the staging folder a command writes its outputs to; commit it as ``out`` when the
    block ends normally, discard it when the block raises (keeping the saved runs when it was
    interrupted or lost a worker). ``keep``: start from a copy of ``out``'s files (runs to resume,
    sections to keep) rather than from an empty folder; ``wait``: wait for another command
    writing ``out`` rather than refuse. Module docstring."""
    check_out(out)
    out = canonical(out)
    made = _make_parents(out.parent)
    stage = sibling(out, PARTIAL)
    try:
        fd = _lock(stage, out, wait)
    except _Busy:
        _remove_made(made)
        raise InputError(f"--out {out} is being written by another gpfverify command; wait for it to finish "
                         "(or pass --wait), or choose another folder") from None
    except BaseException:
        _remove_made(made)
        raise
    for path in made:
        supervise.note("made", str(path))
    supervise.note("out", str(out))
    supervise.note("stage", str(stage))
    committed = False
    try:
        check_out(out)  # again, under the lock: the folder may have changed while this command waited
        _recover(stage, out)
        if keep and out.is_dir():
            shutil.copytree(out, stage, symlinks=True, dirs_exist_ok=True, copy_function=_copy_absent)
        yield stage
        if interrupt_received():  # a Ctrl-C that other code swallowed: interrupted all the same
            raise Interrupted
        _write_list(stage)
        left = _swap_in(stage, out)
        committed = True
        if left is not None:
            print(f"note: {left}", file=streams.diagnostics())
    except BaseException as exc:
        # an allocation failure, also one that compiled code reported as another error (a SystemError
        # near the address-space limit, :func:`gpfverify.memory.out_of_memory`)
        memory_out = isinstance(exc, Exception) and out_of_memory(exc) is not None
        if memory_out:
            release_reserve()  # room for keeping the runs and removing the staging folder
            traceback.clear_frames(exc.__traceback__)  # and the memory the failed work held
        if isinstance(exc, (KeyboardInterrupt, WorkerLost)) or memory_out or interrupt_received():
            finished = 0  # interrupted (also when compiled code turned the Ctrl-C into another error), a worker
            with contextlib.suppress(OSError, InputError):  # lost, memory out: the saved runs are kept
                if stage.exists():
                    finished = _salvage_runs(stage, out)
            exc.add_note(kept_note(out, finished))
        raise
    finally:
        if not committed:
            shutil.rmtree(stage, ignore_errors=True)
            if not out.exists():
                _remove_made(made)
        os.close(fd)
        supervise.note("done", str(stage))


def keep_abandoned(stage: Path, out: Path, made: Iterable[Path]) -> int | None:
    """What the process that supervised a command does when the command's process ended abruptly
    (killed, out of memory) holding ``stage``: what the next command on ``out`` would do, at once —
    the saved runs moved into ``out``, the rest removed, and the folders made to hold ``out``
    removed when nothing was moved (:mod:`gpfverify.supervise`). The number of finished runs
    moved; None when another command holds the folder by now or ``out`` may not be written."""
    try:
        fd = _lock(stage, out, wait=False)
    except (_Busy, OSError, InputError):
        return None
    try:
        finished = _recover(stage, out)
        stage.rmdir()
    except (OSError, InputError):
        return None
    finally:
        os.close(fd)
    if not out.exists():
        _remove_made(list(made))
    return finished


def final_path(path: Path, stage: Path, out: Path) -> Path:
    """Where ``path`` (inside the staging folder) will be once the folder is committed as ``out``:
    for messages and records that name output files."""
    return Path(out) / Path(path).relative_to(stage)
