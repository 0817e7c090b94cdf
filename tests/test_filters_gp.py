"""GP-ADF and GP-UKF against independent routes:

* GP-ADF against Gauss–Hermite quadrature of the GP prediction (law of total covariance, from
  deterministic predictions only) followed by a dense-solve conditioning;
* GP-UKF against a separately written loop over explicit sigma points;
* both, with GPs trained on a linear-Gaussian system, against the exact KF (learned-model
  tolerance);
* a stack of GPs with a shared training set (several sensors of a GPModel, or one stacked
  sensor) against the equivalent multi-output GP;
* a model of the wrong kind or with a transition GP that does not map the state to itself raises.
"""

import numpy as np
import pytest

from gpfverify.errors import InputError
from gpfverify.filters.driver import run_filter
from gpfverify.filters.ekf import ekf_step
from gpfverify.filters.gp_adf import gp_adf_predict, gp_adf_step
from gpfverify.filters.gp_ukf import gp_ukf_step
from gpfverify.filters.kalman import kf_step
from gpfverify.filters.records import Gaussian
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.filters.ukf import ukf_step
from gpfverify.gp import GaussianProcess, GaussianProcessStack
from gpfverify.gp.reference import quadrature_moments
from gpfverify.models import GPModel, Sensor, StateSpaceModel, linear_model
from gpfverify.tolerances import MONTE_CARLO_SIGMAS, QUADRATURE_RTOL, algebra_rtol, learned_model_rtol

QUAD_ORDER = {1: 80, 2: 40}


def _gp(rng, d, e, n=40, scale=2.0):
    """A GP with fixed hyperparameters on smooth nonlinear data."""
    x = rng.uniform(-scale, scale, size=(n, d))
    w = rng.normal(size=(d, e))
    y = np.sin(x @ w) + 0.3 * x @ w
    return GaussianProcess(x, y, lengthscales=rng.uniform(0.8, 1.5, size=(e, d)),
                           signal_var=rng.uniform(0.5, 2.0, size=e), noise_var=rng.uniform(0.01, 0.05, size=e))


def _problem(seed, d, l):
    rng = np.random.default_rng(seed)
    transition, measurement = _gp(rng, d, d), _gp(rng, d, l)
    a = rng.normal(size=(d, d))
    belief = Gaussian(rng.uniform(-0.5, 0.5, size=d), 0.2 * (a @ a.T / d + 0.3 * np.eye(d)))
    return transition, measurement, belief, rng.normal(size=l)


@pytest.mark.parametrize("seed, d, l", [(0, 1, 1), (1, 1, 2), (2, 2, 1), (3, 2, 2)])
def test_gp_adf_step_matches_quadrature_route(seed, d, l):
    transition, measurement, belief, y = _problem(seed, d, l)
    record = gp_adf_step(belief, GPModel(transition, [measurement]), y, k=1)
    pred = quadrature_moments(transition, belief.mean, belief.cov, QUAD_ORDER[d])
    c_p = pred.cov + np.diag(transition.noise_var)
    meas = quadrature_moments(measurement, pred.mean, c_p, QUAD_ORDER[d])
    c_y = meas.cov + np.diag(measurement.noise_var)
    gain = np.linalg.solve(c_y, meas.cross_cov.T).T
    expected = {"mu_p": pred.mean, "C_p": c_p, "mu_y": meas.mean, "C_y": c_y, "C_xy": meas.cross_cov,
                "mu_e": pred.mean + gain @ (y - meas.mean), "C_e": c_p - gain @ meas.cross_cov.T}
    # the quadrature error of the moments is amplified by the solve with C_y
    rtol = QUADRATURE_RTOL * np.linalg.cond(c_y)
    for name, value in expected.items():
        scale = np.abs(value).max()
        np.testing.assert_allclose(getattr(record, name), value, rtol=rtol, atol=rtol * scale, err_msg=name)


