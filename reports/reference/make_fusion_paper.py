"""Render the committed reference pages of the fusion paper's experiments from saved runs.

    python reports/reference/make_fusion_paper.py RUNS_DIR

RUNS_DIR holds one ``gpfverify reproduce`` output folder per setting (named as in COMMANDS). Each
``results.json`` is recomputed from the saved runs with the current summaries, copied (with its
manifest) to ``reports/reference/<experiment>/...``, and the pages are written to
``reports/reference/ct2d/README.md``, ``reports/reference/ungm1d/README.md`` and one
self-contained ``reports/reference/fusion-paper.html``. The per-run files are not committed.
"""

from __future__ import annotations

import sys
from pathlib import Path

from reference_pages import recompute_into, write_page

from gpfverify.experiments import ct2d, ungm1d
from gpfverify.report.render import to_html
from gpfverify.report.sections import fusion_ct2d, fusion_ungm1d

HERE = Path(__file__).resolve().parent
#: folder name -> the exact command that made it (run from the repository root, OUT = RUNS_DIR);
#: the 1000-run folders were made as 200 runs and extended with ``--runs 1000 --resume``, which gives
#: the same runs (seeds are SeedSequence(seed).spawn(runs), indexed by run)
COMMANDS = {
    "ct2d-k300-w0.0698": "gpfverify reproduce ct2d --kappa 300 --omega 0.0698 --runs 1000 --seed 1 --workers 2 --out OUT/ct2d-k300-w0.0698",
    "ct2d-k30-w0.0698": "gpfverify reproduce ct2d --kappa 30 --omega 0.0698 --runs 1000 --seed 1 --workers 2 --out OUT/ct2d-k30-w0.0698",
    "ct2d-k60-w0.0698": "gpfverify reproduce ct2d --kappa 60 --omega 0.0698 --runs 1000 --seed 1 --workers 2 --out OUT/ct2d-k60-w0.0698",
    "ct2d-k300-w0.5": "gpfverify reproduce ct2d --kappa 300 --omega 0.5 --runs 200 --seed 1 --workers 2 --out OUT/ct2d-k300-w0.5",
    "ungm1d-sweep": "gpfverify reproduce ungm1d --runs 200 --seed 1 --workers 2 --out OUT/ungm1d-sweep",
    "ungm1d": "gpfverify reproduce ungm1d --sweep 2 --runs 200 --seed 1 --workers 2 --out OUT/ungm1d",
}
#: the ungm1d folder rendered: the first of these present in RUNS_DIR (the full σ² sweep, else σ² = 1, 2)
UNGM1D_FOLDERS = ("ungm1d-sweep", "ungm1d")


def main(runs_dir: Path) -> None:
    sections = []
    ct = {}
    for name, command in COMMANDS.items():
        if name.startswith("ct2d") and (runs_dir / name / "manifest.json").exists():
            results = recompute_into(runs_dir / name, ct2d, HERE / "ct2d" / name.removeprefix("ct2d-"))
            ct[fusion_ct2d.label(results["params"])] = results
    made_by = "; ".join(c for n, c in COMMANDS.items() if n.startswith("ct2d"))
    sections.append(fusion_ct2d.render(ct, HERE / "ct2d", command=made_by + "; then "
                                       "python reports/reference/make_fusion_paper.py OUT"))
    present = [name for name in UNGM1D_FOLDERS if (runs_dir / name / "manifest.json").exists()]
    if present:
        results = recompute_into(runs_dir / present[0], ungm1d, HERE / "ungm1d")
        sections.append(fusion_ungm1d.render(results, HERE / "ungm1d", command=COMMANDS[present[0]] + "; then "
                                             "python reports/reference/make_fusion_paper.py OUT"))
    for section in sections:
        write_page(section, HERE / section.slug)
    (HERE / "fusion-paper.html").write_text(to_html(sections, "Fusion paper: reference run"), encoding="utf-8")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
