"""Unscented particle filters on the SINS/GPS scenario: one UPF and one GPSR-UPF step with the
proposal vectorised over the particles, against the same step with the proposal run one particle
at a time (a per-particle loop, as the algorithm is usually written). Also the batched rank-one
Cholesky downdate against a per-factor loop.

The step is taken at t = 550 s (in the turn, where the GP residual is active) from particles
drawn from the prior; both routes use the same random numbers and are checked to agree.
"""

from __future__ import annotations

import argparse
from functools import partial
from pathlib import Path

import numpy as np

from _timing import median_seconds, publish
from gpfverify.papers.gpsr_upf import experiment as sins_gps
from gpfverify.filters.gpsr_upf import gpsr_upf_step, sr_ukf_proposal
from gpfverify.filters.resampling import Particles
from gpfverify.filters.sr_ukf import cholupdate
from gpfverify.filters.upf import ukf_proposal, upf_step

STEP = 550


def looped(proposal):
    """The same proposal applied to one particle at a time."""
    def run(belief, model, y, *, k, **kwargs):
        outs = [proposal(Particles(belief.particles[i:i + 1], belief.log_weights[i:i + 1], belief.sqrt_covs[i:i + 1]),
                         model, y, k=k, **kwargs) for i in range(belief.size)]
        return np.concatenate([m for m, _ in outs]), np.concatenate([s for _, s in outs])
    return run


def _setup(particles: int):
    params = sins_gps.Params(particles=particles)
    config, models, upf_model, gpsr_model, _ = sins_gps.setup(params)
    rng = np.random.default_rng(0)
    _, ys = models.true.simulate(STEP, rng, x0=np.zeros(15))
    cloud = Particles.from_gaussian(np.zeros(15), config.initial_cov(), particles, rng)
    return upf_model, gpsr_model, cloud, ys[STEP - 1]


def _cases(particles: int):
    upf_model, gpsr_model, cloud, y = _setup(particles)
    gpsr_sqrt = gpsr_model.process_sqrt

    def upf(proposal):
        return lambda: upf_step(cloud, upf_model, y, k=STEP, rng=np.random.default_rng(1), proposal=proposal).posterior

    def gpsr_vectorised():
        return gpsr_upf_step(cloud, gpsr_model, y, k=STEP, rng=np.random.default_rng(1)).posterior

    def gpsr_loop():
        proposal = partial(looped(sr_ukf_proposal), process_sqrt=gpsr_sqrt)
        return upf_step(cloud, gpsr_model.at_step(STEP), y, k=STEP, rng=np.random.default_rng(1),
                        proposal=proposal).posterior

    return [(f"UPF step, N = {particles}", upf(ukf_proposal), upf(looped(ukf_proposal))),
            (f"GPSR-UPF step, N = {particles}", gpsr_vectorised, gpsr_loop)]


def _downdate_case(particles: int):
    rng = np.random.default_rng(2)
    a = rng.normal(size=(particles, 15, 15))
    factors = np.linalg.cholesky(a @ np.swapaxes(a, 1, 2) + 15 * np.eye(15))
    vectors = 0.5 * rng.normal(size=(particles, 15))
    return (f"rank-one downdate of {particles} 15×15 factors",
            lambda: cholupdate(factors, vectors, -1.0)[0],
            lambda: np.stack([cholupdate(factors[i], vectors[i], -1.0)[0] for i in range(particles)]))


def main() -> None:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    parser.add_argument("--particles", type=int, nargs="+", default=[20, 50])
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    rows = []
    for n in args.particles:
        for label, fast, slow in _cases(n) + [_downdate_case(n)]:
            a, b = fast(), slow()
            pairs = [(a.particles, b.particles), (a.sqrt_covs, b.sqrt_covs), (a.log_weights, b.log_weights)] \
                if isinstance(a, Particles) else [(a, b)]
            diff = max(float(np.max(np.abs(x - z))) for x, z in pairs)
            t_fast = median_seconds(fast, args.repeats)
            t_slow = median_seconds(slow, max(3, args.repeats // 3))
            rows.append([label, f"{1e3 * t_fast:.2f}", f"{1e3 * t_slow:.2f}", f"{t_slow / t_fast:.1f}×",
                         f"{diff:.1e}"])
    publish(["case", "vectorised (ms)", "per-particle loop (ms)", "speed-up", "max |difference|"], rows, args.out)


if __name__ == "__main__":
    main()
