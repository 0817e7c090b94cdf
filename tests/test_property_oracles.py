"""property_tests/README.md names the oracle of every property: each ``@given`` function of
property_tests/ has exactly one line there, and every line names a property that exists."""

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROPERTIES = ROOT / "property_tests"
LINE = re.compile(r"^- `(test_\w+\.py)::(\w+)` — (.+)$")


def _properties() -> set[str]:
    found = set()
    for path in sorted(PROPERTIES.glob("test_*.py")):
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if isinstance(node, ast.FunctionDef) and any(
                    "given" in ast.unparse(d) for d in node.decorator_list):
                found.add(f"{path.name}::{node.name}")
    return found


def _listed() -> list[tuple[str, str]]:
    lines = (PROPERTIES / "README.md").read_text(encoding="utf-8").splitlines()
    return [(f"{m[1]}::{m[2]}", m[3]) for m in map(LINE.match, lines) if m]


def test_every_property_has_one_oracle_line_and_every_line_a_property():
    listed = [name for name, _ in _listed()]
    properties = _properties()
    assert len(properties) >= 60
    assert sorted(set(listed)) == sorted(listed), "a property is listed twice"
    assert sorted(properties - set(listed)) == [], "add these properties' oracles to property_tests/README.md"
    assert sorted(set(listed) - properties) == [], "these listed properties do not exist"


def test_every_oracle_line_says_something():
    assert all(len(oracle.split()) >= 3 for _, oracle in _listed())
