"""Property tests of *your own* fusion rule with the gpfverify pytest plugin's ready-made suites.

The rule here is an inflated convex combination: x = P Σ P_m⁻¹ x_m with P = N (Σ P_m⁻¹)⁻¹. It
claims to be conservative whatever the (unknown) correlation between the N local errors: for any
admissible joint error covariance J, the true error covariance Σ_mn W_m J_mn W_nᵀ of the fused
estimate (W_m = P_cw P_m⁻¹) is at most P, because J ⪯ N blkdiag(J_11, …, J_NN) for every PSD J.
:class:`gpfverify.testing.EstimateRuleSuite` checks that claim on drawn local estimates *with* an
admissible J, that the rule does not depend on the order of the sensors, and that turning every
local angle by φ turns the fused angle by φ. Replace ``inflated_convex_combination`` by your rule:

    pytest examples/test_my_fusion_rule.py --gpfverify-cases out/cases

A failing property prints its shrunk counterexample as a fusion case (``gpfverify fusion case:
{...}``) and, with ``--gpfverify-cases DIR``, writes it as DIR/<suite>-<property>.json for
``gpfverify audit`` and ``gpfverify fuse``. A distributed rule that fuses one fusion step (the
centre's prediction and the sensors' reports) subclasses :class:`gpfverify.testing.CaseRuleSuite`
instead: below, eq. 35 as gpfverify implements it.
"""

from gpfverify.fusion import convex_combination
from gpfverify.fusion.distributed import dmf_update
from gpfverify.testing import CaseRuleSuite, EstimateRuleSuite


def inflated_convex_combination(estimates, circular_state=()):
    """The rule under test: (x_cw, N · P_cw), angle components averaged on the circle."""
    fused = convex_combination(list(estimates), circular_state=circular_state)
    return fused.mean, len(estimates) * fused.cov


class TestInflatedConvexCombination(EstimateRuleSuite):
    rule = staticmethod(inflated_convex_combination)


class TestDistributedFusion(CaseRuleSuite):
    rule = staticmethod(lambda case: dmf_update(case).mean)
