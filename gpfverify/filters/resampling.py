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
from typing import cast

import numpy as np

from gpfverify.angles import difference, wrap
from gpfverify.errors import InputError
from gpfverify.filters import runs
from gpfverify.filters.runs import Streams
from gpfverify.linalg import cholesky, symmetrize

#: Default resampling rule of every filter: resample when N_eff < RESAMPLE_THRESHOLD · N
#: (a threshold ≥ 1 resamples at every step, the SIR filter).
RESAMPLE_THRESHOLD: float = 0.5


def log_sum_exp(values: np.ndarray) -> float | np.ndarray:
    """LSE(a) = log Σ_i exp a_i over the last axis (a float for a 1-D array, one value per run for
    (B, N)), shifted by the largest value a_max:

        LSE(a) = a_max + log1p(Σ_{i ∉ M} exp(a_i − a_max) / |M|) + log |M|,   M = {i : a_i = a_max},

    the accurate form of Blanchard, Higham & Higham (IMA J. Numer. Anal. 41, 2021, Alg. 2, the
    maximal terms kept out of the sum) — numerically the same as ``scipy.special.logsumexp``
    without its array-API overhead, which dominates at particle-filter sizes. −inf when every
    value is −inf; non-finite (inf or NaN) when a value is."""
    a = np.asarray(values, dtype=float)
    a_max = a.max(axis=-1)
    finite = np.isfinite(a_max)
    if a.ndim == 1 and not finite:
        return float(a_max)
    scaled = np.exp(a - np.where(finite, a_max, 0.0)[..., None])
    top = a == a_max[..., None]
    count = np.maximum(np.count_nonzero(top, axis=-1), 1)
    scaled[top] = 0.0
    with np.errstate(invalid="ignore"):
        total = np.where(finite, np.log1p(scaled.sum(axis=-1) / count) + np.log(count) + a_max, a_max)
    return float(total) if a.ndim == 1 else total


def normalize_log_weights(log_weights: np.ndarray) -> np.ndarray:
    """ℓ − LSE(ℓ) over the last axis, so that Σ exp = 1. Raises InputError when every weight of a
    run is zero (or one is NaN/inf)."""
    log_weights = np.asarray(log_weights, dtype=float)
    total = log_sum_exp(log_weights)
    if not np.all(np.isfinite(total)):
        raise InputError("log_weights: every particle has zero (or NaN/inf) weight")
    return log_weights - np.asarray(total)[..., None]


def normalize_runs(log_weights: np.ndarray) -> np.ndarray:
    """:func:`normalize_log_weights` of one run (raising as there), or of each run of (B, N) with
    NaN for a run whose weights are all zero (or NaN/inf): the other runs go on."""
    if log_weights.ndim == 1:
        return normalize_log_weights(log_weights)
    total = log_sum_exp(log_weights)
    return log_weights - np.where(np.isfinite(total), total, np.nan)[:, None]


def effective_sample_size(log_weights: np.ndarray) -> float | np.ndarray:
    """N_eff = 1 / Σ w_i² of the normalised weights (per run over the last axis)."""
    return ess_from_weights(np.exp(normalize_log_weights(log_weights)))


def ess_from_weights(weights: np.ndarray) -> float | np.ndarray:
    """N_eff = 1 / Σ w_i² of weights already normalised (Σ w_i = 1), per run over the last axis."""
    ess = 1.0 / np.sum(weights * weights, axis=-1)
    return float(ess) if np.ndim(ess) == 0 else ess


def systematic_resample(log_weights: np.ndarray, rng: Streams, size: int | None = None) -> np.ndarray:
    """Indices (n,) of the systematic resample of M particles with these (log) weights to
    n = ``size`` draws (default n = M), or (B, n) for the weights (B, M) of B runs with one
    Generator per run. Two guards against rounding: the last cumulative weight is set to 1 (no
    position falls past it) and the indices are clipped to M − 1."""
    return resample_from_weights(np.exp(normalize_log_weights(log_weights)), rng, size)


def resample_from_weights(w: np.ndarray, rng: Streams, size: int | None = None) -> np.ndarray:
    """:func:`systematic_resample` from normalised weights w (M,) or (B, M) (Σ w = 1) already
    formed: one uniform u per run, positions (u + j)/n, j = 0 … n−1."""
    count = w.shape[-1]
    n = count if size is None else int(size)
    if n < 1:
        raise InputError(f"size must be at least 1, got {size}")
    u = runs.uniform(rng)
    positions = (np.asarray(u)[..., None] + np.arange(n)) / n
    cumulative = np.cumsum(w, axis=-1)
    cumulative[..., -1] = 1.0
    return np.minimum(search_runs(cumulative, positions), count - 1)


