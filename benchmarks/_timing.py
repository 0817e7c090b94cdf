"""Shared timing helper for the benchmark scripts."""

from __future__ import annotations

import time

import numpy as np


def median_seconds(fn, repeats: int = 30, warmup: int = 3) -> float:
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


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
