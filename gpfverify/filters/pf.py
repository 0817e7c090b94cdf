"""Bootstrap sampling-importance-resampling particle filter (Gordon, Salmond & Smith 1993).

One step, particles {x_{k−1}^i, w_{k−1}^i}:

    x_k^i ~ p(x_k | x_{k−1}^i)                 (prior as proposal)
    w_k^i ∝ w_{k−1}^i p(y_k | x_k^i)           (seed 003 eq. 7 with q = p(x_k | x_{k−1}))
    x̂_k = Σ w_k^i x_k^i, P̂_k = Σ w_k^i (x_k^i − x̂_k)(x_k^i − x̂_k)ᵀ
    systematic resampling when N_eff < threshold · N (threshold ≥ 1: every step, the SIR filter).

The estimate is taken from the weighted particles *before* resampling (resampling only adds noise).
"""

from __future__ import annotations

import numpy as np

from gpfverify.filters.likelihoods import measurement_loglik, sample_transition
from gpfverify.filters.models import NonlinearModel
from gpfverify.filters.resampling import ParticleSet, ParticleStepInfo, reweight_and_resample
from gpfverify.validate import as_matrix, as_vector


def pf_step(belief: ParticleSet, model: NonlinearModel, y: np.ndarray, k: int,
            rng: np.random.Generator, resample_threshold: float = 1.0) -> tuple[ParticleSet, ParticleStepInfo]:
    """One bootstrap-PF step from the particles at k−1 with measurement y (L,) at time k."""
    y = as_vector(y, "y", model.measurement_dim)
    x = sample_transition(model, as_matrix(belief.particles, "belief.particles", None, model.state_dim), k, rng)
    log_w = belief.log_weights + measurement_loglik(model, y, x, k)
    x, log_w, _, info = reweight_and_resample(x, log_w, rng, resample_threshold)
    return ParticleSet(x, log_w), info
