"""Unscented particle filter (van der Merwe, Doucet, de Freitas & Wan 2000; seed 001 §1.3) with a
pluggable proposal, so that GPSR-UPF can reuse it with a square-root UKF built on a learned model.

Each particle i carries a state x^i, a log weight and the lower Cholesky factor S^i of its own
Gaussian filter's covariance (``Particles.sqrt_covs``). One step:

    (m^i, S'^i) = proposal(x^i_{k−1}, S^i_{k−1}, model, y_k, k)      (e.g. one UKF step per particle)
    x^i_k = m^i + S'^i ε^i,  ε^i ~ N(0, I)                            (draw from q = N(m^i, S'^i S'^iᵀ))
    w^i_k ∝ w^i_{k−1} p(y_k | x^i_k) p(x^i_k | x^i_{k−1}) / q(x^i_k)   (seed 001 eq. for the UPF weights)
    log q(x^i_k) = −½ |ε^i|² − Σ_j log S'^i_jj − (D/2) log 2π
    systematic resampling (of x, S together) when N_eff < threshold · N.

The transition density comes from the model (:func:`~gpfverify.filters.likelihoods.transition_logpdf`),
so non-Gaussian process noise (the gamma benchmark) is weighted exactly while the proposal uses its
Gaussian approximation (``model.f`` and ``model.Q``). Angle outputs are handled by the proposal's
UKF (wrapped innovation, circular sigma-point means) and by the wrapped residual of the likelihood.

A *proposal* is any ``proposal(belief: Particles, model, y (L,), *, k) -> (means (N, D),
sqrt_covs (N, D, D))`` with lower-triangular factors of positive diagonal.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from gpfverify.errors import InputError
from gpfverify.filters import runs
from gpfverify.filters.likelihoods import measurement_loglik, transition_logpdf, whitened_gaussian_logpdf
from gpfverify.filters.records import Gaussian
from gpfverify.filters.resampling import RESAMPLE_THRESHOLD, Particles, ParticleStep, reweight_and_resample
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.filters.ukf import ukf_step
from gpfverify.linalg import cholesky_batched
from gpfverify.models.system import StateSpaceModel, require_model

Proposal = Callable[..., tuple[np.ndarray, np.ndarray]]


def ukf_proposal(belief: Particles, model, y: np.ndarray, *, k: int = 1,
                 params: SigmaParams = SigmaParams()) -> tuple[np.ndarray, np.ndarray]:
    """One UKF step per particle from N(x^i, S^i S^iᵀ) with measurement y: the posterior means and
    Cholesky factors (van der Merwe et al. 2000, Alg. UPF step 2); every particle of B runs at
    once for particles (B, N, D) and y (B, L)."""
    if belief.sqrt_covs is None:
        raise InputError("belief.sqrt_covs: the UKF proposal needs each particle's covariance factor "
                         "(Particles.from_gaussian gives the prior's)")
    covs = belief.sqrt_covs @ np.swapaxes(belief.sqrt_covs, -1, -2)
    record = ukf_step(Gaussian(belief.particles, covs), model, y[..., None, :], k=k, params=params)
    return record.mu_e, cholesky_batched(record.C_e, "UKF proposal covariance")


def proposal_logpdf(white: np.ndarray, sqrt_covs: np.ndarray) -> np.ndarray:
    """log N(m + S ε; m, S Sᵀ) per particle, from ε (N, D) and S (N, D, D): log|S Sᵀ| = 2 Σ log |S_jj|."""
    log_diag = np.log(np.abs(np.diagonal(sqrt_covs, axis1=-2, axis2=-1)))
    return whitened_gaussian_logpdf(white, 2.0 * log_diag.sum(axis=-1))


def upf_step(belief: Particles, model, y: np.ndarray, *, k: int = 1, rng: runs.Streams,
             proposal: Proposal = ukf_proposal, resample_threshold: float = RESAMPLE_THRESHOLD) -> ParticleStep:
    """One UPF step with measurement y (L,) at time k; the record carries the weighted posterior
    estimate taken before resampling. For B runs: particles (B, N, D) with their factors
    (B, N, D, D), y (B, L) and one Generator per run."""
    require_model(model, StateSpaceModel, "the UPF")
    x_prev, y = runs.particle_inputs(belief.particles, y, model, rng)
    if belief.sqrt_covs is None:
        raise InputError("belief.sqrt_covs: the UPF needs each particle's covariance factor "
                         "(e.g. Particles.from_gaussian)")
    means, factors = proposal(belief, model, y, k=k)
    white = runs.normal(rng, means.shape[-2:])
    x = means + np.einsum("...ij,...j->...i", factors, white)
    log_w = (belief.log_weights + measurement_loglik(model, y, x, k)
             + transition_logpdf(model, x, x_prev, k) - proposal_logpdf(white, factors))
    return reweight_and_resample(x, log_w, rng, resample_threshold, factors, model.circular_state)
