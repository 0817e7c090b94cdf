"""Running out of memory is an error of the environment, not a bug nor a failed run: how gpfverify
recognises it, keeps compiled code from hanging on it, and what it tells the user to try.

* :func:`out_of_memory` recognises an allocation failure in an exception and its chain: a
  ``MemoryError`` (also C++'s ``std::bad_alloc`` as casadi raises it), and an ``ImportError`` or
  ``OSError`` that says memory could not be mapped or allocated (a shared library that cannot be
  loaded for want of address space says ``failed to map segment from shared object``; llvmlite
  wraps that in an ``OSError`` of its own, which keeps the cause in its chain).
* :func:`reserve_blas_buffers`: OpenBLAS takes work buffers of 32 MiB when its library loads and
  at the first call that needs one, and keeps them for later calls; when an allocation fails it
  retries for ever inside compiled code, where no Python signal handler runs (measured: ``check``
  under ``ulimit -v 250000`` spun in ``blas_memory_alloc`` and ignored SIGTERM; under 150000 it
  spun while scipy's OpenBLAS loaded), or gives up and ends the process. So a command loads numpy
  and scipy.linalg and makes that first call itself, before anything else, each after checking that
  the address space has room for it (:data:`LIBRARY_ROOM`): a machine without that room is refused
  at once, and a command that starts never meets OpenBLAS's loop afterwards (one BLAS thread,
  :mod:`gpfverify.runtime`: the buffers are reused).
* :func:`near_limit`: an error that says nothing of memory (a compiled extension's ``SystemError:
  error return without exception set`` when an allocation inside it failed) is taken for running
  out of memory when the process's address space came within :data:`NEAR_LIMIT` of the limit set
  on it (``ulimit -v``); the line says so with both numbers.
* :func:`hold_reserve` and :func:`release_reserve`: a command holds back :data:`RESERVE_BYTES` of
  address space while it runs and gives it back when memory has run out, so that it can still
  move its saved runs into ``--out``, remove its staging folder and say so (measured: under a cap
  that ran out while the report was drawn, listing the staging folder failed with ENOMEM and the
  folder was left).
* :func:`advise`: what to try, from the options the command has (``--workers``, ``--batch``),
  recorded for the error line (:func:`advice`) and for the process that reports a command ended
  by an allocation failure (:func:`gpfverify.supervise.note`).
"""

from __future__ import annotations

import errno
import mmap
from collections.abc import Collection

try:  # loaded with the module, not when memory has run out
    import resource
except ImportError:  # not a Unix system
    resource = None  # type: ignore[assignment]

from gpfverify.errors import OutOfMemory

#: address space to find free before loading numpy or scipy.linalg and taking OpenBLAS's buffers:
#: measured 121 MB for numpy and 128 MB for scipy.linalg (their libraries, extension modules and
#: OpenBLAS's buffers; x86-64, OpenBLAS 0.3.31), with half as much again to spare
LIBRARY_ROOM = 192 << 20
#: what a failed allocation says in an ImportError or OSError, lower case
_SIGNS = ("failed to map segment", "cannot allocate memory", "out of memory", "bad_alloc")


#: how close to the address-space limit (``ulimit -v``) a process's peak must have come for an error
#: that says nothing of memory to be taken for an allocation failure: twice OpenBLAS's 32 MiB
#: buffer, the largest single allocation measured failing without a MemoryError
NEAR_LIMIT = 64 << 20


def near_limit() -> str | None:
    """``"its address space reached P MB of the L MB limit"`` when this process's peak address
    space (``VmPeak``) came within :data:`NEAR_LIMIT` of its ``RLIMIT_AS``; None otherwise (no
    limit, or far from it, or not Linux)."""
    if resource is None:
        return None
    try:  # nothing is imported here: this runs when memory may have run out
        limit = resource.getrlimit(resource.RLIMIT_AS)[0]
        if limit == resource.RLIM_INFINITY:
            return None
        with open("/proc/self/status", "rb") as fh:
            peak = next(int(line.split()[1]) * 1024 for line in fh if line.startswith(b"VmPeak:"))
    except Exception:  # noqa: BLE001 - no measure, no claim
        return None
    if peak < limit - NEAR_LIMIT:
        return None
    return f"its address space reached {peak / 1e6:.0f} MB of the {limit / 1e6:.0f} MB limit (ulimit -v)"


def out_of_memory(exc: BaseException, near: bool = True) -> str | None:
    """What ran out of memory, when ``exc`` or an exception in its chain is an allocation failure,
    or (``near``) when this process came near its address-space limit (module docstring); None
    otherwise."""
    found = _allocation_failure(exc)
    if found is None and near:
        peak = near_limit()
        if peak is not None:
            found = f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}, where {peak}"
    return found


def _allocation_failure(exc: BaseException) -> str | None:
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        seen.add(id(current))
        if isinstance(current, OutOfMemory):
            return str(current)
        text = " ".join(str(current).split())
        if isinstance(current, MemoryError):
            return f"MemoryError: {text}" if text else "MemoryError"
        if isinstance(current, (ImportError, OSError)) and (
                getattr(current, "errno", None) == errno.ENOMEM or any(s in text.lower() for s in _SIGNS)):
            return f"{type(current).__name__}: {text[:200]}"
        current = current.__cause__ or current.__context__
    return None


def _room_for(size: int) -> bool:
    """Whether ``size`` bytes of address space can be reserved now (reserved without access, prot 0 =
    PROT_NONE, and given back at once)."""
    try:
        mmap.mmap(-1, size, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS, prot=0).close()
    except OSError:
        return False
    return True


def reserve_blas_buffers() -> None:
    """Load numpy and scipy.linalg and have their OpenBLAS take its work buffers now (module
    docstring); :class:`~gpfverify.errors.OutOfMemory` when the address space has no room for
    one of them."""
    _require_room("numpy")
    import numpy as np

    identity = np.eye(2)
    np.linalg.cholesky(identity)
    _require_room("scipy.linalg")
    import scipy.linalg

    scipy.linalg.cholesky(identity)


def _require_room(library: str) -> None:
    if not _room_for(LIBRARY_ROOM):
        raise OutOfMemory(f"not enough memory to load {library} and its BLAS work buffers ({LIBRARY_ROOM >> 20} MiB "
                          "of address space) when the command started")


#: address space a command holds back for the work that follows running out of memory
RESERVE_BYTES = 32 << 20
_reserve: list[mmap.mmap] = []


def hold_reserve() -> None:
    """Hold back :data:`RESERVE_BYTES` of address space (a mapping nothing touches: no memory is
    used, only the room for it); nothing when it cannot be had."""
    release_reserve()
    try:
        _reserve.append(mmap.mmap(-1, RESERVE_BYTES, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS, prot=0))
    except OSError:
        pass


def release_reserve() -> None:
    """Give back what :func:`hold_reserve` held, for the clean-up after memory ran out."""
    while _reserve:
        _reserve.pop().close()


#: what to try, as :func:`advise` last put it
_advice = ["give gpfverify more memory"]


def advise(options: Collection[str]) -> None:
    """Record what to try when the command runs out of memory, from its ``options`` (its option
    strings), here and with the process that supervises the command."""
    from gpfverify import supervise

    tips = [tip for option, tip in (("--workers", "fewer --workers"), ("--batch", "a smaller --batch"))
            if option in options]
    _advice[0] = f"try {' or '.join(tips)}, or give gpfverify more memory" if tips else "give gpfverify more memory"
    supervise.note("advice", _advice[0])


def advice() -> str:
    """What to try when the command ran out of memory (:func:`advise`)."""
    return _advice[0]
