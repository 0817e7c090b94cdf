"""gpfverify run as a program: the command runs in a child process whose last act is to send its
exit status to the parent, so that no code the command runs can end gpfverify with a status it did
not choose, nor keep it from ending, nor print into its one line.

A system file of ``check`` (or a compiled library) can end its process without any clean-up —
``os._exit(0)`` at import, late in a measurement function, from a thread it started, a C++
``std::bad_alloc`` that aborts, OpenBLAS giving up on an allocation — and a process cannot catch
its own end: it would leave with status 0 and no result. So the command line forks before it
imports anything else (:func:`start`):

* the child runs the command. gpfverify's own output goes through private duplicates of
  descriptors 1 and 2 taken at the fork (:func:`standard_fds`, :mod:`gpfverify.streams`);
  descriptors 1 and 2 themselves are pointed at a pipe to the parent, which *holds* what other
  code writes there (compiled code, worker processes, multiprocessing's resource tracker) until
  the command's outcome is known: printed to stderr after the command's own output when it
  completes (or fails with a bug, status 1), dropped when it fails with status 2 or is
  interrupted — the one line is all — and passed through as it comes with ``GPFVERIFY_DEBUG=1``.
  :func:`note` tells the parent what it is doing that matters if it ends abruptly: ``user``, the
  user's code it runs (as messages name it); ``stage`` and ``done``, a staging folder it holds
  locked with ``flock`` (:mod:`gpfverify.outputs`), the output folder it is for and the parent
  folders made to hold it, and the end of it; ``advice``, what to try when memory runs out. Its
  last act, :func:`finish`, writes its exit status (the sentinel) and flushes its streams;
  threads still running that are not daemons (a system file's) get :data:`THREAD_GRACE_SECONDS`
  to end, and then it ends without them, saying so in one note line when the command succeeded.
  It dies with the parent (``PR_SET_PDEATHSIG``), so killing gpfverify kills the command.
* the parent, which runs nothing else, waits for the child and exits with the status of the
  sentinel. A child that ends without one ends the command with one line: status 2 when it ran
  out of memory (an allocation failure in what it held back, :data:`MEMORY_SIGNS`), when the
  user's code had run in it (named in the line; when it ended the process, the command's staging
  folder is removed, so ``--out`` is as it was) or when it was killed (SIGKILL: out of memory),
  130 when it was stopped by SIGINT or SIGTERM, 1 otherwise (a bug). The runs a killed child had
  saved are moved into ``--out`` at once, as the next command on it would
  (:func:`gpfverify.outputs.keep_abandoned`), and the line says what was kept. A child that sent
  its status but does not end within :data:`GRACE_SECONDS` (a user's ``atexit`` handler that
  hangs) is killed.
* Ctrl-C reaches both processes from the terminal; a SIGINT or SIGTERM sent to the parent alone
  (``kill PID``) is passed on to the child. A child that has not ended :data:`STOP_SECONDS`
  after the first of them (stuck in compiled code, which no Python signal handler interrupts: a
  BLAS allocation retried forever) is killed, and the command ends as interrupted (130). A
  Ctrl-C or SIGTERM that arrives while a command that completed is ending still ends it with
  status 130, never 0, its line saying that the output is complete.

Only on Linux (``fork``, ``sigtimedwait`` and the signal's sender are what this needs); elsewhere,
and when gpfverify is called from Python, the command runs in the calling process.
"""

from __future__ import annotations

import contextlib
import gc
import os
import signal
import sys
import threading
import time
from collections.abc import Callable

#: the operating system's exit, for gpfverify's own use while user code may have replaced os._exit
HARD_EXIT = os._exit
#: how long the child waits for threads that are not daemons once the command is done
THREAD_GRACE_SECONDS = 2.0
#: how long the parent waits for a child that has sent its exit status to end
GRACE_SECONDS = 10.0
#: how long the parent waits for the child to stop after a SIGINT or SIGTERM before it kills it
STOP_SECONDS = 10.0
#: how often the parent looks at the child's pipes and its signals
POLL_SECONDS = 0.05
#: how often a process started by gpfverify checks that its parent is still alive (where the
#: kernel does not tell it)
PARENT_POLL_SECONDS = 0.2
#: the most bytes of other code's output the parent holds (the rest is counted, not kept)
HELD_BYTES = 1 << 20
#: what an allocation failure that ends a process writes to descriptor 2 (C++, OpenBLAS, glibc,
#: CPython's fatal errors), lower case
MEMORY_SIGNS = (b"bad_alloc", b"memory allocation", b"cannot allocate memory", b"out of memory",
                b"memoryerror")