def _gp_ukf_reference(belief, transition, measurement, y, params):
    """Explicit sigma points, one GP prediction per point, sums written out (eq. 21–31)."""
    def points(mean, cov):
        d = mean.size
        lam = params.alpha**2 * (d + params.kappa) - d
        root = np.linalg.cholesky((d + lam) * cov)
        pts = [mean] + [mean + root[:, i] for i in range(d)] + [mean - root[:, i] for i in range(d)]
        wm = [lam / (d + lam)] + [0.5 / (d + lam)] * (2 * d)
        wc = [wm[0] + 1 - params.alpha**2 + params.beta] + wm[1:]
        return pts, wm, wc

    def noise(gp, at):
        _, var = gp.predict(at[None, :])
        return np.diag(var[0] + gp.noise_var)

    pts, wm, wc = points(belief.mean, belief.cov)
    fx = [transition.predict(p[None, :])[0][0] for p in pts]
    mu_p = sum(w * v for w, v in zip(wm, fx))
    c_p = sum(w * np.outer(v - mu_p, v - mu_p) for w, v in zip(wc, fx)) + noise(transition, belief.mean)
    pts, wm, wc = points(mu_p, c_p)
    hy = [measurement.predict(p[None, :])[0][0] for p in pts]
    mu_y = sum(w * v for w, v in zip(wm, hy))
    c_y = sum(w * np.outer(v - mu_y, v - mu_y) for w, v in zip(wc, hy)) + noise(measurement, mu_p)
    c_xy = sum(w * np.outer(p - mu_p, v - mu_y) for w, p, v in zip(wc, pts, hy))
    gain = np.linalg.solve(c_y, c_xy.T).T
    return {"mu_p": mu_p, "C_p": c_p, "mu_y": mu_y, "C_y": c_y, "C_xy": c_xy,
            "mu_e": mu_p + gain @ (y - mu_y), "C_e": c_p - gain @ c_xy.T}


@pytest.mark.parametrize("seed, d, l, params", [(0, 1, 1, SigmaParams()), (3, 2, 2, SigmaParams()),
                                                (4, 2, 3, SigmaParams(0.6, 2.0, 0.5))])
def test_gp_ukf_step_matches_explicit_sigma_point_loop(seed, d, l, params):
    transition, measurement, belief, y = _problem(seed, d, l)
    record = gp_ukf_step(belief, GPModel(transition, [measurement]), y, k=1, params=params)
    expected = _gp_ukf_reference(belief, transition, measurement, y, params)
    rtol = algebra_rtol(np.linalg.cond(expected["C_y"]) * np.linalg.cond(expected["C_p"]))
    for name, value in expected.items():
        np.testing.assert_allclose(getattr(record, name), value, rtol=rtol,
                                   atol=rtol * np.abs(value).max(), err_msg=name)


@pytest.mark.parametrize("step", [gp_adf_step, gp_ukf_step])
def test_batched_gp_steps_equal_per_belief_steps(step):
    transition, measurement, _, _ = _problem(5, 2, 2)
    model = GPModel(transition, [measurement])
    rng = np.random.default_rng(6)
    means = rng.uniform(-1, 1, size=(3, 2, 2))
    covs = np.broadcast_to(np.array([[0.3, 0.1], [0.1, 0.2]]), (3, 2, 2, 2))
    ys = rng.normal(size=(3, 2, 2))
    batched = step(Gaussian(means, covs), model, ys, k=1)
    for index in np.ndindex(3, 2):
        single = step(Gaussian(means[index], covs[index]), model, ys[index], k=1)
        rtol = algebra_rtol(np.linalg.cond(single.C_y) * np.linalg.cond(single.C_p))
        for name in ("mu_p", "C_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e"):
            np.testing.assert_allclose(getattr(batched, name)[index], getattr(single, name),
                                       rtol=rtol, atol=rtol, err_msg=name)


