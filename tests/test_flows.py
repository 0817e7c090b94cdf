"""IE-PFF and EDH against the exact Kalman update on linear-Gaussian models.

For a linear measurement both flows move the particles by affine maps, so the particle mean and
covariance follow an explicit-Euler discretisation of the Kalman λ-path
dx̄/dλ = P Hᵀ R⁻¹ (z − H x̄), dP/dλ = −P Hᵀ R⁻¹ H P exactly, whatever the number of particles:
the oracle is the Kalman update of the particles' own (1/N) moments, the check is first-order
convergence in Δλ.
"""

import numpy as np
import pytest

from gpfverify.errors import InputError
from gpfverify.filters.flows import (edh_step, edh_update, exponential_steps, ie_pff_step, ie_pff_update,
                                     particle_moments, uniform_steps)
from gpfverify.filters.kalman import kf_measurement, kf_step
from gpfverify.filters.records import Gaussian
from gpfverify.filters.resampling import Particles
from gpfverify.models import Sensor, StateSpaceModel, linear_model
from gpfverify.filters.update import gaussian_update
from gpfverify.linalg import right_solve_spd
from gpfverify.tolerances import CONVERGENCE_ORDER_ATOL, algebra_rtol, monte_carlo_atol

def _problem(seed=0, dim=3, meas=2, count=200):
    rng = np.random.default_rng(seed)
    H = rng.normal(size=(meas, dim))
    R = np.diag(rng.uniform(0.2, 0.6, meas))
    model = linear_model(np.eye(dim), H, np.eye(dim), R)
    particles = rng.normal(size=(count, dim)) * rng.uniform(0.5, 2.0, dim) + rng.normal(size=dim)
    prior = Gaussian(*particle_moments(particles))
    z = H @ prior.mean + 2.0 * rng.normal(size=meas)
    kalman = gaussian_update(prior, kf_measurement(prior, model), z)
    return model, particles, z, kalman


def _step_counts(model, particles):
    """Three halvings of Δλ inside the asymptotic range: explicit Euler on the λ-path is stable
    and accurate once Δλ ρ ≲ 1/4, ρ = the largest eigenvalue of P Hᵀ R⁻¹ H at λ = 0."""
    _, P = particle_moments(particles)
    H = model.h_jacobian(particles[0], 0)
    rho = float(np.linalg.eigvals(P @ H.T @ np.linalg.solve(model.R, H)).real.max())
    base = int(2 ** np.ceil(np.log2(4 * max(rho, 1.0))))
    return (base, 2 * base, 4 * base)


def _errors(update, model, particles, z, kalman):
    errs = []
    for count in _step_counts(model, particles):
        mean, cov = particle_moments(update(particles, model, z, uniform_steps(count)))
        errs.append(max(np.abs(mean - kalman.mu_e).max(), np.abs(cov - kalman.C_e).max()))
    return np.array(errs)


def _orders(errs):
    return np.log2(errs[:-1] / errs[1:])


def _ie_pff(particles, model, z, steps):
    return ie_pff_update(particles, model, z, 0, steps)


def _frozen_gain_flow(particles, model, z, steps):
    """The mistake the tests must catch: the gain and ĥ computed once at λ = 0."""
    mean, _ = particle_moments(particles)
    hx = model.h(particles, 0)
    cross = (particles - mean).T @ (hx - hx.mean(axis=0)) / particles.shape[0]
    gain = right_solve_spd(cross, model.R)
    x = particles.copy()
    for dlam in steps:
        hx = model.h(x, 0)
        x = x + dlam * (z - 0.5 * (hx + hx.mean(axis=0))) @ gain.T
    return x


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_ie_pff_converges_first_order_to_the_kalman_update(seed):
    model, particles, z, kalman = _problem(seed)
    errs = _errors(_ie_pff, model, particles, z, kalman)
    assert np.all(np.abs(_orders(errs) - 1.0) < CONVERGENCE_ORDER_ATOL), errs


def test_frozen_gain_is_biased_and_does_not_converge():
    model, particles, z, kalman = _problem(0)
    good = _errors(_ie_pff, model, particles, z, kalman)
    frozen = _errors(_frozen_gain_flow, model, particles, z, kalman)
    # no convergence: halving Δλ does not shrink the error at first order ...
    assert np.all(np.abs(_orders(frozen) - 1.0) > CONVERGENCE_ORDER_ATOL), frozen
    # ... and its error at the finest Δλ exceeds the recomputed gain's at the coarsest
    assert frozen[-1] > good[0]


@pytest.mark.parametrize("seed", [0, 2, 4])
def test_edh_is_exact_for_linear_gaussian_in_the_limit(seed):
    """EDH with P = the particles' covariance and x̄₀ their mean: the Daum–Huang flow carries the
    Gaussian prior to the Kalman posterior; Euler in λ converges at first order."""
    model, particles, z, kalman = _problem(seed)
    _, P = particle_moments(particles)
    errs = _errors(lambda x, m, zz, s: edh_update(x, P, m, zz, 0, s), model, particles, z, kalman)
    assert np.all(np.abs(_orders(errs) - 1.0) < CONVERGENCE_ORDER_ATOL), errs


