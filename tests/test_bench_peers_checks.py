"""The peer benchmark's own checks, on the rows that need no peer library: ``bench_peers.py --quick
--only moments own`` asserts that gpfverify's results agree with their references before it times
them (the gp0 port, the fused kernel against the numpy path, batched against single calls), and
exits non-zero when one disagrees — for instance when a fixed tolerance is exceeded by another
processor's rounding. Times are printed, never asserted."""

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # runs the benchmark script

ROOT = Path(__file__).resolve().parents[1]


def test_the_rows_without_peers_agree_before_they_are_timed(tmp_path):
    table = tmp_path / "peers.md"
    result = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_peers.py"), "--quick", "--only",
                             "moments", "own", "--out", str(table)],
                            capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    text = table.read_text(encoding="utf-8")
    for row in ("vectorised port of gp-adf's gp0", "its own numpy reference path",
                "batched `predict_uncertain`", "numpy exp over E(E+1)/2·n²", "RCC-CI per solve"):
        assert row in text, row
