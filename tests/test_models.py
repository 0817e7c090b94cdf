"""The model layer's guarantees (gpfverify.models):

* a bad model raises InputError naming the part — at construction (covariances, prior, circular
  indices, the probe call of every function) and later, inside a filter step, when a user function
  raises or returns NaN at a state the probe did not visit — never an AttributeError or TypeError
  from inside; a model of the wrong kind given to a filter raises InputError;
* full (non-diagonal) Q and R are honoured: KF, EKF and UKF on a linear model equal the Kalman
  filter written out by hand (F P Fᵀ + Q, H P Hᵀ + R, dense solves);
* the step index k reaches the functions and user Jacobians (a time-varying system);
* central-difference Jacobians agree with analytic ones within their error bound (FD_STEP);
* with_sensors / sensor_model give the right stacked h, R, blocks and angle outputs;
* simulate wraps angle outputs and angle state components to (−π, π].
"""

import numpy as np
import pytest
import scipy.linalg as sla

from gpfverify.errors import InputError
from gpfverify.filters.driver import run_filter
from gpfverify.filters.ekf import ekf_step
from gpfverify.filters.gp_adf import gp_adf_step
from gpfverify.filters.gp_ukf import gp_ukf_step
from gpfverify.filters.kalman import kf_step
from gpfverify.filters.records import Gaussian
from gpfverify.filters.sr_ukf import SqrtGaussian, sr_ukf_step
from gpfverify.filters.ukf import ukf_step
from gpfverify.gp import GaussianProcess
from gpfverify.models import GPModel, Sensor, StateSpaceModel, linear_model
from gpfverify.models.functions import FD_STEP
from gpfverify.tolerances import ALGEBRA_SAFETY, EPS, MONTE_CARLO_SIGMAS, algebra_rtol

FIELDS = ("mu_p", "C_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e")


def _spd(rng, n, floor=0.2):
    a = rng.normal(size=(n, n))
    return a @ a.T / n + floor * np.eye(n)


def _model(**overrides):
    """A valid two-state model with two sensors; ``overrides`` replace constructor arguments."""
    args = dict(transition=lambda x: 0.9 * x, process_cov=0.1 * np.eye(2),
                sensors=[Sensor(lambda x: x[:, :1], [[0.5]]),
                         Sensor(lambda x: np.stack([x[:, 0] + x[:, 1], x[:, 1]], axis=-1), 0.2 * np.eye(2))],
                prior_mean=np.zeros(2), prior_cov=np.eye(2))
    args.update(overrides)
    return StateSpaceModel(**args)


def _gp(rng, d, e):
    x = rng.uniform(-2, 2, size=(30, d))
    return GaussianProcess(x, np.sin(x @ rng.normal(size=(d, e))), lengthscales=np.ones((e, d)),
                           signal_var=np.ones(e), noise_var=np.full(e, 0.02))


# --- bad models: InputError naming the part -------------------------------------------------------

@pytest.mark.parametrize("measure, pattern", [
    (lambda x: np.zeros((x.shape[0], 3)), r"sensor 1 measure returned shape \(1, 3\).*expected \(1, 2\)"),
    (lambda x: np.zeros(x.shape[0]), r"sensor 1 measure returned shape \(1,\)"),
    (lambda x: x[0], r"sensor 1 measure returned shape \(2,\)"),       # one state, not a batch
    (lambda x: np.zeros((x.shape[0], 2)).tolist(), None),              # a list of the right shape is fine
])
def test_wrong_output_shape_of_a_sensor_names_it(measure, pattern):
    sensors = [Sensor(lambda x: x[:, :1], [[0.5]]), Sensor(measure, 0.2 * np.eye(2))]
    if pattern is None:
        assert _model(sensors=sensors).measurement_dim == 3
        return
    with pytest.raises(InputError, match=pattern):
        _model(sensors=sensors)


def test_wrong_shapes_of_matrices_and_jacobians_name_the_part():
    with pytest.raises(InputError, match=r"transition as a matrix must have shape \(2, 2\)"):
        _model(transition=np.eye(3))
    with pytest.raises(InputError, match=r"sensor 0 measure as a matrix must have shape \(1, 2\)"):
        _model(sensors=[Sensor(np.eye(2), [[0.5]])])
    with pytest.raises(InputError, match=r"transition jacobian returned shape \(3,\)"):
        _model(transition_jacobian=lambda x: np.ones(3))
    with pytest.raises(InputError, match="sensor 0 measure jacobian returned shape"):
        _model(sensors=[Sensor(lambda x: x[:, :1], [[0.5]], jacobian=lambda x: np.eye(2))])


