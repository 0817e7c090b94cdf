"""KF, EKF, UKF and the shared Gaussian update against independent routes:

* the KF against conditioning the joint Gaussian of a whole linear trajectory (one dense solve);
* UKF and EKF against the KF on random linear-Gaussian models (any valid α, β, κ);
* the UKF on a nonlinear model against a separately written scalar UKF;
* batched calls against per-element calls; step-record identities; errors on bad input;
* the EKF without user Jacobians (central differences) against the KF on a linear model;
* the KF step (predicted joint, halved symmetrisation, one solve) against the textbook KF in plain
  numpy and against its own predict/measurement/update parts; its errors on a bad belief or y.
"""

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from gpfverify.errors import InputError, NumericalError
from gpfverify.filters.driver import run_filter
from gpfverify.filters.ekf import ekf_step
from gpfverify.filters.kalman import kf_measurement, kf_predict, kf_step
from gpfverify.filters.records import Gaussian, MeasurementMoments
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.filters.ukf import ukf_step
from gpfverify.filters.update import gaussian_update
from gpfverify.linalg import all_finite, symmetrize
from gpfverify.models import Sensor, StateSpaceModel, linear_model
from gpfverify.models.functions import FD_STEP
from gpfverify.papers.gpadf_scalar.scenario import ScalarSetting
from gpfverify.tolerances import algebra_rtol

FIELDS = ("mu_p", "C_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e")


def _spd(rng, n, floor=0.2):
    a = rng.normal(size=(n, n))
    return a @ a.T / n + floor * np.eye(n)


def _linear_problem(seed, d, l, batch=()):
    rng = np.random.default_rng(seed)
    F, H = rng.normal(size=(d, d)) / np.sqrt(d), rng.normal(size=(l, d))
    Q, R = _spd(rng, d), _spd(rng, l)
    mean = rng.normal(size=batch + (d,))
    cov = np.stack([_spd(rng, d) for _ in range(int(np.prod(batch)))]).reshape(batch + (d, d))
    return F, H, Q, R, Gaussian(mean, cov), rng.normal(size=batch + (l,))


def _rtol(*records):
    """Exact-algebra tolerance from the conditioning of the matrices a step solves with."""
    return algebra_rtol(max(np.linalg.cond(r.C_y).max() * np.linalg.cond(r.C_p).max() for r in records))


def _assert_records_equal(a, b, rtol):
    for name in FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        scale = max(np.abs(y).max(), 1.0)
        np.testing.assert_allclose(x, y, rtol=rtol, atol=rtol * scale, err_msg=name)


# --- the KF against the joint Gaussian of the whole trajectory ----------------------------------

def _joint_conditioning(F, H, Q, R, prior, ys):
    """Posterior of x_T given y_1..y_T by conditioning the joint Gaussian of (x_T, y_1..y_T)
    written as linear maps of the independent (x_0, w_1..w_T, v_1..v_T)."""
    d, l, T = F.shape[0], H.shape[0], len(ys)
    n_z = d + T * d + T * l
    cov_z = np.zeros((n_z, n_z))
    cov_z[:d, :d] = prior.cov
    for t in range(T):
        cov_z[d + t * d:d + (t + 1) * d, d + t * d:d + (t + 1) * d] = Q
        o = d + T * d + t * l
        cov_z[o:o + l, o:o + l] = R
    mean_z = np.zeros(n_z)
    mean_z[:d] = prior.mean
    state_map = np.zeros((d, n_z))
    state_map[:, :d] = np.eye(d)
    rows = []
    for t in range(T):
        state_map = F @ state_map
        state_map[:, d + t * d:d + (t + 1) * d] += np.eye(d)
        obs = H @ state_map
        obs[:, d + T * d + t * l:d + T * d + (t + 1) * l] += np.eye(l)
        rows.append(obs)
    obs_map = np.vstack(rows)
    s_yy = obs_map @ cov_z @ obs_map.T
    s_xy = state_map @ cov_z @ obs_map.T
    gain = np.linalg.solve(s_yy, s_xy.T).T
    mean = state_map @ mean_z + gain @ (np.concatenate(ys) - obs_map @ mean_z)
    return mean, state_map @ cov_z @ state_map.T - gain @ s_xy.T


