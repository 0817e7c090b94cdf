"""The README's test counts, generated: how many tests the whole suite has (``make test``) and how
many are not marked slow (``make test-fast``), and the README's two sentences that state them.

    .venv/bin/python tests/readme_counts.py     # collects the suite (half a minute) and rewrites README.md

``tests/test_readme_counts.py`` compares the README with the suite it runs in, so a count that goes
stale fails ``make test`` and ``make test-fast`` with the line to write."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: the README's words around each count (the whole suite; the tests not marked slow)
WHOLE = re.compile(r"(the whole suite \()(\d+)( tests\))")
FAST = re.compile(r"(ruff and the )(\d+)( tests not marked `slow`)")


def stated(text: str) -> tuple[int, int]:
    """(whole suite, not slow) as the README states them."""
    whole, fast = WHOLE.search(text), FAST.search(text)
    if whole is None or fast is None:
        raise ValueError("README.md no longer states the suite's test counts in the expected words")
    return int(whole.group(2)), int(fast.group(2))


def with_counts(text: str, whole: int, fast: int) -> str:
    """``text`` with both counts replaced."""
    return FAST.sub(rf"\g<1>{fast}\g<3>", WHOLE.sub(rf"\g<1>{whole}\g<3>", text, count=1), count=1)


def collected() -> tuple[int, int]:
    """(whole suite, not slow), collected by pytest in a subprocess (the testpaths of pyproject.toml)."""
    def count(*marker: str) -> int:
        out = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "--collect-only", "-q",
                              *marker], cwd=ROOT, capture_output=True, text=True, check=True).stdout
        return int(re.search(r"^(\d+)(?:/\d+)? tests? collected", out, re.M).group(1))
    return count(), count("-m", "not slow")


if __name__ == "__main__":
    text = README.read_text(encoding="utf-8")
    whole, fast = collected()
    README.write_text(with_counts(text, whole, fast), encoding="utf-8")
    print(f"README.md: the whole suite {whole} tests, {fast} not marked slow (it said {stated(text)})")
