"""Ellipsoidal intersection (EI, Sijs & Lazar 2012).

EI removes the "mutual" part Γ, γ that two estimates are assumed to share:
P⁻¹ = P_1⁻¹ + P_2⁻¹ − Γ⁻¹, x = P(P_1⁻¹x_1 + P_2⁻¹x_2 − Γ⁻¹γ), with Γ the largest covariance in
the joint eigenbasis. With Vᵀ P_1 V = I, Vᵀ P_2 V = diag(μ) (:mod:`gpfverify.fusion.pairwise`),
Γ = V⁻ᵀ diag(max(1, μ_i)) V⁻¹, so P = B diag(min(1, μ_i)) Bᵀ (B = P_1 V), and the mutual mean γ
(Sijs & Lazar eq. 10 with η → 0) makes the fused mean, in coordinates u = Vᵀx, take each component
from the more accurate estimate: u_i = u1_i if μ_i > 1, u2_i if μ_i < 1, and their average when
μ_i = 1 to rounding (|μ_i − 1| ≤ algebra_rtol(κ), Sijs & Lazar's η-regularised case). κ is the
condition number of P_1's correlation matrix — what the rounding of the Cholesky-based generalised
eigenproblem depends on (van der Sluis) — not of P_1 itself: the ratios μ_i do not change with
the units of the state components, and neither does the tie rule (a cond(P_1) in mixed units, say
metres and radians, made the tolerance, and with it the fused mean, depend on the units).
For N estimates EI is applied sequentially in the given order. Angle state components are put on
one branch first and the fused angle wrapped (:mod:`gpfverify.fusion.estimates`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gpfverify.filters.records import Gaussian
from gpfverify.fusion.estimates import FusedEstimate, checked_estimates, wrapped
from gpfverify.fusion.pairwise import joint_diagonalise
from gpfverify.linalg import correlation_condition
from gpfverify.tolerances import algebra_rtol


def _two_sensor_ei(first, second) -> FusedEstimate:
    jd = joint_diagonalise(first, second)
    mu = jd.ratios
    tie = np.abs(mu - 1.0) <= algebra_rtol(correlation_condition(first.cov))
    a1 = np.where(tie, 0.5, (mu > 1.0).astype(float))
    q = 1.0 / np.minimum(1.0, mu)
    # mean B diag(1/q)(a1 u1 + a2 u2) with q absorbed: fuse() divides by q, so pre-multiply
    return jd.fuse(q, a1 * q, (1.0 - a1) * q)


def ellipsoidal_intersection(estimates: Sequence, circular_state: Sequence[int] = ()) -> FusedEstimate:
    """EI of N local estimates, pairwise in order; ``circular_state`` the angle state components."""
    checked = checked_estimates(estimates, circular_state=circular_state)
    fused: Gaussian | FusedEstimate = checked[0]
    for nxt in checked[1:]:
        fused = _two_sensor_ei(fused, nxt)
    return wrapped(FusedEstimate(fused.mean, fused.cov), circular_state)