@pytest.mark.parametrize("seed, d, l", [(0, 1, 1), (1, 2, 1), (2, 3, 2), (3, 2, 3)])
def test_kf_equals_conditioning_of_the_joint_trajectory(seed, d, l):
    F, H, Q, R, prior, _ = _linear_problem(seed, d, l)
    ys = np.random.default_rng(seed + 100).normal(size=(5, l))
    run = run_filter(kf_step, linear_model(F, H, Q, R), prior, ys)
    for t in range(1, len(ys) + 1):
        mean, cov = _joint_conditioning(F, H, Q, R, prior, ys[:t])
        rtol = algebra_rtol(np.linalg.cond(run.C_y[t - 1]) * np.linalg.cond(cov))
        np.testing.assert_allclose(run.mu_e[t - 1], mean, rtol=rtol, atol=rtol * np.abs(mean).max())
        np.testing.assert_allclose(run.C_e[t - 1], cov, rtol=rtol, atol=rtol * np.abs(cov).max())


def test_kf_posterior_matches_information_form():
    """C_e⁻¹ = C_p⁻¹ + Hᵀ R⁻¹ H and C_e⁻¹ μ_e = C_p⁻¹ μ_p + Hᵀ R⁻¹ y (a second formula)."""
    F, H, Q, R, prior, y = _linear_problem(7, 3, 2)
    r = kf_step(prior, linear_model(F, H, Q, R), y, k=1)
    info = np.linalg.inv(r.C_p) + H.T @ np.linalg.solve(R, H)
    info_mean = np.linalg.solve(r.C_p, r.mu_p) + H.T @ np.linalg.solve(R, y)
    rtol = _rtol(r)
    np.testing.assert_allclose(np.linalg.inv(info), r.C_e, rtol=rtol, atol=rtol)
    np.testing.assert_allclose(np.linalg.solve(info, info_mean), r.mu_e, rtol=rtol, atol=rtol)


# --- the KF step against the textbook KF and against its parts ----------------------------------

def _textbook_kf(F, H, Q, R, mean, cov, y):
    """One textbook KF cycle in plain numpy: an explicit gain from a dense solve and the Joseph form
    of the covariance update (another route to the same numbers). Returns μ_e, C_e, C_p, C_y."""
    x, P = F @ mean, F @ cov @ F.T + Q
    S = H @ P @ H.T + R
    K = np.linalg.solve(S, H @ P).T  # P Hᵀ S⁻¹ (P and S symmetric)
    I_KH = np.eye(len(x)) - K @ H
    return x + K @ (y - H @ x), I_KH @ P @ I_KH.T + K @ R @ K.T, P, S


@pytest.mark.parametrize("seed, d, l, batch, scale", [(40, 1, 1, (), 1.0), (41, 4, 2, (), 1.0), (42, 3, 3, (), 1.0),
                                                      (43, 5, 2, (3,), 1.0), (44, 2, 1, (2, 3), 1.0),
                                                      (45, 4, 2, (), 1e150)])
