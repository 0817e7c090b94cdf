"""Angle states in the covariance-based baselines (CC/CW, CI, ICI, EI, RCC-CI), on drawn local
estimates whose angle components straddle ±π (:func:`gpfverify.strategies.estimates_across_the_cut`):

* every rule is equivariant under a rotation of the angles by a drawn φ — the fused angles turn
  by φ (on the circle), everything else stays — wherever the rotation puts the cut;
* the fused angles are wrapped to (−π, π].

A rule whose convex solver refuses one of the two problems must refuse the other too (they differ
only by rounding). Tolerances: exact algebra scaled by the conditioning of the P_m and the size of
the means; :data:`~gpfverify.tolerances.SOLVER_TOL` where a convex solver decides the weights.
"""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from gpfverify.angles import wrap
from gpfverify.errors import SolverError
from gpfverify.fusion.ci import covariance_intersection, inverse_covariance_intersection
from gpfverify.fusion.convex import convex_combination
from gpfverify.fusion.ellipsoidal import ellipsoidal_intersection
from gpfverify.fusion.rcc_ci import rcc_ci
from gpfverify.strategies import AngleEstimates, estimates_across_the_cut
from gpfverify.strategies.profiles import scaled_examples
from gpfverify.tolerances import SOLVER_TOL, algebra_rtol

RULES = {
    "cc": (lambda e, a: convex_combination(e, a), False),
    "ci": (lambda e, a: covariance_intersection(e, circular_state=a), True),
    "ici": (lambda e, a: inverse_covariance_intersection(e, circular_state=a), False),
    "ei": (lambda e, a: ellipsoidal_intersection(e, a), False),
    "rcc-ci": (lambda e, a: rcc_ci(e, on_empty="enlarge", circular_state=a), True),
}


def _fused_or_refusal(fuse, estimates, angles):
    try:
        return fuse(estimates, angles)
    except SolverError as exc:
        return exc


@given(drawn=estimates_across_the_cut(count=st.integers(2, 3), state_dim=st.integers(1, 3)),
       rotation=st.floats(-np.pi, np.pi), rule=st.sampled_from(sorted(RULES)))
@settings(max_examples=scaled_examples(0.5))
def test_every_baseline_turns_with_the_angles(drawn: AngleEstimates, rotation, rule):
    fuse, solver = RULES[rule]
    angles = list(drawn.circular_state)
    base = _fused_or_refusal(fuse, drawn.estimates, angles)
    turned = _fused_or_refusal(fuse, drawn.rotated(rotation), angles)
    assert isinstance(base, SolverError) == isinstance(turned, SolverError), (base, turned)
    if isinstance(base, SolverError):
        return
    assert np.all((-np.pi < turned.mean[angles]) & (turned.mean[angles] <= np.pi))
    expected = base.mean.copy()
    expected[angles] = expected[angles] + rotation
    gap = turned.mean - expected
    gap[angles] = wrap(gap[angles])
    scale = max(np.abs(e.mean).max() for e in drawn.estimates) + np.pi
    cond = max(np.linalg.cond(e.cov) for e in drawn.estimates)
    tol = (SOLVER_TOL if solver else algebra_rtol(cond)) * scale
    assert np.abs(gap).max() <= tol, (rule, gap, tol)
