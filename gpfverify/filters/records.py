"""Typed records shared by every Gaussian filter and by fusion.

A filter step is a pure function ``step(belief, model, y) -> StepRecord``; the record carries the
whole prediction/update so that fusion and audits can use it (seed 000 eq. 15–19, 30–31).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


# Gaussian and StepRecord are built at every filter step. A frozen dataclass's generated __init__
# sets each field through object.__setattr__ (about 1 µs for StepRecord's eight on a Xeon, a tenth of
# a Kalman step); theirs fill __dict__ in one call. Frozen as before: assignment still raises.


@dataclass(frozen=True, init=False)
class Gaussian:
    """N(mean, cov): mean (D,), cov (D, D)."""

    mean: np.ndarray
    cov: np.ndarray

    def __init__(self, mean: np.ndarray, cov: np.ndarray):
        self.__dict__.update(mean=mean, cov=cov)


@dataclass(frozen=True, init=False)
class StepRecord:
    """One predict–update cycle of a Gaussian filter.

    mu_p (D,), C_p (D, D): predicted state; mu_y (L,), C_y (L, L): predicted measurement
    (noise included); C_xy (D, L): state–measurement cross covariance; mu_e (D,), C_e (D, D):
    posterior, μ_e = μ_p + C_xy C_y⁻¹ (y − μ_y), C_e = C_p − C_xy C_y⁻¹ C_xyᵀ.
    ``jitter`` is the largest diagonal jitter any factorisation in the step needed (0 if none).
    """

    mu_p: np.ndarray
    C_p: np.ndarray
    mu_y: np.ndarray
    C_y: np.ndarray
    C_xy: np.ndarray
    mu_e: np.ndarray
    C_e: np.ndarray
    jitter: float = 0.0

    def __init__(self, mu_p: np.ndarray, C_p: np.ndarray, mu_y: np.ndarray, C_y: np.ndarray, C_xy: np.ndarray,
                 mu_e: np.ndarray, C_e: np.ndarray, jitter: float = 0.0):
        self.__dict__.update(mu_p=mu_p, C_p=C_p, mu_y=mu_y, C_y=C_y, C_xy=C_xy, mu_e=mu_e, C_e=C_e, jitter=jitter)

    @property
    def posterior(self) -> Gaussian:
        return Gaussian(self.mu_e, self.C_e)

    @property
    def prediction(self) -> Gaussian:
        return Gaussian(self.mu_p, self.C_p)


@dataclass(frozen=True)
class MeasurementMoments:
    """Predicted measurement of a Gaussian filter, before the measurement is seen: mu_y (L,),
    C_y (L, L) noise included, C_xy (D, L) = Cov[x_k, y_k | y_1:k−1] (seed 000 eq. 17).
    Leading batch axes are allowed on every field."""

    mu_y: np.ndarray
    C_y: np.ndarray
    C_xy: np.ndarray
