"""Which tests execute which line: the map that selects a mutant's tests.

:func:`build` runs the whole suite once, unmutated, in a workspace under coverage.py with one
dynamic context per test (pytest-cov's ``--cov-context=test``), and stores for every line of the
package the tests that executed it, with each test's duration (from a JUnit XML report). A mutant
then runs only the tests that execute its line (:func:`tests_for`); a line executed only while the
modules are imported (a constant, a decorator, a default argument) selects the tests that execute
the body of its definition, and failing that, every test that executes any line of its module.

The map stores the digest of every module it recorded (:func:`module_digests`): its lines hold for
a module whose contents are unchanged. After the package changes, a mutant of a changed module has
no selection (*not mapped*, reported apart and not scored) until the map is rebuilt
(``--remap``: the whole suite again); tests added since the map was made are run alone under
coverage and merged into it (:func:`update`).
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


def fingerprint(folders=("gpfverify",), extra=("pyproject.toml",)) -> str:
    """A digest of every Python file of ``folders`` and of the ``extra`` files. The map's lines are
    valid for one package fingerprint (a changed module moves lines: the map is rebuilt); tests added
    since (a new property) are run alone under coverage and merged (:func:`update`)."""
    digest = hashlib.sha256()
    files = sorted(p for folder in folders for p in (ROOT / folder).rglob("*.py"))
    for path in [*files, *(ROOT / name for name in extra)]:
        digest.update(str(path.relative_to(ROOT)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def module_digests() -> dict[str, str]:
    """``gpfverify/x.py`` -> the sha256 of its bytes, for every module of the package."""
    return {str(p.relative_to(ROOT)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted((ROOT / "gpfverify").rglob("*.py"))}


def tests_fingerprint() -> str:
    return fingerprint(TEST_ROOTS, ("conftest.py",))


@dataclass(frozen=True)
class CoverageMap:
    fingerprint: str  #: the package's (:func:`fingerprint`)
    tests: str  #: the test folders' (:func:`tests_fingerprint`) when the map was last completed
    #: "gpfverify/x.py" -> line -> sorted test node ids
    lines: dict[str, dict[int, list[str]]]
    #: test node id -> seconds (under coverage: an upper bound of its plain duration)
    durations: dict[str, float]
    #: tests that fail on the unmutated package (never selected: they cannot tell a mutant)
    failing: list[str]
    seconds: float
    #: "gpfverify/x.py" -> the digest of the module whose lines the map recorded
    modules: dict[str, str]

    def mapped(self, path: str) -> bool:
        """Whether the map's lines of ``path`` were recorded from the module as it is now."""
        return self.modules.get(path) == module_digests().get(path)

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


def _run_under_coverage(workspace: Path, workers: int, targets: list[str]):
    """Run ``targets`` in ``workspace`` under coverage with per-test contexts: (lines, durations, failing)."""
    database, junit = workspace / ".coverage", workspace / "junit.xml"
    database.unlink(missing_ok=True)
    junit.unlink(missing_ok=True)
    workers_args = ["-n", str(workers), "--dist", "loadfile"] if workers > 0 else ["-n", "0"]
    cmd = pytest_command("--hypothesis-profile=ci", *workers_args, "--cov=gpfverify", "--cov-context=test",
                         "--cov-report=", f"--junitxml={junit}", *[f"--ignore={p}" for p in NOT_SELECTED], *targets)
    env = dict(environment(workspace, "ci"), COVERAGE_FILE=str(database))
    subprocess.run(cmd, cwd=workspace, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
    durations, failing = _read_junit(junit) if junit.exists() else ({}, [])
    return (_read_coverage(database, workspace) if database.exists() else {}), durations, failing


def _save(cmap: CoverageMap) -> CoverageMap:
    MAP_FILE.parent.mkdir(parents=True, exist_ok=True)
    MAP_FILE.write_text(json.dumps(cmap.__dict__), encoding="utf-8")
    return cmap


def build(workspace: Path, workers: int = 2, log=print) -> CoverageMap:
    """Run the suite once under coverage in ``workspace`` (``workers`` xdist processes) and store the map."""
    sync(workspace)
    stamp, tests = fingerprint(), tests_fingerprint()
    start = time.perf_counter()
    log(f"coverage map: running the suite once under coverage ({workers} processes; about an hour on a busy "
        "two-core machine)")
    lines, durations, failing = _run_under_coverage(workspace, workers, list(TEST_ROOTS))
    result = _save(CoverageMap(stamp, tests, lines, durations, failing, round(time.perf_counter() - start, 1),
                               module_digests()))
    log(f"coverage map: {len(durations)} tests, {len(failing)} failing unmutated, {result.seconds} s")
    return result


def collected(workspace: Path) -> set[str]:
    """The node ids the suite collects now (``--collect-only``)."""
    proc = subprocess.run(pytest_command("--collect-only", "-n", "0", *[f"--ignore={p}" for p in NOT_SELECTED],
                                         *TEST_ROOTS),
                          cwd=workspace, env=environment(workspace, "ci"), capture_output=True, text=True)
    return {line.strip() for line in proc.stdout.splitlines() if "::" in line}


def update(cmap: CoverageMap, workspace: Path, log=print) -> CoverageMap:
    """Tests the map does not know (added or renamed since it was made): run them alone under coverage
    and merge them into the map. Lines of the package are unchanged (same package fingerprint)."""
    sync(workspace)
    known = set(cmap.durations)
    missing = sorted(collected(workspace) - known)
    if missing:
        log(f"coverage map: {len(missing)} tests the map does not know; running them under coverage")
        lines, durations, failing = _run_under_coverage(workspace, 0, missing)
        merged = {p: {n: list(t) for n, t in v.items()} for p, v in cmap.lines.items()}
        for path, per_line in lines.items():
            for n, tests in per_line.items():
                merged.setdefault(path, {}).setdefault(n, [])
                merged[path][n] = sorted(set(merged[path][n]) | set(tests))
        cmap = CoverageMap(cmap.fingerprint, tests_fingerprint(), merged, {**cmap.durations, **durations},
                           sorted(set(cmap.failing) | set(failing)), cmap.seconds, cmap.modules)
    else:
        cmap = CoverageMap(cmap.fingerprint, tests_fingerprint(), cmap.lines, cmap.durations, cmap.failing,
                           cmap.seconds, cmap.modules)
    return _save(cmap)


def load(workspace: Path | None = None, workers: int = 2, log=print, remap: bool = False) -> CoverageMap:
    """The stored map (updated with the tests added since), unless ``remap`` or there is none: then a
    new one. Modules changed since the stored map was made are not mapped (:meth:`CoverageMap.mapped`)."""
    workspace = workspace or CACHE / "workspace-coverage"
    if MAP_FILE.exists() and not remap:
        data = json.loads(MAP_FILE.read_text(encoding="utf-8"))
        data["lines"] = {p: {int(n): t for n, t in v.items()} for p, v in data["lines"].items()}
        data.setdefault("tests", "")
        stored = CoverageMap(**data)
        if stored.fingerprint != fingerprint():
            now = module_digests()
            changed = sum(stored.modules.get(p) != d for p, d in now.items())
            log(f"coverage map: {changed} of {len(now)} modules changed since the map was made; their mutants "
                "are not mapped (--remap rebuilds the map: the whole suite once under coverage)")
        return stored if stored.tests == tests_fingerprint() else update(stored, workspace, log)
    return build(workspace, workers, log)
