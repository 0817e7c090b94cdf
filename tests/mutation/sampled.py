"""The sampled mutation run: mutants drawn by cosmic-ray, each run against the suite's tests that
execute its line, and the report in reports/mutation/.

    python -m tests.mutation.sampled [--size 420] [--seed 1] [--jobs 2] [--report-only]
                                     [--retry survived] [--out reports/mutation]

Steps (each resumes where an interrupted run stopped):

1. **Draw** the seeded sample (:mod:`tests.mutation.draw`) of the package as it is now.
2. **Map** which tests execute which line (:mod:`tests.mutation.selection`): the whole suite once,
   under coverage, unless the stored map was made from the same package and test files.
3. **Run** each mutant in a workspace (a copy of the project; ``--jobs`` of them side by side):
   write the mutated module there, then

   * the selected tests of ``property_tests/`` with hypothesis's ``mutation`` profile (generated
     examples only, no shrinking) and ``-x``: a failure is *killed by a property*, and nothing else runs;
   * otherwise the selected tests of ``tests/``, ``proofs/`` and ``examples/`` with the ``ci`` profile
     (what ``make test`` runs) and ``-x``: a failure is *killed by the suite*;
   * otherwise the mutant *survived*. A run longer than its time limit (three times the selected
     tests' duration in the coverage run, plus two minutes for start-up and numba's compilation)
     is a *timeout*, counted as killed, as mutation tools count a mutant that hangs the suite.

   Each mutant's result is appended to ``OUT/results.jsonl`` as it finishes; a rerun skips every
   mutant whose result is stored for the same module contents (``--retry survived`` reruns the
   survivors, after a new property, keeping their earlier verdicts as history).
4. **Report** (:mod:`tests.mutation.score`): ``OUT/sampled.md`` and ``OUT/sampled.json``.
"""

from __future__ import annotations

import argparse
import ast
import json
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from queue import Queue

from tests.mutation import draw as drawing
from tests.mutation import score, selection
from tests.mutation.workspace import CACHE, ROOT, environment, forget_compiled, pytest_command, sync

OUT = ROOT / "reports" / "mutation"
SIZE, SEED = 420, 1
PROPERTY_ROOT = "property_tests/"
STARTUP_SECONDS = 120.0
SLOWDOWN = 3.0


