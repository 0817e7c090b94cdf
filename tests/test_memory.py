"""Out of memory is an error path (docs/output-and-errors.md, "Memory"): gpfverify run under an
address-space limit (``ulimit -v``, set with ``resource.setrlimit`` in the child process) at caps
that fail while Python imports numpy and scipy, while OpenBLAS takes its buffers (where it used to
spin for ever), while the experiment's libraries load, and while runs are computed. Every capped
command ends within the time limit with exit status 0 or 2 — 2 with one line naming memory and
what to try, after the experiment's progress lines — leaves no staging folder, and whatever it
kept in ``--out`` is continued by ``--resume`` to the results of an uncapped run."""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from gpfverify.experiments.runner import without_timing
from gpfverify.outputs import FILE_LIST, foreign_entry

sys.path.insert(0, str(Path(__file__).parent))  # the suite imports in importlib mode: the helper beside it
from system_files import LINEAR_SYSTEM  # noqa: E402

pytestmark = [pytest.mark.slow,  # gpfverify in subprocesses under memory limits
              pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS and /proc/self/status")]

CT2D = ["reproduce", "ct2d", "--kappa", "12", "--test-steps", "3", "--fit-points", "12", "--runs", "2"]
#: seconds a capped command may take (it used to hang in OpenBLAS's allocation loop under 250 MB)
LIMIT_SECONDS = 240


def _capped(megabytes: int):
    def limit() -> None:
        size = megabytes * 10**6
        resource.setrlimit(resource.RLIMIT_AS, (size, size))

    return limit


def _run(args, cwd: Path, megabytes: int | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "gpfverify", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=LIMIT_SECONDS, preexec_fn=None if megabytes is None else _capped(megabytes))


def _assert_memory_or_success(proc, command: str, progress: str | None = None) -> None:
    """Exit 0, or exit 2 whose one line (after the progress lines) names memory and what to try."""
    assert "Traceback" not in proc.stderr, proc.stderr
    assert proc.returncode in (0, 2), (proc.returncode, proc.stderr)
    if proc.returncode == 2:
        lines = [line for line in proc.stderr.splitlines() if progress is None or not line.startswith(progress)]
        assert len(lines) == 1, proc.stderr
        assert lines[0].startswith(f"gpfverify {command}: error: out of memory"), lines
        assert "more memory" in lines[0], lines


def _assert_nothing_half_written(folder: Path, out: Path) -> None:
    assert not [p.name for p in folder.iterdir() if p.name.startswith(".gpfverify-")], os.listdir(folder)
    if out.exists():
        assert foreign_entry(out) is None and (out / FILE_LIST).is_file()


CHECK = ["check", "system.py:system", "--steps", "5"]


def _results(folder: Path) -> dict:
    """``out/results.json`` without its timings, the folder it ran in written as ``FOLDER``."""
    text = (folder / "out" / "results.json").read_text().replace(str(folder), "FOLDER")
    return without_timing(json.loads(text))


def _uncapped(folder: Path, args) -> dict:
    (folder / "system.py").write_text(LINEAR_SYSTEM)
    proc = _run([*args, "--out", "out"], folder)
    assert proc.returncode == 0, proc.stderr
    return _results(folder)


def _assert_resumable(proc, folder: Path, args, uncapped: dict) -> None:
    """What a capped command that failed kept in ``out`` (the line says so) is continued by
    ``--resume`` without the cap to the results of an uncapped run."""
    out = folder / "out"
    _assert_nothing_half_written(folder, out)
    if proc.returncode == 0:
        return
    if out.exists():
        assert f"the saved runs are kept in {out}" in proc.stderr.splitlines()[-1], proc.stderr
    resumed = _run([*args, "--out", "out", "--resume"], folder)
    assert resumed.returncode == 0, resumed.stderr
    assert _results(folder) == uncapped


@pytest.fixture(scope="module")
def uncapped_check(tmp_path_factory) -> dict:
    return _uncapped(tmp_path_factory.mktemp("uncapped-check"), CHECK)


@pytest.mark.parametrize("megabytes", [100, 250, 320, 380, 450])
def test_check_under_a_memory_cap_ends_with_one_line_and_resumes(tmp_path, megabytes, uncapped_check):
    (tmp_path / "system.py").write_text(LINEAR_SYSTEM)
    proc = _run([*CHECK, "--out", "out"], tmp_path, megabytes)
    _assert_memory_or_success(proc, "check")
    _assert_resumable(proc, tmp_path, CHECK, uncapped_check)


def test_a_cap_too_small_for_numpy_and_its_blas_buffers_is_refused_at_the_start(tmp_path):
    """The cap under which OpenBLAS used to retry its allocation for ever: refused before it."""
    (tmp_path / "system.py").write_text(LINEAR_SYSTEM)
    proc = _run(["check", "system.py:system", "--steps", "5", "--out", "out"], tmp_path, 250)
    assert proc.returncode == 2 and proc.stderr.startswith(
        "gpfverify check: error: out of memory (not enough memory to load "), proc.stderr


@pytest.fixture(scope="module")
def uncapped_reproduce(tmp_path_factory) -> dict:
    return _uncapped(tmp_path_factory.mktemp("uncapped-reproduce"), CT2D)


@pytest.mark.parametrize("megabytes", [350, 450, 600])
def test_reproduce_under_a_memory_cap_ends_with_one_line_and_resumes(tmp_path, megabytes, uncapped_reproduce):
    proc = _run([*CT2D, "--out", "out"], tmp_path, megabytes)
    _assert_memory_or_success(proc, "reproduce", progress="ct2d:")
    _assert_resumable(proc, tmp_path, CT2D, uncapped_reproduce)


@pytest.mark.parametrize("megabytes", [500])
def test_workers_under_a_memory_cap_end_with_one_line(tmp_path, megabytes):
    """Two workers, each a process under the cap: a worker that cannot start or runs out of memory
    ends the command in one line (memory, or a worker lost), never a traceback."""
    proc = _run([*CT2D, "--workers", "2", "--out", "out"], tmp_path, megabytes)
    assert "Traceback" not in proc.stderr and proc.returncode in (0, 2), proc.stderr
    if proc.returncode == 2:
        lines = [line for line in proc.stderr.splitlines() if not line.startswith("ct2d:")]
        assert len(lines) == 1 and ("out of memory" in lines[0] or "worker process ended" in lines[0]), lines
    _assert_nothing_half_written(tmp_path, tmp_path / "out")