def test_nan_at_the_construction_probe_names_the_part():
    with pytest.raises(InputError, match=r"transition returned NaN at step k=1 \(output 0, for row 0 of the 1 "
                                         r"state\(s\) it was given\)"):
        _model(transition=lambda x: np.full(x.shape, np.nan))
    sensors = [Sensor(lambda x: x[:, :1], [[0.5]]), Sensor(lambda x: np.full((x.shape[0], 2), np.nan), np.eye(2))]
    with pytest.raises(InputError, match="sensor 1 measure returned NaN"):
        _model(sensors=sensors)
    with pytest.raises(InputError, match="transition jacobian returned NaN"):
        _model(transition_jacobian=lambda x: np.full((2, 2), np.inf))


def _nan_beyond(limit):
    """The identity, NaN for states with a component beyond ``limit`` (no warnings raised)."""
    return lambda x: np.where(np.abs(x) > limit, np.nan, x)


@pytest.mark.parametrize("step", [ukf_step, ekf_step])
def test_nan_during_a_filter_step_names_the_part_and_the_step(step):
    """The probe at the prior mean 0 passes; a belief far out produces NaN inside the step."""
    far = Gaussian(np.array([10.0, 0.0]), np.eye(2))
    model = _model(transition=_nan_beyond(5.0))
    with pytest.raises(InputError, match="transition returned NaN at step k=4"):
        step(far, model, np.zeros(3), k=4)
    sensors = [Sensor(lambda x: x[:, :1], [[0.5]]), Sensor(_nan_beyond(5.0), np.eye(2))]
    model = _model(transition=lambda x: x + 10.0, sensors=sensors)
    with pytest.raises(InputError, match=r"sensor 1 measure returned NaN at step k=2 \(output 0, for row"):
        step(Gaussian(np.zeros(2), np.eye(2)), model, np.zeros(3), k=2)


def test_nan_during_an_sr_ukf_step_names_the_part():
    model = _model(transition=_nan_beyond(5.0))
    with pytest.raises(InputError, match="transition returned NaN"):
        sr_ukf_step(SqrtGaussian(np.array([10.0, 0.0]), np.eye(2)), model, np.zeros(3), k=1)


def _raise_beyond(limit, exc):
    def fn(x):
        if np.any(np.abs(x) > limit):
            raise exc("out of the valid range")
        return x
    return fn


