"""Render the committed tbd reference page.

    python -m gpfverify.papers.tbd.page RUN_DIR "COMMAND"        # recompute from saved runs, then render
    python -m gpfverify.papers.tbd.page --committed "COMMAND"    # judge the committed results again, render
    python -m gpfverify.papers.tbd.page --figures                # its figures again, from the committed results

RUN_DIR is the output folder of COMMAND, a ``gpfverify reproduce tbd ... --interpretations ...``
command (stated on the page). The main ``results.json`` and that of every interpretation in
``RUN_DIR/interpretations/NAME/`` are recomputed from their saved runs with the current summary,
the verdicts under each interpretation merged into the main claims (as ``--interpretations``
does; the birth readings' runs read with every detection definition too), and the page goes to
``reports/reference/tbd/`` with its figures, the merged results and the manifest to
``.../tbd/run/``. With ``--committed`` (the per-run files of the committed run are not kept) the
committed ``results.json`` has its claims judged again by the current code from its stored summary,
what only the runs gave carried over (:func:`~gpfverify.reference_pages.rejudge_committed`). The page
states the runs the readings rest on, and the reading of the rule for a particle that leaves the
image recorded before the rule was made (``before-image-exit-rule/gain.json``).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from gpfverify.contract.claims import AS_RUN, read_claims
from gpfverify.papers.tbd import experiment as tbd
from gpfverify.papers.tbd.contract import BIRTH_INTERPRETATIONS, IMAGE_EXIT_INTERPRETATIONS, Params
from gpfverify.papers.tbd.section import GAIN_CLAIM, grid_only, render
from gpfverify.reference_pages import FIGURES, REFERENCE, recompute_into, redraw_figures, rejudge_committed, write_page
from gpfverify.report.document import Paragraph, Table, fmt

HERE = REFERENCE / "tbd"
#: the equal-N gain as the filter gave it before a particle leaving the image counted as a target that left
BEFORE_EXIT_RULE = HERE / "before-image-exit-rule" / "gain.json"


def main(run_dir: Path | None, command: str) -> None:
    results = (rejudge_committed(HERE / "run" / "results.json", tbd) if run_dir is None
               else recompute_into(run_dir, tbd, HERE / "run"))
    section = render(results, HERE)
    section.add(_runs_to_decide_table(results))
    if (note := _birth_runs_note(results)) is not None:
        section.add(note)
    section.add(_image_exit_paragraph(results))
    made = ("then `python -m gpfverify.papers.tbd.page RUN_DIR \"COMMAND\"`; the committed results judged again by "
            "the current code with `python -m gpfverify.papers.tbd.page --committed \"COMMAND\"`")
    section.add(Paragraph(f"Made by `{command}` (the detection readings read its runs and the birth readings'), "
                          f"{made}."))
    write_page(section, HERE, [results])


#: the runs each birth reading was to have (its gain's spread shrinks as 1/√runs)
BIRTH_RUNS_PLANNED = 2000


def _birth_runs_note(results: dict) -> Paragraph | None:
    """How many runs the birth readings rest on, and how to continue them when they fell short of
    :data:`BIRTH_RUNS_PLANNED`; None when no birth reading was run."""
    gain = next(c for c in read_claims(results) if c.id == GAIN_CLAIM)
    runs = sorted({i.n or results["runs_ok"] for i in gain.interpretations
                   if any(i.name == s.name for s in BIRTH_INTERPRETATIONS)})
    if not runs:
        return None
    names = ",".join(s.name for s in BIRTH_INTERPRETATIONS)
    rest = (f"The birth readings rest on {' and '.join(map(str, runs))} runs each; their filters' health checks are "
            "in each reading's own results.json (made with the runs, not committed): a reading whose filters failed "
            "a health gate shows as not decidable in the grid")
    if max(runs) >= BIRTH_RUNS_PLANNED:
        return Paragraph(rest + ".")
    return Paragraph(
        f"{rest}, short of the {BIRTH_RUNS_PLANNED} planned in the time the runs had. `gpfverify reproduce tbd "
        f"--runs {BIRTH_RUNS_PLANNED} --seed 1 --resume --interpretations {names} --out RUN_DIR` continues them "
        "(the main run first: an interpretation runs at most as many runs as the main run).")


def _image_exit_paragraph(results: dict) -> Paragraph:
    """Which rule for a particle that leaves the image the headline uses and why, and the other
    reading's gain as recorded before the rule (``BEFORE_EXIT_RULE``), with its provenance."""
    gain = next(c for c in read_claims(results) if c.id == GAIN_CLAIM)
    run = [i for i in gain.interpretations if i.name in {s.name for s in IMAGE_EXIT_INTERPRETATIONS}]
    before = json.loads(BEFORE_EXIT_RULE.read_text(encoding="utf-8"))
    said = "; ".join(
        f"{key}: {fmt(g['mean_gain_db'], 3)} dB (bootstrap s.e. {fmt(before['snr_gain_interval'][key]['se'], 2)} dB)"
        for key, g in before["snr_gain"].items())
    spec = IMAGE_EXIT_INTERPRETATIONS[0]
    params = Params.from_json(results["params"]).replace(**spec.changes)
    command = " ".join(["gpfverify reproduce tbd", *params.cli_options(), f"--runs {BIRTH_RUNS_PLANNED}",
                        f"--seed {results['seed']}", f"--out OUT/tbd-{spec.name}"])
    runs_now = ("; with the current code: " + ", ".join(f"{i.name}: {i.verdict} ({fmt(i.statistic, 3)} dB, {i.n} "
                                                        "runs)" for i in run)) if run else (
        f"; it has not been run with the current code, which `{command}` does (the runs of the reading "
        f"'{spec.name}' with the seeds of the page, at the birth readings' count)")
    return Paragraph(
        "A particle whose position leaves the image. As run it is a target that left the observed region, its mass "
        "joining the absent hypothesis of eq. 10 — the headline uses this reading because seed 004 defines Eₖ = 1 as "
        "the target being in the observed region (§1), and because without it a lost track lives on off the image "
        "at a high existence probability. Seed 004 does not say what its filter does; the other reading, kept with "
        "its weight (no pixel contradicts it), is the interpretation 'image-exit-kept'. Recorded before the rule "
        f"was made, at commit {before['provenance']['git_commit'][:12]} on {before['runs_ok']} runs (the filter then "
        f"kept such particles): {said}{runs_now}. The rule moved the equal-N gain from that value to the headline's "
        f"{fmt(gain.statistic, 3)} dB.")


