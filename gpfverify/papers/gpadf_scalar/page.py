"""Render the committed gpadf-scalar reference page from saved runs.

    python -m gpfverify.papers.gpadf_scalar.page RUN_DIR "COMMAND"
    python -m gpfverify.papers.gpadf_scalar.page --figures   # its figures again, from the committed results

RUN_DIR is the output folder of COMMAND, the exact ``gpfverify reproduce gpadf-scalar`` command that
made it (stated on the page). The page goes to ``reports/reference/gpadf-scalar/`` with its figures,
and the recomputed results and manifest to ``.../gpadf-scalar/run/``.
"""

from __future__ import annotations

import sys
from pathlib import Path

from gpfverify.papers.gpadf_scalar import experiment, section
from gpfverify.reference_pages import FIGURES, REFERENCE, recompute_into, redraw_figures, write_page
from gpfverify.report.document import Paragraph


def main(run_dir: Path, command: str) -> None:
    page_dir = REFERENCE / experiment.NAME
    results = recompute_into(run_dir, experiment, page_dir / "run")
    page = section.render(results, page_dir)
    page.add(Paragraph(f"Made by `{command}`, then `python -m gpfverify.papers.gpadf_scalar.page "
                       "RUN_DIR \"COMMAND\"`."))
    write_page(page, page_dir, [results])


if __name__ == "__main__":
    if sys.argv[1:] == [FIGURES]:
        page_dir = REFERENCE / experiment.NAME
        redraw_figures(page_dir, page_dir / "run" / "results.json", section.render)
    else:
        main(Path(sys.argv[1]), sys.argv[2])
