"""Render the committed tbd reference page from a run made with its interpretations.

    python reports/reference/tbd/make_page.py RUN_DIR "COMMAND"

RUN_DIR is the output folder of COMMAND, a ``gpfverify reproduce tbd ... --interpretations all``
command (stated on the page). The main ``results.json`` and that of every interpretation in
``RUN_DIR/interpretations/NAME/`` are recomputed from their saved runs with the current summary,
the verdicts under each interpretation merged into the main claims (as ``--interpretations``
does), and the page goes to ``reports/reference/tbd/`` with its figures, the merged results and
the manifest to ``.../tbd/run/``. (``make_single.py tbd`` would recompute the main results only
and drop the interpretations.)
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from reference_pages import write_page  # type: ignore[import-not-found]  # noqa: E402

from gpfverify.experiments import tbd  # noqa: E402
from gpfverify.experiments.runner import _atomic_write_json, rewrite_results  # noqa: E402
from gpfverify.experiments.sensitivity import merge  # noqa: E402
from gpfverify.report.document import Paragraph  # noqa: E402
from gpfverify.report.sections.tbd import render  # noqa: E402


def main(run_dir: Path, command: str) -> None:
    results = rewrite_results(run_dir, tbd)
    tried = [(spec, rewrite_results(run_dir / "interpretations" / spec.name, tbd)) for spec in tbd.INTERPRETATIONS
             if (run_dir / "interpretations" / spec.name / "manifest.json").is_file()]
    results = merge(results, tried)
    _atomic_write_json(run_dir / "results.json", results)
    target = HERE / "run"
    target.mkdir(parents=True, exist_ok=True)
    for name in ("results.json", "manifest.json"):
        shutil.copy(run_dir / name, target / name)
    section = render(results, HERE)
    section.add(Paragraph(f"Made by `{command}`, then `python reports/reference/tbd/make_page.py RUN_DIR "
                          "\"COMMAND\"`."))
    write_page(section, HERE)


if __name__ == "__main__":
    main(Path(sys.argv[1]), sys.argv[2])
