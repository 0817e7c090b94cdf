"""Copies of the project that mutants are applied to — never the working tree.

A *workspace* is a copy of the project's files (the package, the test folders, the documents and
reports the tests read) in the cache folder. A mutant is written into its workspace's copy of one
module, the selected tests run there with the workspace first on ``sys.path``, and the module is
put back; :func:`sync` refreshes a workspace from the working tree before a run (so that a rerun
after an interruption starts from clean files whatever the interruption left).
"""

from __future__ import annotations

import fnmatch
import os
import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: what a workspace holds: everything the suite reads, nothing of git's or the virtualenv's
EXCLUDED = (".git", ".venv", ".hypothesis", "__pycache__", ".pytest_cache", ".mypy_cache", ".ruff_cache",
            ".import_linter_cache", ".mutation-cache", "*.egg-info", "out")
CACHE = ROOT / ".mutation-cache"


def _excluded(name: str) -> bool:
    return any(fnmatch.fnmatch(name, pattern) for pattern in EXCLUDED)


def sync(dest: Path) -> Path:
    """Make ``dest`` an exact copy of the working tree's files (less :data:`EXCLUDED`): a file whose
    bytes differ is rewritten (so a module that a killed run left mutated is put back), a file the
    tree no longer has is removed; folders named in :data:`EXCLUDED` (compiled files) are left alone."""
    dest.mkdir(parents=True, exist_ok=True)
    for folder, dirs, files in os.walk(ROOT):
        dirs[:] = [d for d in dirs if not _excluded(d)]
        here = Path(folder)
        target = dest / here.relative_to(ROOT)
        target.mkdir(exist_ok=True)
        wanted = {f for f in files if not _excluded(f)}
        for name in wanted:
            src, dst = here / name, target / name
            if not dst.is_file() or dst.read_bytes() != src.read_bytes():
                forget_compiled(dst)
                shutil.copy2(src, dst)
        for extra in target.iterdir():
            if extra.name not in wanted and extra.name not in dirs and not _excluded(extra.name):
                shutil.rmtree(extra) if extra.is_dir() and not extra.is_symlink() else extra.unlink()
    return dest


def forget_compiled(module: Path) -> None:
    """Remove the bytecode of one module of a workspace, so that the next process compiles the file as
    it is now (a pyc's source stamp is the file's size and whole-second mtime, which a mutant written
    in the same second as another of the same size would not change)."""
    for pyc in (module.parent / "__pycache__").glob(f"{module.stem}.*.pyc"):
        pyc.unlink(missing_ok=True)


def environment(workspace: Path, profile: str) -> dict[str, str]:
    """The environment of a test process in ``workspace``: the copy first on ``sys.path`` (its
    subprocesses inherit it), one BLAS thread, numba's cache inside the workspace."""
    return dict(os.environ, PYTHONPATH=str(workspace), MPLBACKEND="Agg", HYPOTHESIS_PROFILE=profile,
                NUMBA_CACHE_DIR=str(workspace / ".numba-cache"), OMP_NUM_THREADS="1",
                OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1", PYTHONHASHSEED="0")


def pytest_command(*args: str) -> list[str]:
    """``python -m pytest`` in the current interpreter, with the plugin that records failures."""
    return [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "tests.mutation.outcome_plugin",
            "-q", "--tb=no", "--no-header", *args]


def reset(workspace: Path) -> None:
    """Remove a workspace (a fresh :func:`sync` follows)."""
    shutil.rmtree(workspace, ignore_errors=True)
