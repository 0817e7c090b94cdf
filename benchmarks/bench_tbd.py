"""Frames per second of PF-TBD and TPFTBD (N = 2000, Rutten's 20×20 scenario at 6 dB) against a
straightforward per-particle-loop reference of the same steps.

The reference draws the same random numbers in the same order, so its existence probabilities
and estimates must agree with the vectorised filters (checked and printed).

    .venv/bin/python benchmarks/bench_tbd.py [--particles 2000] [--repeats 5]
"""

from __future__ import annotations

import argparse
import math
import platform
from pathlib import Path

import numpy as np
from scipy.special import expit, logsumexp

from _timing import markdown_table, median_seconds
from gpfverify.filters.resampling import Particles, systematic_resample
from gpfverify.filters.tbd import TbdConfig, initial_belief, pf_tbd_step, tpf_tbd_step
from gpfverify.filters.tbd.pf import birth_proposal
from gpfverify.filters.tbd.two_stage import second_stage_axes, transfer_particles
from gpfverify.papers.tbd.scenario import TbdScenario, scenario_model, simulate


def loop_log_lr(model, state, image) -> float:
    """log L(z | s) of one particle by a double loop over its patch."""
    n, d, p = model.grid_size, model.cell_size, model.patch_radius
    cx, cy = round(state[0] / d), round(state[2] / d)
    amp = d * d * state[4] / (2 * math.pi * model.blur**2)
    total = 0.0
    for i in range(cx - p, cx + p + 1):
        for j in range(cy - p, cy + p + 1):
            if 0 <= i < n and 0 <= j < n:
                h = amp * math.exp(-((i * d - state[0]) ** 2 + (j * d - state[2]) ** 2) / (2 * model.blur**2))
                total += h * (2 * image[i, j] - h) / (2 * model.noise_std**2)
    return total


def loop_pf_step(belief, model, config, image, rng):
    births, log_ratio = birth_proposal(model, config, image, rng)
    noise = rng.standard_normal(belief.particles.shape) @ model.process_factor.T
    continuing = np.array([model.transition_matrix @ s for s in belief.particles]) + noise
    merged = np.concatenate([births, continuing])
    prev = belief.existence
    log_w = np.empty(merged.shape[0])
    for i, s in enumerate(merged):
        if i < config.n_birth:
            prior = model.p_birth * (1 - prev) / config.n_birth
            log_w[i] = loop_log_lr(model, s, image) + log_ratio[i] + (math.log(prior) if prior > 0 else -math.inf)
        else:
            prior = (1 - model.p_death) * prev / config.n_continuing
            log_w[i] = loop_log_lr(model, s, image) + (math.log(prior) if prior > 0 else -math.inf)
    log_mass = float(logsumexp(log_w))
    existence = float(expit(log_mass - math.log(model.p_death * prev + (1 - model.p_birth) * (1 - prev))))
    w = np.exp(log_w - log_mass)
    estimate = sum(wi * s for wi, s in zip(w, merged))
    resampled = merged[systematic_resample(log_w - log_mass, rng, size=config.n_continuing)]
    return merged, w, existence, estimate, Particles.equally_weighted(resampled, existence=existence)


