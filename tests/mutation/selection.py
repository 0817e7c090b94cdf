"""Which tests execute which line: the map that selects a mutant's tests.

:func:`build` runs the whole suite once, unmutated, in a workspace under coverage.py with one
dynamic context per test (pytest-cov's ``--cov-context=test``), and stores for every line of the
package the tests that executed it, with each test's duration (from a JUnit XML report). A mutant
then runs only the tests that execute its line (:func:`tests_for`); a line executed only while the
modules are imported (a constant, a decorator, a default argument) selects the tests that execute
the body of its definition, and failing that, every test that executes any line of its module.

The map is stored with the fingerprint of the files it was made from (:func:`fingerprint`); a
changed package or test file makes it stale, and the mutation run rebuilds it.
"""

from __future__ import annotations

import hashlib
import json
import sqlite3
import subprocess
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from tests.mutation.workspace import CACHE, ROOT, environment, pytest_command, sync

#: folders whose files decide what the suite executes
TEST_ROOTS = ("tests", "property_tests", "proofs", "examples")
#: the curated mutation machinery runs pytest on copies of its own; it tests no line of the package
NOT_SELECTED = ("tests/mutation/",)
MAP_FILE = CACHE / "coverage_map.json"


def fingerprint() -> str:
    """A digest of every Python file of the package and of the test folders, and of conftest.py and
    pyproject.toml: the map is valid for exactly these contents."""
    digest = hashlib.sha256()
    files = sorted(p for folder in ("gpfverify", *TEST_ROOTS) for p in (ROOT / folder).rglob("*.py"))
    for path in [*files, ROOT / "conftest.py", ROOT / "pyproject.toml"]:
        digest.update(str(path.relative_to(ROOT)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


@dataclass(frozen=True)
class CoverageMap:
    fingerprint: str
    #: "gpfverify/x.py" -> line -> sorted test node ids
    lines: dict[str, dict[int, list[str]]]
    #: test node id -> seconds (under coverage: an upper bound of its plain duration)
    durations: dict[str, float]
    #: tests that fail on the unmutated package (never selected: they cannot tell a mutant)
    failing: list[str]
    seconds: float

    def tests_for(self, path: str, line: int, body: range | None = None) -> list[str]:
        """The tests that execute ``line`` of ``path``; else those executing ``body`` (the lines of
        the line's definition); else those executing any line of the module."""
        by_line = self.lines.get(path, {})
        for lines in ([line], list(body or ()), list(by_line)):
            found = sorted({t for n in lines for t in by_line.get(n, ()) if t not in self.failing})
            if found:
                return found
        return []


def _node_id(context: str) -> str | None:
    """pytest-cov's context ``tests/test_x.py::test_y[p]|run`` -> its node id (setup and teardown
    contexts count: a fixture's lines are the test's)."""
    if not context or "|" not in context:
        return None
    node = context.rsplit("|", 1)[0]
    if any(node.startswith(prefix) for prefix in NOT_SELECTED):
        return None
    return node


def _read_coverage(database: Path, workspace: Path) -> dict[str, dict[int, list[str]]]:
    """coverage.py's SQLite file -> package file -> line -> node ids (through its documented schema:
    file, context, line_bits; a line bitmap is decoded with coverage.numbits)."""
    from coverage.numbits import numbits_to_nums

    lines: dict[str, dict[int, set[str]]] = {}
    with sqlite3.connect(database) as db:
        files = dict(db.execute("select id, path from file"))
        contexts = dict(db.execute("select id, context from context"))
        for file_id, context_id, bits in db.execute("select file_id, context_id, numbits from line_bits"):
            node = _node_id(contexts[context_id])
            path = Path(files[file_id])
            if node is None or not path.is_relative_to(workspace / "gpfverify"):
                continue
            per_line = lines.setdefault(str(path.relative_to(workspace)), {})
            for n in numbits_to_nums(bits):
                per_line.setdefault(n, set()).add(node)
    return {p: {n: sorted(t) for n, t in sorted(v.items())} for p, v in sorted(lines.items())}


def _read_junit(report: Path) -> tuple[dict[str, float], list[str]]:
    """Durations and failures per node id from pytest's JUnit XML (classname + name -> node id is
    ambiguous for nested paths, so the node ids come from the ``file``-less classname rule below)."""
    durations: dict[str, float] = {}
    failing: list[str] = []
    for case in ET.parse(report).getroot().iter("testcase"):
        classname, name = case.get("classname", ""), case.get("name", "")
        parts = classname.split(".")
        # the module part ends at the first element that is not a folder of the workspace
        for cut in range(len(parts), 0, -1):
            candidate = "/".join(parts[:cut]) + ".py"
            if (ROOT / candidate).exists():
                node = "::".join([candidate, *parts[cut:], name])
                break
        else:
            continue
        durations[node] = float(case.get("time", 0.0))
        if case.find("failure") is not None or case.find("error") is not None:
            failing.append(node)
    return durations, sorted(failing)


def build(workspace: Path, workers: int = 2, log=print) -> CoverageMap:
    """Run the suite once under coverage in ``workspace`` (``workers`` xdist processes) and store the map."""
    sync(workspace)
    database, junit = workspace / ".coverage", workspace / "junit.xml"
    database.unlink(missing_ok=True)
    stamp = fingerprint()
    start = time.perf_counter()
    log(f"coverage map: running the suite once under coverage ({workers} processes; about half an hour)")
    cmd = pytest_command("--hypothesis-profile=ci", "-n", str(workers), "--dist", "loadfile",
                         "--cov=gpfverify", "--cov-context=test", "--cov-report=", f"--junitxml={junit}",
                         *[f"--ignore={p}" for p in NOT_SELECTED], *TEST_ROOTS)
    env = dict(environment(workspace, "ci"), COVERAGE_FILE=str(database))
    subprocess.run(cmd, cwd=workspace, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
    durations, failing = _read_junit(junit)
    result = CoverageMap(stamp, _read_coverage(database, workspace), durations, failing,
                         round(time.perf_counter() - start, 1))
    MAP_FILE.parent.mkdir(parents=True, exist_ok=True)
    MAP_FILE.write_text(json.dumps(result.__dict__), encoding="utf-8")
    log(f"coverage map: {len(durations)} tests, {len(failing)} failing unmutated, {result.seconds} s")
    return result


def load(rebuild_if_stale: bool = True, workspace: Path | None = None, workers: int = 2, log=print) -> CoverageMap:
    """The stored map if it matches the working tree, else a new one (``rebuild_if_stale``)."""
    if MAP_FILE.exists():
        data = json.loads(MAP_FILE.read_text(encoding="utf-8"))
        data["lines"] = {p: {int(n): t for n, t in v.items()} for p, v in data["lines"].items()}
        stored = CoverageMap(**data)
        if stored.fingerprint == fingerprint() or not rebuild_if_stale:
            return stored
        log("coverage map: the package or its tests changed since the stored map; rebuilding it")
    return build(workspace or CACHE / "workspace-coverage", workers, log)
