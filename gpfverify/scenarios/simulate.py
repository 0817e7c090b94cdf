"""Simulate a trajectory and its measurements from a :class:`~gpfverify.filters.models.NonlinearModel`."""

from __future__ import annotations

import numpy as np

from gpfverify.filters.likelihoods import sample_transition
from gpfverify.filters.models import NonlinearModel


def simulate(model: NonlinearModel, x0: np.ndarray, steps: int,
             rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """States x_1..x_T (T, D) from x_0 (D,) by the model's transition (its own sampler when it has
    non-Gaussian noise) and measurements y_k = h(x_k, k) + v_k, v_k ~ N(0, R), (T, L)."""
    x = np.asarray(x0, dtype=float)[None, :]
    states, measurements = [], []
    noise = rng.multivariate_normal(np.zeros(model.measurement_dim), model.R, size=steps, method="cholesky")
    for k in range(1, steps + 1):
        x = sample_transition(model, x, k, rng)
        states.append(x[0])
        measurements.append(model.h(x, k)[0] + noise[k - 1])
    return np.array(states), np.array(measurements)
