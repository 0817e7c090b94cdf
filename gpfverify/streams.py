"""gpfverify's own standard streams: what a command prints goes where it means to, whatever the
code it runs does to ``sys.stdout``, ``sys.stderr`` or the threads it starts.

While a command runs (:func:`owned`, entered by the command line around every command), gpfverify
writes its result to :func:`result` and its diagnostics (progress, notes, its one error line) to
:func:`diagnostics`, a :class:`Diagnostics` stream that drops a line it cannot write (stderr
closed, on a full device). What other code writes goes through ``sys.stdout`` and ``sys.stderr``,
two :class:`Routed` streams:

* the user's code (:func:`user_code`, entered by :func:`gpfverify.usercode.guarded`) and every
  thread but the command's (a daemon thread's ``print``, a library's thread) write to the
  diagnostics, as they come: a system file's ``print`` shows on stderr, never in ``--json``
  output;
* the command's own thread outside the user's code writes ``sys.stdout`` to the result and
  ``sys.stderr`` to the *held* stream: run as a program, descriptor 2, which
  :mod:`gpfverify.supervise` holds until the command's outcome is known (a library's log lines or
  warnings show after a command that completed, never beside the one line of one that failed);
  called from Python, the diagnostics.

None of them can be closed by other code (``close()`` only flushes), and when other code replaces
them (``sys.stderr = None``) :func:`reinstate` puts them back: the user's code is left with
:func:`user_code`, and the command line reinstates them before it prints its one line.

Run as a program, gpfverify writes its result and diagnostics through private duplicates of
descriptors 1 and 2 taken when it starts (:func:`private_streams`), so that code closing or
redirecting descriptor 1 or 2 changes nothing gpfverify prints.
"""

from __future__ import annotations

import contextlib
import io
import sys
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any


class Diagnostics:
    """stderr that never stops a command: a write that fails (a closed or full stream) is dropped.
    ``close()`` only flushes: the stream is gpfverify's."""

    def __init__(self, stream) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text) if self._stream is not None else len(text)
        except (OSError, ValueError):  # ValueError: the stream was closed
            return len(text)

    def flush(self) -> None:
        with contextlib.suppress(OSError, ValueError, AttributeError):
            self._stream.flush()

    def close(self) -> None:
        self.flush()

    @property
    def closed(self) -> bool:
        return False

    def isatty(self) -> bool:
        try:
            return bool(self._stream.isatty())
        except (OSError, ValueError, AttributeError):
            return False

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


class Routed:
    """``sys.stdout`` or ``sys.stderr`` while a command runs (module docstring): writes from the
    command's thread outside the user's code to ``own``, everything else to ``other``. Errors of
    ``own`` (a closed result pipe) reach the command; ``close()`` only flushes."""

    def __init__(self, own, other: Diagnostics) -> None:
        self.own, self.other = own, other
        self._owner = threading.get_ident()

    def _target(self):
        if threading.get_ident() == self._owner and not _user_depth[0]:
            return self.own
        return self.other

    def write(self, text: str) -> int:
        return self._target().write(text)

    def writelines(self, lines) -> None:
        for line in lines:
            self.write(line)

    def flush(self) -> None:
        self._target().flush()  # a closed result pipe shows here, inside the command's error boundary

    def close(self) -> None:
        with contextlib.suppress(OSError, ValueError):
            self._target().flush()

    @property
    def closed(self) -> bool:
        return False

    def isatty(self) -> bool:
        try:
            return bool(self._target().isatty())
        except (OSError, ValueError, AttributeError):
            return False

    def __getattr__(self, name: str) -> Any:
        return getattr(self._target(), name)


@dataclass(frozen=True)
class _Command:
    """The streams of the command running now (:func:`owned`)."""

    result: Any
    diagnostics: Diagnostics
    stdout: Routed | None
    stderr: Routed


#: how deep the command's thread is inside the user's code (:func:`user_code`)
_user_depth = [0]
#: the commands running now, innermost last (one, except when a command runs another)
_installed: list[_Command] = []


@contextlib.contextmanager
def owned(stdout, stderr, held=None) -> Iterator[None]:
    """gpfverify's streams for the block (module docstring): ``stdout`` the command's result stream
    (None when standard output is closed), ``stderr`` its diagnostics, ``held`` where other code's
    writes to ``sys.stderr`` go (default: the diagnostics). ``sys.stdout`` and ``sys.stderr`` are
    put back as they were found afterwards."""
    saved = sys.stdout, sys.stderr
    diagnostics = Diagnostics(stderr)
    streams = _Command(stdout, diagnostics, None if stdout is None else Routed(stdout, diagnostics),
                       Routed(diagnostics if held is None else Diagnostics(held), diagnostics))
    _installed.append(streams)
    sys.stdout, sys.stderr = streams.stdout, streams.stderr
    try:
        yield
    finally:
        _installed.remove(streams)
        sys.stdout, sys.stderr = saved


def reinstate() -> None:
    """Put the command's streams back as ``sys.stdout`` and ``sys.stderr`` when other code replaced
    them (``sys.stderr = None``, ``sys.stdout = open(...)``)."""
    if _installed:
        sys.stdout, sys.stderr = _installed[-1].stdout, _installed[-1].stderr


def diagnostics():
    """Where gpfverify's diagnostics go: the command's :class:`Diagnostics` stream while a command
    runs, else ``sys.stderr`` (or a stream that drops everything when there is none)."""
    if _installed:
        return _installed[-1].diagnostics
    return sys.stderr if sys.stderr is not None else Diagnostics(None)


def result():
    """Where gpfverify's result goes: the command's standard output while a command runs (also
    from the command's other threads), else ``sys.stdout``."""
    if _installed and _installed[-1].result is not None:
        return _installed[-1].result
    return sys.stdout


@contextlib.contextmanager
def user_code() -> Iterator[None]:
    """The block is the user's code: what it writes to ``sys.stdout`` or ``sys.stderr`` goes to the
    diagnostics as it comes, and the streams it closed or replaced are the command's again when it
    ends. Outside a command (the Python API, a worker process) ``sys.stdout`` is redirected to
    ``sys.stderr`` for the block and both are put back as they were found."""
    if not _installed:
        saved = sys.stdout, sys.stderr
        try:
            with contextlib.redirect_stdout(sys.stderr):
                yield
        finally:
            sys.stdout, sys.stderr = saved
        return
    _user_depth[0] += 1
    try:
        yield
    finally:
        _user_depth[0] -= 1
        reinstate()


def private_streams(fds: tuple[int | None, int | None]) -> tuple[Any, Any]:
    """Text streams for gpfverify's own standard output and error over the descriptors ``fds``
    (private duplicates of 1 and 2, :func:`duplicate`), in the encoding and error handling of the
    interpreter's own streams; None for a standard stream that was closed when gpfverify started."""
    made = []
    for fd, original in zip(fds, (sys.__stdout__, sys.__stderr__)):
        if fd is None or original is None:
            made.append(original)
            continue
        made.append(io.TextIOWrapper(io.FileIO(fd, "w", closefd=True), encoding=original.encoding,
                                     errors=original.errors, line_buffering=original.line_buffering,
                                     write_through=original is sys.__stderr__))
    return made[0], made[1]


def duplicate(fd: int) -> int | None:
    """A private duplicate of descriptor ``fd`` (numbered 10 or above, closed on exec), or None when
    ``fd`` is not open."""
    import fcntl

    try:
        return fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 10)
    except OSError:
        return None
