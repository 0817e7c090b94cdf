"""Weighted particles, effective sample size and systematic resampling — shared by every particle
filter (bootstrap PF, UPF, GPSR-UPF, the particle flows, PF-TBD and TPFTBD), and the one record a
particle-filter step returns.

Weights are kept as logarithms so that likelihoods far in the tails do not underflow:
w_i = exp(ℓ_i − LSE(ℓ)), LSE(ℓ) = log Σ_i exp ℓ_i (:func:`log_sum_exp`). The effective sample size
is N_eff = 1 / Σ w_i² (Kong, Liu & Wong 1994; seed 001's resampling rule "resample when
N_eff < N_T"). Systematic resampling (Kitagawa 1996; Carpenter, Clifford & Fearnhead 1999) of M
weighted particles to n draws takes one u ~ U[0, 1) and the indices of the positions (u + j)/n,
j = 0..n−1, in the cumulative weights: index i is drawn ⌊n w_i⌋ or ⌈n w_i⌉ times and
E[count_i] = n w_i.

Every particle-filter step has the signature ``step(belief: Particles, model, measurement, *, k,
rng, <parameters>) -> ParticleStep``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gpfverify.angles import difference, weighted_mean
from gpfverify.errors import InputError
from gpfverify.linalg import cholesky, symmetrize

#: Default resampling rule of every filter: resample when N_eff < RESAMPLE_THRESHOLD · N
#: (a threshold ≥ 1 resamples at every step, the SIR filter).
RESAMPLE_THRESHOLD: float = 0.5


def log_sum_exp(values: np.ndarray) -> float:
    """LSE(a) = log Σ_i exp a_i of a 1-D array, shifted by the largest value a_max:

        LSE(a) = a_max + log1p(Σ_{i ∉ M} exp(a_i − a_max) / |M|) + log |M|,   M = {i : a_i = a_max},

    the accurate form of Blanchard, Higham & Higham (IMA J. Numer. Anal. 41, 2021, Alg. 2, the
    maximal terms kept out of the sum) — numerically the same as ``scipy.special.logsumexp``
    without its array-API overhead, which dominates at particle-filter sizes. −inf when every
    value is −inf; non-finite (inf or NaN) when a value is."""
    a = np.asarray(values, dtype=float)
    a_max = a.max()
    if not np.isfinite(a_max):
        return float(a_max)
    scaled = np.exp(a - a_max)
    top = a == a_max
    count = np.count_nonzero(top)
    scaled[top] = 0.0
    return float(np.log1p(scaled.sum() / count) + np.log(count) + a_max)


def normalize_log_weights(log_weights: np.ndarray) -> np.ndarray:
    """ℓ − LSE(ℓ), so that Σ exp = 1. Raises InputError when every weight is zero (or one is NaN/inf)."""
    log_weights = np.asarray(log_weights, dtype=float)
    total = log_sum_exp(log_weights)
    if not np.isfinite(total):
        raise InputError("log_weights: every particle has zero (or NaN/inf) weight")
    return log_weights - total


def effective_sample_size(log_weights: np.ndarray) -> float:
    """N_eff = 1 / Σ w_i² of the normalised weights."""
    return ess_from_weights(np.exp(normalize_log_weights(log_weights)))


def ess_from_weights(weights: np.ndarray) -> float:
    """N_eff = 1 / Σ w_i² of weights already normalised (Σ w_i = 1)."""
    return float(1.0 / np.sum(weights * weights))


def systematic_resample(log_weights: np.ndarray, rng: np.random.Generator, size: int | None = None) -> np.ndarray:
    """Indices (n,) of the systematic resample of M particles with these (log) weights to
    n = ``size`` draws (default n = M). Two guards against rounding: the last cumulative weight
    is set to 1 (no position falls past it) and the indices are clipped to M − 1."""
    return resample_from_weights(np.exp(normalize_log_weights(log_weights)), rng, size)


def resample_from_weights(w: np.ndarray, rng: np.random.Generator, size: int | None = None) -> np.ndarray:
    """:func:`systematic_resample` from normalised weights w (M,) (Σ w = 1) already formed."""
    n = w.size if size is None else int(size)
    if n < 1:
        raise InputError(f"size must be at least 1, got {size}")
    positions = (rng.uniform() + np.arange(n)) / n
    cumulative = np.cumsum(w)
    cumulative[-1] = 1.0
    return np.minimum(np.searchsorted(cumulative, positions, side="right"), w.size - 1)


def needs_resampling(log_weights: np.ndarray, threshold: float) -> bool:
    """True when N_eff < threshold · N; ``threshold ≥ 1`` means every step (the SIR filter)."""
    return threshold >= 1.0 or effective_sample_size(log_weights) < threshold * np.size(log_weights)


def moments_from_weights(particles: np.ndarray, weights: np.ndarray,
                         circular_state: Sequence[int] = ()) -> tuple[np.ndarray, np.ndarray]:
    """Mean x̄ = Σ w_i x_i (D,) and covariance Σ w_i (x_i − x̄)(x_i − x̄)ᵀ (D, D) of particles
    (N, D) with normalised weights (N,); the angle components ``circular_state`` are averaged on
    the circle (:func:`gpfverify.angles.weighted_mean`, wrapped to (−π, π]) and their deviations
    x_i − x̄ wrapped."""
    if not len(circular_state):
        mean = weights @ particles
        dev = particles - mean
    else:
        mean = weighted_mean(particles, weights, circular_state)
        dev = difference(particles, mean, circular_state)
    return mean, symmetrize((dev * weights[:, None]).T @ dev)


def weighted_moments(particles: np.ndarray, log_weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`moments_from_weights` with the weights given as (unnormalised) logarithms."""
    return moments_from_weights(particles, np.exp(normalize_log_weights(log_weights)))