def definition_body(path: Path, line: int) -> range | None:
    """The lines of the innermost function or class whose header holds ``line`` (a decorator or a
    default argument is evaluated at import; its effect shows in the body)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    best = None
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            first = min([node.lineno, *(d.lineno for d in node.decorator_list)])
            if first <= line <= (node.end_lineno or node.lineno):
                best = node
    if best is None:
        return None
    return range(best.body[0].lineno, (best.end_lineno or best.lineno) + 1)


def run_phase(workspace: Path, tests: list[str], profile: str, timeout: float) -> dict:
    """Run ``tests`` (node ids) in ``workspace``; stop at the first failure."""
    report = workspace / "mutation_report.jsonl"
    report.unlink(missing_ok=True)
    env = dict(environment(workspace, profile), MUTATION_REPORT=str(report))
    cmd = pytest_command(f"--hypothesis-profile={profile}", "-x", "-n", "0", *tests)
    start = time.perf_counter()
    try:
        proc = subprocess.run(cmd, cwd=workspace, env=env, capture_output=True, text=True, timeout=timeout)
        code: int | None = proc.returncode
    except subprocess.TimeoutExpired:
        code = None
    lines = [json.loads(x) for x in report.read_text().splitlines()] if report.exists() else []
    packages = [x["package"] for x in lines if "package" in x]
    if packages and not all(Path(p).resolve().is_relative_to(workspace.resolve()) for p in packages):
        raise RuntimeError(f"the tests imported {packages}, not the workspace's copy in {workspace}")
    return {"code": code, "seconds": round(time.perf_counter() - start, 1),
            "failed": [x["test"] for x in lines if "test" in x]}


def limit(tests: list[str], durations: dict[str, float]) -> float:
    return STARTUP_SECONDS + SLOWDOWN * sum(durations.get(t, 1.0) for t in tests)


def judge(mutant: drawing.Drawn, workspace: Path, cmap: selection.CoverageMap) -> dict:
    """Apply ``mutant`` in ``workspace``, run its tests, put the module back; the result record."""
    module = workspace / mutant.path
    original = (ROOT / mutant.path).read_text(encoding="utf-8")
    tests = cmap.tests_for(mutant.path, mutant.line, definition_body(ROOT / mutant.path, mutant.line))
    tests.sort(key=lambda t: cmap.durations.get(t, 1.0))  # the quick ones first: -x stops at a kill
    properties = [t for t in tests if t.startswith(PROPERTY_ROOT)]
    others = [t for t in tests if not t.startswith(PROPERTY_ROOT)]
    record = {**mutant.record(), "selected_properties": len(properties), "selected_tests": len(others),
              "map": f"{cmap.fingerprint[:8]}/{cmap.tests[:8]}"}
    if not cmap.mapped(mutant.path):
        return {**record, "verdict": "not mapped", "killed_by": None, "seconds": 0.0}
    if not tests:
        return {**record, "verdict": "not executed", "killed_by": None, "seconds": 0.0}
    mutated = drawing.mutated_source(ROOT / mutant.path, mutant.operator, mutant.occurrence)
    module.write_text(mutated, encoding="utf-8")
    forget_compiled(module)
    seconds = 0.0
    try:
        for group, profile, verdict in ((properties, "mutation", "killed (property)"),
                                        (others, "ci", "killed (suite)")):
            if not group:
                continue
            result = run_phase(workspace, group, profile, limit(group, cmap.durations))
            seconds += result["seconds"]
            if result["code"] is None:
                return {**record, "verdict": "timeout", "phase": profile, "killed_by": None, "seconds": seconds}
            if result["failed"] or result["code"] not in (0, 5):
                first = result["failed"][0] if result["failed"] else f"pytest exit {result['code']}"
                return {**record, "verdict": verdict, "killed_by": first, "seconds": round(seconds, 1)}
        return {**record, "verdict": "survived", "killed_by": None, "seconds": round(seconds, 1)}
    finally:
        module.write_text(original, encoding="utf-8")
        forget_compiled(module)


def load_results(out: Path) -> dict[str, dict]:
    """Stored results by key (the last line of a key wins: a retry appends)."""
    path = out / "results.jsonl"
    if not path.exists():
        return {}
    results: dict[str, dict] = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.strip():
            row = json.loads(line)
            if row["key"] in results:
                row.setdefault("history", [])
                row["history"] = [*results[row["key"]].get("history", []),
                                  {k: results[row["key"]][k] for k in ("verdict", "killed_by", "map")}]
            results[row["key"]] = row
    return results


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=SIZE, help="mutants in the sample (default %(default)s)")
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument("--jobs", type=int, default=2, help="mutants run side by side (default %(default)s)")
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--report-only", action="store_true", help="write the report from the stored results")
    parser.add_argument("--retry", choices=("survived", "timeout", "not executed"), action="append", default=[],
                        help="rerun the stored mutants with this verdict (after a new property)")
    parser.add_argument("--remap", action="store_true",
                        help="rebuild the coverage map (the whole suite once under coverage) before running")
    parser.add_argument("--only", help="run only the sampled mutants whose path contains this text")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    sample_file = args.out / "sample.json"

    def log(message: str) -> None:
        print(message, file=sys.stderr, flush=True)

    drawn = drawing.draw(args.size, args.seed, log)
    sample_file.write_text(json.dumps({"size": args.size, "seed": args.seed,
                                       "mutants": [d.record() for d in drawn]}, indent=1), encoding="utf-8")
    if args.report_only:
        score.write(args.out, drawn, load_results(args.out), args.seed)
        return 0
    results = load_results(args.out)
    todo = [d for d in drawn if d.key not in results or results[d.key]["verdict"] in args.retry]
    todo = [d for d in todo if not args.only or args.only in d.path]
    log(f"{len(drawn) - len(todo)} of {len(drawn)} mutants have a stored result; {len(todo)} to run")
    cmap = selection.load(CACHE / "workspace-coverage", workers=args.jobs, log=log, remap=args.remap)
    workspaces: Queue[Path] = Queue()
    for i in range(args.jobs):
        workspaces.put(sync(CACHE / f"workspace-{i}"))
    lock = threading.Lock()
    done = 0

    def one(mutant: drawing.Drawn) -> None:
        nonlocal done
        workspace = workspaces.get()
        try:
            row = judge(mutant, workspace, cmap)
        finally:
            workspaces.put(workspace)
        with lock:
            if row["verdict"] != "not mapped":  # no verdict: it runs once the map covers its module
                with (args.out / "results.jsonl").open("a", encoding="utf-8") as stream:
                    stream.write(json.dumps(row, ensure_ascii=False) + "\n")
            done += 1
            log(f"[{done}/{len(todo)}] {row['verdict']:18s} {mutant.name} ({row['seconds']} s)")

    with ThreadPoolExecutor(args.jobs) as pool:
        for future in [pool.submit(one, m) for m in todo]:
            future.result()
    score.write(args.out, drawn, load_results(args.out), args.seed)
    return 0


if __name__ == "__main__":
    sys.exit(main())
