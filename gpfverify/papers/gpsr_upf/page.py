"""Render the committed sins-gps reference page from a run with interpretations.

    python -m gpfverify.papers.gpsr_upf.page RUN_DIR "COMMAND" [CONFIRM_DIR "CONFIRM_COMMAND"]
    python -m gpfverify.papers.gpsr_upf.page --figures   # its figures again, from the committed results

RUN_DIR is the output folder of COMMAND (``gpfverify reproduce sins-gps ... --interpretations ...``).
Its ``results.json`` and those of its interpretations are recomputed from the saved runs with the
current summary (claims with the verdict under each interpretation merged, as the runner does) and
copied with its manifest to ``reports/reference/sins-gps/run/``, with one addition:
``"interpretation_summaries"`` — for each interpretation folder, its parameter changes, health
checks, mean N_eff/N and RMS errors, read from ``RUN_DIR/interpretations/<name>/results.json``
(the per-configuration results are 1 MB each and are not committed). The page is then rendered from
that file by :func:`gpfverify.papers.gpsr_upf.section.render`.

CONFIRM_DIR (optional) is a separate run of one interpretation at more runs (its own main run, made
by CONFIRM_COMMAND); its health and claims are added as ``"confirmation"``.
"""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

from gpfverify.experiments.sensitivity import merge_saved  # noqa: E402
from gpfverify.papers.gpsr_upf import experiment as sins_gps
from gpfverify.papers.gpsr_upf import section as section_module
from gpfverify.papers.gpsr_upf.contract import DEFAULT_RUNS, INTERPRETATIONS, Params
from gpfverify.reference_pages import FIGURES, REFERENCE, redraw_figures, write_page
from gpfverify.report.document import Paragraph  # noqa: E402

HERE = REFERENCE / "sins-gps"


def summaries(run_dir: Path) -> dict:
    out = {}
    for spec in INTERPRETATIONS:
        path = run_dir / "interpretations" / spec.name / "results.json"
        if not path.is_file():
            continue
        r = json.loads(path.read_text(encoding="utf-8"))
        out[spec.name] = {"changes": spec.changes, "runs_ok": r["runs_ok"], "health": r["health"],
                          "mean_ess_fraction": r["mean_ess_fraction"], "rms": r["rms"],
                          "reduction": r["reduction"], "reference_rms": r["reference"]["rms"],
                          "cruise_range": r.get("cruise_range"), "claims": _claims(r)}
    return out


def _claims(results: dict) -> dict:
    return {c["id"]: {k: c[k] for k in ("verdict", "statistic", "runs_to_decide", "evidence")}
            for c in results["claims"]}


def confirmation(run_dir: Path, command: str) -> dict:
    r = json.loads((run_dir / "results.json").read_text(encoding="utf-8"))
    params = Params.from_json(r["params"])
    name = next((spec.name for spec in INTERPRETATIONS if Params().replace(**spec.changes) == params), "")
    return {"interpretation": name, "command": command, "runs_ok": r["runs_ok"], "health": r["health"],
            "mean_ess_fraction": r["mean_ess_fraction"], "rms": r["rms"], "claims": _claims(r)}


def main(run_dir: Path, command: str, confirm: tuple[Path, str] | None = None) -> None:
    # recomputed from the saved runs (main and interpretations) with the current summary
    results = merge_saved(run_dir, sins_gps)
    results["interpretation_summaries"] = summaries(run_dir)
    if confirm is not None:
        results["confirmation"] = confirmation(*confirm)
    target = HERE / "run"
    target.mkdir(parents=True, exist_ok=True)
    (target / "results.json").write_text(json.dumps(results, allow_nan=False), encoding="utf-8")
    shutil.copy(run_dir / "manifest.json", target / "manifest.json")
    section = section_module.render(results, HERE)
    also = "" if confirm is None else f" and `{confirm[1]}`"
    extra = "" if confirm is None else " CONFIRM_DIR \"CONFIRM_COMMAND\""
    provenance = json.loads((run_dir / "manifest.json").read_text(encoding="utf-8"))["provenance"]
    section.add(Paragraph(f"Runs made at commit {provenance['git_commit'][:12]} on {provenance['platform']}, "
                          f"{results['runs_ok']} of {results['runs']} runs per configuration (the full profile "
                          f"runs {DEFAULT_RUNS})."))
    section.add(Paragraph(f"Made by `{command}`{also}, then `python -m gpfverify.papers.gpsr_upf.page RUN_DIR "
                          f"\"COMMAND\"{extra}` (which adds the interpretations' health and errors, and the "
                          "confirmation run's, to the committed results.json)."))
    write_page(section, HERE, [results])


if __name__ == "__main__":
    if sys.argv[1:] == [FIGURES]:
        redraw_figures(HERE, HERE / "run" / "results.json", section_module.render)
        sys.exit(0)
    main(Path(sys.argv[1]), sys.argv[2], (Path(sys.argv[3]), sys.argv[4]) if len(sys.argv) > 4 else None)
