"""Running a user's code (the system file of ``gpfverify check``) so that it can neither end
gpfverify, nor write into its output, nor move it to another folder.

While :func:`guarded` is active:

* ``print()`` (anything written to ``sys.stdout``) goes to stderr, so ``check --json`` prints
  only its results;
* ``sys.exit(...)``/``exit()`` (a :class:`SystemExit`) becomes a :class:`UserExit` naming the
  user's file: exit status 2 and one line, never a silent exit 0 or 3;
* ``os._exit(...)``, which ends a process without any cleanup and cannot be caught, is replaced
  by a function raising :class:`UserExit`, so the call is reported the same way. Called from a
  thread the code started, it ends that thread and the block raises :class:`UserExit` when it
  ends. Code that reaches the operating system's exit by another route (``posix._exit``,
  ``ctypes``, a thread calling it after the block) is caught one level up, by
  :mod:`gpfverify.supervise`: the command line runs the command in a child process;
* an exception that is not an :class:`Exception` (a :class:`BaseException` subclass, a
  ``KeyboardInterrupt`` the code raises itself) becomes a :class:`UserCodeError` naming it:
  exit status 2 and one line, not "a bug" and not "interrupted". A Ctrl-C or SIGTERM is told apart
  by the exception gpfverify's own signal handler raises (:class:`Interrupted`); in a worker
  process, which ignores SIGINT, every ``KeyboardInterrupt`` is the code's own; under a handler
  that is not gpfverify's (the Python API in a notebook), every one is taken for an interruption;
* the current folder is restored when the block ends, so a system file that calls
  ``os.chdir`` moves none of gpfverify's relative paths (``--out`` is resolved before the code
  runs anyway).

gpfverify's own hard exits (a worker whose parent died) keep the real ``os._exit``
(:data:`gpfverify.supervise.HARD_EXIT`).
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

from gpfverify import supervise
from gpfverify.errors import InputError

Handler = TypeVar("Handler", bound=Callable[..., Any])


class UserCodeError(InputError):
    """The user's code stopped gpfverify in a way an ordinary error does not: an exit, or an
    exception that is not an :class:`Exception`. The command stops (a run is not just recorded
    as failed)."""


class UserExit(UserCodeError):
    """The user's code tried to end the process."""


class Interrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM, raised by gpfverify's own signal handler (:func:`marks_interrupts`)."""


def marks_interrupts(handler: Handler) -> Handler:
    """``handler``, a SIGINT/SIGTERM handler, marked as one whose KeyboardInterrupts are
    :class:`Interrupted`."""
    handler.raises_interrupted = True  # type: ignore[attr-defined]
    return handler


def _interruptions_are_marked() -> bool:
    """Whether a Ctrl-C is told apart from a KeyboardInterrupt the user's code raises: SIGINT's
    handler is a marked one (:func:`marks_interrupts`), or SIGINT is ignored (a worker process,
    which no Ctrl-C interrupts)."""
    handler = signal.getsignal(signal.SIGINT)
    return handler is signal.SIG_IGN or getattr(handler, "raises_interrupted", False)


def system_file(spec: str) -> str:
    """How messages name the user's code of a ``SYSTEM.py:NAME`` spec: ``the system file SYSTEM.py``."""
    return f"the system file {os.path.basename(str(spec).rsplit(':', 1)[0])}"


#: exits the user's code asked for from threads it started, reported when the guarded block ends
_thread_exits: list[str] = []


@contextlib.contextmanager
def guarded(what: str) -> Iterator[None]:
    """Run the block as user code described by ``what`` (e.g. ``"the system file model.py"``)."""
    def refuse_exit(code: int = 0) -> None:
        if threading.current_thread() is not threading.main_thread():
            _thread_exits.append(f"{what} called os._exit({code!r}) in a thread it started "
                                 f"({threading.current_thread().name})")
            raise SystemExit  # ends that thread, quietly
        raise UserExit(f"{what} called os._exit({code!r}); the system's code must not end the process")

    supervise.note("user", what)
    saved_exit = os._exit
    try:
        folder: int | None = os.open(".", os.O_RDONLY)
    except OSError:  # a current folder that cannot be opened cannot be returned to either
        folder = None
    os._exit = refuse_exit  # type: ignore[assignment]
    try:
        with contextlib.redirect_stdout(sys.stderr):
            yield
    except InputError:
        raise
    except SystemExit as exc:
        raise UserExit(f"{what} called sys.exit({exc.code!r}); the system's code must not end the "
                       "process") from None
    except KeyboardInterrupt as exc:
        if isinstance(exc, Interrupted) or not _interruptions_are_marked():
            raise
        raise UserCodeError(f"{what} raised KeyboardInterrupt{_told(exc)} itself (no Ctrl-C was pressed); "
                            "the system's code must not stop the command") from None
    except Exception:
        raise
    except BaseException as exc:
        raise UserCodeError(f"{what} raised {type(exc).__name__}{_told(exc)}, a BaseException that is not an "
                            "Exception; the system's code must raise Exception subclasses") from None
    finally:
        os._exit = saved_exit
        if folder is not None:
            with contextlib.suppress(OSError):
                os.fchdir(folder)
            os.close(folder)
    if _thread_exits:
        message = _thread_exits[0]
        _thread_exits.clear()
        raise UserExit(f"{message}; the system's code must not end the process")


def _told(exc: BaseException) -> str:
    """`` (its message)``, on one line, when the exception has one."""
    text = " ".join(str(exc).split())
    return f" ({text})" if text else ""
