"""Processes a command started, read from Linux's /proc: a command run as a program forks its
command process (gpfverify.supervise), which starts the worker processes and multiprocessing's
resource tracker, so they are descendants of the process a test starts, not its children."""

from __future__ import annotations

from pathlib import Path


def _stat(pid: int) -> list[str] | None:
    """State and parent of ``pid`` (and the rest of /proc/PID/stat after the command name)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None


def alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, ended but not yet reaped, does not)."""
    fields = _stat(pid)
    return fields is not None and fields[0] != "Z"


def descendants(pid: int) -> set[int]:
    """Every living process descended from ``pid``."""
    parents = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            fields = _stat(int(entry.name))
            if fields is not None and fields[0] != "Z":
                parents[int(entry.name)] = int(fields[1])
    found: set[int] = set()
    frontier = {pid}
    while frontier:
        frontier = {child for child, parent in parents.items() if parent in frontier} - found
        found |= frontier
    return found


def command_line(pid: int) -> str:
    """The command line of ``pid`` ("" once it has ended)."""
    try:
        return Path(f"/proc/{pid}/cmdline").read_text(errors="replace")
    except OSError:
        return ""


def pool_workers(pid: int) -> list[int]:
    """The worker processes of a process pool started under ``pid`` (not the resource tracker)."""
    return [child for child in sorted(descendants(pid)) if "spawn_main" in command_line(child)]


#: the environment variable that sets how many trials a timed sweep runs (a larger sweep for the
#: reader who wants one; the default keeps the suite's time budget)
TRIALS_VARIABLE = "GPFVERIFY_SWEEP_TRIALS"


def sweep_trials(default: int) -> int:
    """How many trials a timed sweep runs: ``GPFVERIFY_SWEEP_TRIALS`` when set, else ``default``."""
    import os

    value = os.environ.get(TRIALS_VARIABLE, "")
    return int(value) if value.strip() else default


def state(pid: int) -> str | None:
    """The state letter of ``pid`` (``"Z"`` once it has ended and is not yet reaped), None when gone."""
    fields = _stat(pid)
    return None if fields is None else fields[0]
