"""A system file that breaks the standard streams, the exit status or the recursion limit, or never
returns (docs/output-and-errors.md, "Your system file"): gpfverify owns its output streams and its
exit status whatever the file's code does. Every test drives the command line in a process of its
own, as a user runs it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))  # the suite imports in importlib mode: the helper beside it
from system_files import MEASURING_SYSTEM  # noqa: E402

pytestmark = pytest.mark.slow  # each test runs gpfverify in subprocesses


#: seconds after which a command counts as hung (a few seconds idle; minutes on a loaded 2-core machine)
HUNG_SECONDS = 300


def _check(tmp_path, *extra, at_import="", in_measurement="pass", after=0):
    (tmp_path / "system.py").write_text(MEASURING_SYSTEM.format(at_import=at_import, in_measurement=in_measurement,
                                                      after=after))
    return subprocess.run([sys.executable, "-m", "gpfverify", "check", "system.py:system", "--steps", "4",
                           "--methods", "cmf,dmf", "--json", *extra],
                          capture_output=True, text=True, cwd=tmp_path, timeout=HUNG_SECONDS)


def _results(proc) -> dict:
    """stdout is the results object and nothing else."""
    assert proc.returncode == 0, proc.stderr
    results = json.loads(proc.stdout)
    assert results["experiment"] == "check" and results["runs_ok"] >= 1
    return results


#: code that daemon threads run to print into the command's output for as long as it runs
SPAMMING_THREAD = '''
import threading, time
def spam():
    while True:
        print("daemon thread says hi"); sys.stdout.write("and writes"); time.sleep(0.0005)
threading.Thread(target=spam, daemon=True).start()
'''


@pytest.mark.parametrize("at_import, in_measurement", [
    ("sys.stdout.close()", "pass"),
    ("sys.stderr = None", "sys.stderr = None"),
    ("sys.stdout = None", "sys.stdout = open(os.devnull, 'w')"),
    ("sys.__stdout__.close(); sys.__stderr__.close()", "pass"),
    ("pass", "sys.stderr.close(); sys.stdout.close()"),
    (SPAMMING_THREAD, "pass"),
], ids=["closes-stdout", "stderr-None", "replaces-stdout", "closes-the-originals", "closes-both-mid-run",
        "daemon-thread-prints"])
def test_a_system_file_that_breaks_the_streams_changes_nothing_gpfverify_prints(tmp_path, at_import,
                                                                                in_measurement):
    proc = _check(tmp_path, at_import=at_import, in_measurement=in_measurement, after=6)
    _results(proc)
    assert "Traceback" not in proc.stderr


def test_compiled_code_writing_to_descriptor_1_lands_on_stderr_after_the_result(tmp_path):
    """Descriptor 1 is not gpfverify's result stream: what compiled code (here os.write) writes there
    is held and shown on stderr once the command has completed."""
    proc = _check(tmp_path, at_import="os.write(1, b'from C at import\\n')",
                  in_measurement="os.write(1, b'from C in a run\\n')", after=6)
    _results(proc)
    assert "from C at import" in proc.stderr and "from C in a run" in proc.stderr


def test_output_held_from_a_command_that_fails_is_dropped(tmp_path):
    """A failed command prints its one line and nothing of what other code wrote to descriptor 2."""
    proc = _check(tmp_path, at_import="os.write(2, b'chatter of a library\\n')",
                  in_measurement="raise RuntimeError('boom')", after=0)
    assert proc.returncode == 2 and proc.stdout == ""
    assert len(proc.stderr.splitlines()) == 1 and "chatter" not in proc.stderr, proc.stderr


@pytest.mark.parametrize("code", ["3", "0"])
def test_an_atexit_handler_cannot_change_the_exit_status(tmp_path, code):
    """atexit.register(os._exit, N) at import (os._exit is gpfverify's guard then) and a handler
    that calls the real one at exit: the command's status stands, and nothing is printed."""
    at_import = (f"import atexit; atexit.register(os._exit, {code}); "
                 f"atexit.register(lambda: __import__('posix')._exit({code}))")
    proc = _check(tmp_path, at_import=at_import)
    _results(proc)
    assert "Traceback" not in proc.stderr and "Exception ignored" not in proc.stderr, proc.stderr
    failing = _check(tmp_path, at_import=at_import, in_measurement="raise RuntimeError('boom')")
    assert failing.returncode == 2 and len(failing.stderr.splitlines()) == 1, failing.stderr


@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_lowered_recursion_limit_is_named_not_blamed_on_the_input(tmp_path, workers):
    """The measurement function lowers the limit to just above its own depth: gpfverify's code
    that runs on after it returns goes deeper and fails — an error of the system file naming the
    limit, not "input nested too deeply" (nor a failed run)."""
    at_import = ("def lower():\n    depth = 1\n    while True:\n        try:\n"
                 "            return sys.setrecursionlimit(depth)\n        except RecursionError:\n"
                 "            depth += 1")
    proc = _check(tmp_path, "--workers", workers, "--runs", "2", at_import=at_import, in_measurement="lower()",
                  after=6)
    assert proc.returncode == 2 and proc.stdout == "", proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(
        "gpfverify check: error: the system file system.py lowered Python's recursion limit to "), lines
    assert "nested too deeply" not in lines[0]


# ---- --timeout -----------------------------------------------------------------------------------

#: a function that never returns, and swallows what it can on its way
NEVER_RETURNS = ("while True:\n            try:\n                time.sleep(60)\n"
                 "            except Exception:\n                pass")


@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_measurement_function_that_never_returns_is_stopped_by_the_timeout(tmp_path, workers):
    start = time.monotonic()
    proc = _check(tmp_path, "--timeout", "2", "--runs", "2", "--workers", workers, "--out", "out",
                  at_import="import time", in_measurement=NEVER_RETURNS, after=12)
    assert proc.returncode == 2 and proc.stdout == "", proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("gpfverify check: error: sensor 1 measure, h (system.py, line "), \
        lines
    assert "did not return within 2 s (--timeout 2)" in lines[0]
    assert sorted(os.listdir(tmp_path)) == ["system.py"]  # nothing left behind
    assert time.monotonic() - start < HUNG_SECONDS


def test_a_system_file_whose_import_never_ends_is_stopped_by_the_timeout(tmp_path):
    proc = _check(tmp_path, "--timeout", "1.5", "--out", "out", at_import="import time\ntime.sleep(3600)")
    assert proc.returncode == 2 and proc.stdout == "", proc.stderr
    assert proc.stderr.splitlines() == [
        "gpfverify check: error: the system file system.py (loading it and building system) did not return within "
        "1.5 s (--timeout 1.5); the command stopped"], proc.stderr
    assert sorted(os.listdir(tmp_path)) == ["system.py"]


def test_the_timeout_does_not_touch_code_that_returns(tmp_path):
    _results(_check(tmp_path, "--timeout", "60", "--workers", "2", "--runs", "2"))


@pytest.mark.parametrize("value", ["0", "-1", "nan", "soon"])
def test_a_timeout_that_is_not_a_positive_number_is_a_usage_error(tmp_path, value):
    proc = _check(tmp_path, "--timeout", value)
    assert proc.returncode == 2 and len(proc.stderr.splitlines()) == 1 and "--timeout" in proc.stderr


def test_a_property_that_never_returns_is_stopped_by_the_timeout(tmp_path):
    suite = tmp_path / "suite"
    suite.mkdir()
    (suite / "test_forever.py").write_text("import time\ndef test_forever():\n    time.sleep(3600)\n"
                                           "def test_fine():\n    pass\n")
    proc = subprocess.run([sys.executable, "-m", "gpfverify", "props", "--suite", str(suite), "--out", "out",
                           "--timeout", "2"], capture_output=True, text=True, cwd=tmp_path, timeout=HUNG_SECONDS)
    assert proc.returncode == 2 and proc.stdout == "", proc.stderr
    assert proc.stderr.splitlines() == [
        "gpfverify props: error: the property suite/test_forever.py::test_forever did not return within 2 s "
        "(--timeout 2); the command stopped"], proc.stderr
    assert sorted(os.listdir(tmp_path)) == ["suite"]