def loop_second_stage(merged, w, model, config, image, estimate):
    axis_x, axis_y = second_stage_axes(model, config, estimate)
    cells = [(i, j) for i in axis_x for j in axis_y]
    z = np.array([image[i, j] for i, j in cells])
    H = np.empty((merged.shape[0], len(cells)))
    for k, s in enumerate(merged):
        amp = model.cell_size**2 * s[4] / (2 * math.pi * model.blur**2)
        cx, cy = round(s[0] / model.cell_size), round(s[2] / model.cell_size)
        for c, (i, j) in enumerate(cells):
            inside = abs(i - cx) <= model.patch_radius and abs(j - cy) <= model.patch_radius
            H[k, c] = amp * math.exp(-((i - s[0]) ** 2 + (j - s[2]) ** 2) / (2 * model.blur**2)) if inside else 0.0
    s_hat = sum(wi * s for wi, s in zip(w, merged))
    z_hat = sum(wi * h for wi, h in zip(w, H))
    P = sum(wi * np.outer(s - s_hat, s - s_hat) for wi, s in zip(w, merged))
    P_xz = sum(wi * np.outer(s - s_hat, h - z_hat) for wi, s, h in zip(w, merged, H))
    S = sum(wi * np.outer(h - z_hat, h - z_hat) for wi, h in zip(w, H)) + model.noise_std**2 * np.eye(z.size)
    K = P_xz @ np.linalg.inv(S)
    return s_hat + K @ (z - z_hat), P - K @ S @ K.T


def run_loop(images, model, config, seed, second_seed):
    rng, second_rng = np.random.default_rng(seed), np.random.default_rng(second_seed)
    belief = initial_belief(model, config, rng)
    out = []
    for image in images:
        merged, w, existence, estimate, belief = loop_pf_step(belief, model, config, image, rng)
        if config.two_stage:
            mean, cov = loop_second_stage(merged, w, model, config, image, estimate)
            particles, _ = transfer_particles(belief.particles, mean, cov, config.zeta, second_rng)
            belief = Particles.equally_weighted(particles, existence=existence)
            estimate = config.zeta * estimate + (1 - config.zeta) * mean
        out.append((existence, estimate))
    return out


def run_vectorised(images, model, config, seed, second_seed):
    rng, second_rng = np.random.default_rng(seed), np.random.default_rng(second_seed)
    belief = initial_belief(model, config, rng)
    out = []
    for k, image in enumerate(images, 1):
        if config.two_stage:
            step = tpf_tbd_step(belief, model, image, k=k, rng=rng, config=config, second_rng=second_rng)
        else:
            step = pf_tbd_step(belief, model, image, k=k, rng=rng, config=config)
        belief = step.posterior
        out.append((belief.existence, step.mean))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    parser.add_argument("--particles", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--reference-frames", type=int, default=3,
                        help="frames the slow reference filters (default 3)")
    parser.add_argument("--out", type=Path, default=None, help="also write the table to this file")
    args = parser.parse_args()
    scenario = TbdScenario()
    model = scenario_model(6.0, scenario)
    images = simulate(model, scenario, np.random.default_rng(0)).images
    ref_images = images[6:6 + args.reference_frames]
    rows = []
    for name, config in (("PF-TBD", TbdConfig(args.particles)),
                         ("TPFTBD (ζ = 0.6)", TbdConfig(args.particles, two_stage=True, zeta=0.6))):
        fast = median_seconds(lambda c=config: run_vectorised(images, model, c, 1, 2), args.repeats, 1) / len(images)
        slow = median_seconds(lambda c=config: run_loop(ref_images, model, c, 1, 2), 1, 0) / len(ref_images)
        a = run_vectorised(ref_images, model, config, 1, 2)
        b = run_loop(ref_images, model, config, 1, 2)
        d_exist = max(abs(x[0] - y[0]) for x, y in zip(a, b))
        d_est = max(float(np.abs(x[1] - y[1]).max()) for x, y in zip(a, b))
        rows.append([name, f"{1 / fast:.1f}", f"{1 / slow:.2f}", f"{slow / fast:.0f}x",
                     f"{d_exist:.1e}", f"{d_est:.1e}"])
    table = (f"N = {args.particles}, {model.grid_size}x{model.grid_size} image, 6 dB, {platform.machine()} "
             f"({platform.python_implementation()} {platform.python_version()}); median of {args.repeats}\n\n"
             + markdown_table(["method", "vectorised frames/s", "loop frames/s", "speed-up",
                               "max abs ΔP_k vs loop", "max abs Δŝ vs loop"], rows))
    print(table)
    if args.out:
        args.out.write_text(table + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
