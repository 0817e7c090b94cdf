"""Render the committed reference page of a one-experiment report section from saved runs.

    python reports/reference/make_single.py EXPERIMENT RUN_DIR "COMMAND"

EXPERIMENT is one of PAGES; RUN_DIR the output folder of COMMAND, the exact ``gpfverify reproduce``
command that made it (stated on the page). The page goes to ``reports/reference/<EXPERIMENT>/``
with its figures, and the recomputed results and manifest to ``.../<EXPERIMENT>/run/``.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

from reference_pages import recompute_into, write_page

from gpfverify.experiments import EXPERIMENTS
from gpfverify.report.document import Paragraph

HERE = Path(__file__).resolve().parent
#: experiment -> report section module rendering it (sins-gps has its own script,
#: reports/reference/sins-gps/make_page.py, which keeps the interpretations' verdicts and health)
PAGES = {"gpadf-scalar": "gpfverify.report.sections.gpadf_scalar",
         "tbd": "gpfverify.report.sections.tbd"}


def main(experiment: str, run_dir: Path, command: str) -> None:
    section_module = importlib.import_module(PAGES[experiment])
    page_dir = HERE / experiment
    results = recompute_into(run_dir, importlib.import_module(EXPERIMENTS[experiment]), page_dir / "run")
    section = section_module.render(results, page_dir)
    section.add(Paragraph(f"Made by `{command}`, then `python reports/reference/make_single.py "
                          f"{experiment} RUN_DIR \"COMMAND\"`."))
    write_page(section, page_dir, [results])


if __name__ == "__main__":
    main(sys.argv[1], Path(sys.argv[2]), sys.argv[3])
