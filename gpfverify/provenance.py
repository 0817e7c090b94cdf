"""What produced a result: the ``"provenance"`` record of CONTRACT.md ("Provenance").

    {"gpfverify": version, "git_commit": str or null, "python": str,
     "packages": {name: version}, "platform": str, "created": ISO-8601 UTC, "command": [argv]}

``git_commit`` is the HEAD of the checkout the package is imported from (an editable install of
the repository), with ``+dirty`` appended when tracked files differ from it; null for an installed
wheel or when git is unavailable. ``command`` is the full command line as a list: the program name
(``gpfverify``) followed by its arguments. Ground floor: imports nothing from the package but its
version.
"""

from __future__ import annotations

import platform
import subprocess
import sys
from datetime import datetime, UTC
from functools import lru_cache
from importlib import metadata
from pathlib import Path

#: the libraries whose versions can change a result
KEY_PACKAGES = ("numpy", "scipy", "cvxpy", "clarabel", "scs", "sympy", "casadi", "matplotlib",
                "hypothesis", "numba")
#: program name recorded as the first element of ``command``
PROGRAM = "gpfverify"


@lru_cache(maxsize=1)
def git_commit() -> str | None:
    """HEAD of the git checkout holding this package (``+dirty`` when tracked files changed), or
    None when the package is not imported from a checkout or git is not available."""
    root = Path(__file__).resolve().parent.parent
    if not (root / ".git").exists():
        return None
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True,
                              text=True, timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if dirty else "") if head else None


@lru_cache(maxsize=1)
def package_versions() -> dict[str, str]:
    """Installed versions of :data:`KEY_PACKAGES` (those not installed are left out)."""
    versions = {}
    for name in KEY_PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return versions


def provenance(argv: list[str] | None = None) -> dict:
    """The provenance record for a result written now by the command ``gpfverify *argv``, where
    ``argv`` are the arguments after the program name exactly as :func:`gpfverify.cli.main`
    receives them (e.g. ``["prove", "--out", "DIR"]``); without ``argv``, the command recorded by
    :func:`set_command` for the running CLI invocation, else this process's ``sys.argv`` as is (an
    API call from a script: the script's command line)."""
    from gpfverify import __version__

    if argv is not None:
        command = [PROGRAM, *map(str, argv)]
    elif _current_argv is not None:
        command = [PROGRAM, *map(str, _current_argv)]
    else:
        command = [str(a) for a in sys.argv]
    return {
        "gpfverify": __version__,
        "git_commit": git_commit(),
        "python": platform.python_version(),
        "packages": package_versions(),
        "platform": platform.platform(),
        "created": datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z"),
        "command": command,
    }


#: the command line of the running CLI invocation (set by :func:`gpfverify.cli.main`)
_current_argv: list[str] | None = None


def set_command(argv: list[str]) -> None:
    """Record the arguments of the running command, so results written deep inside it (by the
    runner, the report) name the command the user typed rather than ``sys.argv``."""
    global _current_argv
    _current_argv = list(argv)


def current() -> dict:
    """:func:`provenance` for the running command (as recorded by :func:`set_command`)."""
    return provenance()


def provenance_lines(record: dict) -> list[str]:
    """The record as short human-readable lines, for report pages."""
    packages = ", ".join(f"{k} {v}" for k, v in sorted(record.get("packages", {}).items()))
    return [f"gpfverify {record.get('gpfverify')} (commit {record.get('git_commit') or 'unknown'}), "
            f"Python {record.get('python')} on {record.get('platform')}",
            f"created {record.get('created')} by `{' '.join(record.get('command', []))}`",
            f"libraries: {packages}"]
