"""Render the committed reference pages of the fusion paper's experiments.

    python reports/reference/make_fusion_paper.py RUNS_DIR     # recompute from saved runs, then render
    python reports/reference/make_fusion_paper.py --committed  # render the committed results.json only

RUNS_DIR holds one ``gpfverify reproduce`` output folder per setting (named as in COMMANDS). Each
``results.json`` is recomputed from the saved runs with the current summaries — with the verdicts
under every interpretation found in ``<folder>/interpretations/<name>/`` merged into its claims —
and copied (with its manifest) to ``reports/reference/<experiment>/<setting>/``. With
``--committed`` the pages are rendered from those committed copies alone. The pages go to
``reports/reference/ct2d/README.md``, ``reports/reference/ungm1d/README.md`` and one
self-contained ``reports/reference/fusion-paper.html``. The per-run files are not committed.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from reference_pages import recompute_into, write_page

from gpfverify.contract.claims import AS_RUN, read_claims
from gpfverify.contract.ct2d import Params as CT2DParams
from gpfverify.experiments import ct2d, ungm1d
from gpfverify.report.render import to_html
from gpfverify.report.sections import fusion_ct2d, fusion_ungm1d

HERE = Path(__file__).resolve().parent
#: folder name -> the commands that made it (run from the repository root, OUT = RUNS_DIR): each
#: main run was first made next to its interpretations (INTERPRETED runs each, the same seed), then
#: extended alone with ``--resume`` to RUNS runs; both counts are read from the results.
MADE = ("gpfverify reproduce {experiment} {options}--runs INTERPRETED --seed 1 --interpretations WHICH "
        "--out OUT/{name}, then gpfverify reproduce {experiment} {options}--runs RUNS --seed 1 --resume "
        "--out OUT/{name}")
#: folder name -> the experiment's options besides the run counts and the seed
OPTIONS = {"ct2d-k300-w0.0698": "--kappa 300 --omega 0.0698 ", "ct2d-k300-w0.5": "--kappa 300 --omega 0.5 ",
           "ct2d-k30-w0.0698": "--kappa 30 --omega 0.0698 ", "ct2d-k60-w0.0698": "--kappa 60 --omega 0.0698 ",
           "ungm1d-sweep": ""}
COMMANDS = {name: MADE.format(experiment=name.split("-")[0], options=options, name=name)
            for name, options in OPTIONS.items()}


def target(name: str) -> Path:
    """Where a folder's results.json and manifest.json are committed."""
    if name.startswith("ct2d-"):
        return HERE / "ct2d" / name.removeprefix("ct2d-")
    return HERE / "ungm1d"


def command(name: str, results: dict) -> str:
    """The commands that made ``results``: the interpretations tried and their run count read from
    its claims, the main run's count from its ``runs``."""
    module = ct2d if name.startswith("ct2d") else ungm1d
    tried = [i for c in read_claims(results) for i in c.interpretations if i.name != AS_RUN]
    names = list(dict.fromkeys(i.name for i in tried))
    which = "all" if set(names) == {s.name for s in module.INTERPRETATIONS} else ",".join(names)
    counts = ", ".join(str(n) for n in sorted({i.n for i in tried if i.n})) or str(results["runs"])
    return (COMMANDS[name].replace("INTERPRETED", counts).replace("WHICH", which)
            .replace("RUNS", str(results["runs"])))


def committed(name: str) -> dict | None:
    path = target(name) / "results.json"
    if not path.exists():
        return None
    results = json.loads(path.read_text(encoding="utf-8"))
    return results if "claims" in results else None  # older, untyped results are not rendered


def main(runs_dir: Path | None) -> None:
    found: dict[str, dict] = {}
    for name in COMMANDS:
        module = ct2d if name.startswith("ct2d") else ungm1d
        if runs_dir is not None and (runs_dir / name / "manifest.json").exists():
            found[name] = recompute_into(runs_dir / name, module, target(name))
        elif (results := committed(name)) is not None:
            found[name] = results
    made = "python reports/reference/make_fusion_paper.py OUT (or --committed: from the committed results.json)"
    sections = []
    commands = [command(n, r) for n, r in found.items() if n.startswith("ct2d")]
    ct = {CT2DParams.from_json(r["params"]).label: r for n, r in found.items() if n.startswith("ct2d")}
    if ct:
        section = fusion_ct2d.render(ct, HERE / "ct2d", command=f"{'; '.join(commands)}; then {made}")
        sections.append(section)
    if "ungm1d-sweep" in found:
        r = found["ungm1d-sweep"]
        sections.append(fusion_ungm1d.render(r, HERE / "ungm1d", command=f"{command('ungm1d-sweep', r)}; then {made}"))
    for section in sections:
        write_page(section, HERE / section.slug,
                   [r for n, r in found.items() if n.split("-")[0] == section.slug])
    (HERE / "fusion-paper.html").write_text(to_html(sections, "Fusion paper: reference run"), encoding="utf-8")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(None if sys.argv[1] == "--committed" else Path(sys.argv[1]))