def test_edh_step_tracks_the_ekf_covariance_of_a_linear_model():
    """The parallel EKF covariance of :func:`edh_step` is the Kalman covariance on a linear model."""
    rng = np.random.default_rng(5)
    F = np.array([[1.0, 1.0], [0.0, 1.0]])
    H = np.array([[1.0, 0.0]])
    Q, R = 0.1 * np.eye(2), np.array([[0.5]])
    model = linear_model(F, H, Q, R)
    belief = Particles.equally_weighted(rng.normal(size=(50, 2)), ekf_cov=np.eye(2))
    kalman = Gaussian(np.zeros(2), np.eye(2))
    for k in range(1, 4):
        z = rng.normal(size=1)
        belief = edh_step(belief, model, z, k=k, rng=rng, step_sizes=uniform_steps(10)).posterior
        kalman = kf_step(kalman, model, z, k=k).posterior
    np.testing.assert_allclose(belief.ekf_cov, kalman.cov, rtol=algebra_rtol(np.linalg.cond(kalman.cov)))


def _bearing_model(sensor, rotation):
    """Bearing of a 2-D position from ``sensor``, measured from an axis rotated by ``rotation``."""
    def h(x, k):
        d = x - sensor
        return np.arctan2(d[:, 1], d[:, 0])[:, None] - rotation

    def jac(x, k):
        d = x - sensor
        return np.array([[-d[1], d[0]]]) / (d @ d)

    return StateSpaceModel(np.eye(2), 0.1 * np.eye(2), [Sensor(h, [[0.01]], circular=(0,), jacobian=jac)],
                           sensor + [-10.0, 0.0], np.eye(2))


@pytest.mark.parametrize("update", ["ie-pff", "edh"])
def test_flows_are_invariant_to_where_the_bearing_wraps(update):
    """Particles straddling the ±π cut give the same flow as in a frame where no cut is near."""
    rng = np.random.default_rng(7)
    sensor = np.zeros(2)
    particles = np.array([-10.0, 0.0]) + rng.normal(size=(100, 2)) * [0.5, 1.5]  # bearings near ±π
    z_true = np.pi - 0.05
    results = []
    for rotation in (0.0, np.pi / 2):
        model = _bearing_model(sensor, rotation)
        z = np.array([np.mod(z_true - rotation + np.pi, 2 * np.pi) - np.pi])
        steps = uniform_steps(50)
        if update == "ie-pff":
            results.append(ie_pff_update(particles, model, z, 0, steps))
        else:
            results.append(edh_update(particles, np.cov(particles.T), model, z, 0, steps))
    np.testing.assert_allclose(results[0], results[1], rtol=algebra_rtol(1e3), atol=algebra_rtol(1e3))


def test_step_schedules():
    for steps in (uniform_steps(7), exponential_steps(29), exponential_steps(5, 0.8)):
        assert np.isclose(steps.sum(), 1.0, rtol=algebra_rtol()) and np.all(steps > 0)
    assert np.all(np.diff(exponential_steps(29)) > 0)
    with pytest.raises(InputError):
        uniform_steps(0)
    with pytest.raises(InputError):
        ie_pff_update(np.zeros((5, 1)), linear_model([[1.0]], [[1.0]], [[1.0]], [[1.0]]), [0.0], 0,
                      np.array([0.5, 0.6]))


def test_ie_pff_step_predicts_before_the_flow():
    """With an uninformative measurement (R huge) the step is the prediction: the particle mean
    is F x̄ up to the process-noise sample mean (the flow moves it by ~ Cov(X, h) R⁻¹ z ≈ 1e-12)."""
    rng = np.random.default_rng(11)
    F, q, count = np.array([[0.9, 0.2], [0.0, 0.8]]), 1e-12, 40
    model = linear_model(F, [[1.0, 0.0]], q * np.eye(2), [[1e12]])
    particles = rng.normal(size=(count, 2))
    record = ie_pff_step(Particles.equally_weighted(particles), model, np.array([3.0]), k=1, rng=rng,
                         step_sizes=uniform_steps(4))
    np.testing.assert_allclose(record.mean, particles.mean(axis=0) @ F.T, rtol=0,
                               atol=monte_carlo_atol(np.sqrt(q), count))
    assert record.ess == count and not record.resampled
    np.testing.assert_array_equal(record.posterior.particles, record.weighted.particles)


