"""Bootstrap sampling-importance-resampling particle filter (Gordon, Salmond & Smith 1993).

One step, particles {x_{k−1}^i, w_{k−1}^i}:

    x_k^i ~ p(x_k | x_{k−1}^i)                 (prior as proposal)
    w_k^i ∝ w_{k−1}^i p(y_k | x_k^i)           (seed 003 eq. 7 with q = p(x_k | x_{k−1}))
    x̂_k = Σ w_k^i x_k^i, P̂_k = Σ w_k^i (x_k^i − x̂_k)(x_k^i − x̂_k)ᵀ
    systematic resampling when N_eff < threshold · N (threshold ≥ 1: every step, the SIR filter).

Angle outputs of the measurement (``model.circular``) enter the likelihood through the wrapped
residual (:func:`~gpfverify.filters.likelihoods.measurement_loglik`); angle state components
(``model.circular_state``) of the estimate are weighted circular means. The estimate is taken from
the weighted particles *before* resampling (resampling only adds noise).
"""

from __future__ import annotations

import numpy as np

from gpfverify.filters import runs
from gpfverify.filters.likelihoods import measurement_loglik, sample_transition
from gpfverify.filters.resampling import RESAMPLE_THRESHOLD, Particles, ParticleStep, reweight_and_resample
from gpfverify.models.system import StateSpaceModel, require_model


def pf_step(belief: Particles, model, y: np.ndarray, *, k: int = 1, rng: runs.Streams,
            resample_threshold: float = RESAMPLE_THRESHOLD) -> ParticleStep:
    """One bootstrap-PF step from the particles at k−1 with measurement y (L,) at time k; for B runs
    (:mod:`~gpfverify.filters.runs`) particles (B, N, D), y (B, L) and one Generator per run."""
    require_model(model, StateSpaceModel, "the bootstrap PF")
    x_prev, y = runs.particle_inputs(belief.particles, y, model, rng)
    x = sample_transition(model, x_prev, k, rng)
    return reweight_and_resample(x, belief.log_weights + measurement_loglik(model, y, x, k), rng,
                                 resample_threshold, circular_state=model.circular_state)
