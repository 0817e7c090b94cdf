"""Writes the example files the docs use, from the three-sensor tracker of
``three_sensor_system.py``:

* ``tracker-measurements.npz`` — a measurements file for ``gpfverify check --measurements``:
  ``y`` (20, 5) stacked in sensor order and the truth ``x`` (20, 4) (docs/check-format.md);
* ``tracker-run.jsonl`` — an audit run file, one fusion case per step (5 steps), as
  ``gpfverify check --out DIR`` writes it (docs/run-file-format.md);
* ``tracker-case.json`` — its first step as a single fusion case for ``gpfverify audit`` and
  ``gpfverify fuse`` (docs/fusion-case-format.md).

Run from the repository root: ``python examples/make_example_files.py``.
"""

import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from gpfverify.cli import main
from gpfverify.systems import load_system

HERE = Path(__file__).resolve().parent
SYSTEM = f"{HERE / 'three_sensor_system.py'}:tracker"


def write_measurements(path: Path, steps: int = 20, seed: int = 7) -> None:
    truth, ys = load_system(SYSTEM).simulate(steps, np.random.default_rng(seed))
    np.savez(path, y=ys, x=truth)


def write_run_and_case(run_path: Path, case_path: Path, steps: int = 5) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "check"
        if main(["check", SYSTEM, "--steps", str(steps), "--out", str(out)]) != 0:
            sys.exit("gpfverify check failed")
        lines = (out / "run.jsonl").read_text(encoding="utf-8").splitlines()
    run_path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    first = json.loads(lines[0])
    first.pop("k")  # a single case carries no step index
    case_path.write_text(json.dumps(first, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    write_measurements(HERE / "tracker-measurements.npz")
    write_run_and_case(HERE / "tracker-run.jsonl", HERE / "tracker-case.json")
