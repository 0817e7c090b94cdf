"""Fusion with angle outputs and an angle state, moved across ±π.

A rotation of every angle output by its own φ_j (central μ_y, local μ_y^m and y alike) and of the
angle state component by ψ (central μ_p, local μ_p^m and μ_e^m alike) changes nothing on the
circle: CMF's and DMF's means (eq. 35) move by ψ in the angle component and not at all elsewhere,
and their covariances do not move. The rotations are chosen here so that the cut falls between
the two values each wrapped difference of eq. 35 subtracts (μ_y^m against μ_y(m), μ_e^m against
μ_p^m) — where an unwrapped difference is off by 2π. Compared in prior standard deviations
(C_p^{-1/2} computed here) within the exact-algebra tolerance of the problem's condition, times the
size of the angles (wrapping rounds by eps · π).
"""

from dataclasses import replace

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from gpfverify.angles import wrap
from gpfverify.fusion.case import FusionCase, split_circular
from gpfverify.fusion.centralized import cmf_update
from gpfverify.fusion.distributed import dmf_update
from gpfverify.fusion.exactness import RankRule
from gpfverify.strategies import fusion_cases
from gpfverify.tolerances import algebra_rtol


def _as_angles(case: FusionCase, output_shift: np.ndarray, state_shift: float) -> FusionCase:
    """Every output an angle and state component 0 an angle, each moved by its shift and wrapped."""
    c = case.central
    circular = tuple(range(c.mu_y.shape[0]))
    state = np.zeros(c.mu_p.shape[0])
    state[0] = state_shift

    def moved_state(v):
        out = v + state
        out[0] = wrap(out[0])
        return out

    central = replace(c, mu_p=moved_state(c.mu_p), mu_y=wrap(c.mu_y + output_shift), circular=circular,
                      circular_state=(0,))
    reports = tuple(replace(r, mu_p=moved_state(r.mu_p), mu_e=moved_state(r.mu_e),
                            mu_y=wrap(r.mu_y + output_shift[b]), circular=own)
                    for r, b, own in zip(case.locals, c.blocks, split_circular(circular, c.sizes)))
    return FusionCase(central, reports, wrap(case.y + output_shift), case.rank_tol)


def _power(cov: np.ndarray, exponent: float) -> np.ndarray:
    values, vectors = np.linalg.eigh(cov)
    return (vectors * values**exponent) @ vectors.T


@given(drawn=fusion_cases(prior="independent", sensors=st.integers(1, 3)),
       rule=st.sampled_from(("numpy", "canonical")), offset=st.floats(-0.5, 0.5))
def test_fusion_does_not_move_when_angles_are_rotated_across_the_cut(drawn, rule, offset):
    case = drawn.case
    c = case.central
    local_mu_y = np.concatenate([r.mu_y for r in case.locals])
    cut_between_outputs = np.pi - 0.5 * (wrap(local_mu_y) + wrap(c.mu_y))
    first = case.locals[0]
    cut_between_states = float(np.pi - 0.5 * (first.mu_e[0] + first.mu_p[0]))
    plain = _as_angles(case, np.zeros_like(c.mu_y), 0.0)
    rotated = _as_angles(case, cut_between_outputs + 1e-3 * offset, cut_between_states)
    whiten = _power(c.C_p, -0.5)
    cond = np.linalg.cond(c.C_p) * np.linalg.cond(c.C_y) * max(np.linalg.cond(r.C_xy.T @ r.C_xy + np.eye(r.mu_y.size))
                                                               for r in case.locals)
    gain_size = np.abs(np.linalg.solve(c.C_y, c.C_xy.T)).sum()
    tol = algebra_rtol(cond) * (1.0 + np.linalg.norm(whiten @ c.mu_p) + 2 * np.pi * gain_size)
    for fuse in (lambda k: cmf_update(k.central, k.y), lambda k: dmf_update(k, rank_rule=RankRule(rule))):
        before, after = fuse(plain), fuse(rotated)
        moved = after.mean - before.mean
        moved[0] = wrap(moved[0] - cut_between_states)
        assert np.linalg.norm(whiten @ moved) <= tol, (before.mean, after.mean)
        np.testing.assert_allclose(after.cov, before.cov, rtol=0, atol=tol * np.abs(c.C_p).max())
        assert -np.pi < after.mean[0] <= np.pi
