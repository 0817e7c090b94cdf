"""Particle filters of seed 003, vectorised over particles, against straightforward per-particle
loops of the same equations: one IE-PFF flow (bearing-only model, N = 50, 20 λ-steps), one EDH
flow, systematic resampling, and the UPF's UKF proposal (one batched UKF step for all particles
against one UKF step per particle). Each reference must give the same numbers (checked, printed).

    .venv/bin/python benchmarks/bench_particle_flow.py [--particles 50] [--repeats 20] [--out FILE]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from _timing import median_seconds, publish
from gpfverify.filters.flows import edh_update, ie_pff_update, uniform_steps
from gpfverify.filters.likelihoods import unwrapped_measurement
from gpfverify.filters.records import Gaussian
from gpfverify.filters.resampling import Particles, normalize_log_weights, systematic_resample
from gpfverify.filters.ukf import ukf_step
from gpfverify.filters.upf import ukf_proposal
from gpfverify.papers.particle_flow.bearing_scenario import INITIAL_STATE, bearing_model


def loop_ie_pff(particles, model, z, k, steps):
    """IE-PFF with explicit sums over particles (seed 003 eq. 36)."""
    x = [p.copy() for p in particles]
    n = len(x)
    for dlam in steps:
        hx = [unwrapped_measurement(model, z, p[None, :], k)[0] for p in x]
        x_mean, h_mean = sum(x) / n, sum(hx) / n
        cross = sum(np.outer(p - x_mean, h - h_mean) for p, h in zip(x, hx)) / n
        gain = cross @ np.linalg.inv(model.R)
        x = [p + dlam * gain @ (z - 0.5 * (h + h_mean)) for p, h in zip(x, hx)]
    return np.array(x)


def loop_edh(particles, P, model, z, k, steps):
    """EDH with A(λ), b(λ) applied particle by particle."""
    x = [p.copy() for p in particles]
    x0_mean = sum(x) / len(x)
    eye, lam0 = np.eye(len(x0_mean)), 0.0
    for dlam in steps:
        lam = lam0 + 0.5 * dlam
        mean = sum(x) / len(x)
        H = model.h_jacobian(mean, k)
        e = unwrapped_measurement(model, z, mean[None, :], k)[0] - H @ mean
        A = -0.5 * P @ H.T @ np.linalg.inv(lam * H @ P @ H.T + model.R) @ H
        b = (eye + 2 * lam * A) @ ((eye + lam * A) @ P @ H.T @ np.linalg.inv(model.R) @ (z - e) + A @ x0_mean)
        x = [p + dlam * (A @ p + b) for p in x]
        lam0 += dlam
    return np.array(x)


def loop_systematic(log_weights, u):
    """Systematic resampling by walking the cumulative weights."""
    w = np.exp(normalize_log_weights(log_weights))
    n, out, i, c = w.size, [], 0, w[0]
    for j in range(n):
        pos = (u + j) / n
        while pos >= c and i < n - 1:
            i += 1
            c += w[i]
        out.append(i)
    return np.array(out)


def loop_ukf_proposal(particles, sqrt_covs, model, z, k):
    means, factors = [], []
    for p, s in zip(particles, sqrt_covs):
        rec = ukf_step(Gaussian(p, s @ s.T), model, z, k=k)
        means.append(rec.mu_e)
        factors.append(np.linalg.cholesky(rec.C_e))
    return np.array(means), np.array(factors)


def main() -> None:
    parser = argparse.ArgumentParser(allow_abbrev=False, description=__doc__.splitlines()[0])
    parser.add_argument("--particles", type=int, default=50)
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    model = bearing_model(0.05, 0.1, 0.01)
    prior = model.prior_cov
    particles = INITIAL_STATE + rng.standard_normal((args.particles, 4)) @ np.sqrt(prior)
    z = model.h(INITIAL_STATE[None, :], 1)[0] + 0.01
    steps = uniform_steps(20)
    log_w = rng.normal(size=args.particles)
    u = 0.37
    factors = np.broadcast_to(np.sqrt(prior), (args.particles, 4, 4)).copy()

    class FixedUniform:
        def uniform(self):
            return u

    cases = [
        ("IE-PFF flow, 20 λ-steps", lambda: ie_pff_update(particles, model, z, 1, steps),
         lambda: loop_ie_pff(particles, model, z, 1, steps)),
        ("EDH flow, 20 λ-steps", lambda: edh_update(particles, prior, model, z, 1, steps),
         lambda: loop_edh(particles, prior, model, z, 1, steps)),
        ("systematic resampling", lambda: systematic_resample(log_w, FixedUniform()),
         lambda: loop_systematic(log_w, u)),
        ("UPF: UKF proposal for all particles",
         lambda: ukf_proposal(Particles.equally_weighted(particles, sqrt_covs=factors), model, z, k=1),
         lambda: loop_ukf_proposal(particles, factors, model, z, 1)),
    ]
    rows = []
    for name, fast, slow in cases:
        a, b = fast(), slow()
        a, b = (a if isinstance(a, tuple) else (a,)), (b if isinstance(b, tuple) else (b,))
        diff = max(float(np.max(np.abs(np.asarray(x, float) - np.asarray(y, float)))) for x, y in zip(a, b))
        t_fast = median_seconds(fast, args.repeats)
        t_slow = median_seconds(slow, args.repeats)
        rows.append([name, f"{t_fast * 1e3:.3f}", f"{t_slow * 1e3:.3f}", f"{t_slow / t_fast:.1f}x", f"{diff:.1e}"])
    print(f"N = {args.particles} particles, bearing-only model (state dim 4), median of {args.repeats}\n")
    publish(["operation", "vectorised (ms)", "per-particle loop (ms)", "speed-up", "max |difference|"],
            rows, args.out)


if __name__ == "__main__":
    main()
