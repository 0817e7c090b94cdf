"""Render the committed tbd reference page from a run made with its interpretations.

    python -m gpfverify.papers.tbd.page RUN_DIR "COMMAND"
    python -m gpfverify.papers.tbd.page --figures   # its figures again, from the committed results

RUN_DIR is the output folder of COMMAND, a ``gpfverify reproduce tbd ... --interpretations all``
command (stated on the page). The main ``results.json`` and that of every interpretation in
``RUN_DIR/interpretations/NAME/`` are recomputed from their saved runs with the current summary,
the verdicts under each interpretation merged into the main claims (as ``--interpretations``
does; the birth readings' runs read with every detection definition too), and the page goes to
``reports/reference/tbd/`` with its figures, the merged results and the manifest to
``.../tbd/run/``; it states the runs the birth readings rest on and how to continue them.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from gpfverify.contract.claims import read_claims  # noqa: E402
from gpfverify.papers.tbd import experiment as tbd
from gpfverify.papers.tbd.contract import BIRTH_INTERPRETATIONS
from gpfverify.papers.tbd.section import GAIN_CLAIM, grid_only, render
from gpfverify.reference_pages import FIGURES, REFERENCE, recompute_into, redraw_figures, write_page
from gpfverify.report.document import Paragraph, Table  # noqa: E402

HERE = REFERENCE / "tbd"


def main(run_dir: Path, command: str) -> None:
    results = recompute_into(run_dir, tbd, HERE / "run")
    # every interpretation tried: those with runs of their own and the summary-only ones (the detection
    # definitions), whose results.json recompute_into has just written from the main run's runs
    # (the birth proposals read with other detection definitions are in the page's birth × detection grid)
    tried = [(spec, json.loads((run_dir / "interpretations" / spec.name / "results.json").read_text("utf-8")))
             for spec in tbd.INTERPRETATIONS if (run_dir / "interpretations" / spec.name / "results.json").is_file()
             and not grid_only(spec.changes)]
    section = render(results, HERE)
    section.add(_runs_to_decide_table(results, tried))
    if (note := _birth_runs_note(results)) is not None:
        section.add(note)
        section.add(_birth_health(run_dir))
    section.add(Paragraph(f"Made by `{command}`, then `python -m gpfverify.papers.tbd.page RUN_DIR "
                          "\"COMMAND\"`."))
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
    rest = f"The birth readings rest on {' and '.join(map(str, runs))} runs each"
    if max(runs) >= BIRTH_RUNS_PLANNED:
        return Paragraph(rest + ".")
    return Paragraph(
        f"{rest}, short of the {BIRTH_RUNS_PLANNED} planned in the time the runs had. `gpfverify reproduce tbd "
        f"--runs {BIRTH_RUNS_PLANNED} --seed 1 --resume --interpretations {names} --out RUN_DIR` continues them "
        "(the main run first: an interpretation runs at most as many runs as the main run).")


def _birth_health(run_dir: Path) -> Paragraph:
    """Each birth reading's SNR-gain verdict under every detection definition with the health of the
    filters it compares, from the readings' own results.json (a failed check withholds the verdict:
    the grid's "not decidable")."""
    said = []
    for birth in BIRTH_INTERPRETATIONS:
        names = [birth.name] + [s.name for s in tbd.INTERPRETATIONS if s.name.startswith(f"{birth.name}-")]
        verdicts, health = [], "not run"
        for name in names:
            path = run_dir / "interpretations" / name / "results.json"
            if not path.is_file():
                continue
            gain = next(c for c in read_claims(json.loads(path.read_text("utf-8"))) if c.id == GAIN_CLAIM)
            withheld = next((c for c in gain.caveats if c.startswith("verdict withheld")), None)
            # "verdict withheld (would be 'X'): ..." -> "would be 'X'"
            verdicts.append(f"{name}: {gain.verdict}" + (f" ({withheld.split('(', 1)[1].split(')', 1)[0]})"
                                                         if withheld else ""))
            if name == birth.name:
                failed = [c for c in gain.caveats if " — " in c and not c.startswith("health of the filters")]
                health = "; ".join(failed) if failed else "every check passed"
        said.append(f"{birth.name}, health of PF-TBD and TPFTBD at N = 2000: {health}; the gain claim "
                    + ", ".join(verdicts))
    return Paragraph("The birth readings' filters and verdicts (a failed health check withholds the verdict, which "
                     "the grid shows as not decidable): " + " — ".join(said) + ".")


def _runs_to_decide_table(results: dict, tried: list) -> Table:
    """Per claim, the runs that would decide it as run and under each interpretation (from each
    interpretation's own results.json; blank where the verdict is decided)."""
    def cell(claim) -> str:
        if claim is None:
            return "—"
        if claim.verdict != "undecided":
            return claim.verdict
        return f"undecided: about {claim.runs_to_decide} runs" if claim.runs_to_decide else "undecided"

    rows = []
    for claim in read_claims(results):
        if claim.timing:
            continue
        row = [claim.claim, cell(claim)]
        for _, other in tried:
            row.append(cell(next((c for c in read_claims(other) if c.id == claim.id), None)))
        rows.append(row)
    return Table(["claim", f"as run ({results['runs_ok']} runs)",
                  *(f"{spec.name} ({other['runs_ok']} runs)" for spec, other in tried)], rows,
                 "Runs that would decide each undecided verdict, as run and under each interpretation (were the "
                 "mean and spread seen here the true ones; the paper used 3000 runs per SNR)")


if __name__ == "__main__":
    if sys.argv[1:] == [FIGURES]:
        redraw_figures(HERE, HERE / "run" / "results.json", render)
    else:
        main(Path(sys.argv[1]), sys.argv[2])
