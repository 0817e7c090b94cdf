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

import dataclasses
import json
import math
import sys
from pathlib import Path

from reference_pages import recompute_into, write_page

from gpfverify.contract.ct2d import Params as CT2DParams
from gpfverify.contract.serial import to_json
from gpfverify.experiments import ct2d, ungm1d
from gpfverify.experiments.fusion_run import ClaimContext
from gpfverify.report.render import to_html
from gpfverify.report.sections import fusion_ct2d, fusion_ungm1d

HERE = Path(__file__).resolve().parent
#: folder name -> the exact command that made it (run from the repository root, OUT = RUNS_DIR).
#: On a shared 2-core machine under heavy load (≈ 50 s wall per κ = 300 run) these run counts are
#: what fitted; the pages state, per undecided claim, the run count that would decide it.
COMMANDS = {
    "ct2d-k300-w0.5": "gpfverify reproduce ct2d --kappa 300 --omega 0.5 --runs 1000 --seed 1 --out OUT/ct2d-k300-w0.5 "
                      "(stopped for time after RUNS runs, then summarised with --runs RUNS --resume)",
    "ct2d-k30-w0.0698": "gpfverify reproduce ct2d --kappa 30 --omega 0.0698 --runs 20 --seed 1 --interpretations all "
                        "--out OUT/ct2d-k30-w0.0698, then the main run extended with --runs RUNS --resume "
                        "(the interpretations keep 20 runs)",
    "ct2d-k60-w0.0698": "gpfverify reproduce ct2d --kappa 60 --omega 0.0698 --runs 20 --seed 1 --interpretations "
                        "canonical-rank --out OUT/ct2d-k60-w0.0698, then the main run extended with --runs RUNS "
                        "--resume (the interpretation keeps 20 runs)",
    "ungm1d-sweep": "gpfverify reproduce ungm1d --runs 10 --seed 1 --interpretations canonical-rank "
                    "--out OUT/ungm1d-sweep",
}
#: the earlier reference run of κ = 300, Ω = 2π/90 (1000 runs, numpy's rank rule; commit ae10113),
#: committed before the claims became records and not re-run here: its claims are recomputed from the
#: per-run summaries it stores (:func:`earlier_k300`)
EARLIER_K300 = HERE / "ct2d" / "k300-w0.0698" / "results.json"
EARLIER_K300_COMMAND = ("gpfverify reproduce ct2d --kappa 300 --omega 0.0698 --runs 1000 --seed 1 --out OUT "
                        "(an earlier release, commit ae10113; claims recomputed from its stored summaries)")
EARLIER_CAVEAT = ("an earlier 1000-run result whose per-run records were not kept: its claims are recomputed from "
                  "the per-run means it stores; the filters' health checks (divergence, NEES) need the per-run "
                  "records and are not available for it")


def earlier_k300() -> dict | None:
    """The earlier κ = 300, Ω = 2π/90 result with its claims recomputed by today's claim functions
    from the summaries it stores (its parameters were the defaults of today's Params at that κ, Ω)."""
    if not EARLIER_K300.exists():
        return None
    old = json.loads(EARLIER_K300.read_text(encoding="utf-8"))
    if "claims" in old:  # already in today's format
        return old
    params = CT2DParams(kappa=old["params"]["kappa"], omega=2 * math.pi / 90)
    body = {**old, "params": params.to_json(), "health": [],
            "start_perturbation": {"mean": params.start_mean, "std": params.perturbation_std,
                                   "initial_cov_scale": params.start_cov_scale}}
    ctx = ClaimContext(ct2d.NAME, params.label, "", old["runs_ok"], ct2d.DEFAULT_RUNS)
    claims = [dataclasses.replace(c, caveats=(*c.caveats, EARLIER_CAVEAT))
              for c in ct2d.claims(params, body, ctx)]
    return to_json({**body, "claims": claims, "timing_claims": ct2d.time_claims(ctx, body)})


def target(name: str) -> Path:
    """Where a folder's results.json and manifest.json are committed."""
    if name.startswith("ct2d-"):
        return HERE / "ct2d" / name.removeprefix("ct2d-")
    return HERE / "ungm1d"


def command(name: str, results: dict) -> str:
    return COMMANDS[name].replace("RUNS", str(results["runs"]))


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
    earlier = earlier_k300()
    if earlier is not None:
        found = {"ct2d-k300-w0.0698": earlier, **found}
        commands.insert(0, EARLIER_K300_COMMAND)
    ct = {CT2DParams.from_json(r["params"]).label: r for n, r in found.items() if n.startswith("ct2d")}
    if ct:
        section = fusion_ct2d.render(ct, HERE / "ct2d", command=f"{'; '.join(commands)}; then {made}")
        sections.append(section)
    if "ungm1d-sweep" in found:
        r = found["ungm1d-sweep"]
        sections.append(fusion_ungm1d.render(r, HERE / "ungm1d", command=f"{command('ungm1d-sweep', r)}; then {made}"))
    for section in sections:
        write_page(section, HERE / section.slug)
    (HERE / "fusion-paper.html").write_text(to_html(sections, "Fusion paper: reference run"), encoding="utf-8")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(None if sys.argv[1] == "--committed" else Path(sys.argv[1]))
