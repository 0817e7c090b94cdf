"""Angle states in the covariance-based baselines (CC/CW, CI, ICI, EI, RCC-CI): the fused angle is a
weighted circular mean. Oracles written here: the local headings moved onto one branch by hand
(adding 2π where needed) and the linear rule in numpy; the same local estimates rotated by π and by
angles that move the ±π cut through them — every rule equivariant; and a tracker whose fused
position must stay near the truth when the local headings straddle the cut."""

import numpy as np
import pytest

from gpfverify.angles import wrap
from gpfverify.errors import InputError
from gpfverify.filters.records import Gaussian
from gpfverify.fusion.ci import covariance_intersection, inverse_covariance_intersection
from gpfverify.fusion.convex import convex_combination
from gpfverify.fusion.ellipsoidal import ellipsoidal_intersection
from gpfverify.fusion.rcc_ci import rcc_ci
from gpfverify.tolerances import SOLVER_TOL, algebra_rtol

#: state (p_x [m], p_y [m], speed [m/s], heading θ [rad])
HEADING = 3
TRUTH = np.array([1000.0, -500.0, 20.0, 3.11])
#: the local headings of the report that a linear average turned into a kilometre of error
LOCAL_HEADINGS = (-3.12, -3.07, 3.10)


def _covariances(seed: int = 4) -> list[np.ndarray]:
    """Three local covariances whose heading errors are correlated with position (as after a
    coordinated-turn prediction): a heading error of 0.1 rad moves the position by tens of metres."""
    rng = np.random.default_rng(seed)
    covs = []
    for _ in range(3):
        root = np.diag([30.0, 30.0, 1.0, 0.05]) @ (np.eye(4) + 0.4 * rng.standard_normal((4, 4)))
        cov = root @ root.T
        covs.append(0.5 * (cov + cov.T))
    return covs


def _estimates(rotation: float = 0.0, headings=LOCAL_HEADINGS) -> list[Gaussian]:
    rng = np.random.default_rng(7)
    out = []
    for cov, theta in zip(_covariances(), headings):
        mean = TRUTH + rng.multivariate_normal(np.zeros(4), 0.01 * cov)
        mean[HEADING] = wrap(theta + rotation)
        out.append(Gaussian(mean, cov))
    return out


def _on_branch_by_hand(estimates: list[Gaussian]) -> list[Gaussian]:
    """Negative headings moved up by 2π (every local heading here is within 0.1 rad of ±π)."""
    out = []
    for e in estimates:
        mean = e.mean.copy()
        if mean[HEADING] < 0:
            mean[HEADING] += 2 * np.pi
        out.append(Gaussian(mean, e.cov))
    return out


def _cond() -> float:
    return max(np.linalg.cond(c) for c in _covariances())


def _close_on_circle(a, b, rtol: float) -> None:
    d = np.asarray(a, float) - np.asarray(b, float)
    d[HEADING] = wrap(d[HEADING])
    scale = np.abs(TRUTH)
    assert np.all(np.abs(d) <= rtol * scale), d / scale


RULES = {
    "cc": (lambda e, a: convex_combination(e, a), None),
    "ci-trace-two": (lambda e, a: covariance_intersection(e[:2], "trace", circular_state=a), None),
    "ci-det-two": (lambda e, a: covariance_intersection(e[1:], "det", circular_state=a), None),
    "ici": (lambda e, a: inverse_covariance_intersection(e, circular_state=a), None),
    "ei": (lambda e, a: ellipsoidal_intersection(e, a), None),
    "rcc-ci": (lambda e, a: rcc_ci(e, on_empty="enlarge", circular_state=a), SOLVER_TOL),
}


def test_convex_combination_is_the_information_mean_on_one_branch():
    """CC against numpy: P = (Σ P_m⁻¹)⁻¹, x = P Σ P_m⁻¹ x_m on hand-unwrapped headings, wrapped."""
    estimates = _estimates()
    unwrapped = _on_branch_by_hand(estimates)
    info = [np.linalg.inv(e.cov) for e in unwrapped]
    cov = np.linalg.inv(sum(info))
    mean = cov @ sum(i @ e.mean for i, e in zip(info, unwrapped))
    mean[HEADING] = wrap(mean[HEADING])
    fused = convex_combination(estimates, circular_state=[HEADING])
    _close_on_circle(fused.mean, mean, algebra_rtol(_cond()))
    assert -np.pi < fused.mean[HEADING] <= np.pi
    np.testing.assert_allclose(fused.cov, cov, rtol=algebra_rtol(_cond()), atol=0)


@pytest.mark.parametrize("rule", RULES)
def test_every_baseline_matches_the_hand_unwrapped_linear_rule(rule):
    """With the headings on one branch by hand, the rule needs no angle handling: the circular
    rule must give the same fused estimate, wrapped, and a fused position near the truth."""
    fuse, solver_tol = RULES[rule]
    estimates = _estimates()
    circular = fuse(estimates, [HEADING])
    by_hand = fuse(_on_branch_by_hand(estimates), [])
    expected = by_hand.mean.copy()
    expected[HEADING] = wrap(expected[HEADING])
    _close_on_circle(circular.mean, expected, solver_tol or algebra_rtol(_cond()))
    assert -np.pi < circular.mean[HEADING] <= np.pi
    local_std = max(np.sqrt(c[0, 0] + c[1, 1]) for c in _covariances())
    assert np.linalg.norm(circular.mean[:2] - TRUTH[:2]) <= 3 * local_std


