"""Every shell command in README.md and docs/*.md runs as typed after the documented set-up
(``. .venv/bin/activate``), in order, from a copy of the repository's examples — what a new user
does on a fresh clone. A block preceded by ``<!-- docs-test: skip (REASON) -->`` is skipped with
that reason; no shell command may sit outside a fenced block (it would escape this test)."""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # runs every documented command

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"(?:<!-- docs-test: skip \((?P<reason>[^)]+)\) -->\n)?```(?P<lang>sh|text|json|python)\n"
                   r"(?P<body>.*?)```", re.S)
#: an indented or bare line that a user would type into a shell
LOOSE_COMMAND = re.compile(r"^(?: {4}|\t)(?:gpfverify|make|python) ", re.M)


def _blocks(path: Path) -> list[tuple[str, str | None]]:
    return [(m["body"], m["reason"]) for m in FENCE.finditer(path.read_text(encoding="utf-8")) if m["lang"] == "sh"]


def _outside_fences(path: Path) -> str:
    return FENCE.sub("", path.read_text(encoding="utf-8"))


@pytest.mark.parametrize("path", DOCS, ids=lambda p: p.name)
def test_no_shell_command_outside_a_tested_block(path):
    loose = LOOSE_COMMAND.findall(_outside_fences(path))
    assert not loose, f"{path.name}: put these commands in a ```sh block (or ```text for a synopsis): {loose}"


@pytest.fixture(scope="module")
def user_folder(tmp_path_factory):
    """A folder laid out as the repository root is for a user: the examples, and .venv (the
    environment running these tests)."""
    folder = tmp_path_factory.mktemp("clone")
    shutil.copytree(ROOT / "examples", folder / "examples")
    activate = Path(sys.prefix) / "bin" / "activate"
    if not activate.exists():
        pytest.skip(f"the tests do not run in a virtualenv ({sys.prefix} has no bin/activate)")
    (folder / ".venv").symlink_to(sys.prefix)
    return folder


@pytest.mark.parametrize("path", DOCS, ids=lambda p: p.name)
def test_the_shell_blocks_run_as_typed(path, user_folder):
    blocks = _blocks(path)
    skipped = [reason for _, reason in blocks if reason]
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH")}
    env["PATH"] = "/usr/bin:/bin"  # a fresh shell: gpfverify is on PATH only after the documented set-up
    ran = 0
    for body, reason in blocks:
        if reason:
            continue
        script = ". .venv/bin/activate\nset -e\n" + body
        proc = subprocess.run(["bash", "-c", script], cwd=user_folder, env=env, capture_output=True, text=True,
                              timeout=300)
        assert proc.returncode == 0, f"{path.name}:\n{body}\nstdout: {proc.stdout[-2000:]}\nstderr: {proc.stderr[-2000:]}"
        ran += 1
    if not ran:
        pytest.skip(f"{path.name}: no shell block to run" + (f" ({'; '.join(skipped)})" if skipped else ""))


def _python_blocks(path: Path) -> list[tuple[str, str | None]]:
    return [(m["body"], m["reason"]) for m in FENCE.finditer(path.read_text(encoding="utf-8"))
            if m["lang"] == "python"]


@pytest.mark.parametrize("path", [p for p in DOCS if p.name != "README.md"], ids=lambda p: p.name)
def test_the_python_blocks_of_the_docs_run_as_written(path):
    """Each Python block of docs/*.md runs on its own (a user pastes it into a fresh session);
    README.md's blocks run in tests/test_readme_examples.py, with what they compute checked."""
    ran = 0
    for body, reason in _python_blocks(path):
        if reason:
            continue
        exec(compile(body, str(path), "exec"), {})
        ran += 1
    if not ran:
        pytest.skip(f"{path.name}: no Python block to run")
