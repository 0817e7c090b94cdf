"""Unscented particle filter (van der Merwe, Doucet, de Freitas & Wan 2000; seed 001 §1.3) with a
pluggable proposal, so that GPSR-UPF can reuse it with a square-root UKF built on a learned model.

Each particle i carries a state x^i, a log weight and the lower Cholesky factor S^i of its own
Gaussian filter's covariance. One step:

    (m^i, S'^i) = proposal(x^i_{k−1}, S^i_{k−1}, model, y_k, k)      (e.g. one UKF step per particle)
    x^i_k = m^i + S'^i ε^i,  ε^i ~ N(0, I)                            (draw from q = N(m^i, S'^i S'^iᵀ))
    w^i_k ∝ w^i_{k−1} p(y_k | x^i_k) p(x^i_k | x^i_{k−1}) / q(x^i_k)   (seed 001 eq. for the UPF weights)
    systematic resampling (of x, S together) when N_eff < threshold · N.

The transition density comes from the model (:func:`~gpfverify.filters.likelihoods.transition_logpdf`),
so non-Gaussian process noise (the gamma benchmark) is weighted exactly while the proposal uses its
Gaussian approximation (``model.f`` and ``model.Q``).

A *proposal* is any ``proposal(particles (N, D), sqrt_covs (N, D, D), model, y (L,), k) ->
(means (N, D), sqrt_covs (N, D, D))`` with lower-triangular factors of positive diagonal.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from gpfverify.filters.likelihoods import LOG_2PI, measurement_loglik, transition_logpdf
from gpfverify.filters.models import NonlinearModel
from gpfverify.filters.records import Gaussian
from gpfverify.filters.resampling import ParticleStepInfo, reweight_and_resample, weighted_moments
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.filters.ukf import ukf_step
from gpfverify.linalg import cholesky_batched
from gpfverify.linalg import cholesky
from gpfverify.validate import as_matrix, as_vector

Proposal = Callable[[np.ndarray, np.ndarray, NonlinearModel, np.ndarray, int],
                    tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class ParticleCloud:
    """UPF particles: particles (N, D), log_weights (N,), sqrt_covs (N, D, D) lower Cholesky factors
    of each particle's filter covariance."""

    particles: np.ndarray
    log_weights: np.ndarray
    sqrt_covs: np.ndarray

    @classmethod
    def from_gaussian(cls, mean: np.ndarray, cov: np.ndarray, count: int,
                      rng: np.random.Generator) -> "ParticleCloud":
        """``count`` equally weighted draws from N(mean, cov), each carrying the factor of ``cov``."""
        factor = cholesky(cov, "prior covariance").factor
        mean = np.asarray(mean, dtype=float)
        particles = mean + rng.standard_normal((count, mean.size)) @ factor.T
        return cls(particles, np.full(count, -np.log(count)),
                   np.broadcast_to(factor, (count,) + factor.shape).copy())

    def moments(self) -> tuple[np.ndarray, np.ndarray]:
        return weighted_moments(self.particles, self.log_weights)


def ukf_proposal(particles: np.ndarray, sqrt_covs: np.ndarray, model: NonlinearModel, y: np.ndarray,
                 k: int, params: SigmaParams = SigmaParams()) -> tuple[np.ndarray, np.ndarray]:
    """One UKF step per particle from N(x^i, S^i S^iᵀ) with measurement y: the posterior means and
    Cholesky factors (van der Merwe et al. 2000, Alg. UPF step 2)."""
    covs = sqrt_covs @ np.swapaxes(sqrt_covs, -1, -2)
    record = ukf_step(Gaussian(particles, covs), model, y, k, params)
    return record.mu_e, cholesky_batched(record.C_e, "UKF proposal covariance")


def gaussian_proposal_logpdf(white: np.ndarray, sqrt_covs: np.ndarray) -> np.ndarray:
    """log N(m + S ε; m, S Sᵀ) = −½|ε|² − Σ log S_jj − (D/2) log 2π, per particle."""
    log_diag = np.log(np.abs(np.diagonal(sqrt_covs, axis1=-2, axis2=-1)))
    return -0.5 * np.sum(white * white, axis=-1) - log_diag.sum(axis=-1) - 0.5 * white.shape[-1] * LOG_2PI


def upf_step(cloud: ParticleCloud, model: NonlinearModel, y: np.ndarray, k: int, rng: np.random.Generator,
             proposal: Proposal = ukf_proposal,
             resample_threshold: float = 0.5) -> tuple[ParticleCloud, ParticleStepInfo]:
    """One UPF step with measurement y (L,) at time k; the info carries the weighted posterior
    estimate taken before resampling."""
    y = as_vector(y, "y", model.measurement_dim)
    as_matrix(cloud.particles, "cloud.particles", None, model.state_dim)
    means, factors = proposal(cloud.particles, cloud.sqrt_covs, model, y, k)
    white = rng.standard_normal(means.shape)
    x = means + np.einsum("nij,nj->ni", factors, white)
    log_w = (cloud.log_weights + measurement_loglik(model, y, x, k)
             + transition_logpdf(model, x, cloud.particles, k) - gaussian_proposal_logpdf(white, factors))
    x, log_w, (factors,), info = reweight_and_resample(x, log_w, rng, resample_threshold, factors)
    return ParticleCloud(x, log_w, factors), info
