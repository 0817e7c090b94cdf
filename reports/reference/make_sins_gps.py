"""Render the committed reference page of seed 001's experiment (GPSR-UPF, SINS/GPS) from saved runs.

    python reports/reference/make_sins_gps.py RUN_DIR

RUN_DIR is the output folder of COMMAND. Its ``results.json`` is recomputed from the saved runs with
the current summary, copied (with its manifest) to ``reports/reference/sins-gps/run/``, and the page
is written to ``reports/reference/sins-gps/README.md`` with its figures. The per-run files are not
committed.
"""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

from gpfverify.experiments import sins_gps
from gpfverify.experiments.runner import write_results
from gpfverify.report.document import Paragraph
from gpfverify.report.render import to_markdown
from gpfverify.report.sections import sins_gps as section_module

HERE = Path(__file__).resolve().parent / section_module.SLUG
#: the exact command that made RUN_DIR (run from the repository root)
COMMAND = "gpfverify reproduce sins-gps --runs 20 --seed 1 --workers 2 --out RUN_DIR"


def main(run_dir: Path) -> None:
    manifest = json.loads((run_dir / "manifest.json").read_text(encoding="utf-8"))
    results = write_results(sins_gps, run_dir, manifest)
    target = HERE / "run"
    target.mkdir(parents=True, exist_ok=True)
    shutil.copy(run_dir / "results.json", target / "results.json")
    shutil.copy(run_dir / "manifest.json", target / "manifest.json")
    section = section_module.render(results, HERE)
    section.add(Paragraph(f"Made by `{COMMAND}`, then `python reports/reference/make_sins_gps.py RUN_DIR`."))
    (HERE / "README.md").write_text(to_markdown(section, HERE), encoding="utf-8")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