_channel: int | None = None  # the child's end of the pipe to the parent
_standard_fds: tuple[int | None, int | None] | None = None  # the child's private copies of 1 and 2
_users: set[str] = set()  # the user's code already named to the parent
_SIGNALS = {signal.SIGINT, signal.SIGTERM, signal.SIGCHLD}
_CRASHES = {signal.SIGSEGV, signal.SIGBUS, signal.SIGILL, signal.SIGFPE, signal.SIGABRT}


#: what the parent calls for a staging folder its killed child left: keep(stage, out, made) -> the
#: end of the one line, saying what was kept (:func:`start`)
Keep = Callable[[str, str, list[str]], str]


def start(command: str, keep: Keep | None = None) -> None:
    """Fork (module docstring). The parent waits for the child and ends the process with the
    command's exit status (at once: it has nothing to clean up); the child, and the process
    where this is not done, returns to run the command. ``keep`` keeps the saved runs of a
    staging folder a killed child left (the command line passes
    :func:`gpfverify.outputs.keep_abandoned`'s wrapper: this module sits below it)."""
    global _channel, _standard_fds
    if not sys.platform.startswith("linux"):
        return
    from gpfverify.streams import duplicate

    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, _SIGNALS)  # from before the fork: none is lost
    try:
        read_end, write_end = os.pipe()
        held_read, held_write = os.pipe()
        with contextlib.suppress(OSError, AttributeError):
            import fcntl

            fcntl.fcntl(held_write, fcntl.F_SETPIPE_SZ, HELD_BYTES)  # fewer waits for a chatty library
        gc.freeze()  # the objects made so far stay out of the child's collections: no copies of their pages
        pid = os.fork()
    except OSError:  # no process to spare: run the command here
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
        return
    if pid == 0:
        os.close(read_end)
        os.close(held_read)
        _standard_fds = (duplicate(1), duplicate(2))
        for fd in (1, 2):
            os.dup2(held_write, fd)
        os.close(held_write)
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
        _channel = write_end
        exit_with_parent(os.getppid())
        return
    os.close(write_end)
    os.close(held_write)
    HARD_EXIT(_wait(command, pid, read_end, held_read, keep))


def standard_fds() -> tuple[int | None, int | None]:
    """Private duplicates of descriptors 1 and 2 for gpfverify's own output (module docstring): the
    ones the child took at the fork, else taken now (None for a descriptor that is not open)."""
    if _standard_fds is not None:
        return _standard_fds
    from gpfverify.streams import duplicate

    return duplicate(1), duplicate(2)


def note(kind: str, text: str) -> None:
    """Tell the parent, if this process is a supervised child, ``kind`` (module docstring):
    ``user`` (said once per text), ``made``, ``out``, ``stage``, ``done``, ``advice`` or ``exit``."""
    if _channel is None or (kind == "user" and text in _users):
        return
    if kind == "user":
        _users.add(text)
    with contextlib.suppress(OSError):
        os.write(_channel, kind.encode() + b":" + os.fsencode(text) + b"\0")