def equal_log_weights(count: int) -> np.ndarray:
    """ℓ_i = −log N for N = ``count`` particles."""
    return np.full(count, -np.log(count))


@dataclass(frozen=True)
class Particles:
    """The belief of every particle filter: particles (N, D) and log_weights (N,) (not necessarily
    normalised), with optional per-filter extras (``None`` when a filter does not carry them):

    * ``sqrt_covs`` (N, D, D): lower Cholesky factors of each particle's own Gaussian filter
      covariance (UPF, GPSR-UPF);
    * ``ekf_cov`` (D, D): the covariance of the parallel EKF that the EDH flow carries;
    * ``existence``: the probability P_k that a target exists (PF-TBD, TPFTBD), the particles
      being the state given existence.
    """

    particles: np.ndarray
    log_weights: np.ndarray
    sqrt_covs: np.ndarray | None = None
    ekf_cov: np.ndarray | None = None
    existence: float | None = None

    @classmethod
    def equally_weighted(cls, particles: np.ndarray, **extras) -> Particles:
        """Particles (N, D) with weights 1/N; ``extras`` are the optional fields."""
        particles = np.asarray(particles, dtype=float)
        return cls(particles, equal_log_weights(particles.shape[0]), **extras)

    @classmethod
    def from_gaussian(cls, mean: np.ndarray, cov: np.ndarray, count: int,
                      rng: np.random.Generator) -> Particles:
        """``count`` equally weighted draws x_i = μ + L ε_i (L the Cholesky factor of ``cov``,
        ε_i ~ N(0, I)), each carrying the factor L as its ``sqrt_covs`` (the UPF's initial set)."""
        factor = cholesky(cov, "prior covariance").factor
        mean = np.asarray(mean, dtype=float)
        particles = mean + rng.standard_normal((count, mean.size)) @ factor.T
        return cls(particles, equal_log_weights(count), np.broadcast_to(factor, (count,) + factor.shape).copy())

    @property
    def size(self) -> int:
        return self.particles.shape[0]

    def moments(self) -> tuple[np.ndarray, np.ndarray]:
        """Weighted mean (D,) and covariance (D, D)."""
        return weighted_moments(self.particles, self.log_weights)

    def effective_sample_size(self) -> float:
        return effective_sample_size(self.log_weights)


@dataclass(frozen=True)
class ParticleStep:
    """One particle-filter step: ``posterior`` (the next belief, after any resampling),
    ``weighted`` (the weighted set the estimate is taken from, before resampling; normalised
    log weights), the estimate ``mean`` (D,) and ``cov`` (D, D), the effective sample size of the
    weighted set and whether the step resampled."""

    posterior: Particles
    weighted: Particles
    mean: np.ndarray
    cov: np.ndarray
    ess: float
    resampled: bool


def reweight_and_resample(particles: np.ndarray, log_weights: np.ndarray, rng: np.random.Generator,
                          resample_threshold: float, sqrt_covs: np.ndarray | None = None,
                          circular_state: Sequence[int] = ()) -> ParticleStep:
    """Normalise the weights, take the weighted estimate (angle components ``circular_state`` on
    the circle), resample (the particles with their ``sqrt_covs``) when :func:`needs_resampling`;
    the estimate is taken before resampling (which only adds noise)."""
    log_weights = normalize_log_weights(log_weights)
    weighted = Particles(particles, log_weights, sqrt_covs)
    w = np.exp(log_weights)  # formed once for the estimate, N_eff and the resample
    mean, cov = moments_from_weights(particles, w, circular_state)
    ess = float(1.0 / np.sum(w * w))
    resample = resample_threshold >= 1.0 or ess < resample_threshold * w.size
    posterior = weighted
    if resample:
        idx = resample_from_weights(w, rng)
        posterior = Particles(particles[idx], equal_log_weights(particles.shape[0]),
                              None if sqrt_covs is None else sqrt_covs[idx])
    return ParticleStep(posterior, weighted, mean, cov, ess, resample)
