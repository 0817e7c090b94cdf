"""One oracle suite for every filter family on the common protocol ``step(belief, model, y, *, k)``:

* on a linear-Gaussian model with full Q and R every Gaussian family equals the exact Kalman filter
  (computed here by hand from F, H, Q, R — not through the library's KF) to rounding, and every
  particle family (bootstrap PF, UPF, GPSR-UPF without residuals) equals it statistically: the mean
  over independent runs of (filter − KF) is zero within Monte Carlo error;
* on the reference three-sensor tracker whose bearing crosses ±π, every angle-aware family equals
  the same filter run in a rotated bearing frame (the bearing measured from the opposite direction,
  so that no value is near the cut and no wrapping happens there); the filter that ignores the
  angle flag does not, so the oracle can fail. The particle families see the same wrapped
  residuals in both frames, so with the same generator they agree to rounding.

The flows (EDH, IE-PFF) reach the Kalman update only as the λ-step shrinks; their oracle is the
order of convergence (``test_flows.py``). The GP families filter with *learned* models; their
oracle is the KF on the true and on the learned noise (``test_filters_gp.py``).
"""

from dataclasses import replace

import numpy as np
import pytest

from gpfverify.angles import wrap
from gpfverify.errors import InputError
from gpfverify.filters.driver import run_filter
from gpfverify.filters.ekf import ekf_step
from gpfverify.filters.gpsr_upf import GPResidualModel, gpsr_upf_step
from gpfverify.filters.kalman import kf_step
from gpfverify.filters.pf import pf_step
from gpfverify.filters.records import Gaussian
from gpfverify.filters.resampling import Particles
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.filters.sr_ukf import SqrtGaussian, sr_ukf_step
from gpfverify.filters.ukf import ukf_step
from gpfverify.filters.upf import upf_step
from gpfverify.models import StateSpaceModel, linear_model
from gpfverify.scenarios.three_sensor import SENSOR_RANGE_BEARING, three_sensor_model
from gpfverify.tolerances import algebra_rtol, monte_carlo_atol


def sqrt_ukf(belief, model, y, *, k):
    """The SR-UKF on Gaussian beliefs, so that every family runs through the same driver."""
    record = sr_ukf_step(SqrtGaussian(belief.mean, np.linalg.cholesky(belief.cov)), model, y, k=k)
    return record.to_record()


GAUSSIAN_FAMILIES = {"kf": kf_step, "ekf": ekf_step, "ukf": ukf_step, "sr-ukf": sqrt_ukf,
                     "ukf-scaled": lambda b, m, y, *, k: ukf_step(b, m, y, k=k, params=SigmaParams(0.5, 2.0, 1.0))}
ANGLE_AWARE = ("ekf", "ukf", "sr-ukf", "ukf-scaled")


def _spd(rng, n):
    a = rng.normal(size=(n, n))
    return a @ a.T / n + 0.3 * np.eye(n)


def _hand_kalman(F, H, Q, R, mean, cov, ys):
    """The textbook KF with explicit inverses — an independent route, fine at these sizes."""
    means, covs = [], []
    for y in ys:
        mean, cov = F @ mean, F @ cov @ F.T + Q
        S = H @ cov @ H.T + R
        K = cov @ H.T @ np.linalg.inv(S)
        mean, cov = mean + K @ (y - H @ mean), cov - K @ S @ K.T
        means.append(mean)
        covs.append(cov)
    return np.array(means), np.array(covs)


@pytest.mark.parametrize("family", sorted(GAUSSIAN_FAMILIES))
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_gaussian_family_equals_the_kalman_filter_on_a_linear_model(family, seed):
    rng = np.random.default_rng(seed)
    d, sizes = 4, (2, 1)
    F = np.eye(d) + 0.3 * rng.normal(size=(d, d)) / np.sqrt(d)
    H, Q = rng.normal(size=(sum(sizes), d)), _spd(rng, d)
    R = np.zeros((3, 3))
    R[:2, :2], R[2:, 2:] = _spd(rng, 2), _spd(rng, 1)
    model = linear_model(F, H, Q, R, rng.normal(size=d), _spd(rng, d), sizes=sizes)
    _, ys = model.simulate(12, rng)
    run = run_filter(GAUSSIAN_FAMILIES[family], model, Gaussian(model.prior_mean, model.prior_cov), ys)
    means, covs = _hand_kalman(F, H, Q, R, model.prior_mean, model.prior_cov, ys)
    rtol = algebra_rtol(max(np.linalg.cond(c) for c in run.C_y) * max(np.linalg.cond(c) for c in covs))
    scale = np.abs(means).max() + np.sqrt(np.abs(covs).max())
    np.testing.assert_allclose(run.mu_e, means, rtol=0, atol=rtol * scale)
    np.testing.assert_allclose(run.C_e, covs, rtol=0, atol=rtol * np.abs(covs).max())


