"""Reading the files a user hands to gpfverify: regular files only, sizes bounded before anything
is allocated, one line naming the file for every refusal.

* :func:`open_regular` opens a path for reading and refuses what is not a regular file once
  links are resolved (a device such as ``/dev/zero``, a named pipe, a folder, a socket): such a
  "file" can be endless or block forever. The check is made on the opened descriptor (no race
  between a check and the open), and the open does not wait for a pipe's writer.
* :func:`read_npz` reads a ``numpy.savez`` archive after checking every member's ``.npy`` header:
  numeric arrays only (pickled objects are never loaded), each name once (two members of one
  name are refused, as a JSON key given twice is), no encrypted member, declared sizes within
  what the archive holds (a truncated or empty archive is refused) and within the memory this
  machine has free (a few kilobytes of compressed zeros may declare gigabytes). A member whose
  data is damaged (a flipped byte: a bad CRC or deflate stream) is refused when it is read. :class:`NpzArchive` does
  the same for a caller that reads large arrays a block of rows at a time.

Every refusal is a :class:`~gpfverify.errors.CaseFileError` (an ``InputError``) whose message
names the path. This module imports numpy and the standard library only.
"""

from __future__ import annotations

import io
import math
import os
import stat
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np

from gpfverify.errors import CaseFileError

#: dtype kinds an archive may hold: booleans, integers, floats, complex numbers, strings (the
#: caller decides which it accepts); objects (pickles), structured and void dtypes are refused
NPZ_KINDS = "biufcUS"
#: share of the machine's available memory one input may declare
MEMORY_SHARE = 0.25


def memory_budget() -> int:
    """Bytes one input may take: :data:`MEMORY_SHARE` of the memory available now (Linux's
    MemAvailable; elsewhere the physical memory)."""
    try:
        with open("/proc/meminfo", "rb") as fh:
            for line in fh:
                if line.startswith(b"MemAvailable:"):
                    return int(int(line.split()[1]) * 1024 * MEMORY_SHARE)
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") * MEMORY_SHARE)
    except (AttributeError, ValueError, OSError):
        return 4 << 30


def human_bytes(n: float) -> str:
    """``n`` bytes as a short text (``8.0 GB``)."""
    for unit in ("bytes", "kB", "MB", "GB", "TB", "PB"):
        if abs(n) < 1000 or unit == "PB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1000
    return f"{n:.1f} PB"  # pragma: no cover


_KINDS = {stat.S_ISDIR: "a folder", stat.S_ISCHR: "a character device", stat.S_ISBLK: "a block device",
          stat.S_ISFIFO: "a named pipe", stat.S_ISSOCK: "a socket"}