def test_a_raising_user_function_is_reported_with_its_part_and_cause():
    # at construction
    with pytest.raises(InputError, match="transition raised ZeroDivisionError: integer division") as info:
        _model(transition=lambda x: x * (1 // 0))
    assert isinstance(info.value.__cause__, ZeroDivisionError)

    def boom(x):
        raise KeyError("boom")
    sensors = [Sensor(lambda x: x[:, :1], [[0.5]]), Sensor(boom, np.eye(2))]
    with pytest.raises(InputError, match="sensor 1 measure raised KeyError"):
        _model(sensors=sensors)
    named = [Sensor(lambda x: x[:, :1], [[0.5]]), Sensor(boom, np.eye(2), name="range-bearing")]
    with pytest.raises(InputError, match=r"sensor 1 \(range-bearing\) measure raised KeyError"):
        _model(sensors=named)
    with pytest.raises(InputError, match="sensor 0 measure jacobian raised TypeError"):
        _model(sensors=[Sensor(lambda x: x[:, :1], [[0.5]], jacobian=lambda x: None + 1)])
    # later, inside a filter step, where the function fails
    sensors = [Sensor(lambda x: x[:, :1], [[0.5]]), Sensor(_raise_beyond(5.0, ValueError), np.eye(2))]
    model = _model(transition=lambda x: x + 10.0, sensors=sensors)
    for step in (ukf_step, ekf_step):
        with pytest.raises(InputError, match="sensor 1 measure raised ValueError: out of the valid range"):
            step(Gaussian(np.zeros(2), np.eye(2)), model, np.zeros(3), k=1)
    model = _model(transition=_raise_beyond(5.0, AttributeError))
    with pytest.raises(InputError, match="transition raised AttributeError"):
        ukf_step(Gaussian(np.array([10.0, 0.0]), np.eye(2)), model, np.zeros(3), k=1)


@pytest.mark.parametrize("Q, pattern", [
    (np.array([[1.0, 0.5], [0.0, 1.0]]), "process_cov is not symmetric"),
    (np.array([[1.0, 2.0], [2.0, 1.0]]), "process_cov is not positive semidefinite"),
    (-np.eye(2), "process_cov is not positive semidefinite"),
    (np.array([[1.0, np.nan], [np.nan, 1.0]]), "process_cov"),
    (np.eye(3), r"prior_mean must have shape \(3,\)"),  # Q fixes D = 3: the prior has the wrong size
    ("a", "process_cov must be numeric"),
])
def test_bad_process_covariance(Q, pattern):
    with pytest.raises(InputError, match=pattern):
        _model(process_cov=Q)


def test_singular_process_covariance_is_allowed():
    """Q only needs to be positive semidefinite (a noise-free state component)."""
    assert _model(process_cov=np.diag([1.0, 0.0])).state_dim == 2


@pytest.mark.parametrize("R, pattern", [
    (np.ones((2, 2)), "sensor noise_cov is not positive definite"),           # PSD, singular
    (np.zeros((2, 2)), "sensor noise_cov is not positive definite"),
    (np.array([[1.0, 2.0], [2.0, 1.0]]), "sensor noise_cov is not positive semidefinite"),
    (np.array([[1.0, 0.3], [0.0, 1.0]]), "sensor noise_cov is not symmetric"),
])
def test_bad_measurement_covariance(R, pattern):
    with pytest.raises(InputError, match=pattern):
        Sensor(lambda x: x, R)
    with pytest.raises(InputError, match=pattern.replace("sensor", "sensor 'gps'")):
        Sensor(lambda x: x, R, name="gps")

    def range_bearing(x):
        return x

    with pytest.raises(InputError, match=pattern.replace("sensor", r"sensor \(measure range_bearing\)")):
        Sensor(range_bearing, R)


def test_prior_of_the_wrong_size():
    with pytest.raises(InputError, match="prior_mean"):
        _model(prior_mean=np.zeros(3))
    with pytest.raises(InputError, match="prior_cov"):
        _model(prior_cov=np.eye(3))
    with pytest.raises(InputError, match="prior_cov"):
        _model(prior_cov=-np.eye(2))
    with pytest.raises(InputError, match="prior_mean"):
        _model(prior_mean=np.array([0.0, np.nan]))


@pytest.mark.parametrize("circular, pattern", [
    ((2,), "index 2 is out of range for 2 component"),
    ((-1,), "index -1 is out of range"),
    ((0, 0), "lists an index twice"),
    ((0.5,), "must hold integers"),
    ((1.0,), "must hold integers"),
    ((True,), "must hold integers"),
    (("0",), "must hold integers"),
    (1, "must be a list of 0-based indices"),
])
def test_bad_circular_indices(circular, pattern):
    with pytest.raises(InputError, match="sensor circular " + pattern):
        Sensor(lambda x: x, np.eye(2), circular=circular)
    with pytest.raises(InputError, match="circular_state " + pattern):
        _model(circular_state=circular)
    rng = np.random.default_rng(0)
    with pytest.raises(InputError, match="sensor 0 circular " + pattern):
        GPModel(_gp(rng, 2, 2), [_gp(rng, 2, 2)], sensor_circular=[circular])
    with pytest.raises(InputError, match="circular_state " + pattern):
        GPModel(_gp(rng, 2, 2), [_gp(rng, 2, 2)], circular_state=circular)


def test_circular_indices_are_sorted_integers():
    sensor = Sensor(lambda x: x, np.eye(3), circular=[np.int64(2), 0])
    assert sensor.circular == (0, 2) and all(type(i) is int for i in sensor.circular)


@pytest.mark.parametrize("fn, prior_mean", [
    (lambda x: np.cumsum(x, axis=0), np.array([1.0, -2.0])),          # row i depends on rows before it
    (lambda x: x * x.shape[0], np.array([1.0, -2.0])),                # depends on the batch size
    (lambda x: np.cumsum(x, axis=0), np.zeros(2)),                   # ... even where the state is zero
    (lambda x: x - x.mean(axis=0) + x[0], np.array([1.0, -2.0])),     # right for identical rows only
], ids=["cumsum", "batch-size", "cumsum-at-zero", "first-row"])
def test_a_function_that_is_not_vectorised_is_refused(fn, prior_mean):
    with pytest.raises(InputError, match="transition is not vectorised over the leading axis"):
        _model(transition=fn, prior_mean=prior_mean)
    sensors = [Sensor(lambda x: x[:, :1], [[0.5]]), Sensor(fn, np.eye(2))]
    with pytest.raises(InputError, match="sensor 1 measure is not vectorised"):
        _model(sensors=sensors, prior_mean=prior_mean)


@pytest.mark.parametrize("sensors, pattern", [
    ([Sensor(lambda x: x[:, :1], [[0.5]]), (lambda x: x, np.eye(2))], r"sensors\[1\] must be a gpfverify.models.Sensor, got tuple"),
    ([np.eye(2)], r"sensors\[0\] must be a gpfverify.models.Sensor, got ndarray"),
    ([], "at least one sensor"),
])
def test_sensors_must_be_sensor_objects(sensors, pattern):
    with pytest.raises(InputError, match=pattern):
        _model(sensors=sensors)


def test_functions_must_be_callable_or_matrices():
    with pytest.raises(InputError, match="transition must be callable, got str"):
        _model(transition="x")
    with pytest.raises(InputError, match="transition jacobian must be callable"):
        _model(transition_jacobian=np.eye(2))
    with pytest.raises(InputError, match="transition_sampler must be callable"):
        _model(transition_sampler=3)


@pytest.mark.parametrize("step", [kf_step, ekf_step, ukf_step])
def test_a_gp_model_given_to_a_known_model_filter_raises(step):
    rng = np.random.default_rng(1)
    gp_model = GPModel(_gp(rng, 2, 2), [_gp(rng, 2, 1)])
    with pytest.raises(InputError, match="needs a StateSpaceModel"):
        step(Gaussian(np.zeros(2), np.eye(2)), gp_model, np.zeros(1), k=1)
    with pytest.raises(InputError, match="SR-UKF needs a StateSpaceModel"):
        sr_ukf_step(SqrtGaussian(np.zeros(2), np.eye(2)), gp_model, np.zeros(1), k=1)


@pytest.mark.parametrize("step", [gp_adf_step, gp_ukf_step])
def test_a_state_space_model_given_to_a_gp_filter_raises(step):
    with pytest.raises(InputError, match="needs a GPModel"):
        step(Gaussian(np.zeros(2), np.eye(2)), _model(), np.zeros(3), k=1)


def test_gp_model_refuses_mismatched_gps():
    rng = np.random.default_rng(2)
    with pytest.raises(InputError, match="transition GP gives 1 outputs, expected 2"):
        GPModel(_gp(rng, 2, 1), [_gp(rng, 2, 1)])
    with pytest.raises(InputError, match="sensor 1's GP takes 3 inputs, expected the state's 2"):
        GPModel(_gp(rng, 2, 2), [_gp(rng, 2, 1), _gp(rng, 3, 1)])
    with pytest.raises(InputError, match="sensor 0's GP must be a GaussianProcess"):
        GPModel(_gp(rng, 2, 2), [np.eye(2)])
    with pytest.raises(InputError, match="sensor_circular has 2 entries for 1 sensors"):
        GPModel(_gp(rng, 2, 2), [_gp(rng, 2, 1)], sensor_circular=[(), ()])


# --- full Q and R, against the Kalman filter written out by hand ----------------------------------

def _hand_kf(F, H, Q, R, prior, y, offset_f=0.0, offset_h=0.0):
    """One Kalman step with every formula written out (affine offsets allowed)."""
    mu_p = F @ prior.mean + offset_f
    C_p = F @ prior.cov @ F.T + Q
    mu_y = H @ mu_p + offset_h
    C_y = H @ C_p @ H.T + R
    C_xy = C_p @ H.T
    gain = np.linalg.solve(C_y, C_xy.T).T
    return {"mu_p": mu_p, "C_p": C_p, "mu_y": mu_y, "C_y": C_y, "C_xy": C_xy,
            "mu_e": mu_p + gain @ (y - mu_y), "C_e": C_p - gain @ C_y @ gain.T}


def _assert_record(record, expected, rtol, label=""):
    for name in FIELDS:
        want = expected[name]
        np.testing.assert_allclose(getattr(record, name), want, rtol=rtol,
                                   atol=rtol * max(1.0, np.abs(want).max()), err_msg=f"{label} {name}")


def _linear_sensor(H, R):
    """x ↦ H x as a numpy callable with its Jacobian (a closure: default arguments would be taken
    for the step index k)."""
    return Sensor(lambda x: x @ H.T, R, jacobian=lambda x: H)


def _correlated(rng, n, correlation=0.8):
    """A full covariance with strong correlations (off-diagonal entries ≈ ``correlation``·σ_i σ_j)."""
    std = rng.uniform(0.5, 1.5, size=n)
    corr = np.full((n, n), correlation) + (1.0 - correlation) * np.eye(n)
    return corr * np.outer(std, std)


@pytest.mark.parametrize("seed, d, sizes", [(0, 2, (2,)), (1, 3, (2, 1)), (2, 3, (3, 2))])
def test_full_process_and_measurement_covariances_are_honoured(seed, d, sizes):
    rng = np.random.default_rng(seed)
    F, H = rng.normal(size=(d, d)) / np.sqrt(d), rng.normal(size=(sum(sizes), d))
    Q = _correlated(rng, d)
    R = sla.block_diag(*(_correlated(rng, s) for s in sizes))  # full within each sensor
    prior, y = Gaussian(rng.normal(size=d), _spd(rng, d)), rng.normal(size=sum(sizes))
    expected = _hand_kf(F, H, Q, R, prior, y)
    rtol = algebra_rtol(np.linalg.cond(expected["C_y"]) * np.linalg.cond(expected["C_p"]))
    # the off-diagonal entries matter: with diag(Q), diag(R) the filter would be far off
    diagonal = _hand_kf(F, H, np.diag(np.diag(Q)), np.diag(np.diag(R)), prior, y)
    assert np.abs(diagonal["C_e"] - expected["C_e"]).max() > ALGEBRA_SAFETY * rtol * np.abs(expected["C_e"]).max()

    matrices = linear_model(F, H, Q, R, sizes=sizes)
    ends = np.cumsum((0,) + sizes)
    callables = StateSpaceModel(lambda x: x @ F.T, Q, [_linear_sensor(H[a:b], R[a:b, a:b])
                                                       for a, b in zip(ends[:-1], ends[1:])],
                                np.zeros(d), np.eye(d), transition_jacobian=lambda x: F)
    np.testing.assert_array_equal(matrices.R, R)
    np.testing.assert_array_equal(callables.R, R)
    _assert_record(kf_step(prior, matrices, y, k=1), expected, rtol, "KF")
    for model, label in ((matrices, "matrices"), (callables, "callables")):
        _assert_record(ekf_step(prior, model, y, k=1), expected, rtol, f"EKF {label}")
        _assert_record(ukf_step(prior, model, y, k=1), expected, rtol, f"UKF {label}")
        sr = sr_ukf_step(SqrtGaussian(prior.mean, np.linalg.cholesky(prior.cov)), model, y, k=1)
        _assert_record(sr.to_record(), expected, rtol, f"SR-UKF {label}")


def test_linear_model_refuses_cross_sensor_noise():
    """R of several sensors must be block diagonal (sensor noises are independent)."""
    R = _correlated(np.random.default_rng(3), 3)
    with pytest.raises(InputError, match="R must be block diagonal"):
        linear_model(np.eye(2), np.ones((3, 2)), np.eye(2), R, sizes=(2, 1))
    with pytest.raises(InputError, match="sizes"):
        linear_model(np.eye(2), np.ones((3, 2)), np.eye(2), np.eye(3), sizes=(2, 2))


# --- the step index --------------------------------------------------------------------------------

def _time_varying(rng, d=2, l=2, analytic=True):
    """f(x, k) = s_k A x + k b, h(x, k) = H x + k c, s_k = 1 + 0.1 k; the user Jacobian of f takes
    k too (s_k A)."""
    A, H = rng.normal(size=(d, d)) / np.sqrt(d), rng.normal(size=(l, d))
    b, c = rng.normal(size=d), rng.normal(size=l)
    scale = lambda k: 1.0 + 0.1 * k  # noqa: E731
    model = StateSpaceModel(
        lambda x, k: scale(k) * x @ A.T + k * b, _correlated(rng, d),
        [Sensor(lambda x, k: x @ H.T + k * c, _correlated(rng, l))], np.zeros(d), np.eye(d),
        transition_jacobian=(lambda x, k: scale(k) * A) if analytic else None)
    return model, (lambda k: scale(k) * A), H, b, c


@pytest.mark.parametrize("analytic", [True, False], ids=["user-jacobian", "central-differences"])
def test_the_step_index_reaches_functions_and_jacobians(analytic):
    rng = np.random.default_rng(4)
    model, F_k, H, b, c = _time_varying(rng, analytic=analytic)
    ys = rng.normal(size=(5, 2))
    prior = Gaussian(rng.normal(size=2), _spd(rng, 2))
    for step in (ekf_step, ukf_step):
        run = run_filter(step, model, prior, ys, first_k=3)
        belief = prior
        for t, y in enumerate(ys):
            k = 3 + t
            expected = _hand_kf(F_k(k), H, model.Q, model.R, belief, y, k * b, k * c)
            cond = np.linalg.cond(expected["C_y"]) * np.linalg.cond(expected["C_p"])
            # central differences of a linear function: rounding only, eps/FD_STEP relative
            # (see test_filters_linear), amplified by the solve with C_y
            rtol = algebra_rtol(cond) if analytic or step is ukf_step else algebra_rtol(cond / FD_STEP)
            _assert_record(run.record(t), expected, rtol, f"{step.__name__} k={k}")
            belief = Gaussian(expected["mu_e"], expected["C_e"])
        # a different first_k gives a different run: k is not ignored
        assert not np.allclose(run_filter(step, model, prior, ys, first_k=1).mu_e, run.mu_e)


def test_functions_without_k_are_time_invariant_and_called_without_it():
    calls = []
    model = _model(transition=lambda x: calls.append(x.shape) or 0.9 * x)
    calls.clear()
    prior = Gaussian(np.ones(2), np.eye(2))
    a = ukf_step(prior, model, np.zeros(3), k=1)
    b = ukf_step(prior, model, np.zeros(3), k=7)
    assert calls  # called (with one argument: no TypeError), and k changes nothing
    assert all(np.array_equal(getattr(a, f), getattr(b, f)) for f in FIELDS)


# --- central-difference Jacobians against analytic ones --------------------------------------------

def _fd_bound(x, value_bound, slope, third):
    """Bound on |J_fd − J| (E, D) of central differences at the state x (D,).

    With h_j = FD_STEP · max(1, |x_j|) (gpfverify.models.functions.central_difference_jacobian),
    (f_i(x + h_j e_j) − f_i(x − h_j e_j)) / (2 h_j) differs from ∂f_i/∂x_j by
    * truncation ≤ h_j² · max|∂³f_i/∂x_j³| / 6 (Taylor remainder; ``third`` (E, D) bounds it) and
    * rounding: each value carries ≈ eps·``value_bound`` (E,) and the perturbed argument
      x_j ± h_j is rounded by ≈ eps |x_j|, moving the value by eps |x_j| |∂f_i/∂x_j| (``slope``
      (E, D)); divided by 2 h_j. The rounding part gets the project's ALGEBRA_SAFETY factor.
    With FD_STEP = eps^(1/3) both parts are O(eps^(2/3)) ≈ 4e-11 for unit-scale functions, so the
    bound still rejects a forward difference (O(h) ≈ 6e-6) or a wrong step."""
    h = FD_STEP * np.maximum(1.0, np.abs(x))[None, :]
    rounding = EPS * (value_bound[:, None] + np.abs(x)[None, :] * slope) / h
    return h**2 * third / 6.0 + ALGEBRA_SAFETY * rounding


@pytest.mark.parametrize("scale", [1.0, 100.0], ids=["unit", "large-state"])
def test_central_differences_agree_with_analytic_jacobians(scale):
    """f_i(x, k) = sin(w_i · x) + k x_i: ∂f_i/∂x_j = w_ij cos(w_i·x) + k δ_ij, |∂³f_i/∂x_j³| ≤ |w_ij|³."""
    rng = np.random.default_rng(5)
    W = rng.normal(size=(3, 3)) / scale
    k = 2
    fn = lambda x, k: np.sin(x @ W.T) + k * x  # noqa: E731
    model = StateSpaceModel(fn, np.eye(3), [Sensor(lambda x: x[:, :1], [[1.0]])], np.zeros(3), np.eye(3))
    for x in scale * rng.normal(size=(6, 3)):
        analytic = W * np.cos(W @ x)[:, None] + k * np.eye(3)
        slope = np.abs(W) + k * np.eye(3)
        bound = _fd_bound(x, 1.0 + np.abs(W) @ np.abs(x) + k * np.abs(x), slope, np.abs(W) ** 3)
        error = np.abs(model.f_jacobian(x, k) - analytic)
        assert np.all(error <= bound), (error / bound).max()
    # a forward difference would be far outside the bound (the test can fail)
    x = scale * rng.normal(size=3)
    h = FD_STEP * np.maximum(1.0, np.abs(x))
    forward = np.stack([(fn((x + h[j] * e)[None], k)[0] - fn(x[None], k)[0]) / h[j]
                        for j, e in enumerate(np.eye(3))], axis=1)
    analytic = W * np.cos(W @ x)[:, None] + k * np.eye(3)
    assert np.any(np.abs(forward - analytic) > _fd_bound(x, 1.0 + np.abs(W) @ np.abs(x) + k * np.abs(x),
                                                         np.abs(W) + k * np.eye(3), np.abs(W) ** 3))


def test_central_differences_of_a_bearing_across_the_cut_are_wrapped():
    """θ = atan2(x_1, x_0) at x_0 = −2, x_1 = FD_STEP/2: the perturbed points x_1 ± h lie on both
    sides of the ±π cut. ∂θ/∂x = (−x_1, x_0)/r², |∂³θ/∂x_j³| ≤ 6/r³, |θ| ≤ π."""
    bearing = lambda x: np.arctan2(x[:, 1], x[:, 0])[:, None]  # noqa: E731
    wrapped = StateSpaceModel(np.eye(2), np.eye(2), [Sensor(bearing, [[0.1]], circular=[0])],
                              np.array([-2.0, 0.0]), np.eye(2))
    x = np.array([-2.0, FD_STEP / 2])
    r2 = x @ x
    analytic = np.array([[-x[1] / r2, x[0] / r2]])
    bound = _fd_bound(x, np.array([np.pi]), np.abs(analytic), np.full((1, 2), 6.0 / r2**1.5))
    assert np.all(np.abs(wrapped.h_jacobian(x) - analytic) <= bound)
    plain = StateSpaceModel(np.eye(2), np.eye(2), [Sensor(bearing, [[0.1]])], np.array([-2.0, 0.0]), np.eye(2))
    # unwrapped, the difference quotient of x_1 is off by 2π / (2h), h = FD_STEP
    assert np.abs(plain.h_jacobian(x) - analytic).max() > np.pi / FD_STEP - np.abs(analytic).max()


def test_user_jacobians_are_used_as_given_and_broadcast_over_batches():
    rng = np.random.default_rng(6)
    W = rng.normal(size=(2, 2))
    model = _model(transition=lambda x: np.sin(x @ W.T), transition_jacobian=lambda x: W * np.cos(W @ x)[:, None])
    xs = rng.normal(size=(4, 3, 2))
    jac = model.f_jacobian(xs)
    assert jac.shape == (4, 3, 2, 2)
    for index in np.ndindex(4, 3):
        np.testing.assert_array_equal(jac[index], W * np.cos(W @ xs[index])[:, None])


# --- derived models ------------------------------------------------------------------------------

def _three_sensors():
    """Sensors of sizes 2, 1, 1: range-bearing (angle output 1), a linear one, a pure angle."""
    rb = Sensor(lambda x: np.stack([np.hypot(x[:, 0], x[:, 1]), np.arctan2(x[:, 1], x[:, 0])], axis=-1),
                np.array([[0.3, 0.1], [0.1, 0.2]]), circular=[1], name="range-bearing")
    lin = Sensor(np.array([[1.0, -1.0]]), [[0.5]], name="linear")
    ang = Sensor(lambda x: np.arctan2(x[:, 0], 1.0 + x[:, 1] ** 2)[:, None], [[0.05]], circular=[0], name="angle")
    return StateSpaceModel(np.eye(2), 0.1 * np.eye(2), [rb, lin, ang], np.array([1.0, 1.0]), np.eye(2))


def test_with_sensors_and_sensor_model_stack_h_r_and_angle_outputs():
    model = _three_sensors()
    assert model.sizes == (2, 1, 1) and model.circular == (1, 3)
    x = np.random.default_rng(7).normal(size=(5, 2))
    per_sensor = [s.measure(x, 1) for s in model.sensors]
    covs = [s.noise_cov for s in model.sensors]

    sub = model.with_sensors([2, 0])
    assert sub.sizes == (1, 2) and sub.measurement_dim == 3
    assert sub.circular == (0, 2)                      # the angle sensor first, then the bearing
    assert sub.blocks == (slice(0, 1), slice(1, 3))
    np.testing.assert_array_equal(sub.h(x), np.concatenate([per_sensor[2], per_sensor[0]], axis=1))
    np.testing.assert_array_equal(sub.R, sla.block_diag(covs[2], covs[0]))
    np.testing.assert_array_equal(sub.h_jacobian(x),
                                  np.concatenate([model.sensors[2].measure.jacobian(x),
                                                  model.sensors[0].measure.jacobian(x)], axis=-2))
    residual = sub.residual(np.array([np.pi - 0.1, 1.0, np.pi - 0.1]), np.array([-np.pi + 0.1, 0.0, -np.pi + 0.1]))
    np.testing.assert_allclose(residual, [-0.2, 1.0, -0.2], rtol=0, atol=algebra_rtol() * np.pi)

    alone = model.sensor_model(0)
    assert alone.sizes == (2,) and alone.circular == (1,)
    np.testing.assert_array_equal(alone.h(x), per_sensor[0])
    np.testing.assert_array_equal(alone.R, covs[0])
    assert model.sensor_model(1).circular == () and model.sensor_model(2).circular == (0,)
    # the rest of the system is the same, and the original is untouched
    for derived in (sub, alone):
        np.testing.assert_array_equal(derived.f(x), model.f(x))
        assert derived.circular_state == model.circular_state
        np.testing.assert_array_equal(derived.Q, model.Q)
        np.testing.assert_array_equal(derived.prior_mean, model.prior_mean)
    assert model.sizes == (2, 1, 1) and model.circular == (1, 3)
    np.testing.assert_array_equal(model.R, sla.block_diag(*covs))
    for bad, pattern in (([], "at least one sensor"), ([0, 0], "twice"), ([3], "out of range")):
        with pytest.raises(InputError, match=pattern):
            model.with_sensors(bad)


def test_gp_model_with_sensors_keeps_each_sensors_angle_outputs():
    rng = np.random.default_rng(8)
    gp_model = GPModel(_gp(rng, 2, 2), [_gp(rng, 2, 2), _gp(rng, 2, 1), _gp(rng, 2, 1)],
                       sensor_circular=[(1,), (), (0,)])
    assert gp_model.circular == (1, 3)
    sub = gp_model.with_sensors([2, 0])
    assert sub.sizes == (1, 2) and sub.circular == (0, 2) and sub.sensor_circular == ((0,), (1,))
    assert sub.sensors == (gp_model.sensors[2], gp_model.sensors[0])
    assert gp_model.sensor_model(1).circular == ()


# --- simulation ------------------------------------------------------------------------------------

def test_simulate_wraps_angle_outputs_and_state_components():
    """Measurements [x_0, 3 x_0 (an angle), x_1 (an angle)]; state component 1 an angle that grows
    by 2 per step. Angle values lie in (−π, π] and differ from the unwrapped value by a multiple of 2π;
    the other outputs are not wrapped."""
    noise = np.diag([0.01, 0.01, 0.01])
    sensor = Sensor(lambda x: np.stack([x[:, 0], 3.0 * x[:, 0], x[:, 1]], axis=-1), noise, circular=[1, 2])
    model = StateSpaceModel(lambda x: x + np.array([0.0, 2.0]), np.diag([0.01, 0.01]), [sensor],
                            np.array([10.0, 0.0]), 0.01 * np.eye(2), circular_state=[1])
    states, ys = model.simulate(200, np.random.default_rng(9))
    angles = np.concatenate([ys[:, 1], states[:, 1], ys[:, 2]])
    assert np.all(angles > -np.pi) and np.all(angles <= np.pi)
    assert np.abs(ys[:, 0]).min() > np.pi                  # the plain output is not wrapped
    assert np.abs(3.0 * states[:, 0]).min() > np.pi        # so the wrap of output 1 did something
    sigma = np.sqrt(np.diag(noise))
    # output 1 − 3 x_0 and output 2 − x_1, wrapped, are measurement noise; output 0 − x_0 too, unwrapped
    wrapped = lambda a: np.pi - np.mod(np.pi - a, 2.0 * np.pi)  # noqa: E731
    assert np.all(np.abs(ys[:, 0] - states[:, 0]) <= MONTE_CARLO_SIGMAS * sigma[0])
    assert np.all(np.abs(wrapped(ys[:, 1] - 3.0 * states[:, 0])) <= MONTE_CARLO_SIGMAS * sigma[1])
    assert np.all(np.abs(wrapped(ys[:, 2] - states[:, 1])) <= MONTE_CARLO_SIGMAS * sigma[2])
    with pytest.raises(InputError, match="steps must be at least 1"):
        model.simulate(0, np.random.default_rng(0))


def test_transition_draws_are_numpys_multivariate_normal_draws():
    from gpfverify.scenarios.three_sensor import three_sensor_model

    model = three_sensor_model()
    x = np.random.default_rng(0).normal(size=(200, model.state_dim))
    drawn = model.sample_transition(x, 1, np.random.default_rng(5))
    noise = np.random.default_rng(5).multivariate_normal(np.zeros(model.state_dim), model.Q, size=200,
                                                         method="cholesky")
    # numpy's route to the same draws: equal to the rounding of the product with the factor
    tol = algebra_rtol(np.linalg.cond(model.Q))
    np.testing.assert_allclose(drawn, model.f(x, 1) + noise, rtol=tol, atol=tol * np.abs(noise).max())
