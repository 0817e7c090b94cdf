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
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from gpfverify.angles import wrap
from gpfverify.errors import SolverError
from gpfverify.fusion.centralized import cmf_update
from gpfverify.fusion.ci import covariance_intersection, inverse_covariance_intersection
from gpfverify.fusion.convex import convex_combination
from gpfverify.fusion.distributed import dmf_update
from gpfverify.fusion.ellipsoidal import ellipsoidal_intersection
from gpfverify.fusion.rcc_ci import rcc_ci
from gpfverify.strategies import AngleEstimates, estimates_across_the_cut, fusion_cases
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


def _turned_case(case, angles: list[int], shift: np.ndarray):
    """``case`` with the state components ``angles`` marked as angles and turned by ``shift``
    (per component) in the centre's and every sensor's μ_p and μ_e (wrapped); measurements and
    their predictions unchanged."""
    import dataclasses

    def turn(vector):
        out = np.array(vector, dtype=float)
        out[angles] = wrap(out[angles] + shift)
        return out

    central = dataclasses.replace(case.central, mu_p=turn(case.central.mu_p), circular_state=tuple(angles))
    locals_ = tuple(dataclasses.replace(r, mu_p=turn(r.mu_p), mu_e=turn(r.mu_e)) for r in case.locals)
    return dataclasses.replace(case, central=central, locals=locals_)


@given(drawn=fusion_cases(sensors=st.integers(1, 3)), data=st.data(), rotation=st.floats(-np.pi, np.pi))
@settings(max_examples=scaled_examples(0.5))
def test_cmf_and_dmf_turn_with_angle_states_across_the_cut(drawn, data, rotation):
    """A drawn case with some state components made angles, placed near ±π (the centre's
    predicted angle at π + δ), and the same case turned by a drawn angle: CMF's and DMF's fused
    angles turn by it, the other components and the gap DMF − CMF (on the circle) stay."""
    case = drawn.case
    d = case.state_dim
    angles = sorted(data.draw(st.sets(st.integers(0, d - 1), min_size=1, max_size=d), label="angles"))
    near_cut = np.pi - case.central.mu_p[angles] + data.draw(st.floats(-0.3, 0.3), label="delta")
    base = _turned_case(case, angles, near_cut)
    # eq. 35 wraps μ_e^m − μ_p^m: a difference at ±π itself is where the wrap is discontinuous
    assume(all(np.all(np.abs(wrap(r.mu_e[angles] - r.mu_p[angles])) < np.pi * (1 - 1e-6)) for r in base.locals))
    turned = _turned_case(base, angles, np.full(len(angles), rotation))
    eig = np.linalg.eigvalsh(case.central.C_y)
    rtol = algebra_rtol(eig[-1] / eig[0])
    for fuse in (lambda c: cmf_update(c.central, c.y).mean, lambda c: dmf_update(c).mean):
        a, b = fuse(base), fuse(turned)
        expected = a.copy()
        expected[angles] = expected[angles] + rotation
        gap = b - expected
        gap[angles] = wrap(gap[angles])
        scale = np.abs(a).max() + np.pi + np.sqrt(np.abs(case.central.C_p).max())
        assert np.abs(gap).max() <= rtol * scale, (gap, rtol * scale)