@pytest.mark.parametrize("step", [gp_adf_step, gp_ukf_step])
@pytest.mark.parametrize("as_sensors", [True, False], ids=["two-sensors", "one-stacked-sensor"])
def test_stack_with_shared_training_set_equals_multi_output_gp(step, as_sensors):
    """One-output GPs on the same inputs, as two sensors of a GPModel (whose measurement is their
    GaussianProcessStack) or as one sensor that is their stack, are the two-output GP."""
    transition, joint, belief, y = _problem(8, 2, 2)
    parts = [GaussianProcess(joint.X, joint.Y[:, a], joint.lengthscales[a], joint.signal_var[a:a + 1],
                             joint.noise_var[a:a + 1]) for a in range(2)]
    model = GPModel(transition, parts if as_sensors else [GaussianProcessStack(parts)])
    assert isinstance(model.measurement, GaussianProcessStack)
    stacked = step(belief, model, y, k=1)
    direct = step(belief, GPModel(transition, [joint]), y, k=1)
    rtol = algebra_rtol(np.linalg.cond(direct.C_y) * np.linalg.cond(direct.C_p))
    for name in ("mu_y", "C_y", "C_xy", "mu_e", "C_e"):
        np.testing.assert_allclose(getattr(stacked, name), getattr(direct, name), rtol=rtol,
                                   atol=rtol * np.abs(getattr(direct, name)).max(), err_msg=name)


def test_transition_gp_must_map_the_state_to_itself():
    transition, measurement, belief, _ = _problem(0, 2, 1)
    with pytest.raises(InputError, match="transition GP"):
        GPModel(measurement, [measurement])
    with pytest.raises(InputError, match="belief"):
        gp_adf_predict(Gaussian(np.zeros(3), np.eye(3)), GPModel(transition, [measurement]), k=1)


@pytest.mark.parametrize("step", [gp_adf_step, gp_ukf_step])
def test_gp_filters_refuse_a_state_space_model(step):
    """The GP families need a GPModel: a StateSpaceModel (even one built from the GPs' means)
    raises InputError naming the filter, not an AttributeError from inside."""
    transition, measurement, belief, y = _problem(0, 2, 1)
    model = StateSpaceModel(transition.predict_mean, np.diag(transition.noise_var),
                            [Sensor(measurement.predict_mean, np.diag(measurement.noise_var))],
                            np.zeros(2), np.eye(2))
    with pytest.raises(InputError, match="needs a GPModel"):
        step(belief, model, y, k=1)


# --- trained on a linear-Gaussian system, both track the exact KF ----------------------------------

F, H, Q, R = 0.8, 2.0, 0.1, 0.05
N_TRAIN = 100


@pytest.fixture(scope="module")
def linear_gps():
    rng = np.random.default_rng(2024)
    xf, xg = rng.uniform(-4, 4, size=(N_TRAIN, 1)), rng.uniform(-4, 4, size=(N_TRAIN, 1))
    transition = GaussianProcess.fit(xf, F * xf[:, 0] + np.sqrt(Q) * rng.standard_normal(N_TRAIN),
                                     restarts=1, seed=1)
    measurement = GaussianProcess.fit(xg, H * xg[:, 0] + np.sqrt(R) * rng.standard_normal(N_TRAIN),
                                      restarts=1, seed=2)
    x, ys = rng.normal(), []
    for _ in range(15):
        x = F * x + np.sqrt(Q) * rng.standard_normal()
        ys.append([H * x + np.sqrt(R) * rng.standard_normal()])
    return transition, measurement, np.array(ys)


def _kf_run(ys, q, r):
    return run_filter(kf_step, linear_model([[F]], [[H]], [[q]], [[r]]), Gaussian(np.zeros(1), np.eye(1)), ys)


def _assert_tracks(learned, exact, ys, cov_rtol, mean_rtol):
    """Covariances within ``cov_rtol``; means within ``mean_rtol`` σ_p (1 + |z|), z the exact
    filter's normalised innovation (a relative gain error δ moves μ_e by about δ σ_p |z|)."""
    np.testing.assert_allclose(learned.C_p, exact.C_p, rtol=cov_rtol)
    np.testing.assert_allclose(learned.C_e, exact.C_e, rtol=cov_rtol)
    z = np.abs(ys - exact.mu_y) / np.sqrt(exact.C_y[:, :, 0])
    bound = mean_rtol * np.sqrt(exact.C_p[:, :, 0]) * (1.0 + z)
    assert np.all(np.abs(learned.mu_e - exact.mu_e) <= bound)


