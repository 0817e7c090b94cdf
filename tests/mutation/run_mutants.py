"""Mutation testing of the numerical core, on copies — never on the working tree.

    python -m tests.mutation.run_mutants [--only NAME ...] [--jobs 2] [--out reports/mutation] [--every-test]

For each mutant of :mod:`tests.mutation.mutants`: copy ``gpfverify/``, ``property_tests/``,
``conftest.py`` and ``pyproject.toml`` to a fresh temporary folder, apply the one replacement there,
and run the mutant's property tests (hypothesis profile ``mutation``: ``ci``'s generated examples, no
explicit ``@example`` s, no shrinking; ``-x``) with that copy first on
``sys.path`` (the plugin checks that the copy's package is the one imported). Tests that already
fail on an unmutated copy are deselected. A mutant is

* ``killed (property)`` when a ``@given`` test fails,
* ``killed (example only)`` when only plain tests fail,
* ``survived`` otherwise (``timeout``/``error`` are reported as such).

Writes ``OUT/kill_table.json`` and ``OUT/kill_table.md`` (with each survivor's ``note`` from
:mod:`tests.mutation.mutants`); ``--render`` rewrites the markdown from an existing JSON table
without running anything. ``--every-test`` runs every selected test of a mutant instead of stopping
at the first failure, so that ``killed_by`` lists every test that notices it and the table says
which mutants each property kills. Exits 1 unless every mutant is killed by a property.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from tests.mutation.mutants import MUTANTS, Mutant

ROOT = Path(__file__).resolve().parents[2]
COPIED = ("gpfverify", "property_tests", "conftest.py", "pyproject.toml")
PLUGIN = Path(__file__).with_name("kill_plugin.py")


def make_copy(dest: Path) -> Path:
    for name in COPIED:
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, dest / name, ignore=shutil.ignore_patterns("__pycache__", ".hypothesis"))
        else:
            shutil.copy2(src, dest / name)
    shutil.copy2(PLUGIN, dest / "kill_plugin.py")
    return dest


def apply(mutant: Mutant, copy: Path) -> None:
    target = copy / mutant.path
    text = target.read_text(encoding="utf-8")
    if text.count(mutant.old) != 1:
        raise ValueError(f"{mutant.name}: the snippet occurs {text.count(mutant.old)} times in {mutant.path}")
    target.write_text(text.replace(mutant.old, mutant.new), encoding="utf-8")


def run_tests(copy: Path, tests, deselect=(), timeout: float = 900.0, stop_first: bool = True,
              extra=()) -> dict:
    report = copy / "mutation_report.jsonl"
    report.unlink(missing_ok=True)
    env = dict(os.environ, PYTHONPATH=str(copy), MPLBACKEND="Agg", MUTATION_REPORT=str(report),
               HYPOTHESIS_PROFILE="mutation")
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "kill_plugin", "-q",
           "--hypothesis-profile=mutation", "--tb=no", "-o", "addopts=--import-mode=importlib", *extra]
    if stop_first:
        cmd.append("-x")
    for nodeid in deselect:
        cmd += ["--deselect", nodeid]
    cmd += list(tests)
    start = time.perf_counter()
    try:
        proc = subprocess.run(cmd, cwd=copy, env=env, capture_output=True, text=True, timeout=timeout)
        code, tail = proc.returncode, proc.stdout.strip().splitlines()[-1:] or [""]
    except subprocess.TimeoutExpired:
        code, tail = None, ["timeout"]
    lines = [json.loads(x) for x in report.read_text().splitlines()] if report.exists() else []
    packages = [x["package"] for x in lines if "package" in x]
    if packages and not all(Path(p).resolve().is_relative_to(copy.resolve()) for p in packages):
        raise RuntimeError(f"the tests imported {packages}, not the copy in {copy}")
    failures = [x for x in lines if "test" in x]
    return {"code": code, "seconds": round(time.perf_counter() - start, 1), "summary": tail[0],
            "failed": failures}


def verdict(result: dict) -> str:
    if result["code"] is None:
        return "timeout"
    if any(f["property"] for f in result["failed"]):
        return "killed (property)"
    if result["failed"]:
        return "killed (example only)"
    if result["code"] not in (0, 5):
        return f"error (exit {result['code']})"
    return "survived"


def baseline_failures(tests, timeout: float) -> list[str]:
    with tempfile.TemporaryDirectory(prefix="gpfverify-baseline-") as tmp:
        result = run_tests(make_copy(Path(tmp)), tests, timeout=timeout, stop_first=False)
    return sorted(f["test"] for f in result["failed"])


def run_one(mutant: Mutant, deselect, timeout: float, every_test: bool = False) -> dict:
    """One mutant's row; a snippet that no longer occurs exactly once is reported as
    ``does not apply`` (never skipped silently). ``every_test``: do not stop at the first failure."""
    row = {"mutant": mutant.name, "area": mutant.area, "file": mutant.path, "tests": list(mutant.tests)}
    with tempfile.TemporaryDirectory(prefix="gpfverify-mutant-") as tmp:
        copy = make_copy(Path(tmp))
        try:
            apply(mutant, copy)
        except ValueError as exc:
            return {**row, "verdict": "does not apply", "killed_by": [], "seconds": 0.0, "error": str(exc)}
        result = run_tests(copy, mutant.tests, [d for d in deselect if d.split("::")[0] in mutant.tests], timeout,
                           stop_first=not every_test)
    return {**row, "verdict": verdict(result), "killed_by": [f["test"] for f in result["failed"]],
            "seconds": result["seconds"]}


def write_table(out: Path, rows: dict[str, dict], baseline: list[str], every_test: bool) -> list[dict]:
    """Write OUT/kill_table.json and .md with the rows of the current mutants, in their order."""
    ordered = [rows[m.name] for m in MUTANTS if m.name in rows]
    out.mkdir(parents=True, exist_ok=True)
    (out / "kill_table.json").write_text(json.dumps({"baseline_failures": baseline, "every_test": every_test,
                                                     "mutants": ordered}, indent=2, ensure_ascii=False),
                                         encoding="utf-8")
    (out / "kill_table.md").write_text(markdown(ordered, baseline, every_test), encoding="utf-8")
    return ordered


def kills_by_property(rows: list[dict]) -> dict[str, list[str]]:
    """Property test (node id) -> the mutants it failed on, in the table's order."""
    kills: dict[str, list[str]] = {}
    for r in rows:
        for test in r["killed_by"]:
            kills.setdefault(test, []).append(r["mutant"])
    return dict(sorted(kills.items()))


