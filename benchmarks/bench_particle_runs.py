"""Monte Carlo runs per CPU-second of the particle-method experiments, runs advanced together as
arrays (``run_batch`` with B runs) against one run at a time (``run_one`` looped), in one process
and one benchmark run, with the machine's load recorded; and the floor: the time of the exp and
random-number calls alone for the same arithmetic, and how far the batched path is from it.

    .venv/bin/python benchmarks/bench_particle_runs.py [--batch 32] [--out benchmarks/results/particle_runs.md]

Experiments and sizes (each experiment's own parameters; ``tbd`` at the paper's N = 2000 and at
the report's quick profile): per-run runs are few (they are slow), batched runs B. Both sides
are checked to give the same records (every field but the CPU seconds) before their times count.

The floor of an experiment is its arithmetic with the interpreter taken out: the exp calls and the
random draws a run makes (and, for the flows, the element-wise passes of each λ-step), made as
single numpy calls on arrays holding every run of a large batch, divided by its runs. It is a lower
bound on what any implementation of the same algorithms in numpy can reach, not a target.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from _timing import markdown_table
from gpfverify.contract.serial import to_json
from gpfverify.experiments.batching import without_seconds


def _cpu(fn):
    start = time.process_time()
    out = fn()
    return out, time.process_time() - start


# ---- the experiments -------------------------------------------------------------------------------
def _pff1d():
    from gpfverify.papers.particle_flow.pff1d_contract import QUICK_PARAMS
    from gpfverify.papers.particle_flow import pff1d_experiment as pff1d
    return "pff1d (quick grid: Q ∈ {0.1, 10}, R = 1, Δλ ∈ {0.1, 0.01}, gamma R = 0.1; N = 50, T = 50)", \
        pff1d, QUICK_PARAMS, _pff1d_floor


def _tbd_quick():
    from gpfverify.papers.tbd.contract import QUICK_PARAMS
    from gpfverify.papers.tbd import experiment as tbd
    return "tbd (quick: N = 500, 4 SNRs)", tbd, QUICK_PARAMS, _tbd_floor


def _tbd_paper():
    from gpfverify.papers.tbd.contract import Params
    from gpfverify.papers.tbd import experiment as tbd
    return "tbd (paper: N = 2000, 9 SNRs)", tbd, Params(), _tbd_floor


def _bearing():
    from gpfverify.papers.particle_flow import bearing_experiment as bearing
    return "bearing (paper: PF 50 and 200, IE-PFF 50)", bearing, bearing.PROFILES["full"].settings[0].params, \
        _bearing_floor


# ---- floors: the run's arithmetic as single numpy calls over a large batch --------------------------
FLOOR_RUNS = 1024


def _floor_seconds(calls, runs: int = FLOOR_RUNS) -> float:
    """CPU seconds per run of ``calls`` (each a function of the run count) over ``runs`` runs."""
    _, seconds = _cpu(lambda: [call(runs) for call in calls])
    return seconds / runs


def _flow_calls(rng, particles: int, lam_steps: int, passes: int = 10):
    """``lam_steps`` λ-steps of a flow, ``passes`` element-wise passes over N particles each."""
    def call(runs):
        x = rng.standard_normal(runs * particles)
        for _ in range(lam_steps):
            for _ in range(passes):
                np.multiply(x, 0.999, out=x)
    return call


def _pf_calls(rng, particles: int, steps: int, dim: int = 1):
    """A bootstrap PF: per step the transition draws, one exp per particle, one uniform."""
    def call(runs):
        for _ in range(steps):
            rng.standard_normal(runs * particles * dim)
            np.exp(rng.standard_normal(runs * particles))
            rng.random(runs)
    return call


def _pff1d_floor(params) -> float:
    rng = np.random.default_rng(0)
    cells = len(params.table_q) * len(params.table_r)
    lam = sum(int(round(1 / d)) for d in params.dlambda) * len(params.spacings) * 2  # two flows
    gamma_lam = int(round(1 / params.gamma_dlambda)) * len(params.spacings) * 2 * len(params.gamma_r)
    filters = (cells + len(params.gamma_r)) * 2  # PF and UPF per case
    n, T = params.particles, params.steps
    calls = [_flow_calls(rng, n, T * (cells * lam + gamma_lam)), _pf_calls(rng, n, T * filters)]
    return _floor_seconds(calls, 256)


def _tbd_floor(params) -> float:
    """Per frame of each sequence of each method: exp of the point-spread factors of the merged set
    (2 axes × (2p+1) × N), the births' uniforms (8 per birth), the propagation's normals
    (5 per continuing particle) and one exp per merged particle for the weights."""
    rng = np.random.default_rng(0)
    from gpfverify.papers.tbd.contract import main_methods, sweep_methods
    counts = [m.particles for m in main_methods(params)] * len(params.snr)
    counts += [m.particles for m in sweep_methods(params)]
    width = 2 * params.patch_radius + 1
    frames = params.frames * 2  # target present and absent

    def call(runs):
        for n in counts:
            for _ in range(frames):
                np.exp(rng.standard_normal(2 * width * n * runs))
                rng.random(8 * (n // 2) * runs)
                rng.standard_normal(5 * (n // 2) * runs)
                np.exp(rng.standard_normal(n * runs))
    return _floor_seconds([call], 16)


def _bearing_floor(params) -> float:
    rng = np.random.default_rng(0)
    calls = []
    for sized in params.filters:
        if sized.method.key == "ie-pff":
            calls.append(_flow_calls(rng, sized.particles * 4, params.duration * int(round(1 / params.dlambda))))
        else:
            calls.append(_pf_calls(rng, sized.particles, params.duration, 4))
    return _floor_seconds(calls, 256)


EXPERIMENTS = {"pff1d": _pff1d, "tbd-quick": _tbd_quick, "tbd": _tbd_paper, "bearing": _bearing}


def measure(name: str, batch: int, per_run: int) -> list:
    title, module, params, floor = EXPERIMENTS[name]()
    seeds = [np.random.SeedSequence(20261205, spawn_key=(i,)) for i in range(batch)]
    module.run_one(params, seeds[0])  # warm-up: imports, caches
    alone, alone_seconds = _cpu(lambda: [module.run_one(params, s) for s in seeds[:per_run]])
    together, together_seconds = _cpu(lambda: module.run_batch(params, seeds))
    if without_seconds(to_json(alone)) != without_seconds(to_json(together[:per_run])):
        raise SystemExit(f"{name}: run_batch and run_one disagree")
    floor_seconds = floor(params)
    per_run_rate, batch_rate = per_run / alone_seconds, batch / together_seconds
    return [title, f"{per_run_rate:.3g}", f"{batch_rate:.3g} (B = {batch})", f"{batch_rate / per_run_rate:.1f} ×",
            f"{1 / floor_seconds:.3g}", f"{(together_seconds / batch) / floor_seconds:.0f} ×"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=32)
    parser.add_argument("--experiments", nargs="*", default=list(EXPERIMENTS))
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    load_before = os.getloadavg()
    rows = []
    with threadpool_limits(1):
        for name in args.experiments:
            per_run = 1 if name in ("tbd", "pff1d") else 4
            rows.append(measure(name, args.batch if name != "tbd" else min(args.batch, 16), per_run))
    load_after = os.getloadavg()
    before, after = (", ".join(f"{x:.1f}" for x in load) for load in (load_before, load_after))
    text = (f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
            f"{platform.python_version()}, numpy {np.__version__}, one BLAS thread; load average (1, 5, 15 min) "
            f"{before} before, {after} after\n\n"
            "Runs per CPU-second (process time), one run at a time (`run_one` looped) and B runs together "
            "(`run_batch`), in one process; both sides give the same records but for CPU seconds (checked). "
            "Floor: runs per CPU-second of the run's exp and random-number calls alone, made once over a large "
            "batch (see the script); last column: the batched path's CPU time per run over the floor's.\n\n"
            + markdown_table(["experiment", "runs/CPU-s, per run", "runs/CPU-s, batched", "speed-up",
                              "floor runs/CPU-s", "batched / floor"], rows))
    print(text)
    if args.out:
        args.out.write_text(text + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
