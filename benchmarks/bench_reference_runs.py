"""What deciding the reference pages' undecided claims would cost: runs per CPU-second of each
reference setting, batched, and the CPU hours of the runs its claims need.

For every committed reference result (``reports/reference/**/results.json``) with an undecided claim
whose runs-needed estimate (the claim record's ``runs_to_decide``: the runs that would decide it
were the mean and spread seen the true ones) is at most ``--cap`` runs, the setting's experiment
runs ``--batch`` runs of the reference seed together (``run_batch``, the setting's own recorded
parameters, process CPU time, BLAS on one thread), once. The table gives the claims, the runs the
setting's command would use (the largest estimate among its claims, rounded up to a thousand), the
measured runs per CPU-second and the CPU hours that count of runs takes, and the command (the
reference command with that run count; the same seed, so its first runs are the reference's runs,
and ``--resume`` with a larger ``--runs`` extends a study). Only the main setting's runs are
counted: an interpretation's runs (``--interpretation-runs``) come on top.

    .venv/bin/python benchmarks/bench_reference_runs.py --out benchmarks/results/reference_runs.md
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import platform
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from _timing import markdown_table


REFERENCE = Path(__file__).resolve().parents[1] / "reports" / "reference"

#: results folder (under reports/reference) -> the command that made it, RUNS for the main run count
COMMANDS = {
    "ct2d/k300-w0.0698": "gpfverify reproduce ct2d --kappa 300 --omega 0.0698 --runs RUNS --seed 1 "
                         "--interpretations all --interpretation-runs 40 --out OUT/ct2d-k300-w0.0698",
    "ct2d/k300-w0.5": "gpfverify reproduce ct2d --kappa 300 --omega 0.5 --runs RUNS --seed 1 "
                      "--interpretations all --interpretation-runs 40 --out OUT/ct2d-k300-w0.5",
    "ct2d/k30-w0.0698": "gpfverify reproduce ct2d --kappa 30 --omega 0.0698 --runs RUNS --seed 1 "
                        "--interpretations all --interpretation-runs 40 --out OUT/ct2d-k30-w0.0698",
    "ct2d/k60-w0.0698": "gpfverify reproduce ct2d --kappa 60 --omega 0.0698 --runs RUNS --seed 1 "
                        "--interpretations all --interpretation-runs 40 --out OUT/ct2d-k60-w0.0698",
    "ungm1d": "gpfverify reproduce ungm1d --runs RUNS --seed 1 --interpretations all --interpretation-runs 100 "
              "--out OUT/ungm1d-sweep",
    "tbd/run": "gpfverify reproduce tbd --runs RUNS --seed 1 --interpretations birth-uniform,birth-threshold-2 "
               "--interpretation-runs 2000 --out OUT/tbd",
    "particle-flow/bearing": "gpfverify reproduce bearing --runs RUNS --seed 1 --interpretations all --out OUT/bearing",
    "particle-flow/pff1d": ("gpfverify reproduce pff1d --runs RUNS --seed 1 --interpretations vdm-gaussian "
                            "--out OUT/pff1d"),
    # the second model run on its own: the interpretation vdm-gaussian as the main run
    "particle-flow/pff1d/vdm-gaussian": "gpfverify reproduce pff1d --interpretation vdm-gaussian --runs RUNS --seed 1 "
                                        "--out OUT/pff1d-vdm-gaussian",
}


def undecided(results: dict, cap: int) -> list[tuple[str, int]]:
    """(slug, runs needed) of the setting's own undecided claims (accuracy and timing) needing at
    most ``cap`` runs."""
    claims = results.get("claims", []) + results.get("timing_claims", [])
    return [(c.get("id", "?"), c["runs_to_decide"]) for c in claims
            if c.get("verdict") == "undecided" and c.get("runs_to_decide") and c["runs_to_decide"] <= cap]


def settings(cap: int):
    from gpfverify.papers import EXPERIMENTS

    for path in sorted(REFERENCE.glob("**/results.json")):
        folder = path.parent.relative_to(REFERENCE).as_posix()
        results = json.loads(path.read_text(encoding="utf-8"))
        claims = undecided(results, cap)
        if claims:
            module = importlib.import_module(EXPERIMENTS[results["experiment"]])
            yield folder, module, module.Params.from_json(results["params"]), results, claims


def runs_per_cpu_second(module, params, batch: int, seed: int) -> float:
    seeds = [np.random.SeedSequence(seed, spawn_key=(i,)) for i in range(batch)]
    module.run_batch(params, seeds[:1])  # compile and import outside the timing
    start = time.process_time()
    module.run_batch(params, seeds)
    return batch / (time.process_time() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cap", type=int, default=20000, help="largest runs-needed estimate counted")
    parser.add_argument("--batch", type=int, default=8, help="runs measured together per setting")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    rows = []
    for folder, module, params, results, claims in settings(args.cap):
        runs = 1000 * math.ceil(max(n for _, n in claims) / 1000)
        rate = runs_per_cpu_second(module, params, args.batch, results.get("seed", 1))
        rows.append([folder, "; ".join(f"{slug} ({n})" for slug, n in claims), results["runs"], runs, f"{rate:.3g}",
                     f"{runs / rate / 3600:.2f}", "`" + COMMANDS.get(folder, "?").replace("RUNS", str(runs)) + "`"])
        print(" | ".join(str(c) for c in rows[-1]), flush=True)
    text = [f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
            f"{platform.python_version()}, numpy {np.__version__}; BLAS threads 1 "
            f"(threadpoolctl); load average (1, 5, 15 min) at the start {load}, "
            f"at the end {', '.join(f'{v:.2f}' for v in os.getloadavg())}",
            "", f"Undecided claims of the reference pages needing at most {args.cap} runs (the claim's runs-needed "
            f"estimate in brackets), the setting's runs at the reference and for the command below, batched runs "
            f"per CPU-second ({args.batch} runs of the reference seed in one run_batch, once), and the CPU hours "
            "of the command's main runs (divide by the cores given to --workers or to a cluster).", "",
            markdown_table(["setting", "undecided claims (runs needed)", "reference runs", "runs", "runs/CPU-s",
                            "CPU hours", "command"], rows)]
    out = "\n".join(text)
    print(out)
    if args.out:
        args.out.write_text(out + "\n", encoding="utf-8")


if __name__ == "__main__":
    with threadpool_limits(1):  # numpy is imported already: the environment variable would come too late
        main()