def _runs_to_decide_table(results: dict) -> Table:
    """Per claim, its verdict as run and under each interpretation with runs or readings of its own
    (the birth × detection grid's readings are in the grid), and for an undecided one about how many
    runs would decide it — from the claims' interpretation entries."""
    claims = [c for c in read_claims(results) if not c.timing]
    names = list(dict.fromkeys(i.name for c in claims for i in c.interpretations
                               if i.name != AS_RUN and not grid_only(i.params)))
    counts = {i.name: i.n or results["runs_ok"] for c in claims for i in c.interpretations}

    def cell(verdict: str, to_decide: int | None) -> str:
        if verdict != "undecided":
            return verdict
        return f"undecided: about {to_decide} runs" if to_decide else "undecided"

    rows = []
    for claim in claims:
        by_name = {i.name: i for i in claim.interpretations}
        rows.append([claim.claim, cell(claim.verdict, claim.runs_to_decide),
                     *(cell(by_name[n].verdict, by_name[n].runs_to_decide) if n in by_name else "—" for n in names)])
    return Table(["claim", f"as run ({results['runs_ok']} runs)", *(f"{n} ({counts[n]} runs)" for n in names)], rows,
                 "Runs that would decide each undecided verdict, as run and under each interpretation (were the "
                 "mean and spread seen here the true ones; the paper used 3000 runs per SNR)")


if __name__ == "__main__":
    if sys.argv[1:] == [FIGURES]:
        redraw_figures(HERE, HERE / "run" / "results.json", render)
    elif len(sys.argv) != 3:
        sys.exit(__doc__)
    else:
        main(None if sys.argv[1] == "--committed" else Path(sys.argv[1]), sys.argv[2])
