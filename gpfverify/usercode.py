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
* the current folder and Python's recursion limit are restored when the block ends, so a system
  file that calls ``os.chdir`` moves none of gpfverify's relative paths (``--out`` is resolved
  before the code runs anyway) and one that lowers the limit (``sys.setrecursionlimit``) leaves
  gpfverify's own code its limit (a ``RecursionError`` under the lowered limit is an error of the
  user's code, naming the limit, not "input nested too deeply"); ``sys.stdout`` and ``sys.stderr`` are gpfverify's again
  (:func:`gpfverify.streams.user_code`), whatever the code closed or replaced.

:func:`time_limited` (``--timeout SECONDS``) stops a call of the user's code that does not return
in time: :class:`UserTimeout`, exit status 2 and one line naming the function and the time. It
works by ``SIGALRM`` in the thread that runs the code (the main thread of the command's process
or of a worker process): Python code and waits (``time.sleep``, I/O) are interrupted; compiled
code that never returns to Python is not (Ctrl-C and SIGTERM still stop the command,
:mod:`gpfverify.supervise`). The exception it raises derives from :class:`BaseException`, so an
``except Exception`` in the user's code does not swallow it, and it is raised again every
:data:`REPEAT_SECONDS` until the call gives up.

:func:`note_interrupt` records that a Ctrl-C or SIGTERM reached gpfverify's handler, so that one
swallowed by other code (a weak-reference callback, the user's ``except BaseException``) still ends
the command as interrupted.

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

from gpfverify import streams, supervise
from gpfverify.errors import InputError

Handler = TypeVar("Handler", bound=Callable[..., Any])


class UserCodeError(InputError):
    """The user's code stopped gpfverify in a way an ordinary error does not: an exit, or an
    exception that is not an :class:`Exception`. The command stops (a run is not just recorded
    as failed)."""


class UserExit(UserCodeError):
    """The user's code tried to end the process."""


class UserTimeout(UserCodeError):
    """A call of the user's code did not return within ``--timeout`` (:func:`time_limited`)."""


class Interrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM, raised by gpfverify's own signal handler (:func:`marks_interrupts`)."""


#: how many Ctrl-Cs or SIGTERMs gpfverify's handler has seen since the command started
_interrupts = [0]


def note_interrupt() -> None:
    """Record that gpfverify's handler saw a Ctrl-C or SIGTERM (module docstring)."""
    _interrupts[0] += 1


def interrupt_received() -> bool:
    """Whether a Ctrl-C or SIGTERM reached gpfverify's handler since :func:`forget_interrupts`."""
    return _interrupts[0] > 0


def forget_interrupts() -> None:
    """A command starts: no interrupt seen yet."""
    _interrupts[0] = 0


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
    saved_exit, recursion_limit = os._exit, sys.getrecursionlimit()
    try:
        folder: int | None = os.open(".", os.O_RDONLY)
    except OSError:  # a current folder that cannot be opened cannot be returned to either
        folder = None
    os._exit = refuse_exit  # type: ignore[assignment]
    try:
        with streams.user_code():
            yield
    except Exception as exc:
        if sys.getrecursionlimit() < recursion_limit and _caused_by(exc, RecursionError):
            raise UserCodeError(f"{what} lowered Python's recursion limit to {sys.getrecursionlimit()} "
                                f"(sys.setrecursionlimit; it was {recursion_limit}), too low for the code it calls; "
                                "leave the limit as it is") from None
        raise
    except SystemExit as exc:
        raise UserExit(f"{what} called sys.exit({exc.code!r}); the system's code must not end the "
                       "process") from None
    except KeyboardInterrupt as exc:
        if isinstance(exc, Interrupted) or not _interruptions_are_marked():
            raise
        raise UserCodeError(f"{what} raised KeyboardInterrupt{_told(exc)} itself (no Ctrl-C was pressed); "
                            "the system's code must not stop the command") from None
    except BaseException as exc:
        raise UserCodeError(f"{what} raised {type(exc).__name__}{_told(exc)}, a BaseException that is not an "
                            "Exception; the system's code must raise Exception subclasses") from None
    finally:
        os._exit = saved_exit
        sys.setrecursionlimit(recursion_limit)
        if folder is not None:
            with contextlib.suppress(OSError):
                os.fchdir(folder)
            os.close(folder)
    if _thread_exits:
        message = _thread_exits[0]
        _thread_exits.clear()
        raise UserExit(f"{message}; the system's code must not end the process")


def _caused_by(exc: BaseException, kind: type[BaseException]) -> bool:
    """Whether ``exc`` or an exception in its chain (cause or context) is a ``kind``."""
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        if isinstance(current, kind):
            return True
        seen.add(id(current))
        current = current.__cause__ or current.__context__
    return False


def _told(exc: BaseException) -> str:
    """`` (its message)``, on one line, when the exception has one."""
    text = " ".join(str(exc).split())
    return f" ({text})" if text else ""


# ---- --timeout ------------------------------------------------------------------------------------

#: seconds between two raises of :class:`_TimeUp` in a call that swallowed the first
REPEAT_SECONDS = 0.1


class _TimeUp(BaseException):
    """Raised in the user's code when its time is up; :func:`time_limited` turns it into
    :class:`UserTimeout` (a BaseException, so that ``except Exception`` does not swallow it)."""


class _Limit(threading.local):
    """The time limit of this process (seconds or None) and the call it governs now."""

    seconds: float | None = None
    depth = 0
    timed_out: str | None = None


_limit = _Limit()


def set_time_limit(seconds: float | None) -> None:
    """Limit every call of the user's code in this process to ``seconds`` (None: no limit). Called
    from the main thread (it sets the SIGALRM handler)."""
    _limit.seconds = seconds
    if seconds is not None and signal.getsignal(signal.SIGALRM) is not _time_up:
        signal.signal(signal.SIGALRM, _time_up)


def time_limit() -> float | None:
    """The limit :func:`set_time_limit` set (for worker processes)."""
    return _limit.seconds


def _time_up(signum, frame) -> None:
    if _limit.depth:
        signal.setitimer(signal.ITIMER_REAL, REPEAT_SECONDS)  # again, should the code swallow this one
        raise _TimeUp


@contextlib.contextmanager
def time_limited(what: str | Callable[[], str]) -> Iterator[None]:
    """Run the block, the user's code described by ``what`` (or by what ``what()`` returns, asked
    only when the time is up), within the limit of :func:`set_time_limit`: :class:`UserTimeout`
    when it has not returned by then. A block inside another is governed by the outer one; no
    limit in a thread other than the main one (no SIGALRM there)."""
    seconds = _limit.seconds
    if seconds is None or _limit.depth or threading.current_thread() is not threading.main_thread():
        yield
        return
    _limit.depth = 1
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    except _TimeUp:
        _limit.timed_out = (f"{what() if callable(what) else what} did not return within {seconds:g} s "
                            f"(--timeout {seconds:g}); the command stopped")
        raise UserTimeout(_limit.timed_out) from None
    finally:
        _limit.depth = 0  # first: a SIGALRM arriving now is ignored
        signal.setitimer(signal.ITIMER_REAL, 0)


def call_limited(what: str | Callable[[], str], fn: Callable[..., Any], *args) -> Any:
    """``fn(*args)``, the user's function described by ``what``, within the time limit (at no cost
    when there is none)."""
    if _limit.seconds is None:
        return fn(*args)
    with time_limited(what):
        return fn(*args)


def describe(fn: Callable) -> str:
    """A user's function as messages name it: ``h (system.py, line 12)``."""
    code = getattr(fn, "__code__", None)
    name = getattr(fn, "__qualname__", None) or type(fn).__name__
    if code is None:
        return name
    return f"{name} ({os.path.basename(code.co_filename)}, line {code.co_firstlineno})"


def timed_out() -> str | None:
    """The message of the last call that ran out of time (a caller that cannot see the exception,
    such as pytest's report of a property, reads it here), or None; reading it forgets it."""
    what, _limit.timed_out = _limit.timed_out, None
    return what