def markdown(rows: list[dict], baseline: list[str], every_test: bool = False) -> str:
    killed = sum(r["verdict"] == "killed (property)" for r in rows)
    notes = {m.name: m.note for m in MUTANTS}
    out = ["# Mutation kill table", "",
           f"{killed} of {len(rows)} mutants killed by a property (hypothesis profile `mutation`: the `ci` "
           "profile's generated examples without explicit examples or shrinking, "
           + ("every selected test run" if every_test else "`-x`") + ", on a copy of the package). "
           "Regenerate with `python -m tests.mutation.run_mutants"
           + (" --every-test" if every_test else "") + "`.", "",
           "| mutant | area | verdict | first failing test | seconds |", "|---|---|---|---|---|"]
    for r in rows:
        first = r["killed_by"][0].split("::")[-1] if r["killed_by"] else "—"
        name = r["mutant"].replace("|", "\\|")
        out.append(f"| {name} | {r['area']} | {r['verdict']} | {first} | {r['seconds']} |")
    survivors = [r for r in rows if r["verdict"] != "killed (property)"]
    if survivors:
        out += ["", "## Not killed by a property", ""]
        out += [f"* **{r['mutant']}** ({r['verdict']}): {notes.get(r['mutant']) or 'not explained'}"
                for r in survivors]
    if every_test:
        out += ["", "## What each test kills", "",
                "Every test that failed on at least one mutant (the properties are `@given` tests), and the "
                "mutants it failed on.", "", "| test | mutants | which |", "|---|---|---|"]
        for test, names in kills_by_property(rows).items():
            shown = "; ".join(n.replace("|", "\\|") for n in names)
            out.append(f"| {test.split('/')[-1]} | {len(names)} | {shown} |")
    if baseline:
        out += ["", "Deselected (failing on the unmutated copy already): " + ", ".join(f"`{b}`" for b in baseline)]
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", help="mutant names (substring match)")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--timeout", type=float, default=900.0)
    parser.add_argument("--out", type=Path, default=ROOT / "reports" / "mutation")
    parser.add_argument("--no-baseline", action="store_true", help="do not run the unmutated copy first")
    parser.add_argument("--render", action="store_true", help="rewrite OUT/kill_table.md from OUT/kill_table.json")
    parser.add_argument("--merge", action="store_true",
                        help="keep the other mutants' rows of OUT/kill_table.json, replace the chosen ones")
    parser.add_argument("--missing", action="store_true", help="only the mutants OUT/kill_table.json lacks")
    parser.add_argument("--every-test", action="store_true",
                        help="run every selected test of a mutant (killed_by lists all that notice it)")
    args = parser.parse_args(argv)
    if args.render:
        table = json.loads((args.out / "kill_table.json").read_text(encoding="utf-8"))
        (args.out / "kill_table.md").write_text(markdown(table["mutants"], table["baseline_failures"],
                                                         table.get("every_test", False)), encoding="utf-8")
        return 0
    chosen = [m for m in MUTANTS if not args.only or any(o in m.name for o in args.only)]
    if args.missing:
        earlier = json.loads((args.out / "kill_table.json").read_text(encoding="utf-8"))
        known = {r["mutant"] for r in earlier["mutants"]}
        chosen = [m for m in chosen if m.name not in known]
    tests = sorted({t for m in chosen for t in m.tests})
    baseline = [] if args.no_baseline else baseline_failures(tests, args.timeout)
    rows: dict[str, dict] = {}
    table: list[dict] = []
    every_test = args.every_test
    if args.merge and (args.out / "kill_table.json").exists():
        earlier = json.loads((args.out / "kill_table.json").read_text(encoding="utf-8"))
        rows = {r["mutant"]: r for r in earlier["mutants"]}
        baseline = sorted(set(baseline) | set(earlier["baseline_failures"]))
        every_test = every_test and earlier.get("every_test", False)  # a merged table is as complete as its rows
    with ThreadPoolExecutor(args.jobs) as pool:
        for r in pool.map(lambda m: run_one(m, baseline, args.timeout, args.every_test), chosen):
            print(f"{r['verdict']:24s} {r['mutant']} ({r['seconds']} s)", flush=True)
            rows[r["mutant"]] = r
            # after every mutant: an interrupted run keeps its rows
            table = write_table(args.out, rows, baseline, every_test)
    return 0 if all(r["verdict"] == "killed (property)" for r in table) else 1


if __name__ == "__main__":
    sys.exit(main())