def test_kf_step_equals_the_textbook_kf(seed, d, l, batch, scale):
    """Every record field against the textbook cycle, per batch element; C_p, C_y, C_e exactly
    symmetric. ``scale`` 1e150 makes the sums of squares of the finiteness check overflow: the
    belief is still finite and must be accepted."""
    F, H, Q, R, prior, y = _linear_problem(seed, d, l, batch)
    prior, y = Gaussian(scale * prior.mean, scale**2 * prior.cov), scale * y
    record = kf_step(prior, linear_model(F, H, Q, R), y, k=1)
    for index in np.ndindex(batch):
        mean, cov, C_p, C_y = _textbook_kf(F, H, Q, R, prior.mean[index], prior.cov[index], y[index])
        rtol = algebra_rtol(np.linalg.cond(C_y) * np.linalg.cond(C_p))
        for name, want in (("mu_p", F @ prior.mean[index]), ("C_p", C_p), ("mu_y", H @ F @ prior.mean[index]),
                           ("C_y", C_y), ("C_xy", C_p @ H.T), ("mu_e", mean), ("C_e", cov)):
            np.testing.assert_allclose(getattr(record, name)[index], want, rtol=rtol,
                                       atol=rtol * np.abs(want).max(), err_msg=name)
    for name in ("C_p", "C_y", "C_e"):
        cov = getattr(record, name)
        assert np.array_equal(cov, np.swapaxes(cov, -1, -2)), name


@pytest.mark.parametrize("batch", [(), (4,)])
def test_kf_step_equals_predict_measurement_update(batch):
    """The step's predicted joint N(A μ, A C Aᵀ + B) against kf_predict, kf_measurement and
    gaussian_update in turn (to rounding), and its halved symmetrisation bit for bit against
    (M + Mᵀ)/2 of M = A C Aᵀ + B formed in plain numpy."""
    F, H, Q, R, prior, y = _linear_problem(46, 4, 2, batch)
    model = linear_model(F, H, Q, R)
    step = kf_step(prior, model, y, k=1)
    prediction = kf_predict(prior, model, k=1)
    parts = gaussian_update(prediction, kf_measurement(prediction, model, k=1), y)
    _assert_records_equal(step, parts, _rtol(parts))
    A = np.vstack([F, H @ F])
    B = symmetrize(np.block([[Q, Q @ H.T], [H @ Q, H @ Q @ H.T + R]]))
    joint = symmetrize(A @ prior.cov @ A.T + B)
    for name, block in (("C_p", joint[..., :4, :4]), ("C_y", joint[..., 4:, 4:]), ("C_xy", joint[..., :4, 4:])):
        assert np.array_equal(getattr(step, name), block), name


@pytest.mark.parametrize("mean, cov, y, pattern", [
    (np.zeros(2), np.eye(2), np.ones(3), "y must have 1 entries"),
    (np.zeros(2), np.eye(2), np.array([-np.inf]), "y contains inf"),  # NaN: a missing measurement
    (np.array([0.0, np.nan]), np.eye(2), np.ones(1), "belief.mean contains NaN or inf"),
    (np.zeros(2), np.diag([1.0, np.inf]), np.ones(1), "belief.cov contains NaN or inf"),
    (np.zeros((3, 2)), np.stack([np.eye(2), np.eye(2), np.full((2, 2), np.nan)]), np.ones((3, 1)),
     "belief.cov contains NaN or inf"),
    (np.zeros(3), np.eye(3), np.ones(1), "belief must have mean"),
    (np.zeros(2), np.eye(3), np.ones(1), "belief must have mean"),
    (["a", "b"], np.eye(2), np.ones(1), "belief.mean must be numeric"),
])
def test_kf_step_rejects_a_bad_belief_or_y(mean, cov, y, pattern):
    F, H, Q, R, _, _ = _linear_problem(47, 2, 1)
    with pytest.raises(InputError, match=pattern):
        kf_step(Gaussian(mean, cov), linear_model(F, H, Q, R), y, k=1)


def test_all_finite_is_exact_where_its_sum_of_squares_overflows():
    """The check behind the step's: finite entries whose squares overflow are still finite; any NaN
    or ±inf is found, in C- and Fortran-ordered and strided arrays, alone or among others."""
    big = np.array([[1e200, -1e200], [3e300, 0.0]])
    assert all_finite(big) and all_finite(np.asfortranarray(big), big[:, 0], np.zeros(0))
    for bad in (np.nan, np.inf, -np.inf):
        for layout in (lambda a: a, np.asfortranarray, lambda a: a[:, ::2]):
            a = np.ones((3, 4))
            a[1, 2] = bad
            assert not all_finite(layout(a)) and not all_finite(np.ones(2), layout(a))


