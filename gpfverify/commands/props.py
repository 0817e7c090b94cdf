"""``gpfverify props``: run the property suite and write ``DIR/summary.json``.

The properties live in the repository's ``property_tests/`` folder (next to ``tests/`` and
``proofs/``, consuming the package like them), so the command needs the source tree: it finds the
folder next to the installed package (an editable install, which ``make test``/``make report``
make) or takes ``--suite DIR``. The strategies they use ship in the package
(:mod:`gpfverify.strategies`) for users' own properties.

pytest runs in-process with the chosen hypothesis profile (``ci``: derandomised, the one
``make test`` uses; ``dev``; ``thorough``: many examples, minutes). Fusion properties save each
shrunk counterexample as a case file in ``DIR/counterexamples/`` (``gpfverify audit`` reads them).
``summary.json``:

    {"profile", "suite", "passed": bool, "seconds",
     "properties": [{"name", "outcome", "examples", "seconds", "counterexample_files",
                     "failure"}],
     "totals": {"properties", "passed", "failed", "examples"}}

``examples`` is the number of examples hypothesis ran for the property (all phases; null when it
failed on an explicit ``@example`` before generating any, or is not a hypothesis test), ``failure``
the first lines of the failure report with the shrunk example. Exit status 0 when every property
holds, 1 when one fails, 2 on a usage error.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import time
from pathlib import Path

from gpfverify.cli import positive_seconds
from gpfverify.errors import InputError
from gpfverify.outputs import add_wait_argument, final_path, out_path, output_folder
from gpfverify.streams import diagnostics

PROFILES = ("ci", "dev", "thorough")
FAILURE_LINES = 40
#: how :func:`gpfverify.strategies.counterexamples.saving_case_on_failure` notes a saved file
NOTE_PREFIX = "counterexample case file:"


def default_suite() -> Path:
    import gpfverify

    return Path(gpfverify.__file__).resolve().parent.parent / "property_tests"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--profile", choices=PROFILES, default="ci",
                        help="hypothesis profile: ci (derandomised, as in make test), dev, "
                             "thorough (many examples, minutes); default ci")
    parser.add_argument("--out", type=out_path, required=True, help="output folder for summary.json")
    add_wait_argument(parser)
    parser.add_argument("--suite", type=Path, default=None,
                        help="folder of property modules (default: property_tests/ of the source "
                             "tree the package is installed from)")
    parser.add_argument("-k", dest="keyword", default=None, metavar="EXPR",
                        help="only properties whose name matches this pytest -k expression")
    parser.add_argument("--timeout", type=positive_seconds, default=None, metavar="SECONDS",
                        help="stop the command (exit status 2, one line naming the property) when one property "
                             "has not finished after SECONDS (default: no limit)")


def make_collector(pytest):
    """A pytest plugin recording each property's outcome, example count, time and failure text
    (``pytest`` is passed in: it is imported only when props runs)."""

    class Collector:
        def __init__(self) -> None:
            self.records: dict[str, dict] = {}
            self.collection_errors: list[str] = []

        def pytest_collectreport(self, report):
            """A module of the suite that cannot be collected (an import error): its first error line."""
            if report.failed:
                lines = report.longreprtext.splitlines()
                cause = next((line[1:].strip() for line in reversed(lines) if line.startswith("E ")),
                             lines[-1].strip() if lines else "")
                self.collection_errors.append(f"{report.nodeid or 'the suite'}: {cause}")

        @pytest.hookimpl(hookwrapper=True)
        def pytest_pyfunc_call(self, pyfuncitem):
            """Each property within ``--timeout`` (:func:`gpfverify.usercode.time_limited`); one that
            runs out of time stops the session."""
            from gpfverify.usercode import time_limit, time_limited

            test = pyfuncitem.obj
            if time_limit() is None:
                yield
                return

            def limited(*args, **kwargs):
                try:
                    with time_limited(f"the property {pyfuncitem.nodeid}"):
                        return test(*args, **kwargs)
                except InputError:
                    pyfuncitem.session.shouldstop = "a property ran out of time"
                    raise

            pyfuncitem.obj = limited
            try:
                yield
            finally:
                pyfuncitem.obj = test

        def _record(self, nodeid: str) -> dict:
            return self.records.setdefault(nodeid, {"name": nodeid, "outcome": "passed",
                                                    "examples": None, "seconds": 0.0,
                                                    "counterexample_files": [], "failure": None})

        @pytest.hookimpl(hookwrapper=True, trylast=True)
        def pytest_runtest_call(self, item):
            """Count the examples hypothesis runs (its own statistics callback still gets them)."""
            from hypothesis.statistics import collector

            record = self._record(item.nodeid)
            outer = collector.value

            def note(stats):
                phases = [v for k, v in stats.items() if k.endswith("-phase") and isinstance(v, dict)]
                record["examples"] = sum(len(p.get("test-cases", ())) for p in phases)
                if outer is not None:
                    outer(stats)

            with collector.with_value(note):
                yield

        def pytest_runtest_logreport(self, report):
            record = self._record(report.nodeid)
            record["seconds"] += report.duration
            if report.skipped and report.when in ("setup", "call"):
                record["outcome"] = "xfailed" if hasattr(report, "wasxfail") else "skipped"
            elif report.failed:
                record["outcome"] = "failed"
                text = report.longreprtext
                lines = text.splitlines()
                first_error = next((i for i, line in enumerate(lines) if line.startswith("E ")), 0)
                record["failure"] = "\n".join(lines[first_error:][:FAILURE_LINES])
                record["counterexample_files"] = sorted({
                    line.split(NOTE_PREFIX, 1)[1].strip() for line in lines if NOTE_PREFIX in line})
            elif report.passed and hasattr(report, "wasxfail"):
                record["outcome"] = "failed"
                record["failure"] = f"unexpectedly passed (strict xfail: {report.wasxfail})"

    return Collector()


def _run_suite(pytest, suite: Path, stage: Path, args: argparse.Namespace) -> dict:
    """Run the property suite with its counterexamples written under ``stage``: the summary.
    pytest's own output goes to stderr when the suite ran, nowhere when pytest refused the
    arguments (the one error line says why); hypothesis keeps its files in a temporary folder,
    not in the current one."""
    import io
    import tempfile

    from hypothesis import configuration

    from gpfverify.usercode import Interrupted, UserTimeout, interrupt_received, timed_out

    counterexamples = stage / "counterexamples"
    collector = make_collector(pytest)
    options = [str(suite), "-q", "-p", "no:cacheprovider", f"--hypothesis-profile={args.profile}",
               f"--rootdir={suite.parent}", "-W", "ignore::UserWarning"]
    if args.keyword:
        options += ["-k", args.keyword]
    home = getattr(configuration, "__hypothesis_home_directory")
    captured = io.StringIO()
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="gpfverify-hypothesis-") as scratch, \
            contextlib.redirect_stdout(captured), contextlib.redirect_stderr(captured):
        os.environ["GPFVERIFY_COUNTEREXAMPLES"] = str(counterexamples)
        configuration.set_hypothesis_home_dir(scratch)
        try:
            code = pytest.main(options, plugins=[collector])
        finally:
            configuration.set_hypothesis_home_dir(home)
            os.environ.pop("GPFVERIFY_COUNTEREXAMPLES", None)
    seconds = time.perf_counter() - start
    late = timed_out()
    if late is not None:
        raise UserTimeout(late)
    if interrupt_received():  # Ctrl-C or SIGTERM, which pytest caught: the command is interrupted
        raise Interrupted
    if code == pytest.ExitCode.INTERRUPTED and not collector.collection_errors:
        raise InputError("a property raised KeyboardInterrupt itself (no Ctrl-C was pressed): the property suite "
                         "stopped")
    if code not in (pytest.ExitCode.OK, pytest.ExitCode.TESTS_FAILED):
        said = collector.collection_errors or [line.strip() for line in captured.getvalue().splitlines()
                                               if line.startswith(("ERROR:", "E ")) or "error:" in line.lower()]
        raise InputError(f"the property suite could not run (pytest exit status {int(code)})"
                         + (f": {said[0]}" if said else ""))
    diagnostics().write(captured.getvalue())
    files = sorted(counterexamples.glob("*.json")) if counterexamples.is_dir() else []
    properties = sorted(collector.records.values(), key=lambda r: r["name"])
    from gpfverify.provenance import current

    return {
        "provenance": current(),
        "profile": args.profile, "suite": str(suite), "passed": code == pytest.ExitCode.OK,
        "seconds": round(seconds, 3), "properties": properties,
        "counterexample_files": [str(f) for f in files],
        "totals": {"properties": len(properties),
                   "passed": sum(r["outcome"] == "passed" for r in properties),
                   "failed": sum(r["outcome"] == "failed" for r in properties),
                   "examples": sum(r["examples"] or 0 for r in properties)},
    }


def run(args: argparse.Namespace) -> int:
    try:
        import hypothesis  # noqa: F401
        import pytest
    except ImportError as exc:
        raise InputError(f"props needs pytest and hypothesis, dependencies of gpfverify that are missing "
                         f"here (reinstall gpfverify): {exc}") from None
    from gpfverify.strategies.profiles import register_profiles

    register_profiles()  # also for a --suite outside the repository (no root conftest.py)
    suite = (args.suite or default_suite()).resolve()
    if not suite.is_dir() or not any(suite.glob("test_*.py")):
        raise InputError(f"no property suite at {suite}: gpfverify props needs the source tree "
                         "(property_tests/) or --suite DIR")
    with output_folder(args.out, keep=False, wait=args.wait) as stage:
        summary = _run_suite(pytest, suite, stage, args)
        summary["counterexample_files"] = [str(final_path(Path(f), stage, args.out))
                                           for f in summary["counterexample_files"]]
        for record in summary["properties"]:
            record["counterexample_files"] = [str(final_path(Path(f), stage, args.out)) if f.startswith(str(stage))
                                              else f for f in record["counterexample_files"]]
        (stage / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    out, seconds = args.out, summary["seconds"]
    totals = summary["totals"]
    print(f"props ({args.profile}): {totals['passed']} of {totals['properties']} properties hold, "
          f"{totals['examples']} examples, {seconds:.1f} s -> {out / 'summary.json'}",
          file=sys.stdout if summary["passed"] else diagnostics())
    return 0 if summary["passed"] else 1
