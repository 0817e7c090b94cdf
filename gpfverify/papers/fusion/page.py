"""Render the committed reference pages of the fusion paper's experiments.

    python -m gpfverify.papers.fusion.page RUNS_DIR     # recompute from saved runs, then render
    python -m gpfverify.papers.fusion.page --committed  # judge the committed results.json again, render

RUNS_DIR holds one ``gpfverify reproduce`` output folder per setting (named as in COMMANDS). Each
``results.json`` is recomputed from the saved runs with the current summaries — with the verdicts
under every interpretation found in ``<folder>/interpretations/<name>/`` merged into its claims —
and copied (with its manifest) to ``reports/reference/<experiment>/<setting>/``. With
``--committed`` the pages are rendered from those committed copies alone. The pages go to
``reports/reference/ct2d/README.md``, ``reports/reference/ungm1d/README.md`` and one
self-contained ``reports/reference/fusion-paper.html``. The per-run files are not committed; with
``--committed`` each committed ``results.json`` has its claims judged again by the current code
from its stored summary, what only the runs gave carried over, and is written back. An
interpretation run on its own at a setting's parameters (``gpfverify reproduce ... --interpretation
NAME --out RUNS_DIR/<folder>-<NAME>``) is copied likewise to ``.../<setting>/<NAME>/``, and the
setting's claims take their verdict under that interpretation from it where it has more runs than
the entry they hold (:func:`gpfverify.reference_pages.with_reading_runs`).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from gpfverify.contract.claims import AS_RUN, ClaimRecord, read_claims
from gpfverify.contract.serial import to_json
from gpfverify.experiments.runner import read_manifest, results_of
from gpfverify.experiments.batching import batch_option
from gpfverify.papers.fusion import ct2d_experiment as ct2d
from gpfverify.papers.fusion import ct2d_section as fusion_ct2d
from gpfverify.papers.fusion import ungm1d_experiment as ungm1d
from gpfverify.papers.fusion import ungm1d_section as fusion_ungm1d
from gpfverify.papers.fusion.ct2d_contract import Params as CT2DParams
from gpfverify.papers.fusion.section import rank_rules_table
from gpfverify.reference_pages import (REFERENCE, reading_commands, reading_runs, readings_into, recompute_into,
                                      rejudge_committed, runs_needed_table, verdicts_by_run_count,
                                      with_reading_runs, write_page)
from gpfverify.report.render import to_html

HERE = REFERENCE
#: the caption's explanation of the runs-needed tables
RUNS_NEEDED = ("each claim's verdict as run on the first n runs (the same seeds) and on all of them; a decided "
               "verdict needed more runs than the last count at which it was another and at most the next; an "
               "undecided one states about how many runs would decide it, were the mean and spread seen here the "
               "true ones")
#: folder name -> the command that makes it (run from the repository root, OUT = RUNS_DIR): the main
#: run's RUNS runs and each interpretation's INTERPRETED runs (the same seed), both counts read from
#: the results; the same bytes whether it runs at once or is interrupted and continued with --resume.
MADE = ("gpfverify reproduce {experiment} {options}--runs RUNS --seed 1 BATCH--interpretations WHICH "
        "--interpretation-runs INTERPRETED --out OUT/{name}")
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
    batch = batch_option(results)
    tried = [i for c in read_claims(results) for i in c.interpretations if i.name != AS_RUN]
    names = list(dict.fromkeys(i.name for i in tried))
    which = "all" if set(names) == {s.name for s in module.INTERPRETATIONS} else ",".join(names)
    if not names:
        options = OPTIONS[name]
        return (f"gpfverify reproduce {name.split('-')[0]} {options}--runs {results['runs']} --seed 1 {batch}"
                f"--out OUT/{name}")
    # the interpretations with runs of their own ran fewer; those that read the main run's runs have its count
    alone = reading_runs(target(name), module)  # run on their own: their commands follow the main one
    counts = ", ".join(str(n) for n in sorted({i.n for i in tried
                                               if i.n and i.n != results["runs"] and i.name not in alone})) \
        or str(results["runs"])
    main = (COMMANDS[name].replace("INTERPRETED", counts).replace("WHICH", which)
            .replace("RUNS", str(results["runs"])).replace("BATCH", batch))
    own = reading_commands(target(name), module, lambda reading, runs: (
        f"gpfverify reproduce {name.split('-')[0]} {OPTIONS[name]}--interpretation {reading} --runs {runs} "
        f"--seed 1 --out OUT/{name}-{reading}"))
    return f"{main}; {own}" if own else main


def committed(name: str) -> dict | None:
    """The committed results of a folder with its claims judged again by the current code from the
    stored summary (:func:`~gpfverify.reference_pages.rejudge_committed`), None when there are none."""
    path = target(name) / "results.json"
    if not path.exists():
        return None
    if "claims" not in json.loads(path.read_text(encoding="utf-8")):
        return None  # older, untyped results are not rendered
    return rejudge_committed(path, ct2d if name.startswith("ct2d") else ungm1d)


#: each folder's verdicts on its first runs (reference_pages.RUN_LADDER), committed next to its results
BY_RUNS = "verdicts-by-runs.json"


def by_run_count(name: str, runs_dir: Path | None, results: dict) -> dict[int, list[ClaimRecord]]:
    """The claims' verdicts on the first n runs (computed from the saved runs and committed, or read
    back from the committed file)."""
    path = target(name) / BY_RUNS
    if runs_dir is not None:
        module = ct2d if name.startswith("ct2d") else ungm1d
        found = verdicts_by_run_count(runs_dir / name, module, results["runs"])
        path.write_text(json.dumps({str(n): [to_json(c) for c in claims] for n, claims in found.items()}, indent=1),
                        encoding="utf-8")
        return found
    if not path.exists():
        return {}
    return {int(n): [ClaimRecord.from_json(c) for c in claims]
            for n, claims in json.loads(path.read_text(encoding="utf-8")).items()}


#: each folder's Proposition 1 judgement under each rank rule read, committed next to its results
RANK_RULES = "rank-rules.json"


def equivalence_by_setting(name: str, results: dict) -> dict[str, dict]:
    """``{setting label: {family: one_step_gap}}`` of one folder's results.json."""
    if name.startswith("ct2d"):
        return {CT2DParams.from_json(results["params"]).label: results["one_step_gap"]}
    return {f"σ² = {float(k):g}": r["one_step_gap"] for k, r in fusion_ungm1d.by_noise(results).items()}


