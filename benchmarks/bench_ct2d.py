"""Cost of one ct2d Monte Carlo run at κ = 300 (training + 50 steps × twelve methods): gpfverify
against a straightforward implementation.

gpfverify: :func:`gpfverify.papers.fusion.ct2d_experiment.run_one` with its defaults, broken down into training
(the transition GP and both sensors' GPs), filtering (the four single-sensor filters), fusion
(CMF, DMF, CW, RCC-CI for both families) and the rest (metrics, rank decisions, audit, rounding
probe). Times are process CPU seconds (BLAS pinned to one thread): the machine is shared and its
load inflates wall time; the per-component split, recorded in wall time, is scaled to the run's CPU
time. The max relative difference between the two moment routes is rounding amplified by the
conditioning of K (see the ct2d report page).

Straightforward reference, measured piece by piece on the same data:

* training: evidence maximisation on all κ samples with 3 restarts (the library's default) instead
  of hyperparameters from ≤ 100 evenly spaced samples and 1 restart;
* GP-ADF moments: the literal formulas of ``bench_gp.reference_moments`` (explicit inverses, K_a
  refactorised at every call, Q built block by block) instead of :meth:`predict_uncertain`; checked
  to agree before timing. The reference run is estimated as reference training + the GP-ADF
  methods' time × the measured moment-matching ratio + everything else as ours.
"""

from __future__ import annotations

import argparse
import platform
import time
from pathlib import Path

import numpy as np

from _timing import markdown_table, median_cpu_seconds
from bench_gp import reference_moments
from gpfverify.papers.fusion.contract import FusionRun
from gpfverify.contract.methods import Method
from gpfverify.papers.fusion import ct2d_experiment as ct2d
from gpfverify.papers.fusion.run import train_models
from gpfverify.gp import GaussianProcess
from gpfverify.papers.fusion.scenario import simulate_data

FILTERING = ("Sensor1", "Sensor2")
FUSION = ("CMF", "DMF", "CW", "RCC-CI")


def timed(fn):
    wall, cpu = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - wall, time.process_time() - cpu


def breakdown(record: FusionRun) -> dict[str, float]:
    """Seconds per component of one run record."""
    out = {"training": record.training_seconds, "filtering": 0.0, "fusion": 0.0, "GP-ADF methods": 0.0}
    for family, rec in record.families.items():
        for key, per_step in rec.seconds.items():
            method = Method.parse(key)
            rule = f"Sensor{method.sensor}" if method.is_sensor else method.rule
            spent = float(np.sum(per_step))
            out["filtering" if rule in FILTERING else "fusion"] += spent
            if family == "GP-ADF" and rule in ("Sensor1", "Sensor2", "CMF", "DMF"):
                out["GP-ADF methods"] += spent
    return out


def main() -> None:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="runs of ours timed (median)")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    params = ct2d.Params(kappa=300)
    seeds = np.random.SeedSequence(1).spawn(args.runs)
    runs = [timed(lambda s=s: ct2d.run_one(params, s)) for s in seeds]
    parts = [breakdown(r) for r, _, _ in runs]
    wall = float(np.median([w for _, w, _ in runs]))
    cpu = float(np.median([c for _, _, c in runs]))
    part = {k: float(np.median([p[k] for p in parts])) for k in parts[0]}
    rest = wall - part["training"] - part["filtering"] - part["fusion"]

    rng = np.random.default_rng(0)
    data = simulate_data(ct2d.scenario(params), rng)
    _, ours_train, ours_train_cpu = timed(lambda: train_models(data, 1, 100, np.random.default_rng(1)))

    def reference_training():
        GaussianProcess.fit(data.transition_inputs, data.transition_targets, 3, 0)
        for y in data.measurement_targets:
            GaussianProcess.fit(data.measurement_inputs, y, 3, 0)

    _, ref_train, ref_train_cpu = timed(reference_training)

    gp = train_models(data, 1, 100, np.random.default_rng(1)).transition
    mu, sigma = data.test_states[0], 50.0 * np.eye(2)
    args_ref = (gp.X, gp.Y, gp.lengthscales, gp.signal_var, gp.noise_var, mu, sigma)
    ours_mm, ref_mm = gp.predict_uncertain(mu, sigma), reference_moments(*args_ref)
    agree = max(np.abs(ours_mm.mean - ref_mm[0]).max() / np.abs(ref_mm[0]).max(),
                np.abs(ours_mm.cov - ref_mm[1]).max() / np.abs(ref_mm[1]).max())
    t_ours = median_cpu_seconds(lambda: gp.predict_uncertain(mu, sigma), 10)
    t_ref = median_cpu_seconds(lambda: reference_moments(*args_ref), 3)
    mm_ratio = t_ref / t_ours
    # the components are recorded in wall time; on a loaded machine scale them to CPU time
    share = cpu / wall
    cpu_part = {k: v * share for k, v in part.items()}
    reference_run = (ref_train_cpu + cpu_part["GP-ADF methods"] * mm_ratio
                     + (cpu - cpu_part["training"] - cpu_part["GP-ADF methods"]))

    rows = [["whole run (median of ours)", f"{cpu:.2f} CPU (wall {wall:.2f})",
             f"{reference_run:.1f} CPU (estimated)", f"{reference_run / cpu:.1f}x"],
            ["  training (3 GPs)", f"{cpu_part['training']:.2f}", "", ""],
            ["  filtering (4 single-sensor filters)", f"{cpu_part['filtering']:.2f}", "", ""],
            ["  fusion (CMF, DMF, CW, RCC-CI x 2)", f"{cpu_part['fusion']:.2f}", "", ""],
            ["  rest (metrics, ranks, audit, probe)", f"{rest * share:.2f}", "", ""],
            ["training alone, one data set", f"{ours_train_cpu:.2f} CPU (wall {ours_train:.2f})",
             f"{ref_train_cpu:.2f} CPU (wall {ref_train:.2f})", f"{ref_train_cpu / ours_train_cpu:.1f}x"],
            ["GP-ADF moments, n = 300, D = E = 2", f"{t_ours * 1e3:.2f} ms CPU", f"{t_ref * 1e3:.1f} ms CPU",
             f"{mm_ratio:.1f}x (max rel. diff {agree:.1e})"]]
    table = markdown_table(["ct2d, κ = 300, 50 steps", "gpfverify s", "straightforward s", "ratio"], rows)
    header = (f"Machine: {platform.processor() or platform.machine()}, {platform.python_version()}, "
              f"numpy {np.__version__}; load average {', '.join(f'{x:.1f}' for x in __import__('os').getloadavg())}")
    print(header + "\n\n" + table)
    if args.out:
        args.out.write_text(header + "\n\n" + table + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