def search_runs(cumulative: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``np.searchsorted(cumulative, values, side="right")`` of one run (1-D), or of each run's row
    of (B, M) and (B, n): numpy searches one sorted array per call, so one call per run."""
    rows = zip(cumulative.reshape(-1, cumulative.shape[-1]), values.reshape(-1, values.shape[-1]))
    return np.array([np.searchsorted(c, v, side="right") for c, v in rows], dtype=np.intp).reshape(values.shape)


def needs_resampling(log_weights: np.ndarray, threshold: float) -> bool:
    """True when N_eff < threshold · N; ``threshold ≥ 1`` means every step (the SIR filter)."""
    return bool(threshold >= 1.0 or effective_sample_size(log_weights) < threshold * np.size(log_weights))


def weighted_sum(weights: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Σ_i w_i v_i for weights (..., N) and values (..., N, E): (..., E), one BLAS product per run."""
    return (weights[..., None, :] @ values)[..., 0, :]


def moments_from_weights(particles: np.ndarray, weights: np.ndarray,
                         circular_state: Sequence[int] = ()) -> tuple[np.ndarray, np.ndarray]:
    """Mean x̄ = Σ w_i x_i (..., D) and covariance Σ w_i (x_i − x̄)(x_i − x̄)ᵀ (..., D, D) of particles
    (..., N, D) with normalised weights (..., N) (leading axes: runs); the angle components
    ``circular_state`` are averaged on the circle relative to the first particle (as
    :func:`gpfverify.angles.weighted_mean`, wrapped to (−π, π]) and their deviations x_i − x̄
    wrapped."""
    mean = weighted_sum(weights, particles)
    if len(circular_state):
        idx = list(circular_state)
        reference = particles[..., 0, idx]
        turns = wrap(particles[..., idx] - reference[..., None, :])
        mean[..., idx] = wrap(reference + weighted_sum(weights, turns))
    dev = difference(particles, mean[..., None, :], circular_state)
    return mean, symmetrize(np.swapaxes(dev * weights[..., None], -1, -2) @ dev)


def weighted_moments(particles: np.ndarray, log_weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`moments_from_weights` with the weights given as (unnormalised) logarithms."""
    return moments_from_weights(particles, np.exp(normalize_log_weights(log_weights)))


def equal_log_weights(count: int, runs: tuple[int, ...] = ()) -> np.ndarray:
    """ℓ_i = −log N for N = ``count`` particles, (N,) or (*runs, N)."""
    return np.full((*runs, count), -np.log(count))


@dataclass(frozen=True)
class Particles:
    """The belief of every particle filter: particles (N, D) and log_weights (N,) (not necessarily
    normalised) of one run, or (B, N, D) and (B, N) of B runs (:mod:`gpfverify.filters.runs`),
    with optional per-filter extras (``None`` when a filter does not carry them; with the run
    axis first when there is one):

    * ``sqrt_covs`` (N, D, D): lower Cholesky factors of each particle's own Gaussian filter
      covariance (UPF, GPSR-UPF);
    * ``ekf_cov`` (D, D): the covariance of the parallel EKF that the EDH flow carries;
    * ``existence``: the probability P_k that a target exists (PF-TBD, TPFTBD), the particles
      being the state given existence (a float, or (B,)).
    """

    particles: np.ndarray
    log_weights: np.ndarray
    sqrt_covs: np.ndarray | None = None
    ekf_cov: np.ndarray | None = None
    existence: float | np.ndarray | None = None

    @classmethod
    def equally_weighted(cls, particles: np.ndarray, **extras) -> Particles:
        """Particles (N, D) or (B, N, D) with weights 1/N; ``extras`` are the optional fields."""
        particles = np.asarray(particles, dtype=float)
        return cls(particles, equal_log_weights(particles.shape[-2], particles.shape[:-2]), **extras)

    @classmethod
    def from_gaussian(cls, mean: np.ndarray, cov: np.ndarray, count: int, rng: Streams) -> Particles:
        """``count`` equally weighted draws x_i = μ + L ε_i (L the Cholesky factor of ``cov``,
        ε_i ~ N(0, I)), each carrying the factor L as its ``sqrt_covs`` (the UPF's initial set);
        one set per run when ``rng`` is a sequence of Generators."""
        factor = cholesky(cov, "prior covariance").factor
        mean = np.asarray(mean, dtype=float)
        particles = mean + runs.normal(rng, (count, mean.size)) @ factor.T
        return cls(particles, equal_log_weights(count, particles.shape[:-2]),
                   np.broadcast_to(factor, particles.shape[:-1] + factor.shape).copy())

    @property
    def size(self) -> int:
        """Particles per run, N."""
        return self.particles.shape[-2]

    def moments(self) -> tuple[np.ndarray, np.ndarray]:
        """Weighted mean (..., D) and covariance (..., D, D)."""
        return weighted_moments(self.particles, self.log_weights)

    def effective_sample_size(self) -> float | np.ndarray:
        return effective_sample_size(self.log_weights)


@dataclass(frozen=True)
class ParticleStep:
    """One particle-filter step: ``posterior`` (the next belief, after any resampling),
    ``weighted`` (the weighted set the estimate is taken from, before resampling; normalised
    log weights), the estimate ``mean`` (D,) and ``cov`` (D, D), the effective sample size of the
    weighted set and whether the step resampled (for B runs: (B, D), (B, D, D), (B,) and (B,))."""

    posterior: Particles
    weighted: Particles
    mean: np.ndarray
    cov: np.ndarray
    ess: float | np.ndarray
    resampled: bool | np.ndarray


def take_particles(values: np.ndarray, index: np.ndarray) -> np.ndarray:
    """values[b, index[b]] per run: values (B, M, *E) at indices (B, n) -> (B, n, *E), as one
    gather from the runs' rows laid end to end."""
    runs, count = values.shape[:2]
    rows = index + (np.arange(runs) * count)[:, None]
    return values.reshape((runs * count,) + values.shape[2:])[rows]


def reweight_and_resample(particles: np.ndarray, log_weights: np.ndarray, rng: Streams,
                          resample_threshold: float, sqrt_covs: np.ndarray | None = None,
                          circular_state: Sequence[int] = ()) -> ParticleStep:
    """Normalise the weights, take the weighted estimate (angle components ``circular_state`` on
    the circle), resample (the particles with their ``sqrt_covs``) when :func:`needs_resampling`;
    the estimate is taken before resampling (which only adds noise). For B runs (particles
    (B, N, D), one Generator per run) each run decides and draws for itself; a run whose weights
    are all zero gets NaN (one run alone raises InputError)."""
    if particles.ndim == 2:  # one run: a batch of one, whose weights must not all vanish
        if not np.isfinite(log_sum_exp(log_weights)):
            raise InputError("log_weights: every particle has zero (or NaN/inf) weight")
        step = reweight_and_resample(particles[None], log_weights[None], [cast(np.random.Generator, rng)],
                                     resample_threshold, None if sqrt_covs is None else sqrt_covs[None],
                                     circular_state)
        return first_run(step)
    log_weights = normalize_runs(log_weights)
    weighted = Particles(particles, log_weights, sqrt_covs)
    w = np.exp(log_weights)  # formed once for the estimate, N_eff and the resample
    mean, cov = moments_from_weights(particles, w, circular_state)
    ess = 1.0 / np.sum(w * w, axis=-1)
    resample = (resample_threshold >= 1.0) | (ess < resample_threshold * w.shape[-1])
    posterior = weighted
    rows = np.flatnonzero(resample & np.isfinite(ess))  # a failed run draws nothing more
    if rows.size:
        idx = resample_from_weights(w[rows], runs.subset(rng, rows))
        new_x, new_lw = particles.copy(), log_weights.copy()
        new_x[rows] = take_particles(particles[rows], idx)
        new_lw[rows] = equal_log_weights(particles.shape[-2])
        new_s = None
        if sqrt_covs is not None:
            new_s = sqrt_covs.copy()
            new_s[rows] = take_particles(sqrt_covs[rows], idx)
        posterior = Particles(new_x, new_lw, new_s)
    return ParticleStep(posterior, weighted, mean, cov, ess, resample)


def first_run(step: ParticleStep) -> ParticleStep:
    """The step of the first run of a batch, as a one-run step (fields without the run axis, N_eff a
    float, ``resampled`` a bool)."""
    def strip(belief: Particles) -> Particles:
        return Particles(belief.particles[0], belief.log_weights[0],
                         None if belief.sqrt_covs is None else belief.sqrt_covs[0],
                         None if belief.ekf_cov is None else belief.ekf_cov[0],
                         None if belief.existence is None else float(np.asarray(belief.existence)[0]))
    weighted = strip(step.weighted)
    posterior = weighted if step.posterior is step.weighted else strip(step.posterior)
    return ParticleStep(posterior, weighted, step.mean[0], step.cov[0], float(np.asarray(step.ess)[0]),
                        bool(np.asarray(step.resampled)[0]))
