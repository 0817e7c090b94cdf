"""A property test of *your own* fusion rule with gpfverify's hypothesis strategies.

The rule here is an inflated convex combination: x = P Σ P_m⁻¹ x_m with P = N (Σ P_m⁻¹)⁻¹. It
claims to be conservative whatever the (unknown) correlation between the N local errors: for any
admissible joint error covariance J, the true error covariance Σ_mn W_m J_mn W_nᵀ of the fused
estimate (W_m = P_cw P_m⁻¹) is at most P, because J ⪯ N blkdiag(J_11, …, J_NN) for every PSD J.
``correlated_estimates`` draws the local estimates *with* an admissible J, so the claim can be
checked against the truth; replace ``inflated_convex_combination`` by your own rule.

    pytest examples/test_my_fusion_rule.py
"""

import numpy as np
from hypothesis import given, settings

from gpfverify.fusion import convex_combination
from gpfverify.strategies import correlated_estimates
from gpfverify.tolerances import algebra_rtol


def inflated_convex_combination(estimates):
    """The rule under test: (x_cw, N · P_cw)."""
    fused = convex_combination(list(estimates))
    return fused.mean, len(estimates) * fused.cov


@settings(max_examples=200, deadline=None)
@given(correlated_estimates(count=3, state_dim=2))
def test_the_rule_is_conservative_for_every_admissible_correlation(drawn):
    mean, claimed = inflated_convex_combination(drawn.estimates)
    information = sum(np.linalg.inv(e.cov) for e in drawn.estimates)
    gains = [np.linalg.solve(information, np.linalg.inv(e.cov)) for e in drawn.estimates]
    true_cov = drawn.error_cov_of(gains)
    # claimed − true must be positive semidefinite, up to the rounding of forming both
    slack = np.linalg.eigvalsh(claimed - true_cov)[0]
    assert slack >= -algebra_rtol(np.linalg.cond(claimed)) * np.abs(claimed).max()


@settings(max_examples=100, deadline=None)
@given(correlated_estimates(count=3, state_dim=2))
def test_the_rule_does_not_depend_on_the_order_of_the_sensors(drawn):
    forward = inflated_convex_combination(drawn.estimates)
    backward = inflated_convex_combination(drawn.estimates[::-1])
    scale = np.abs(forward[1]).max()
    np.testing.assert_allclose(backward[0], forward[0], rtol=0, atol=algebra_rtol(1e3) * max(np.abs(forward[0]).max(), 1.0))
    np.testing.assert_allclose(backward[1], forward[1], rtol=0, atol=algebra_rtol(1e3) * scale)
