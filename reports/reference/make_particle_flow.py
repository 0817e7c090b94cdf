"""Render the committed reference page of seed 003's experiments (particle flows) from saved runs.

    python reports/reference/make_particle_flow.py RUNS_DIR

RUNS_DIR holds the ``gpfverify reproduce`` output folders named as in COMMANDS. Each
``results.json`` is recomputed from the saved runs with the current summaries, copied (with its
manifest) to ``reports/reference/particle-flow/<experiment>/``, and the page is written to
``reports/reference/particle-flow/README.md`` with its figures. The per-run files are not committed.
"""

from __future__ import annotations

import sys
from pathlib import Path

from reference_pages import recompute_into, write_page

from gpfverify.experiments import bearing, pff1d
from gpfverify.report.sections import particle_flow

HERE = Path(__file__).resolve().parent / particle_flow.SLUG
#: folder name -> the exact command that made it (run from the repository root, OUT = RUNS_DIR)
COMMANDS = {
    "pff1d": "gpfverify reproduce pff1d --runs 30 --seed 1 --spacings uniform --workers 2 --out OUT/pff1d",
    "bearing": "gpfverify reproduce bearing --runs 200 --seed 1 --workers 2 --out OUT/bearing",
}
MODULES = {"pff1d": pff1d, "bearing": bearing}


def main(runs_dir: Path) -> None:
    results = {name: recompute_into(runs_dir / name, MODULES[name], HERE / name) for name in COMMANDS}
    command = "; ".join(COMMANDS.values()) + "; then python reports/reference/make_particle_flow.py OUT"
    section = particle_flow.render(results, HERE, command=command)
    write_page(section, HERE)


if __name__ == "__main__":
    main(Path(sys.argv[1]))