# --- UKF and EKF reduce to the KF on linear models -----------------------------------------------

@given(seed=st.integers(0, 2**31 - 1), d=st.integers(1, 4), l=st.integers(1, 3),
       alpha=st.floats(0.05, 2.0), beta=st.floats(-1.0, 3.0), kappa=st.floats(-3.0, 5.0))
def test_ukf_equals_kf_on_linear_models_for_any_valid_parameters(seed, d, l, alpha, beta, kappa):
    params = SigmaParams(alpha, beta, kappa)
    assume(d + params.lam(d) > 0)  # valid: D + λ = α²(D + κ) > 0 (invalid ones: next test)
    F, H, Q, R, prior, y = _linear_problem(seed, d, l)
    model = linear_model(F, H, Q, R)
    kf = kf_step(prior, model, y, k=1)
    ukf = ukf_step(prior, model, y, k=1, params=params)
    # a small sigma-point spread √(D + λ) amplifies rounding (cancellation in χ − μ)
    _assert_records_equal(ukf, kf, _rtol(kf) / min(1.0, d + params.lam(d)))


@pytest.mark.parametrize("seed, d, l", [(11, 1, 1), (12, 3, 2), (13, 2, 4)])
def test_ekf_equals_kf_on_linear_models(seed, d, l):
    F, H, Q, R, prior, y = _linear_problem(seed, d, l)
    model = linear_model(F, H, Q, R)
    kf = kf_step(prior, model, y, k=1)
    _assert_records_equal(ekf_step(prior, model, y, k=1), kf, _rtol(kf))


def test_invalid_sigma_parameters_raise():
    F, H, Q, R, prior, y = _linear_problem(0, 2, 1)
    with pytest.raises(InputError, match="D \\+ λ"):
        ukf_step(prior, linear_model(F, H, Q, R), y, k=1, params=SigmaParams(alpha=1.0, kappa=-2.5))


# --- batches --------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["kf", "ekf", "ukf"])
def test_batched_step_equals_per_element_steps(name):
    F, H, Q, R, prior, y = _linear_problem(21, 3, 2, batch=(4, 5))
    model = linear_model(F, H, Q, R)
    step = {"kf": lambda b, yy: kf_step(b, model, yy, k=1),
            "ekf": lambda b, yy: ekf_step(b, model, yy, k=1),
            "ukf": lambda b, yy: ukf_step(b, model, yy, k=1, params=SigmaParams(0.5, 2.0, 1.0))}[name]
    batched = step(prior, y)
    for index in np.ndindex(4, 5):
        single = step(Gaussian(prior.mean[index], prior.cov[index]), y[index])
        for field in FIELDS:
            np.testing.assert_allclose(getattr(batched, field)[index], getattr(single, field),
                                       rtol=_rtol(single), atol=_rtol(single), err_msg=field)


# --- the UKF on a nonlinear model against a separately written scalar UKF ----------------------

def _scalar_ukf_reference(m0, p0, y, f, h, q, r, alpha, beta, kappa):
    """Textbook scalar UKF with explicit loops (Wan & van der Merwe 2000, D = 1)."""
    lam = alpha**2 * (1 + kappa) - 1
    weights_m = [lam / (1 + lam), 0.5 / (1 + lam), 0.5 / (1 + lam)]
    weights_c = [weights_m[0] + 1 - alpha**2 + beta, weights_m[1], weights_m[2]]

    def points(m, p):
        spread = np.sqrt((1 + lam) * p)
        return [m, m + spread, m - spread]

    fx = [f(x) for x in points(m0, p0)]
    mp = sum(w * v for w, v in zip(weights_m, fx))
    pp = sum(w * (v - mp) ** 2 for w, v in zip(weights_c, fx)) + q
    xs = points(mp, pp)
    hy = [h(x) for x in xs]
    my = sum(w * v for w, v in zip(weights_m, hy))
    pyy = sum(w * (v - my) ** 2 for w, v in zip(weights_c, hy)) + r
    pxy = sum(w * (x - mp) * (v - my) for w, x, v in zip(weights_c, xs, hy))
    return mp + pxy / pyy * (y - my), pp - pxy**2 / pyy