@pytest.mark.parametrize("step", [gp_adf_step, gp_ukf_step])
def test_gp_filters_trained_on_linear_system_track_the_kf(linear_gps, step):
    """Against the KF on the true model: the learned noise variances are estimates from N_TRAIN
    samples, so covariances agree to learned_model_rtol (5 s.e. of a variance estimate)."""
    transition, measurement, ys = linear_gps
    learned = run_filter(step, GPModel(transition, [measurement]), Gaussian(np.zeros(1), np.eye(1)), ys)
    rtol = learned_model_rtol(N_TRAIN)
    _assert_tracks(learned, _kf_run(ys, Q, R), ys, rtol, rtol)


@pytest.mark.parametrize("step", [gp_adf_step, gp_ukf_step])
def test_gp_filters_match_the_kf_with_the_learned_noise(linear_gps, step):
    """Against the KF with the GPs' learned noise variances: what is left is the GP's model
    uncertainty, whose share of the covariances is ρ = max latent variance / noise variance along
    the run; covariances agree to 5ρ and means to 5√ρ σ_p (1 + |z|)."""
    transition, measurement, ys = linear_gps
    learned = run_filter(step, GPModel(transition, [measurement]), Gaussian(np.zeros(1), np.eye(1)), ys)
    exact = _kf_run(ys, transition.noise_var[0], measurement.noise_var[0])
    rho = max(float(np.max(transition.predict(learned.mu_e[:-1])[1] / transition.noise_var)),
              float(np.max(measurement.predict(learned.mu_p)[1] / measurement.noise_var)))
    _assert_tracks(learned, exact, ys, MONTE_CARLO_SIGMAS * rho, MONTE_CARLO_SIGMAS * np.sqrt(rho))


# --- one record check for every Gaussian filter ------------------------------------------------------

def _every_filter(seed):
    """The measurement and each filter's record, from one belief: UKF and EKF on the known model
    f, h = the GP means, GP-UKF and GP-ADF on the GPs themselves."""
    transition, measurement, belief, y = _problem(seed, 2, 2)
    model = StateSpaceModel(transition.predict_mean, np.diag(transition.noise_var),
                            [Sensor(measurement.predict_mean, np.diag(measurement.noise_var))],
                            belief.mean, belief.cov)  # no Jacobians: the EKF uses central differences
    gp_model = GPModel(transition, [measurement])
    return y, {"UKF": ukf_step(belief, model, y, k=1), "EKF": ekf_step(belief, model, y, k=1),
               "GP-UKF": gp_ukf_step(belief, gp_model, y, k=1),
               "GP-ADF": gp_adf_step(belief, gp_model, y, k=1)}


@pytest.mark.parametrize("seed", [0, 1])
def test_every_filter_record_is_a_consistent_gaussian_conditioning(seed):
    """For each filter: the joint [[C_p, C_xy], [C_xyᵀ, C_y]] is symmetric positive definite, and
    μ_e, C_e are its conditioning on y (dense solve as the second route)."""
    y, records = _every_filter(seed)
    for name, r in records.items():
        joint = np.block([[r.C_p, r.C_xy], [r.C_xy.T, r.C_y]])
        assert np.array_equal(joint, joint.T), name
        assert np.linalg.eigvalsh(joint).min() > 0, name
        gain = np.linalg.solve(r.C_y, r.C_xy.T).T
        rtol = algebra_rtol(np.linalg.cond(joint))
        np.testing.assert_allclose(r.mu_e, r.mu_p + gain @ (y - r.mu_y), rtol=rtol, atol=rtol, err_msg=name)
        np.testing.assert_allclose(r.C_e, r.C_p - gain @ r.C_xy.T, rtol=rtol, atol=rtol, err_msg=name)
