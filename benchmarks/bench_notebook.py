"""What a notebook's view of a fusion run costs, against the whole check page of the same run.

A 25-step run of the reference three-sensor tracker (``examples/three_sensor_system.py:tracker``,
UKF family, CMF, DMF, CC and CI, its truth given): median process CPU seconds (one BLAS thread) and
bytes of ``gpfverify.notebook.fusion_run_html`` (the compact check page a result cell shows) and of
``gpfverify.notebook.write_page`` (the whole page with every figure), and their ratio.

    .venv/bin/python benchmarks/bench_notebook.py [--out benchmarks/results/notebook.md]
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")

import numpy as np  # noqa: E402

from _timing import median_cpu_seconds, publish  # noqa: E402
from gpfverify.model_fusion import run_fusion  # noqa: E402
from gpfverify.notebook import fusion_run_html, write_page  # noqa: E402
from gpfverify.systems import load_system  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
STEPS = 25


def main(out: Path | None) -> None:
    model = load_system(f"{ROOT / 'examples' / 'three_sensor_system.py'}:tracker")
    truth, ys = model.simulate(STEPS, np.random.default_rng(3))
    fused = run_fusion(model, ys, family="ukf", methods=("cmf", "dmf", "cc", "ci"))
    view = fusion_run_html(fused, truth)
    with tempfile.TemporaryDirectory() as folder:
        page = write_page(fused, Path(folder) / "page", truth)
        page_bytes = page.stat().st_size
        page_seconds = median_cpu_seconds(lambda: write_page(fused, Path(folder) / "page", truth), repeats=5)
    view_seconds = median_cpu_seconds(lambda: fusion_run_html(fused, truth), repeats=5)
    rows = [["notebook view (fusion_run_html)", f"{view_seconds:.3f}", f"{len(view.encode()) / 1000:.0f}"],
            ["whole check page (write_page)", f"{page_seconds:.3f}", f"{page_bytes / 1000:.0f}"],
            ["view / page", f"{view_seconds / page_seconds:.2f}", f"{len(view.encode()) / page_bytes:.2f}"]]
    publish(["a 25-step run's", "CPU seconds (median of 5)", "kB"], rows, out)
    load = "load average {:.1f}, {:.1f}, {:.1f} (1, 5, 15 min) at the end".format(*os.getloadavg())
    print(load)
    if out:
        out.write_text(out.read_text(encoding="utf-8") + f"\n{load}; {os.cpu_count()} CPUs.\n", encoding="utf-8")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path)
    main(parser.parse_args().out)