@pytest.mark.parametrize("alpha, beta, kappa", [(1.0, 0.0, 2.0), (0.5, 2.0, 0.0)])
def test_ukf_matches_a_separately_written_scalar_ukf(alpha, beta, kappa):
    model = ScalarSetting().model()
    rng = np.random.default_rng(5)
    means, ys = rng.uniform(-10, 10, size=50), rng.uniform(-5, 5, size=50)
    record = ukf_step(Gaussian(means[:, None], np.full((50, 1, 1), 0.25)), model, ys[:, None], k=1,
                      params=SigmaParams(alpha, beta, kappa))
    f = lambda x: float(model.f(np.array([[x]]), 1)[0, 0])  # noqa: E731
    h = lambda x: float(model.h(np.array([[x]]), 1)[0, 0])  # noqa: E731
    for i in range(50):
        mean, var = _scalar_ukf_reference(means[i], 0.25, ys[i], f, h, model.Q[0, 0], model.R[0, 0],
                                          alpha, beta, kappa)
        rtol = algebra_rtol(record.C_p[i, 0, 0] / record.C_e[i, 0, 0])
        assert record.mu_e[i, 0] == pytest.approx(mean, rel=rtol, abs=rtol)
        assert record.C_e[i, 0, 0] == pytest.approx(var, rel=rtol)


# --- the update: identities and errors -----------------------------------------------------------

def test_update_record_is_consistent():
    rng = np.random.default_rng(3)
    d, l = 3, 2
    joint = _spd(rng, d + l)
    prior = Gaussian(rng.normal(size=d), joint[:d, :d])
    moments = MeasurementMoments(rng.normal(size=l), joint[d:, d:], joint[:d, d:])
    y = rng.normal(size=l)
    r = gaussian_update(prior, moments, y)
    gain = np.linalg.solve(moments.C_y, moments.C_xy.T).T
    rtol = algebra_rtol(np.linalg.cond(joint))
    np.testing.assert_allclose(r.C_e, prior.cov - gain @ moments.C_xy.T, rtol=rtol, atol=rtol)
    np.testing.assert_allclose(r.mu_e, prior.mean + gain @ (y - moments.mu_y), rtol=rtol, atol=rtol)
    assert np.array_equal(r.C_e, r.C_e.T)
    # the posterior covariance is the Schur complement: PSD and no larger than the prior
    assert np.linalg.eigvalsh(r.C_e).min() > 0
    assert np.linalg.eigvalsh(prior.cov - r.C_e).min() >= -rtol * np.abs(prior.cov).max()


@pytest.mark.parametrize("c_y, pattern", [(np.diag([1.0, -1e-3]), "C_y is not positive definite"),
                                          (np.zeros((2, 2)), "C_y is not positive definite"),
                                          (np.diag([1.0, np.nan]), "C_y contains NaN")])
def test_update_raises_on_bad_innovation_covariance(c_y, pattern):
    prior = Gaussian(np.zeros(2), np.eye(2))
    with pytest.raises(NumericalError, match=pattern):
        gaussian_update(prior, MeasurementMoments(np.zeros(2), c_y, 0.1 * np.eye(2)), np.ones(2))


def test_update_names_the_failing_batch_element():
    c_y = np.stack([np.eye(2), np.diag([1.0, -0.5]), np.eye(2)])
    prior = Gaussian(np.zeros((3, 2)), np.broadcast_to(np.eye(2), (3, 2, 2)))
    with pytest.raises(NumericalError, match=r"batch index \(1,\)"):
        gaussian_update(prior, MeasurementMoments(np.zeros((3, 2)), c_y, np.zeros((3, 2, 2))), np.ones((3, 2)))


