"""Shared timing helper for the benchmark scripts."""

from __future__ import annotations

import time

import numpy as np


def median_seconds(fn, repeats: int = 30, warmup: int = 3, clock=time.perf_counter) -> float:
    """Median duration of one call by ``clock`` (wall time by default)."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        start = clock()
        fn()
        times.append(clock() - start)
    return float(np.median(times))


def median_cpu_seconds(fn, repeats: int = 30, warmup: int = 1) -> float:
    """Median process CPU time of one call: unlike wall time, not inflated by other processes."""
    return median_seconds(fn, repeats, warmup, clock=time.process_time)


def markdown_table(headers: list[str], rows: list[list]) -> str:
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def publish(headers: list[str], rows: list[list], out=None) -> str:
    """Print the machine line and the Markdown table; also write them to ``out`` when given."""
    import platform

    header = (f"Machine: {platform.processor() or platform.machine()}, {platform.python_version()}, "
              f"numpy {np.__version__}")
    text = header + "\n\n" + markdown_table(headers, rows)
    print(text)
    if out:
        out.write_text(text + "\n", encoding="utf-8")
    return text