def finish(command: str, code: int) -> int:
    """The child's last act (module docstring): flush, send ``code``, give the threads that are not
    daemons :data:`THREAD_GRACE_SECONDS` to end, and end without the ones still running. Returns
    ``code`` when no thread is left."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    note("exit", str(code))
    deadline = time.monotonic() + THREAD_GRACE_SECONDS
    left = []
    for thread in threading.enumerate():
        if thread is threading.main_thread() or thread.daemon:
            continue
        thread.join(max(0.0, deadline - time.monotonic()))
        if thread.is_alive():
            left.append(thread.name)
    if left:
        if code == 0:
            with contextlib.suppress(Exception):
                print(f"gpfverify {command}: note: not waiting for {len(left)} thread(s) still running "
                      f"({', '.join(left)}); they end with gpfverify", file=sys.stderr, flush=True)
        HARD_EXIT(code)
    return code


def exit_with_parent(parent_pid: int) -> None:
    """End this process as soon as its parent (``parent_pid``, which started it) is gone, killed by
    any signal, SIGKILL included, when no clean-up of the parent's can run: on Linux the kernel
    delivers SIGKILL at once (``PR_SET_PDEATHSIG``); elsewhere a daemon thread watches."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(Exception):
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL), 0, 0, 0)  # PR_SET_PDEATHSIG
        if os.getppid() != parent_pid:  # the parent died before the prctl took effect
            HARD_EXIT(1)
        return

    def watch():
        while os.getppid() == parent_pid:
            time.sleep(PARENT_POLL_SECONDS)
        HARD_EXIT(1)

    if os.getppid() != parent_pid:
        HARD_EXIT(1)
    threading.Thread(target=watch, name="gpfverify-parent-watch", daemon=True).start()


def _read(fd: int) -> bytes:
    """What the child has written so far (the pipe is non-blocking)."""
    chunks = []
    while True:
        try:
            chunk = os.read(fd, 65536)
        except BlockingIOError:
            break
        if not chunk:
            break
        chunks.append(chunk)
    return b"".join(chunks)


class _Held:
    """What other code in the child wrote to descriptors 1 and 2 (module docstring): kept up to
    :data:`HELD_BYTES`, or passed through at once when ``live``."""

    def __init__(self, fd: int, live: bool) -> None:
        self.fd, self.live = fd, live
        self.data, self.dropped = bytearray(), 0
        os.set_blocking(fd, False)

    def take(self) -> None:
        chunk = _read(self.fd)
        if self.live:
            _write(chunk)
            return
        room = max(0, HELD_BYTES - len(self.data))
        self.data += chunk[:room]
        self.dropped += len(chunk) - min(room, len(chunk))

    def memory_sign(self) -> str | None:
        """The first line held that tells of an allocation that failed (:data:`MEMORY_SIGNS`)."""
        for line in bytes(self.data).splitlines():
            if any(sign in line.lower() for sign in MEMORY_SIGNS):
                return " ".join(line.decode(errors="replace").split())[:160]
        return None

    def release(self) -> None:
        """Print what was held, after the command's own output."""
        self.take()
        _write(bytes(self.data))
        if self.dropped:
            _write(f"[gpfverify: {self.dropped} more bytes of output were not kept]\n".encode())


def _wait(command: str, pid: int, read_end: int, held_fd: int, keep: Keep | None) -> int:
    """The parent: wait for the child, pass on the signals sent to this process alone, stop a
    child that does not stop, and return the command's exit status (module docstring)."""
    os.set_blocking(read_end, False)
    held = _Held(held_fd, live=bool(os.environ.get("GPFVERIFY_DEBUG")))
    received = bytearray()
    finished_at = stop_by = None
    forced = False
    while True:
        info = signal.sigtimedwait(_SIGNALS, POLL_SECONDS)
        received += _read(read_end)
        held.take()
        if info is not None and info.si_signo != signal.SIGCHLD:
            if info.si_code <= 0:  # sent by a process (kill); the terminal's Ctrl-C reached the child itself
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, info.si_signo)
            stop_by = stop_by or time.monotonic() + STOP_SECONDS
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        now = time.monotonic()
        if b"exit:" in received:
            finished_at = finished_at or now
        if (finished_at is not None and now - finished_at > GRACE_SECONDS) or (
                stop_by is not None and now > stop_by and finished_at is None):
            forced = finished_at is None
            os.kill(pid, signal.SIGKILL)
            _, status = os.waitpid(pid, 0)
            break
    received += _read(read_end)
    os.close(read_end)
    late = bool({signal.SIGINT, signal.SIGTERM} & signal.sigpending())  # came as the child ended
    code = _outcome(command, _records(bytes(received)), status, held, interrupted=stop_by is not None or late,
                    forced=forced, keep=keep)
    if code in (0, 1) and not held.live:
        held.release()
    os.close(held_fd)
    return code