def open_regular(path) -> BinaryIO:
    """``path`` opened for binary reading; CaseFileError when it cannot be opened or is not a
    regular file after resolving links (the open itself never blocks on a pipe)."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise CaseFileError(f"cannot read {path}: {exc.strerror or exc}") from None
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            kind = next((name for test, name in _KINDS.items() if test(mode)), "not a regular file")
            raise CaseFileError(f"cannot read {path}: it is {kind}, not a regular file "
                                f"(gpfverify reads files, not devices or pipes)")
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_regular(path) -> bytes:
    """The bytes of a regular file (:func:`open_regular`), refused when larger than the memory
    budget."""
    with open_regular(path) as fh:
        size = os.fstat(fh.fileno()).st_size
        budget = memory_budget()
        if size > budget:
            raise CaseFileError(f"{path} is {human_bytes(size)}, more than this machine can hold now "
                                f"({human_bytes(budget)})")
        try:
            return fh.read()
        except OSError as exc:
            raise CaseFileError(f"cannot read {path}: {exc.strerror or exc}") from None


@dataclass(frozen=True)
class NpyHeader:
    """A member's ``.npy`` header: shape, dtype, memory order and the member's declared sizes."""

    name: str
    shape: tuple[int, ...]
    dtype: np.dtype
    fortran_order: bool
    header_bytes: int
    member_bytes: int

    @property
    def nbytes(self) -> int:
        return math.prod(self.shape) * self.dtype.itemsize

    @property
    def row_bytes(self) -> int:
        return math.prod(self.shape[1:]) * self.dtype.itemsize


#: what zipfile and zlib raise for a damaged member: a bad CRC (BadZipFile), a corrupted deflate
#: stream (zlib.error), a truncated one (EOFError), a member it cannot decompress
#: (NotImplementedError: an unknown method; RuntimeError: a password needed)
_DAMAGED = (zipfile.BadZipFile, zlib.error, OSError, EOFError, ValueError, NotImplementedError, RuntimeError)


def _one_line(message: object) -> str:
    return " ".join(str(message).split())


class NpzArchive:
    """A ``numpy.savez`` archive with every member's header checked on opening (module
    docstring). :meth:`read` reads one array whole (its size within the memory budget);
    :meth:`row_reader` reads a large C-ordered array a block of rows at a time."""

    def __init__(self, path):
        self.path = Path(path)
        self._fh = open_regular(self.path)
        try:
            size = os.fstat(self._fh.fileno()).st_size
            if size == 0:
                raise CaseFileError(f"{self.path} is empty, not an npz archive (numpy.savez / "
                                    f"numpy.savez_compressed)")
            try:
                self._zip = zipfile.ZipFile(self._fh)
            except (zipfile.BadZipFile, OSError, EOFError, ValueError) as exc:
                raise CaseFileError(f"{self.path} is not an npz archive (numpy.savez / "
                                    f"numpy.savez_compressed), or it is truncated: {_one_line(exc)}") from None
            self.headers: dict[str, NpyHeader] = {}
            for info in self._zip.infolist():
                if not info.filename.endswith(".npy"):
                    raise CaseFileError(f"{self.path} holds {info.filename!r}, which is not a .npy array "
                                        f"(an npz archive holds only arrays)")
                if info.filename[:-4] in self.headers:  # zipfile would read the last of them silently
                    raise CaseFileError(f"{self.path} holds two arrays named {info.filename[:-4]!r}: which one is "
                                        "meant is not clear (an npz archive names each array once)")
                if info.flag_bits & 0x1:
                    raise CaseFileError(f"{self.path}: array {info.filename[:-4]} is encrypted; gpfverify reads "
                                        "archives as numpy.savez writes them, unencrypted")
                header = self._header(info)
                self.headers[header.name] = header
        except BaseException:
            self._fh.close()
            raise

    def __enter__(self) -> NpzArchive:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self._zip.close()
        self._fh.close()

    @property
    def files(self) -> list[str]:
        return list(self.headers)

    def _open(self, info: zipfile.ZipInfo):
        try:
            return self._zip.open(info)
        except _DAMAGED as exc:
            raise CaseFileError(f"{self.path}: array {info.filename[:-4]} cannot be read: "
                                f"{_one_line(exc)}") from None

    def _header(self, info: zipfile.ZipInfo) -> NpyHeader:
        name = info.filename[:-4]
        where = f"{self.path}: array {name}"
        with self._open(info) as member:
            try:
                version = np.lib.format.read_magic(member)
                if version == (1, 0):
                    shape, fortran, dtype = np.lib.format.read_array_header_1_0(member)
                elif version == (2, 0):
                    shape, fortran, dtype = np.lib.format.read_array_header_2_0(member)
                else:
                    raise CaseFileError(f"{where} uses .npy format version {version}, which gpfverify "
                                        f"does not read (1.0 and 2.0 are what numpy.savez writes)")
                header_bytes = member.tell()
            except CaseFileError:
                raise
            except (ValueError, SyntaxError, TypeError) as exc:
                raise CaseFileError(f"{where} has no readable .npy header: {_one_line(exc)}") from None
            except _DAMAGED as exc:
                raise CaseFileError(f"{where} cannot be read, the archive is damaged: {_one_line(exc)}") from None
        if dtype.hasobject or dtype.kind not in NPZ_KINDS or dtype.fields is not None:
            raise CaseFileError(f"{where} cannot be read: its dtype {dtype} is not numeric (arrays of "
                                f"Python objects are never loaded)")
        header = NpyHeader(name, tuple(int(s) for s in shape), dtype, bool(fortran), header_bytes,
                           int(info.file_size))
        if header.header_bytes + header.nbytes != header.member_bytes:
            raise CaseFileError(f"{where} declares shape {header.shape} ({human_bytes(header.nbytes)}) but "
                                f"the archive holds {human_bytes(header.member_bytes - header_bytes)} of data "
                                f"for it: the archive is damaged or truncated")
        return header

    def check_budget(self, names, budget: int | None = None) -> None:
        """Refuse when the arrays ``names`` together declare more bytes than ``budget``
        (default :func:`memory_budget`)."""
        budget = memory_budget() if budget is None else budget
        total = sum(self.headers[n].nbytes for n in names)
        if total > budget:
            big = max(names, key=lambda n: self.headers[n].nbytes)
            h = self.headers[big]
            raise CaseFileError(f"{self.path}: its arrays declare {human_bytes(total)} (array {big} has shape "
                                f"{h.shape}, {human_bytes(h.nbytes)}), more than this machine can hold now "
                                f"({human_bytes(budget)})")

    def read(self, name: str) -> np.ndarray:
        """Array ``name`` whole (its declared size checked against the memory budget first)."""
        self.check_budget([name])
        header = self.headers[name]
        with self._open(self._zip.getinfo(name + ".npy")) as member:
            member.seek(header.header_bytes)
            return self._read_into(member, header, header.shape, name)

    def _read_into(self, member, header: NpyHeader, shape: tuple[int, ...], name: str) -> np.ndarray:
        out = np.empty(shape, dtype=header.dtype, order="F" if header.fortran_order else "C")
        buffer = memoryview(out.reshape(-1, order="A").view(np.uint8).data) if out.size else memoryview(b"")
        try:
            filled = 0
            while filled < len(buffer):
                got = member.readinto(buffer[filled:])
                if not got:
                    raise CaseFileError(f"{self.path}: array {name} is truncated (expected "
                                        f"{human_bytes(len(buffer))}, got {human_bytes(filled)})")
                filled += got
        except CaseFileError:
            raise
        except _DAMAGED as exc:
            raise CaseFileError(f"{self.path}: array {name} cannot be read, the archive is damaged: "
                                f"{_one_line(exc)}") from None
        return out

    def row_reader(self, name: str) -> RowReader:
        """Sequential reader of array ``name``'s rows (first axis); a Fortran-ordered array is
        read whole (within the budget) and handed out in rows."""
        return RowReader(self, name)


class RowReader:
    """``take(count)`` returns the next ``count`` rows of one archive member (module docstring)."""

    def __init__(self, archive: NpzArchive, name: str):
        self.archive, self.name = archive, name
        self.header = archive.headers[name]
        self._whole: np.ndarray | None = None
        self._member: io.BufferedIOBase | None = None
        self._next = 0
        if self.header.fortran_order or not self.header.shape:
            self._whole = archive.read(name)
        else:
            self._member = archive._open(archive._zip.getinfo(name + ".npy"))
            self._member.seek(self.header.header_bytes)

    def take(self, count: int) -> np.ndarray:
        rows = self.header.shape[0]
        count = max(0, min(count, rows - self._next))
        start, self._next = self._next, self._next + count
        if self._whole is not None:
            return self._whole[start:start + count]
        assert self._member is not None
        return self.archive._read_into(self._member, self.header, (count,) + self.header.shape[1:], self.name)

    def close(self) -> None:
        if self._member is not None:
            self._member.close()


def read_npz(path, shapes: dict[str, tuple[int | None, ...]] | None = None) -> dict[str, np.ndarray]:
    """Every array of an npz archive after the header checks of :class:`NpzArchive`; with
    ``shapes`` only those arrays (the ones present), each refused from its header alone when its
    declared shape differs (``None`` matches any size); then a check that together they fit in
    memory. For ``check --measurements`` / ``--training`` and other small archives."""
    with NpzArchive(path) as archive:
        wanted = [n for n in archive.files if shapes is None or n in shapes]
        for name, want in (shapes or {}).items():
            if name not in archive.headers:
                continue
            declared = archive.headers[name].shape
            if len(declared) != len(want) or any(w is not None and d != w for d, w in zip(declared, want)):
                shown = str(tuple("?" if w is None else w for w in want)).replace("'", "")
                raise CaseFileError(f"{archive.path}: array {name} has shape {declared}, expected {shown}")
        archive.check_budget(wanted)
        return {n: archive.read(n) for n in wanted}
