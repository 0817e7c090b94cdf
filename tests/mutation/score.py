"""The sampled mutation report: one record (``OUT/sampled.json``), rendered as ``OUT/sampled.md``.

Every count is computed once, in :func:`summarise`. The score is the share of the sampled mutants
that the suite kills, among those not classed equivalent; its 95 % interval is Wilson's score
interval for a binomial proportion (the sample is a probability sample of the package's lines, so
the share estimates the package's score, a mutant per equal number of lines). Timeouts count as
killed. A mutant that no test executes counts as a survivor.

A survivor is either classed *equivalent* in :mod:`tests.mutation.equivalents` (with one line a
reader can check) or listed as *not answered*. A mutant that survived an earlier run (its
``history``) and is killed now was *answered* by a new or stronger test; the report names the test.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from pathlib import Path

import numpy as np

from tests.mutation.draw import Drawn
from tests.mutation.equivalents import reason_for

KILLED = ("killed (property)", "killed (suite)", "timeout")
Z95 = 1.959963984540054  # the standard normal's 97.5 % quantile


def wilson(k: int, n: int) -> tuple[float, float]:
    """Wilson's 95 % score interval for k successes in n trials."""
    if n == 0:
        return (0.0, 1.0)
    p = k / n
    centre = (p + Z95**2 / (2 * n)) / (1 + Z95**2 / n)
    half = Z95 * math.sqrt(p * (1 - p) / n + Z95**2 / (4 * n * n)) / (1 + Z95**2 / n)
    return (max(0.0, centre - half), min(1.0, centre + half))


def _measure(rows: list[dict]) -> dict:
    counted = [r for r in rows if not r.get("equivalent")]
    n = len(counted)
    suite = sum(r["verdict"] in KILLED for r in counted)
    prop = sum(r["verdict"] == "killed (property)" for r in counted)
    return {"mutants": len(rows), "equivalent": len(rows) - n, "counted": n,
            "killed_by_suite": suite, "suite_score": suite / n if n else None, "suite_interval": wilson(suite, n),
            "killed_by_properties": prop, "property_score": prop / n if n else None,
            "property_interval": wilson(prop, n)}


def summarise(drawn: list[Drawn], results: dict[str, dict]) -> dict:
    """The record: the sample's rows (with their equivalence class), and the measures overall and by area."""
    rows = []
    for d in drawn:
        row = results.get(d.key)
        if row is None:
            continue
        row = dict(row)
        reason = reason_for(d) if row["verdict"] not in KILLED else None
        row["equivalent"] = reason
        earlier = [h for h in row.get("history", []) if h["verdict"] not in KILLED]
        row["answered_by"] = row["killed_by"] if earlier and row["verdict"] in KILLED else None
        rows.append(row)
    areas = sorted({d.area for d in drawn})
    drawn_in = Counter(d.area for d in drawn)
    return {"sample_size": len(drawn), "run": len(rows), "drawn_by_area": dict(sorted(drawn_in.items())),
            "verdicts": dict(Counter(r["verdict"] for r in rows)),
            "overall": _measure(rows),
            "areas": {a: {**_measure([r for r in rows if r["area"] == a]), "drawn": drawn_in[a]} for a in areas},
            "maps": sorted({r["map"] for r in rows}),
            "seconds": round(sum(r["seconds"] for r in rows), 1),
            "median_seconds": float(np.median([r["seconds"] for r in rows])) if rows else None, "rows": rows}


def _pct(x: float | None) -> str:
    return "—" if x is None else f"{100 * x:.1f} %"


def _interval(iv) -> str:
    return f"[{100 * iv[0]:.1f}, {100 * iv[1]:.1f}] %"


def _code(text: str) -> str:
    return "`" + text.replace("`", "'").replace("|", "\\|")[:110] + "`" if text else "(nothing)"


def render(record: dict, seed: int) -> str:
    o = record["overall"]
    out = ["# Sampled mutation report", "",
           f"Mutants drawn by cosmic-ray over the whole package: a seeded sample (seed {seed}) of "
           f"{record['sample_size']} in proportion to each module's statement lines; {record['run']} of them run "
           "(the scores are over the mutants run; the table by area says which were not). "
           "How it is made, what it costs and how to regenerate it: [README.md](README.md).", "",
           "| measure | killed | of | share | 95 % interval |", "|---|---|---|---|---|",
           f"| whole suite | {o['killed_by_suite']} | {o['counted']} | {_pct(o['suite_score'])} | "
           f"{_interval(o['suite_interval'])} |",
           f"| property_tests alone | {o['killed_by_properties']} | {o['counted']} | {_pct(o['property_score'])} | "
           f"{_interval(o['property_interval'])} |", "",
           f"{o['equivalent']} survivors classed equivalent are not counted. Verdicts: "
           + ", ".join(f"{v} {n}" for v, n in sorted(record["verdicts"].items())) + ". "
           f"Test time: {record['seconds'] / 3600:.1f} h of processes, "
           f"a median {record['median_seconds']} s per mutant run.", "",
           "## By area", "",
           "| area | drawn | run | equivalent | suite | 95 % interval | property_tests | 95 % interval |",
           "|---|---|---|---|---|---|---|---|"]
    for area, m in record["areas"].items():
        out.append(f"| {area} | {m['drawn']} | {m['mutants']} | {m['equivalent']} "
                   f"| {m['killed_by_suite']} ({_pct(m['suite_score'])}) "
                   f"| {_interval(m['suite_interval'])} | {m['killed_by_properties']} ({_pct(m['property_score'])}) "
                   f"| {_interval(m['property_interval'])} |")
    survivors = [r for r in record["rows"] if r["verdict"] not in KILLED]
    out += ["", f"## Survivors ({len(survivors)})", "",
            "| mutant | line as written | as mutated | class |", "|---|---|---|---|"]
    for r in survivors:
        klass = f"equivalent: {r['equivalent']}" if r["equivalent"] else (
            "not executed by any test" if r["verdict"] == "not executed" else "not answered")
        out.append(f"| {r['path']}:{r['line']} {r['operator'].removeprefix('core/')} | {_code(r['before'])} "
                   f"| {_code(r['after'])} | {klass} |")
    answered = [r for r in record["rows"] if r["answered_by"]]
    if answered:
        out += ["", f"## Survivors of an earlier run answered by a new or stronger test ({len(answered)})", "",
                "| mutant | as mutated | killed now by |", "|---|---|---|"]
        for r in answered:
            out.append(f"| {r['path']}:{r['line']} {r['operator'].removeprefix('core/')} | {_code(r['after'])} "
                       f"| `{r['answered_by']}` |")
    property_only = Counter(r["verdict"] for r in record["rows"] if r["verdict"] == "killed (suite)")
    out += ["", f"{property_only.get('killed (suite)', 0)} mutants were killed by tests/, proofs/ or examples/ "
            "after every selected property passed.", ""]
    return "\n".join(out)


def write(out: Path, drawn: list[Drawn], results: dict[str, dict], seed: int = 1) -> dict:
    record = summarise(drawn, results)
    (out / "sampled.json").write_text(json.dumps(record, indent=1, ensure_ascii=False), encoding="utf-8")
    (out / "sampled.md").write_text(render(record, seed), encoding="utf-8")
    return record
