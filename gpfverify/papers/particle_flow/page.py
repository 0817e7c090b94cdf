"""Render the committed reference page of seed 003's experiments (particle flows) from saved runs.

    python -m gpfverify.papers.particle_flow.page RUNS_DIR

RUNS_DIR holds the ``gpfverify reproduce`` output folders named as in COMMANDS (each with its
``interpretations/<name>/`` runs). Each ``results.json`` — the main one and every
interpretation's — is recomputed from the saved runs with the current summaries, the claims'
verdicts under each interpretation are merged into the main one, which is copied (with its
manifest) to ``reports/reference/particle-flow/<experiment>/``, and the page is written to
``reports/reference/particle-flow/README.md`` with its figures. The Table-1 grid on the second
model (the interpretation vdm-gaussian) is rendered next to the main one, and its results.json
copied with its manifest to ``.../pff1d/vdm-gaussian/``. An experiment whose folder is not in RUNS_DIR
keeps its committed results, judged again by the current code from their stored summaries
(:func:`~gpfverify.reference_pages.rejudge_committed`; the page states the commit each was made at).
An interpretation run on its own (``gpfverify reproduce NAME --interpretation READING --out
RUNS_DIR/NAME-READING``) is copied likewise to ``.../<experiment>/<READING>/`` (the second model's
too, replacing the one run next to the main run when it has more runs), and the claims take their
verdict under that interpretation from it (:func:`~gpfverify.reference_pages.with_reading_runs`).
The per-run files are not committed.
"""

from __future__ import annotations

import functools
import json
import shutil
import sys
from pathlib import Path

from gpfverify.contract.experiment import RunEntry, SectionRuns
from gpfverify.experiments.batching import batch_option
from gpfverify.papers.particle_flow import bearing_experiment as bearing
from gpfverify.papers.particle_flow import pff1d_experiment as pff1d
from gpfverify.papers.particle_flow import section as particle_flow
from gpfverify.reference_pages import (REFERENCE, reading_commands, readings_into, recompute_into, rejudge_committed,
                                      with_reading_runs, write_page)
from gpfverify.report.document import Paragraph
from gpfverify.report.inputs import SectionInput

HERE = REFERENCE / particle_flow.SLUG
#: folder name -> the exact command that made it (run from the repository root, OUT = RUNS_DIR)
#: (RUNS: the record's runs; BATCH: its --batch, :func:`~gpfverify.experiments.batching.batch_option`)
COMMANDS = {
    "pff1d": "gpfverify reproduce pff1d --runs RUNS --seed 1 BATCH--workers 2 --interpretations vdm-gaussian "
             "--out OUT/pff1d, then gpfverify reproduce pff1d --runs RUNS --seed 1 BATCH--workers 2 --resume "
             "--interpretations measurement-linear,noise-as-std --interpretation-runs 10 --out OUT/pff1d",
    "bearing": "gpfverify reproduce bearing --runs RUNS --seed 1 BATCH--workers 1 --interpretations all "
               "--out OUT/bearing",
}
MODULES = {"pff1d": pff1d, "bearing": bearing}
#: the interpretation that runs the Table-1 grid on the other 1-D model
SECOND_MODEL = "vdm-gaussian"
#: the outside run the second model's Fig. 1(b) cell is set against (the same model, Q = 1, R = 0.1, Δλ = 0.001)
OUTSIDE_RUN = ("an independent implementation of the same model at Q = 1, R = 0.1, Δλ = 0.001 gave IE-PFF − PF = "
               "−0.020 ± 0.006 in per-run RMSE over 30 runs (24 of 30 won by IE-PFF) and −0.016 ± 0.004 on 60 more")


