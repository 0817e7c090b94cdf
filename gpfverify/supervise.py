"""gpfverify run as a program: the command runs in a child process whose last act is to send its
exit status to the parent, so that no code the command runs can end gpfverify with a status it did
not choose, nor keep it from ending.

A system file of ``check`` (or a compiled library) can end its process without any clean-up —
``os._exit(0)`` at import, late in a measurement function, from a thread it started — and a
process cannot catch its own end: it would leave with status 0 and no result. So the command line
forks before it imports anything else (:func:`start`):

* the child runs the command. :func:`note` tells the parent what it is doing that matters if it
  ends abruptly: ``user``, the user's code it runs (as messages name it); ``stage`` and ``done``,
  a staging folder it holds locked with ``flock`` (:mod:`gpfverify.outputs`) and the end of it.
  Its last act, :func:`finish`, writes its exit status (the sentinel) and flushes its streams;
  threads still running that are not daemons (a system file's) get :data:`THREAD_GRACE_SECONDS`
  to end, and then it ends without them, saying so in one note line when the command succeeded.
  It dies with the parent (``PR_SET_PDEATHSIG``), so killing gpfverify kills the command.
* the parent, which runs nothing else, waits for the child and exits with the status
  of the sentinel. A child that ends without one ends the command with one line: status 2 when
  the user's code had run in it (named in the line; when it ended the process, the command's
  staging folder is removed, so ``--out`` is as it was) or when it was killed (SIGKILL: out of
  memory; the runs it saved are kept for the next command on ``--out``), 130 when it was stopped by
  SIGINT or SIGTERM, 1 otherwise (a bug).
  A child that sent its status but does not end within :data:`GRACE_SECONDS` (a user's ``atexit``
  handler that hangs) is killed.
* Ctrl-C reaches both processes from the terminal; a SIGINT or SIGTERM sent to the parent alone
  (``kill PID``) is passed on to the child.

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

#: the operating system's exit, for gpfverify's own use while user code may have replaced os._exit
HARD_EXIT = os._exit
#: how long the child waits for threads that are not daemons once the command is done
THREAD_GRACE_SECONDS = 2.0
#: how long the parent waits for a child that has sent its exit status to end
GRACE_SECONDS = 10.0
#: how often a process started by gpfverify checks that its parent is still alive (where the
#: kernel does not tell it)
PARENT_POLL_SECONDS = 0.2

_channel: int | None = None  # the child's end of the pipe to the parent
_users: set[str] = set()  # the user's code already named to the parent
_SIGNALS = {signal.SIGINT, signal.SIGTERM, signal.SIGCHLD}
_CRASHES = {signal.SIGSEGV, signal.SIGBUS, signal.SIGILL, signal.SIGFPE, signal.SIGABRT}


def start(command: str) -> None:
    """Fork (module docstring). The parent waits for the child and ends the process with the
    command's exit status (at once: it has nothing to clean up); the child, and the process
    where this is not done, returns to run the command."""
    global _channel
    if not sys.platform.startswith("linux"):
        return
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, _SIGNALS)  # from before the fork: none is lost
    try:
        read_end, write_end = os.pipe()
        gc.freeze()  # the objects made so far stay out of the child's collections: no copies of their pages
        pid = os.fork()
    except OSError:  # no process to spare: run the command here
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
        return
    if pid == 0:
        os.close(read_end)
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
        _channel = write_end
        exit_with_parent(os.getppid())
        return
    os.close(write_end)
    HARD_EXIT(_wait(command, pid, read_end))


def note(kind: str, text: str) -> None:
    """Tell the parent, if this process is a supervised child, ``kind`` (module docstring):
    ``user`` (said once per text), ``stage``, ``done`` or ``exit``."""
    if _channel is None or (kind == "user" and text in _users):
        return
    if kind == "user":
        _users.add(text)
    with contextlib.suppress(OSError):
        os.write(_channel, kind.encode() + b":" + os.fsencode(text) + b"\0")


def finish(command: str, code: int) -> int:
    """The child's last act (module docstring): flush, send ``code``, give the threads that are not
    daemons :data:`THREAD_GRACE_SECONDS` to end, and end without the ones still running. Returns
    ``code`` for ``sys.exit`` when none is."""
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


def _wait(command: str, pid: int, read_end: int) -> int:
    """The parent: wait for the child, pass on the signals sent to this process alone, and return
    the command's exit status (module docstring)."""
    os.set_blocking(read_end, False)
    received = bytearray()
    finished_at = None
    while True:
        info = signal.sigtimedwait(_SIGNALS, 0.5)
        received += _read(read_end)
        if info is not None and info.si_signo != signal.SIGCHLD:
            if info.si_code <= 0:  # sent by a process (kill); the terminal's Ctrl-C reached the child itself
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, info.si_signo)
            continue
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        if b"exit:" in received:
            finished_at = finished_at or time.monotonic()
            if time.monotonic() - finished_at > GRACE_SECONDS:
                os.kill(pid, signal.SIGKILL)
                _, status = os.waitpid(pid, 0)
                break
    received += _read(read_end)
    os.close(read_end)
    return _outcome(command, _records(bytes(received)), status)


def _records(data: bytes) -> dict[str, list[str]]:
    records: dict[str, list[str]] = {}
    for record in data.split(b"\0"):
        kind, sep, text = record.partition(b":")
        if sep:
            records.setdefault(kind.decode(), []).append(os.fsdecode(text))
    return records


def _outcome(command: str, records: dict[str, list[str]], status: int) -> int:
    """The exit status of a child that ended with ``status`` after sending ``records``."""
    if records.get("exit"):
        return int(records["exit"][-1])
    if os.WIFSIGNALED(status) and os.WTERMSIG(status) in (signal.SIGINT, signal.SIGTERM):
        _say(f"gpfverify {command}: interrupted")
        return 130
    user = records.get("user", [None])[-1]
    left = [path for path in records.get("stage", []) if path not in records.get("done", [])]
    if os.WIFEXITED(status):
        how = f"ended the process (exit status {os.WEXITSTATUS(status)}) before the command finished"
        if user is None:
            _say(f"gpfverify {command}: internal error: the process running the command {how} (a bug: please "
                 "report it)")
            return 1
        kept = [path for path in left if not _discard(path)]  # the user's code ended it: nothing is kept
        _say(f"gpfverify {command}: error: {user} {how} (os._exit, or an exit from a thread it started or from "
             f"compiled code){'; --out was left as it was' if left and not kept else ''}")
        return 2
    number = os.WTERMSIG(status)
    how = f"{'crashed' if number in _CRASHES else 'was killed'} ({signal.Signals(number).name}) before it finished"
    if user is None and number in _CRASHES:
        _say(f"gpfverify {command}: internal error: the process running the command {how} (a bug: please report it)")
        return 1
    _say(f"gpfverify {command}: error: the process running {user or 'the command'} {how}"
         f"{'; the runs it had saved are kept for the next command on --out' if left else ''}")
    return 2


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


def _say(line: str) -> None:
    with contextlib.suppress(OSError):
        os.write(2, (line + "\n").encode(errors="replace"))