@pytest.mark.parametrize("rule", ["cc", "ci-det-two", "ei"])
def test_a_linear_average_of_the_headings_is_far_off(rule):
    """The control: without ``circular_state`` the headings −3.12, −3.07, 3.10 are averaged as
    numbers and the fused position moves far from the truth (the test above can fail)."""
    fuse, _ = RULES[rule]
    plain = fuse(_estimates(), [])
    local_std = max(np.sqrt(c[0, 0] + c[1, 1]) for c in _covariances())
    assert np.linalg.norm(plain.mean[:2] - TRUTH[:2]) > 3 * local_std


@pytest.mark.parametrize("rotation", [np.pi, 0.5, -2.0, 3.0, 0.05, -0.03])
@pytest.mark.parametrize("rule", RULES)
def test_every_baseline_is_equivariant_under_a_rotation_of_the_headings(rule, rotation):
    """The local headings rotated by ``rotation`` (π, and angles that move the cut through them):
    the fused heading rotates by the same angle, everything else stays."""
    fuse, solver_tol = RULES[rule]
    base = fuse(_estimates(), [HEADING])
    turned = fuse(_estimates(rotation), [HEADING])
    expected = base.mean.copy()
    expected[HEADING] = wrap(expected[HEADING] + rotation)
    _close_on_circle(turned.mean, expected, solver_tol or algebra_rtol(_cond()))
    np.testing.assert_allclose(turned.cov, base.cov, rtol=solver_tol or algebra_rtol(_cond()),
                               atol=(solver_tol or algebra_rtol(_cond())) * np.abs(base.cov).max())


def test_the_fused_heading_does_not_depend_on_the_sensors_order():
    estimates = _estimates()
    forward = convex_combination(estimates, [HEADING])
    backward = convex_combination(estimates[::-1], [HEADING])
    _close_on_circle(forward.mean, backward.mean, algebra_rtol(_cond()))


def test_rcc_ci_primal_centre_is_wrapped_and_agrees_with_its_dual_centre():
    result = rcc_ci(_estimates(), on_empty="enlarge", circular_state=[HEADING])
    assert -np.pi < result.primal_mean[HEADING] <= np.pi
    assert result.discrepancy <= SOLVER_TOL * np.linalg.norm(TRUTH)


@pytest.mark.parametrize("bad, message", [([4], "circular_state index 4 is out of range"),
                                          ([3, 3], "circular_state lists an index twice")])
def test_a_bad_circular_state_is_refused(bad, message):
    with pytest.raises(InputError, match=message):
        convex_combination(_estimates(), bad)


@pytest.mark.parametrize("method", ["cc", "ci", "ici", "ei", "rcc-ci"])
def test_fuse_reads_the_case_files_circular_state(tmp_path, capsys, method):
    """``fuse --method M`` on a heading scene across the cut (case file with a top-level
    ``circular_state``) and on the same scene rotated by π: the fused heading rotates by π."""
    import json

    from gpfverify.cli import main
    from gpfverify.fusion.case import case_to_dict
    from tests.test_fusion_angle_states import scene

    means = []
    for rotation in (0.0, np.pi):
        path = tmp_path / f"case-{rotation}.json"
        path.write_text(json.dumps(case_to_dict(scene(3.10, (-3.12, -3.07), rotation))))
        assert main(["fuse", str(path), "--method", method, "--json"]) == 0
        means.append(np.array(json.loads(capsys.readouterr().out)["mean"]))
    assert -np.pi < means[1][0] <= np.pi
    tol = SOLVER_TOL if method in ("ci", "rcc-ci") else algebra_rtol(10.0)
    assert abs(wrap(means[1][0] - means[0][0] - np.pi)) <= tol * np.pi
    assert abs(means[1][1] - means[0][1]) <= tol


def test_wrap_stays_in_the_half_open_interval_at_the_cut():
    """Every value wraps into (−π, π], including the float just above π, whose remainder rounds to
    2π (it gave −π), and −π itself."""
    just_above = np.nextafter(np.pi, 4.0)
    values = np.array([just_above, -np.pi, np.pi, 3 * np.pi, np.nextafter(-np.pi, -4.0), -just_above])
    wrapped = wrap(values)
    assert np.all((-np.pi < wrapped) & (wrapped <= np.pi))
    assert wrap(just_above) == np.pi and wrap(-np.pi) == np.pi


def test_the_smallest_intersecting_size_does_not_see_the_cut():
    """c_min of the local ellipsoids is the same for the headings across the cut and turned away
    from it by π/2 (and far larger when the headings are taken as plain numbers)."""
    from gpfverify.fusion.rcc_ci import smallest_intersecting_size

    across = smallest_intersecting_size(_estimates(), [HEADING])
    away = smallest_intersecting_size(_estimates(np.pi / 2), [HEADING])
    assert abs(across - away) <= SOLVER_TOL * away
    assert smallest_intersecting_size(_estimates(), []) > 10 * across
