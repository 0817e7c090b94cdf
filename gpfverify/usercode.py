"""Running a user's code (the system file of ``gpfverify check``) so that it can neither end
gpfverify nor write into its output.

While :func:`guarded` is active:

* ``print()`` (anything written to ``sys.stdout``) goes to stderr, so ``check --json`` prints
  only its results;
* ``sys.exit(...)``/``exit()`` (a :class:`SystemExit`) becomes an
  :class:`~gpfverify.errors.InputError` naming the user's file: exit status 2 and one line, never a
  silent exit 0 or 3;
* ``os._exit(...)``, which ends a process without any cleanup and cannot be caught, is replaced
  by a function raising :class:`UserExit` (an ``InputError``), so the call is reported the same
  way. Code that reaches the operating system's exit by another route (``ctypes``, a signal to
  itself) is not intercepted.

gpfverify's own hard exits (a worker whose parent died) keep the real ``os._exit``: they take it
before any user code runs (:data:`HARD_EXIT`).
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator

from gpfverify.errors import InputError

#: the operating system's exit, for gpfverify's own use while user code may be running
HARD_EXIT = os._exit


class UserExit(InputError):
    """The user's code tried to end the process."""


def system_file(spec: str) -> str:
    """How messages name the user's code of a ``SYSTEM.py:NAME`` spec: ``the system file SYSTEM.py``."""
    return f"the system file {os.path.basename(str(spec).rsplit(':', 1)[0])}"


@contextlib.contextmanager
def guarded(what: str) -> Iterator[None]:
    """Run the block as user code described by ``what`` (e.g. ``"the system file model.py"``)."""
    def refuse_exit(code: int = 0) -> None:
        raise UserExit(f"{what} called os._exit({code!r}); the system's code must not end the process")

    saved = os._exit
    os._exit = refuse_exit  # type: ignore[assignment]
    try:
        with contextlib.redirect_stdout(sys.stderr):
            yield
    except SystemExit as exc:
        raise UserExit(f"{what} called sys.exit({exc.code!r}); the system's code must not end the "
                       "process") from None
    finally:
        os._exit = saved
