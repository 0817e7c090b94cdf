"""Convex combination (CC, "CW" in seed 000's figures; Chong & Mori 2001).

Treats the local estimation errors as uncorrelated:

    P = (Σ_m P_m⁻¹)⁻¹,   x = P Σ_m P_m⁻¹ x_m.

It is CI with every weight 1 (so P_CC ⪯ P_CI(ω) for every ω on the simplex), optimistic when the
local errors are correlated (they are: the sensors share the process noise). Angle state
components are averaged on the circle (:mod:`gpfverify.fusion.estimates`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gpfverify.fusion.estimates import (FusedEstimate, checked_estimates, information_form,
                                        weighted_information_fusion, wrapped)


def convex_combination(estimates: Sequence, circular_state: Sequence[int] = ()) -> FusedEstimate:
    """CC/CW fusion of local estimates (objects with ``mean`` and ``cov``); ``circular_state`` the
    angle state components."""
    checked = checked_estimates(estimates, circular_state=circular_state)
    fused = weighted_information_fusion(information_form(checked), np.ones(len(checked)))
    return wrapped(FusedEstimate(fused.mean, fused.cov), circular_state)