def rank_rule_readings(name: str, runs_dir: Path | None, results: dict) -> dict[str, dict]:
    """Proposition 1 step by step as run (the canonical rule; also on the first runs, as many as the
    numpy-rank interpretation ran) and under numpy's rule (computed from the saved runs and committed,
    or read back from the committed file)."""
    path = target(name) / RANK_RULES
    if runs_dir is None:
        return json.loads(path.read_text(encoding="utf-8")) if path.exists() else {}
    module = ct2d if name.startswith("ct2d") else ungm1d
    readings = {f"canonical, as run, {results['runs_ok']} runs": equivalence_by_setting(name, results)}
    numpy_path = runs_dir / name / "interpretations" / "numpy-rank" / "results.json"
    if numpy_path.is_file():
        numpy = json.loads(numpy_path.read_text(encoding="utf-8"))
        if numpy["runs"] < results["runs"]:
            first = results_of(module, runs_dir / name, read_manifest(runs_dir / name), numpy["runs"])
            readings[f"canonical, as run, first {first['runs_ok']} runs"] = equivalence_by_setting(name, first)
        readings[f"numpy-rank, {numpy['runs_ok']} runs"] = equivalence_by_setting(name, numpy)
    path.write_text(json.dumps(readings, indent=1, ensure_ascii=False), encoding="utf-8")
    return readings


def main(runs_dir: Path | None) -> None:
    found: dict[str, dict] = {}
    for name in COMMANDS:
        module = ct2d if name.startswith("ct2d") else ungm1d
        if runs_dir is not None and (runs_dir / name / "manifest.json").exists():
            found[name] = recompute_into(runs_dir / name, module, target(name))
        elif (results := committed(name)) is not None:
            found[name] = results
        if name in found:  # the interpretations run on their own (OUT/<name>-<interpretation>), committed beside
            if runs_dir is not None:
                readings_into(runs_dir, name, target(name), module)
            found[name] = with_reading_runs(found[name], target(name), module)
    source = {name: runs_dir if runs_dir is not None and (runs_dir / name).is_dir() else None for name in found}
    ladders = {name: by_run_count(name, source[name], r) for name, r in found.items()}
    rules = {name: rank_rule_readings(name, source[name], r) for name, r in found.items()}
    made = "python -m gpfverify.papers.fusion.page OUT (or --committed: from the committed results.json)"
    sections = []
    commands = [command(n, r) for n, r in found.items() if n.startswith("ct2d")]
    ct = {CT2DParams.from_json(r["params"]).label: r for n, r in found.items() if n.startswith("ct2d")}
    if ct:
        section = fusion_ct2d.render(ct, HERE / "ct2d", command=f"{'; '.join(commands)}; then {made}")
        readings: dict[str, dict] = {}
        for name in (n for n in found if n.startswith("ct2d")):
            for reading, by_label in rules[name].items():
                readings.setdefault(reading, {}).update(by_label)
        if readings:
            section.add(rank_rules_table(readings))
        for name, r in found.items():
            if name.startswith("ct2d") and ladders[name]:
                section.add(runs_needed_table(r, ladders[name], "The runs each claim needed — "
                                              f"{CT2DParams.from_json(r['params']).label}: {RUNS_NEEDED}"))
        sections.append(section)
    if "ungm1d-sweep" in found:
        r = found["ungm1d-sweep"]
        section = fusion_ungm1d.render(r, HERE / "ungm1d", command=f"{command('ungm1d-sweep', r)}; then {made}")
        if rules["ungm1d-sweep"]:
            section.add(rank_rules_table(rules["ungm1d-sweep"]))
        if ladders["ungm1d-sweep"]:
            section.add(runs_needed_table(r, ladders["ungm1d-sweep"], f"The runs each claim needed: {RUNS_NEEDED}"))
        sections.append(section)
    for section in sections:
        write_page(section, HERE / section.slug,
                   [r for n, r in found.items() if n.split("-")[0] == section.slug])
    (HERE / "fusion-paper.html").write_text(to_html(sections, "Fusion paper: reference run"), encoding="utf-8")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(None if sys.argv[1] == "--committed" else Path(sys.argv[1]))
