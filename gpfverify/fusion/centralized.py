"""Centralized measurement fusion (CMF) on plain arrays (seed 000 §3.1, eq. 15–16 / 30–31).

The centre updates its prediction with the stacked measurement y = [y¹; …; y^N]:

    G = C_xy C_y⁻¹,   μ_e = μ_p + G (y ⊖ μ_y),   C_e = C_p − G C_xyᵀ,

where ⊖ is the difference with the angle outputs (``central.circular``) wrapped to (−π, π].

G split into column blocks G_m (one per sensor) is also what the distributed rule (eq. 35) uses.
"""

from __future__ import annotations

import numpy as np

from gpfverify.angles import difference, wrap_components
from gpfverify.filters.records import Gaussian
from gpfverify.fusion.case import CentralPrediction
from gpfverify.linalg import right_solve_spd, symmetrize


def fusion_gain(central: CentralPrediction) -> np.ndarray:
    """G = C_xy C_y⁻¹ (D, L) by a Cholesky solve (never an inverse)."""
    return right_solve_spd(central.C_xy, central.C_y, "central.C_y")


def fused_covariance(central: CentralPrediction, gain: np.ndarray) -> np.ndarray:
    """C_e = C_p − G C_xyᵀ, symmetrised: shared by CMF and DMF (Proposition 1)."""
    return symmetrize(central.C_p - gain @ central.C_xy.T)


def cmf_update(central: CentralPrediction, y: np.ndarray, gain: np.ndarray | None = None) -> Gaussian:
    """The CMF posterior N(μ_p + G (y ⊖ μ_y), C_p − G C_xyᵀ) for the stacked measurement ``y``
    (angle state components of the mean wrapped to (−π, π])."""
    gain = fusion_gain(central) if gain is None else gain
    innovation = difference(y, central.mu_y, central.circular)
    mean = wrap_components(central.mu_p + gain @ innovation, central.circular_state)
    return Gaussian(mean, fused_covariance(central, gain))
