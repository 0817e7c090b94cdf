"""Solvers' own output kept off gpfverify's stdout and stderr.

Compiled solvers write to the process's file descriptors 1 and 2 directly (SCS prints
"ERROR: could not determine problem status." from C whatever cvxpy's ``verbose`` says), so
redirecting ``sys.stdout`` is not enough: :func:`solver_output_discarded` points descriptors 1 and
2 at the null device for the duration of a solve and restores them afterwards. A solver's status
reaches the user through the exception or result the caller makes of it, in gpfverify's words.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager, redirect_stderr, redirect_stdout


def _open_descriptor(fd: int) -> bool:
    try:
        os.fstat(fd)
    except OSError:
        return False
    return True


@contextmanager
def solver_output_discarded() -> Iterator[None]:
    """Descriptors 1 and 2 (those that are open) write to os.devnull inside the block, and so do
    Python's ``sys.stdout`` and ``sys.stderr`` (a solver's Python interface prints there, e.g. SCS's
    "WARNING - large complementary slackness residual"); Python's buffered streams are flushed first
    so nothing written before the block is lost or reordered."""
    for stream in (sys.stdout, sys.stderr):
        if stream is not None:
            stream.flush()
    saved = [(fd, os.dup(fd)) for fd in (1, 2) if _open_descriptor(fd)]
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        for fd, _ in saved:
            os.dup2(null, fd)
        with open(os.devnull, "w") as sink, redirect_stdout(sink), redirect_stderr(sink):
            yield
    finally:
        for fd, copy in saved:
            os.dup2(copy, fd)
            os.close(copy)
        os.close(null)