def test_flows_reject_bad_input():
    model = linear_model(np.eye(2), np.eye(2)[:1], np.eye(2), np.eye(1))
    with pytest.raises(InputError, match="z"):
        ie_pff_update(np.zeros((5, 2)), model, np.zeros(3), 0, uniform_steps(2))
    with pytest.raises(InputError, match="particles"):
        edh_update(np.zeros((5, 3)), np.eye(2), model, np.zeros(1), 0, uniform_steps(2))
    with pytest.raises(InputError, match="particles"):
        ie_pff_update(np.zeros((1, 2)), model, np.zeros(1), 0, uniform_steps(2))
    with pytest.raises(InputError, match="ekf_cov"):
        edh_step(Particles.equally_weighted(np.zeros((5, 2))), model, np.zeros(1), rng=np.random.default_rng(0),
                 step_sizes=uniform_steps(2))


@pytest.mark.parametrize("flow", ["ie-pff", "edh"])
def test_a_flow_of_an_angle_state_does_not_depend_on_where_the_cut_at_pi_falls(flow):
    """Rotation invariance: a heading cloud straddling ±π, flowed towards a heading measurement
    (a bearing output), gives the same posterior — mean, covariance and each particle, modulo 2π —
    as the same problem rotated by π, where the cloud sits around 0 and nothing is cut. The
    transition draws the same noise in both (the same seed); the estimate's heading is in (−π, π]."""
    def model(offset):
        return StateSpaceModel(transition=np.array([[1.0, 0.1], [0.0, 1.0]]), process_cov=np.diag([1e-4, 1e-4]),
                               sensors=[Sensor(np.eye(1, 2), np.array([[0.02]]), circular=[0])],
                               prior_mean=[np.pi - 0.02 + offset, 0.1], prior_cov=np.diag([0.01, 0.01]),
                               circular_state=[0])

    cloud = np.random.default_rng(5).normal(size=(300, 2)) * [0.15, 0.05] + [np.pi - 0.02, 0.1]
    results = []
    for offset in (0.0, -np.pi):
        particles = cloud + [offset, 0.0]
        particles[:, 0] = (particles[:, 0] + np.pi) % (2 * np.pi) - np.pi
        z = np.array([(np.pi - 0.05 + offset + np.pi) % (2 * np.pi) - np.pi])
        if flow == "edh":
            belief = Particles.equally_weighted(particles, ekf_cov=np.diag([0.0225, 0.0025]))
            step = edh_step(belief, model(offset), z, k=1, rng=np.random.default_rng(9),
                            step_sizes=exponential_steps(29))
        else:
            step = ie_pff_step(Particles.equally_weighted(particles), model(offset), z, k=1,
                               rng=np.random.default_rng(9), step_sizes=uniform_steps(50))
        assert -np.pi < step.mean[0] <= np.pi
        assert np.all((-np.pi < step.posterior.particles[:, 0]) & (step.posterior.particles[:, 0] <= np.pi))
        results.append(step)
    cut, uncut = results
    tol = algebra_rtol(300.0) * 2 * np.pi  # rounding of N-term sums and the flow's products
    def off_by_pi(a, b):  # a − b − π wrapped to [−π, π): zero when a is b turned by π
        return (a - b) % (2 * np.pi) - np.pi

    assert np.abs(off_by_pi(cut.posterior.particles[:, 0], uncut.posterior.particles[:, 0])).max() <= tol
    np.testing.assert_allclose(cut.posterior.particles[:, 1], uncut.posterior.particles[:, 1], rtol=0, atol=tol)
    assert abs(off_by_pi(cut.mean[0], uncut.mean[0])) <= tol
    np.testing.assert_allclose(cut.cov, uncut.cov, rtol=0, atol=tol * np.abs(uncut.cov).max())


def test_ie_pff_update_on_the_van_der_merwe_benchmark_is_the_papers_scalar_flow():
    """On the 1-D benchmark of the particle-flow experiment (quadratic measurement up to k = 30, linear
    after) the update is seed 003's flow written out for scalars — at every λ-step K = mean((x − x̄)(h − h̄))/R
    and x ← x + Δλ K (z − (h(x) + h̄)/2) — from the same predicted particles."""
    from gpfverify.papers.particle_flow.pff1d_scenario import vdm_gaussian_model

    rng = np.random.default_rng(11)
    model = vdm_gaussian_model(1.0, 0.1)
    steps = uniform_steps(200)
    for k, h in ((12, lambda x: 0.2 * x * x), (40, lambda x: 0.5 * x - 2.0)):
        particles = 2.0 + rng.normal(size=(50, 1))
        z = float(h(2.3)) + 0.1
        x = particles[:, 0].copy()
        for dlam in steps:
            hx = h(x)
            gain = np.mean((x - x.mean()) * (hx - hx.mean())) / 0.1
            x = x + dlam * gain * (z - 0.5 * (hx + hx.mean()))
        flowed = ie_pff_update(particles, model, np.array([z]), k, steps)[:, 0]
        np.testing.assert_allclose(flowed, x, rtol=algebra_rtol(len(steps)), atol=algebra_rtol(len(steps)))
