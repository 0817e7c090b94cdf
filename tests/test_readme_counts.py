"""The README states the suite's size — the whole suite and the tests not marked slow — as the suite
it runs in counts it: collected by this very session (selected and deselected alike), never typed.
``tests/readme_counts.py`` rewrites the README's numbers."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

HERE = Path(__file__).parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))  # the suite imports in importlib mode: the helper beside it
import readme_counts  # noqa: E402


def _test_files(config: pytest.Config) -> set[Path]:
    """Every file of the testpaths that pytest collects from (pyproject.toml's python_files)."""
    patterns = config.getini("python_files")
    return {path.resolve() for folder in config.getini("testpaths") for pattern in patterns
            for path in (ROOT / folder).rglob(pattern) if "fixtures" not in path.parts}


def test_the_readmes_test_counts_are_those_of_the_suite(request, deselected_tests):
    config = request.config
    items = [*request.session.items, *deselected_tests]
    files = {Path(str(item.path)).resolve() for item in items}
    missing = _test_files(config) - files
    if missing:
        pytest.skip(f"the README counts the whole suite; this session collected part of it (not {len(missing)} "
                    "test files)")
    whole = len(items)
    fast = sum(1 for item in items if item.get_closest_marker("slow") is None)
    text = readme_counts.README.read_text(encoding="utf-8")
    assert readme_counts.stated(text) == (whole, fast), (
        f"README.md states {readme_counts.stated(text)} tests (whole suite, not slow); the suite has "
        f"({whole}, {fast}): run `.venv/bin/python tests/readme_counts.py`")
    assert readme_counts.stated(readme_counts.with_counts(text, whole + 1, fast + 2)) == (whole + 1, fast + 2)
