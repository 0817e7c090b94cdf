"""Weighted particle sets, effective sample size and systematic resampling — shared by every
particle filter (bootstrap PF, UPF, GPSR-UPF, PF-TBD).

Weights are kept as logarithms so that likelihoods far in the tails do not underflow:
w_i = exp(ℓ_i − logsumexp ℓ). The effective sample size is N_eff = 1 / Σ w_i² (Kong, Liu & Wong
1994; seed 001's resampling rule "resample when N_eff < N_T"). Systematic resampling (Kitagawa
1996; Carpenter, Clifford & Fearnhead 1999) draws one u ~ U[0, 1) and takes the indices of
(u + j)/N, j = 0..N−1, in the cumulative weights: each index i is kept ⌊N w_i⌋ or ⌈N w_i⌉ times
and E[count_i] = N w_i.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import logsumexp

from gpfverify.errors import InputError
from gpfverify.linalg import symmetrize


def normalize_log_weights(log_weights: np.ndarray) -> np.ndarray:
    """ℓ − logsumexp(ℓ), so that Σ exp = 1. Raises InputError when every weight is zero."""
    log_weights = np.asarray(log_weights, dtype=float)
    total = logsumexp(log_weights)
    if not np.isfinite(total):
        raise InputError("log_weights: every particle has zero (or NaN/inf) weight")
    return log_weights - total


def effective_sample_size(log_weights: np.ndarray) -> float:
    """N_eff = 1 / Σ w_i² of the normalised weights."""
    w = np.exp(normalize_log_weights(log_weights))
    return float(1.0 / np.sum(w * w))


def systematic_resample(log_weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Indices (N,) of the systematic resample of N particles with these (log) weights."""
    w = np.exp(normalize_log_weights(log_weights))
    n = w.size
    positions = (rng.uniform() + np.arange(n)) / n
    cumulative = np.cumsum(w)
    cumulative[-1] = 1.0  # rounding must not leave the last position without a particle
    return np.searchsorted(cumulative, positions, side="right")


def needs_resampling(log_weights: np.ndarray, threshold: float) -> bool:
    """True when N_eff < threshold · N; ``threshold ≥ 1`` means every step (the SIR filter)."""
    return threshold >= 1.0 or effective_sample_size(log_weights) < threshold * np.size(log_weights)


def weighted_moments(particles: np.ndarray, log_weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean (D,) and covariance (D, D) = Σ w_i (x_i − x̄)(x_i − x̄)ᵀ of particles (N, D)."""
    w = np.exp(normalize_log_weights(log_weights))
    mean = w @ particles
    dev = particles - mean
    return mean, symmetrize((dev * w[:, None]).T @ dev)


@dataclass(frozen=True)
class ParticleSet:
    """Weighted particles: particles (N, D), log_weights (N,) (not necessarily normalised)."""

    particles: np.ndarray
    log_weights: np.ndarray

    @classmethod
    def equally_weighted(cls, particles: np.ndarray) -> "ParticleSet":
        particles = np.asarray(particles, dtype=float)
        return cls(particles, np.full(particles.shape[0], -np.log(particles.shape[0])))

    @property
    def size(self) -> int:
        return self.particles.shape[0]

    def moments(self) -> tuple[np.ndarray, np.ndarray]:
        return weighted_moments(self.particles, self.log_weights)

    def effective_sample_size(self) -> float:
        return effective_sample_size(self.log_weights)


@dataclass(frozen=True)
class ParticleStepInfo:
    """Posterior estimate of one particle-filter step: mean (D,), cov (D, D), the effective sample
    size before resampling and whether the step resampled."""

    mean: np.ndarray
    cov: np.ndarray
    ess: float
    resampled: bool


def reweight_and_resample(particles: np.ndarray, log_weights: np.ndarray, rng: np.random.Generator,
                          resample_threshold: float, *carried: np.ndarray):
    """Normalise the weights, take the weighted estimate, resample (with any per-particle arrays in
    ``carried``) when :func:`needs_resampling`. Returns (particles, log_weights, carried, info)."""
    log_weights = normalize_log_weights(log_weights)
    mean, cov = weighted_moments(particles, log_weights)
    ess = effective_sample_size(log_weights)
    resample = needs_resampling(log_weights, resample_threshold)
    if resample:
        idx = systematic_resample(log_weights, rng)
        particles = particles[idx]
        carried = tuple(a[idx] for a in carried)
        log_weights = np.full(particles.shape[0], -np.log(particles.shape[0]))
    return particles, log_weights, carried, ParticleStepInfo(mean, cov, ess, resample)