def gpsr_upf_without_residuals(belief, model, y, *, k, rng):
    """GPSR-UPF with no GP correction: the UPF with the SR-UKF proposal and exact weights."""
    return gpsr_upf_step(belief, GPResidualModel(model), y, k=k, rng=rng)


#: particle family -> (step, particles per run, whether the belief carries per-particle factors)
PARTICLE_FAMILIES = {"pf": (pf_step, 4000, False), "upf": (upf_step, 1000, True),
                     "gpsr-upf": (gpsr_upf_without_residuals, 1000, True)}


def _particles(model, count, rng, with_factors):
    belief = Particles.from_gaussian(model.prior_mean, model.prior_cov, count, rng)
    return belief if with_factors else replace(belief, sqrt_covs=None)


@pytest.mark.parametrize("family", sorted(PARTICLE_FAMILIES))
def test_every_particle_family_equals_the_kalman_filter_in_expectation(family):
    """24 independent runs of 4 steps: the average of (filter − KF) in the posterior mean and
    covariance is within 5 standard errors (from the runs' own spread) of zero."""
    step, count, with_factors = PARTICLE_FAMILIES[family]
    model = linear_model(np.array([[1.0, 1.0], [0.0, 0.9]]), [[1.0, 0.0]], np.diag([0.3, 0.2]), [[0.5]],
                         prior_mean=[0.5, -0.5])
    _, ys = model.simulate(4, np.random.default_rng(3), x0=model.prior_mean)
    means, covs = _hand_kalman(*model.linear_matrices(), model.Q, model.R, model.prior_mean, model.prior_cov, ys)
    runs, errors = 24, []
    for seed in range(runs):
        rng = np.random.default_rng(100 + seed)
        belief = _particles(model, count, rng, with_factors)
        for k, y in enumerate(ys, 1):
            record = step(belief, model, y, k=k, rng=rng)
            belief = record.posterior
        errors.append(np.concatenate([record.mean - means[-1], (record.cov - covs[-1]).ravel()]))
    errors = np.array(errors)
    np.testing.assert_array_less(np.abs(errors.mean(0)), monte_carlo_atol(errors.std(0, ddof=1), runs))


# --- angles: the rotated bearing frame ---------------------------------------------------------------

ROTATION = np.pi  # the bearing measured from the opposite direction: ±π becomes 0


def opposite_bearing(x):
    """[‖p − s‖, atan2(−(p_y − s_y), −(p_x − s_x))]: the bearing measured from the opposite
    direction, h + π on the circle, continuous where h crosses ±π."""
    dx, dy = x[:, 0] - SENSOR_RANGE_BEARING[0], x[:, 1] - SENSOR_RANGE_BEARING[1]
    return np.stack([np.hypot(dx, dy), np.arctan2(-dy, -dx)], axis=1)


def rotated_frame(model: StateSpaceModel, circular: bool) -> StateSpaceModel:
    """The same system with sensor 1's bearing measured from the opposite direction;
    ``circular`` says whether the bearing keeps its angle flag."""
    bearing = model.sensors[1]
    rotated = replace(bearing, measure=opposite_bearing, circular=bearing.circular if circular else ())
    return StateSpaceModel(model.transition, model.Q, (model.sensors[0], rotated, model.sensors[2]),
                           model.prior_mean, model.prior_cov)


def without_angles(model: StateSpaceModel) -> StateSpaceModel:
    sensors = tuple(replace(s, circular=()) for s in model.sensors)
    return StateSpaceModel(model.transition, model.Q, sensors, model.prior_mean, model.prior_cov)


