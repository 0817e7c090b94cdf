"""Process-level settings, and one BLAS thread inside gpfverify's own calls.

gpfverify's matrices are small (tens to a thousand rows); multithreaded BLAS on them costs more in
thread start-up and contention than it gains — measured up to 80× slower GP fitting on a loaded
2-core machine (learning the README's tracker: 28 s with OpenBLAS's two threads while one other
process keeps a core busy, 9.3 s with one thread). So:

* processes started by the command line and the Monte Carlo workers use one BLAS thread unless
  the user has set the thread variables (:func:`default_single_blas_thread`);
* in the Python API, where the user's process and its BLAS are the user's, the hot entry points
  (filter steps and runs, model learning, GP fitting, fusion runs, eq. 35 and the audit of a
  fusion step) are decorated with
  :func:`one_blas_thread`: BLAS is limited to one thread for the duration of the call (with
  threadpoolctl) and restored afterwards, so the user's settings outside gpfverify's calls are
  untouched. Nested calls pay nothing; a user who set a thread variable is obeyed.
"""

from __future__ import annotations

import contextlib
import functools
import gc
import os
import sys
import threading
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

BLAS_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                    "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")

F = TypeVar("F", bound=Callable[..., Any])


class _Nesting(threading.local):
    """Per thread: whether a limited call is running (a class default, so reading it costs no
    failed attribute lookup)."""

    depth = 0


_state = _Nesting()
_controller: Any = None
_controller_modules = -1


def default_single_blas_thread() -> None:
    """Set every BLAS thread variable the user has not set to 1 (effective only before numpy
    loads its BLAS, and for child processes started afterwards)."""
    for var in BLAS_THREAD_VARS:
        os.environ.setdefault(var, "1")


def _blas_controller():
    """A threadpoolctl controller of the BLAS libraries loaded now (rebuilt when modules were
    imported since, which may have loaded another BLAS, e.g. scipy's)."""
    global _controller, _controller_modules
    if _controller is None or len(sys.modules) != _controller_modules:
        from threadpoolctl import ThreadpoolController

        _controller, _controller_modules = ThreadpoolController(), len(sys.modules)
    return _controller


def _limit_needed() -> bool:
    """Whether a call must limit BLAS itself: not when nested in a limited call, nor when the user
    set a BLAS thread variable (the command line sets them to 1 itself)."""
    if _state.depth:
        return False
    environ = os.environ
    for var in BLAS_THREAD_VARS:
        if var in environ:
            return False
    return True


@contextlib.contextmanager
def blas_limited() -> Iterator[None]:
    """BLAS limited to one thread inside the block (module docstring); a no-op when
    :func:`_limit_needed` says so or when threadpoolctl is missing."""
    if not _limit_needed():
        yield
        return
    try:
        limit = _blas_controller().limit(limits=1, user_api="blas")
    except ImportError:  # pragma: no cover - threadpoolctl is a dependency
        limit = contextlib.nullcontext()
    _state.depth = 1
    try:
        with limit:
            yield
    finally:
        _state.depth = 0


def one_blas_thread(fn: F) -> F:
    """Decorator: ``fn`` runs with BLAS limited to one thread (:func:`blas_limited`). When no limit
    is needed the call goes straight through, without a context manager: a Kalman step is about
    15 µs, and the context manager's enter and exit cost about 2 µs of it."""

    @functools.wraps(fn)
    def limited(*args, **kwargs):
        if not _limit_needed():
            return fn(*args, **kwargs)
        with blas_limited():
            return fn(*args, **kwargs)

    return limited  # type: ignore[return-value]


@contextlib.contextmanager
def no_cycle_collection() -> Iterator[None]:
    """Python's cyclic garbage collector paused for a block that builds many containers without
    cycles (run records: lists and dicts of floats, tens of thousands per batch of runs). Each of its
    collections walks every live container, so building a batch's records with it running took about
    twice as long (measured on ``check``'s three-sensor tracker, 64 runs of 40 steps). Restored on
    leaving, as it was; reference counting frees everything as usual meanwhile."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def progress_shown(stream=None) -> bool:
    """Whether a progress bar is drawn (the runs of
    :func:`~gpfverify.experiments.runner.run_experiment`, the blocks of
    :func:`~gpfverify.commands.audit.audit_run_file`): on a terminal, and in a Jupyter notebook, where
    rich draws it as a live output cell (with ``ipywidgets`` installed: ``pip install
    'gpfverify[notebook]'``). Off a terminal elsewhere (a log file, CI) it is not."""
    from gpfverify.streams import diagnostics

    stream = diagnostics() if stream is None else stream  # gpfverify's own stderr, not other code's
    if stream.isatty():
        return True
    if "ipykernel" not in sys.modules:  # no kernel loaded: not a notebook, and no import of rich needed
        return False
    from rich.console import Console

    return Console().is_jupyter