def _records(data: bytes) -> dict[str, list[str]]:
    records: dict[str, list[str]] = {}
    for record in data.split(b"\0"):
        kind, sep, text = record.partition(b":")
        if sep:
            records.setdefault(kind.decode(), []).append(os.fsdecode(text))
    return records


def _outcome(command: str, records: dict[str, list[str]], status: int, held: _Held, interrupted: bool,
             forced: bool, keep: Keep | None = None) -> int:
    """The exit status of a child that ended with ``status`` after sending ``records``
    (``interrupted``: a SIGINT or SIGTERM reached this process; ``forced``: the child did not stop
    after it and was killed; ``keep``: :func:`start`'s)."""
    left = [path for path in records.get("stage", []) if path not in records.get("done", [])]
    if records.get("exit"):
        code = int(records["exit"][-1])
        if interrupted and code == 0:
            _say(f"gpfverify {command}: interrupted as it ended; the command had completed and its output "
                 "is complete")
            return 130
        return code
    if forced:
        _say(f"gpfverify {command}: interrupted; the process running the command did not stop within "
             f"{STOP_SECONDS:.0f} s (stuck where no signal reaches it, such as compiled code) and was killed"
             f"{_keep(records, left, keep)}")
        return 130
    if os.WIFSIGNALED(status) and os.WTERMSIG(status) in (signal.SIGINT, signal.SIGTERM):
        _say(f"gpfverify {command}: interrupted")
        return 130
    how = (f"ended the process (exit status {os.WEXITSTATUS(status)})" if os.WIFEXITED(status) else
           f"{'crashed' if os.WTERMSIG(status) in _CRASHES else 'was killed'} "
           f"({signal.Signals(os.WTERMSIG(status)).name})")
    sign = held.memory_sign()
    if sign is not None:
        advice = records.get("advice", ["try fewer --workers"])[-1]
        _say(f"gpfverify {command}: error: out of memory: the process running the command {how} after an "
             f"allocation failed ({sign}); {advice}{_keep(records, left, keep)}")
        return 2
    user = records.get("user", [None])[-1]
    if os.WIFEXITED(status):
        how += " before the command finished"
        if user is None:
            _say(f"gpfverify {command}: internal error: the process running the command {how} (a bug: please "
                 "report it)")
            return 1
        remaining = [path for path in left if not _discard(path)]  # the user's code ended it: nothing is kept
        _say(f"gpfverify {command}: error: {user} {how} (os._exit, or an exit from a thread it started or from "
             f"compiled code){'; --out was left as it was' if left and not remaining else ''}")
        return 2
    how += " before it finished"
    if user is None and os.WTERMSIG(status) in _CRASHES:
        _say(f"gpfverify {command}: internal error: the process running the command {how} (a bug: please report it)")
        return 1
    _say(f"gpfverify {command}: error: the process running {user or 'the command'} {how}{_keep(records, left, keep)}")
    return 2


def _keep(records: dict[str, list[str]], left: list[str], keep: Keep | None) -> str:
    """Keep the saved runs of the staging folder the child left (``left``) with ``keep``, as the
    next command on ``--out`` would; the end of the one line saying what was kept ("" when the
    child held no folder)."""
    out = records.get("out", [None])[-1]
    if not left:
        return ""
    if out is None or keep is None:
        return "; the runs it had saved are kept for the next command on --out"
    return f"; {keep(left[-1], out, records.get('made', []))}"


def _discard(folder: str) -> bool:
    """Remove a staging folder the child left (``stage`` noted, no ``done``) unless another process
    holds its lock by now (a command that waited for it); whether it is gone."""
    import fcntl
    import shutil

    try:
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW)
    except OSError:
        return not os.path.lexists(folder)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        shutil.rmtree(folder, ignore_errors=True)
    except OSError:
        return False
    finally:
        os.close(fd)
    return not os.path.lexists(folder)


def _write(data: bytes) -> None:
    while data:
        try:
            data = data[os.write(2, data):]
        except OSError:
            return


def _say(line: str) -> None:
    _write((line + "\n").encode(errors="replace"))