def test_bad_shapes_raise_input_errors():
    F, H, Q, R, prior, y = _linear_problem(0, 2, 1)
    model = linear_model(F, H, Q, R)
    with pytest.raises(InputError, match="y must have 1 entries"):
        kf_step(prior, model, np.ones(3), k=1)
    with pytest.raises(InputError, match="belief"):
        kf_step(Gaussian(np.zeros(3), np.eye(3)), model, y, k=1)
    with pytest.raises(InputError, match="belief.mean contains NaN"):
        ukf_step(Gaussian(np.array([np.nan, 0.0]), np.eye(2)), model, y, k=1)
    with pytest.raises(InputError, match="process_cov is not positive semidefinite"):
        linear_model(F, H, -Q, R)
    nonlinear = StateSpaceModel(lambda x: x @ F.T, Q, [Sensor(lambda x: x @ H.T, R)], np.zeros(2), np.eye(2))
    with pytest.raises(InputError, match="Kalman filter needs a linear model"):
        kf_step(prior, nonlinear, y, k=1)


# --- the EKF without user Jacobians ----------------------------------------------------------------

@pytest.mark.parametrize("seed, d, l", [(31, 1, 1), (32, 3, 2), (33, 2, 4)])
def test_ekf_with_central_difference_jacobians_equals_kf_on_linear_models(seed, d, l):
    """Numpy callables without Jacobians: the EKF differentiates by central differences. For a
    linear function these have no truncation error, only rounding: f(x ± h e_j) carry eps·|f| each
    and are divided by 2h, h = FD_STEP·max(1, |x_j|), so the Jacobian loses a factor 1/FD_STEP of
    relative precision (eps/FD_STEP instead of eps) and the solve with C_y amplifies that by
    cond(C_y): algebra_rtol with the condition number cond(C_y)/FD_STEP."""
    F, H, Q, R, prior, y = _linear_problem(seed, d, l)
    kf = kf_step(prior, linear_model(F, H, Q, R), y, k=1)
    callables = StateSpaceModel(lambda x: x @ F.T, Q, [Sensor(lambda x: x @ H.T, R)], np.zeros(d), np.eye(d))
    ekf = ekf_step(prior, callables, y, k=1)
    rtol = algebra_rtol(np.linalg.cond(kf.C_y) / FD_STEP)
    _assert_records_equal(ekf, kf, rtol)


# --- the driver ----------------------------------------------------------------------------------

def test_driver_stacks_records_and_passes_the_time_index_and_params():
    F, H, Q, R, prior, _ = _linear_problem(9, 2, 1)
    seen = []
    model = StateSpaceModel(lambda x, k: seen.append(k) or x @ F.T, Q, [Sensor(H, R)], np.zeros(2), np.eye(2))
    seen.clear()  # the construction probe called f at k = 1
    params = SigmaParams(0.5, 2.0, 1.0)
    ys = np.random.default_rng(0).normal(size=(4, 1))
    run = run_filter(ukf_step, model, prior, ys, first_k=3, params=params)
    assert sorted(set(seen)) == [3, 4, 5, 6]
    assert run.mu_e.shape == (4, 2) and run.C_e.shape == (4, 2, 2) and run.C_xy.shape == (4, 2, 1)
    assert len(run) == 4
    belief = prior
    for t in range(4):  # the same as stepping by hand, each posterior feeding the next step
        record = ukf_step(belief, model, ys[t], k=3 + t, params=params)
        _assert_records_equal(run.record(t), record, 0.0)
        belief = record.posterior
    default = run_filter(ukf_step, model, prior, ys, first_k=3)  # the params really reached the step
    assert not np.array_equal(default.C_e, run.C_e)
    with pytest.raises(InputError, match="ys"):
        run_filter(ukf_step, model, prior, np.zeros(0))