@pytest.fixture(scope="module")
def crossing():
    """A three-sensor run whose bearing crosses the cut, and the same measurements in the rotated
    frame, where the bearing stays near 0."""
    model = three_sensor_model()
    _, ys = model.simulate(20, np.random.default_rng(7))
    bearing = ys[:, 3]
    assert np.any(bearing > 2.5) and np.any(bearing < -2.5)  # the run crosses ±π
    rotated_ys = ys.copy()
    rotated_ys[:, 3] = wrap(bearing + ROTATION)
    assert np.all(np.abs(rotated_ys[:, 3]) < 1.0)  # far from the cut in the rotated frame
    return model, ys, rotated_ys


def _run(family, model, ys):
    return run_filter(GAUSSIAN_FAMILIES[family], model, Gaussian(model.prior_mean, model.prior_cov), ys)


@pytest.mark.parametrize("family", ANGLE_AWARE)
def test_angle_aware_filters_equal_the_rotated_frame_without_wrapping(family, crossing):
    model, ys, rotated_ys = crossing
    aware = _run(family, model, ys)
    # oracle: the rotated problem, where the bearing never nears ±π, filtered with no angle flag
    oracle = _run(family, rotated_frame(model, circular=False), rotated_ys)
    rtol = algebra_rtol(max(np.linalg.cond(c) for c in oracle.C_y))
    scale = np.abs(oracle.mu_e).max()
    np.testing.assert_allclose(aware.mu_e, oracle.mu_e, rtol=0, atol=rtol * scale)
    np.testing.assert_allclose(aware.C_e, oracle.C_e, rtol=0, atol=rtol * np.abs(oracle.C_e).max())
    # and the rotated problem with the flag on gives the same again (wrapping is a no-op there)
    flagged = _run(family, rotated_frame(model, circular=True), rotated_ys)
    np.testing.assert_allclose(flagged.mu_e, oracle.mu_e, rtol=0, atol=rtol * scale)


@pytest.mark.parametrize("family", ANGLE_AWARE)
def test_ignoring_the_angle_flag_is_wrong_at_the_cut(family, crossing):
    """Without the flag the innovation at the crossing is ≈ 2π rad: the position estimate leaves
    the oracle by more than its own posterior standard deviation (so the check above can fail)."""
    model, ys, rotated_ys = crossing
    oracle = _run(family, rotated_frame(model, circular=False), rotated_ys)
    naive = _run(family, without_angles(model), ys)
    std = np.sqrt(np.diagonal(oracle.C_e, axis1=1, axis2=2)[:, :2])
    assert np.max(np.abs(naive.mu_e[:, :2] - oracle.mu_e[:, :2]) / std) > 1.0


def test_the_kalman_filter_refuses_a_nonlinear_model(crossing):
    model = crossing[0]
    with pytest.raises(InputError, match="linear model"):
        kf_step(Gaussian(model.prior_mean, model.prior_cov), model, crossing[1][0])


@pytest.mark.parametrize("family", sorted(PARTICLE_FAMILIES))
def test_particle_families_equal_the_rotated_frame(family, crossing):
    """Same generator, same draws: the likelihoods of wrapped residuals are the same in both frames,
    so the estimates agree to rounding; without the angle flag they do not (a 2π residual)."""
    model, ys, rotated_ys = crossing
    step, _, with_factors = PARTICLE_FAMILIES[family]

    def run(m, measurements):
        rng = np.random.default_rng(13)
        belief, means = _particles(m, 300, rng, with_factors), []
        for k, y in enumerate(measurements, 1):
            record = step(belief, m, y, k=k, rng=rng)
            belief = record.posterior
            means.append(record.mean)
        return np.array(means)

    oracle = run(rotated_frame(model, circular=True), rotated_ys)
    rtol = algebra_rtol()
    np.testing.assert_allclose(run(model, ys), oracle, rtol=0, atol=rtol * np.abs(oracle).max())
    naive = run(without_angles(model), ys)
    assert not np.allclose(naive, oracle, rtol=0, atol=rtol * np.abs(oracle).max())