def main(runs_dir: Path) -> None:
    results = {name: recompute_into(runs_dir / name, MODULES[name], HERE / name)
               if (runs_dir / name / "manifest.json").is_file()
               else rejudge_committed(HERE / name / "results.json", MODULES[name]) for name in COMMANDS}
    for name in COMMANDS:  # the interpretations run on their own (OUT/<name>-<interpretation>), committed beside
        readings_into(runs_dir, name, HERE / name, MODULES[name])
        results[name] = with_reading_runs(results[name], HERE / name, MODULES[name])
    entries = tuple(RunEntry(name, "", name, f"{name}/results.json") for name in COMMANDS)
    data = SectionInput(particle_flow.SLUG, HERE, SectionRuns(particle_flow.SLUG, "reference", 1, entries),
                        tuple(results[name] for name in COMMANDS))
    section = particle_flow.render_section(data)
    second = runs_dir / "pff1d" / "interpretations" / SECOND_MODEL / "results.json"
    if second.is_file() and not _committed_has_more(HERE / "pff1d" / SECOND_MODEL, second.parent):
        target = HERE / "pff1d" / SECOND_MODEL
        target.mkdir(parents=True, exist_ok=True)
        for name in ("results.json", "manifest.json"):
            shutil.copy(second.parent / name, target / name)
    elif (HERE / "pff1d" / SECOND_MODEL / "results.json").is_file():
        rejudge_committed(HERE / "pff1d" / SECOND_MODEL / "results.json", pff1d)
    if (HERE / "pff1d" / SECOND_MODEL / "results.json").is_file():
        section.blocks[-1:-1] = _second_model_blocks(
            json.loads((HERE / "pff1d" / SECOND_MODEL / "results.json").read_text(encoding="utf-8")))
    alone = [reading_commands(HERE / name, MODULES[name], functools.partial(_alone, name)) for name in COMMANDS]
    made = [made_by(name, results[name]) for name in COMMANDS]
    command = "; ".join([*made, *filter(None, alone)]) + \
        "; then python -m gpfverify.papers.particle_flow.page OUT"
    second_runs = _runs_of(HERE / "pff1d" / SECOND_MODEL)
    from gpfverify.contract.claims import read_claims

    undecided = [f"{c.id}: about {c.runs_to_decide}" for r in results.values() for c in read_claims(r)
                 if c.verdict == "undecided" and c.runs_to_decide]
    section.blocks.insert(0, Paragraph(f"Made by: {command}"))
    runs = {name: results[name]["runs"] for name in COMMANDS}
    section.blocks.insert(1, Paragraph(
        f"Scale: pff1d ran {runs['pff1d']} runs (the paper: {pff1d.PAPER_RUNS}) on the paper's whole Table-1 grid "
        "(Q ∈ {0.1, 1, 10}, R ∈ {0.1, 1}, Δλ ∈ {0.1, 0.01, 0.001}, uniform and exponential λ-steps), the Fig. 1(b) "
        f"cell Q = 1, R = 0.1 included, and the gamma case at every R; the same grid on the second model "
        f"({SECOND_MODEL}) at {second_runs} runs with uniform λ-steps; bearing {runs['bearing']} runs (the "
        f"paper: {bearing.PAPER_RUNS}); the interpretations at " + _interpretation_runs(results) + ". Runs that "
        "would decide the "
        "undecided verdicts as run, were the observed mean and spread the true ones: "
        + ("; ".join(undecided) or "none") + "."))
    write_page(section, HERE, list(results.values()))


def made_by(name: str, results: dict) -> str:
    """The command of :data:`COMMANDS` that made ``results``, with its runs and --batch."""
    return COMMANDS[name].replace("RUNS", str(results["runs"])).replace("BATCH", batch_option(results))


def _alone(name: str, reading: str, runs: int) -> str:
    """The command that runs the interpretation ``reading`` of ``name`` on its own."""
    return f"gpfverify reproduce {name} --interpretation {reading} --runs {runs} --seed 1 --out OUT/{name}-{reading}"


def _runs_of(folder: Path) -> int | None:
    """The runs of the run committed in ``folder`` (its manifest), None when there is none."""
    path = folder / "manifest.json"
    return json.loads(path.read_text(encoding="utf-8"))["runs"] if path.is_file() else None


def _committed_has_more(committed: Path, run_dir: Path) -> bool:
    """Has the run committed in ``committed`` more runs than the one in ``run_dir``?"""
    mine, theirs = _runs_of(committed), _runs_of(run_dir)
    return mine is not None and theirs is not None and mine > theirs


def _interpretation_runs(results: dict) -> str:
    """Each experiment's interpretations with the runs each rests on (from the merged claims)."""
    from gpfverify.contract.claims import AS_RUN, read_claims

    said = []
    for name, r in results.items():
        runs = {i.name: i.n or r["runs_ok"] for c in read_claims(r) for i in c.interpretations if i.name != AS_RUN}
        said.append(f"{name}: " + (", ".join(f"{k} {n} runs" for k, n in runs.items()) or "none"))
    return "; ".join(said)


def _second_model_blocks(results: dict) -> list:
    """The Table-1 grid as the interpretation vdm-gaussian ran it (same seeds), its health, and its
    Fig. 1(b) comparison at the stable Δλ next to the outside run's."""
    from gpfverify.contract.claims import read_claims
    from gpfverify.papers.particle_flow.pff1d_contract import STABLE_DLAMBDA

    cell = next((c for c in read_claims(results)
                 if c.id == f"pff1d/ie-pff-beats-pf-and-edh-fig1b/dlambda={STABLE_DLAMBDA[0]:g}"), None)
    check = "" if cell is None else (f" This run at that cell, against PF and EDH: {cell.evidence} — {cell.verdict} "
                                     "for the claim, which needs IE-PFF ahead of both.")
    return [Paragraph(f"The Table-1 grid on the second model ({SECOND_MODEL}: the van der Merwe et al. (2000) "
                      "benchmark of the gamma case with Gaussian process noise N(0, Q), the paper's uniform λ-steps, "
                      f"the same seeds; its verdicts are in the sensitivity table). For comparison, {OUTSIDE_RUN}."
                      f"{check}"),
            *particle_flow.table1_blocks(results, HERE),
            *particle_flow.health_blocks(f"pff1d under {SECOND_MODEL}", results)]


if __name__ == "__main__":
    main(Path(sys.argv[1]))
