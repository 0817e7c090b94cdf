"""A pytest-xdist worker whose last garbage collection is slow ends its session without the stray
``KeyboardInterrupt`` traceback execnet's SIGINT once printed after every test had passed (the
suite's conftest collects before the worker reports finished, see its ``pytest_sessionfinish``).
The slow collection is made on purpose: a reference cycle in the oldest generation whose finaliser
sleeps 7 s, longer than the 5 s execnet waits."""

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("xdist")
pytestmark = pytest.mark.slow  # a pytest session in a subprocess that waits 7 s on purpose

ROOT = Path(__file__).resolve().parents[1]

SLOW_GARBAGE = '''
import gc
import sys
import time


class Slow:
    def __del__(self):
        try:
            time.sleep(7)
        except KeyboardInterrupt:
            print("KeyboardInterrupt in a finaliser", file=sys.__stderr__, flush=True)
            raise


def test_leaves_a_cycle_only_a_full_collection_frees():
    kept = [Slow()]
    kept[0].cycle = kept
    gc.collect()  # reachable still: moved to the oldest generation, which only a full collection walks
    del kept
'''

CONFTEST = f'''
import importlib.util

_spec = importlib.util.spec_from_file_location("gpfverify_suite_conftest", {str(ROOT / "conftest.py")!r})
_suite = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_suite)
pytest_sessionfinish = _suite.pytest_sessionfinish
'''


def test_a_slow_last_collection_in_a_worker_prints_no_keyboardinterrupt(tmp_path):
    (tmp_path / "test_garbage.py").write_text(SLOW_GARBAGE)
    (tmp_path / "conftest.py").write_text(CONFTEST)
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    proc = subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-n", "1", "-q",
                           "test_garbage.py"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "1 passed" in proc.stdout
    assert "KeyboardInterrupt" not in proc.stdout + proc.stderr, proc.stdout + proc.stderr
