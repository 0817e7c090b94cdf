"""The reference three-sensor system written three ways — numpy callables
(:mod:`gpfverify.scenarios.three_sensor`), casadi expressions (StateSpaceModel.from_casadi) and sympy
expressions (StateSpaceModel.from_sympy) — must be the same model: the same f and h, the same
Jacobians (exact for casadi and sympy, central differences for the numpy sensors) and the same
EKF and UKF runs; bad casadi and sympy input raises InputError naming the part."""

from dataclasses import replace

import casadi as ca
import numpy as np
import pytest
import sympy as sp

from gpfverify.errors import InputError
from gpfverify.filters.ekf import ekf_step
from gpfverify.filters.records import Gaussian
from gpfverify.filters.ukf import ukf_step
from gpfverify.models import Sensor, StateSpaceModel
from gpfverify.models.functions import FD_STEP
from gpfverify.scenarios.three_sensor import SENSOR_RANGE, SENSOR_RANGE_BEARING, three_sensor_model
from gpfverify.tolerances import EPS, algebra_rtol

SEED = 7
BATCH = 64
STEPS = 20
#: Safety factor on the central-difference error model of :func:`fd_tolerance`: f(x ± h) is
#: computed with a few roundings (each ≤ 1 ulp of |f|) and x ± h is itself rounded.
FD_SAFETY = 10.0

REFERENCE = three_sensor_model()
F = REFERENCE.transition.matrix


# -- the three forms ----------------------------------------------------------------------------

def casadi_three_sensor() -> StateSpaceModel:
    """The reference model from casadi expressions in x = [p_x, p_y, v_x, v_y]."""
    x = ca.SX.sym("x", 4)
    dist = lambda s: ca.sqrt((x[0] - s[0]) ** 2 + (x[1] - s[1]) ** 2)  # noqa: E731
    s1 = SENSOR_RANGE_BEARING
    measures = [x[:2], ca.vertcat(dist(s1), ca.atan2(x[1] - s1[1], x[0] - s1[0])), dist(SENSOR_RANGE)]
    return _rebuilt(StateSpaceModel.from_casadi, x, ca.mtimes(ca.DM(F), x), measures)


def sympy_three_sensor() -> StateSpaceModel:
    """The reference model from sympy expressions in the symbols p_x, p_y, v_x, v_y."""
    px, py, vx, vy = states = sp.symbols("p_x p_y v_x v_y", real=True)
    dist = lambda s: sp.sqrt((px - s[0]) ** 2 + (py - s[1]) ** 2)  # noqa: E731
    s1 = SENSOR_RANGE_BEARING
    measures = [[px, py], [dist(s1), sp.atan2(py - s1[1], px - s1[0])], [dist(SENSOR_RANGE)]]
    return _rebuilt(StateSpaceModel.from_sympy, states, sp.Matrix(F) * sp.Matrix(states), measures)


def _rebuilt(build, state, transition, measures, **kwargs) -> StateSpaceModel:
    """The reference model's noise, prior and sensor names and circular outputs with new functions."""
    sensors = [replace(s, measure=m) for s, m in zip(REFERENCE.sensors, measures, strict=True)]
    return build(state, transition, REFERENCE.Q, sensors, REFERENCE.prior_mean, REFERENCE.prior_cov,
                 **kwargs)


def sympy_via_casadi(model: StateSpaceModel) -> StateSpaceModel:
    """The sympy model with every function replaced by its ``.casadi_function()``."""
    sensors = [replace(s, measure=s.measure.casadi_function()) for s in model.sensors]
    return replace(model, transition=model.transition.casadi_function(), sensors=sensors)


CASADI, SYMPY = casadi_three_sensor(), sympy_three_sensor()
FORMS = {"casadi": CASADI, "sympy": SYMPY, "sympy.casadi_function": sympy_via_casadi(SYMPY)}


# -- helpers -----------------------------------------------------------------------------------

def random_states(rng: np.random.Generator, n: int) -> np.ndarray:
    """States (n, 4) around the reference track: positions in a box, velocities of a few m/s."""
    positions = rng.uniform([-50.0, -60.0], [50.0, 60.0], size=(n, 2))
    return np.hstack([positions, rng.normal(0.0, 4.0, size=(n, 2))])


def assert_close(actual, expected, rtol: float) -> None:
    """|actual − expected| ≤ rtol · (|expected| + its largest magnitude along the leading axis):
    relative per entry, with an absolute floor on the scale of that entry over the batch."""
    expected = np.asarray(expected)
    scale = np.max(np.abs(expected), axis=0, keepdims=True)
    assert np.all(np.abs(actual - expected) <= rtol * (np.abs(expected) + scale)), (
        f"max relative difference {np.max(np.abs(actual - expected) / (np.abs(expected) + scale))} > {rtol}")


def fd_tolerance(model: StateSpaceModel, x: np.ndarray) -> np.ndarray:
    """Bound on |J_fd − J| (N, L, D) for the central differences of ``model``'s h at states x (N, D).

    With h_j = FD_STEP · max(1, |x_j|) (functions.central_difference_jacobian) the error of
    (f_i(x + h_j e_j) − f_i(x − h_j e_j)) / (2 h_j) is rounding eps |f_i| / h_j plus truncation
    h_j² |∂³f_i/∂x_j³| / 6. For the range r = ‖p − s‖ and the bearing atan2 from a sensor at
    distance r ≥ 1, |∂³f/∂p_j³| ≤ 3 / r² (and 0 along the velocities), so with r_min the smallest
    distance from any state to any sensor, |J_fd − J| ≤ FD_SAFETY (eps |f_i| / h_j + h_j² / (2 r_min²)).
    """
    sensors = np.array([SENSOR_RANGE_BEARING, SENSOR_RANGE])
    r_min = np.min(np.linalg.norm(x[:, None, :2] - sensors[None], axis=-1))
    assert r_min >= 1.0
    step = FD_STEP * np.maximum(1.0, np.abs(x))[:, None, :]                # (N, 1, D)
    values = np.abs(model.h(x))[:, :, None]                                # (N, L, 1)
    return FD_SAFETY * (EPS * values / step + step**2 / (2.0 * r_min**2))


def run(step, model: StateSpaceModel, measurements: np.ndarray) -> list:
    """The filter ``step`` over y_1..y_T from the prior: one StepRecord per step."""
    belief, records = Gaussian(model.prior_mean, model.prior_cov), []
    for k, y in enumerate(measurements, start=1):
        records.append(step(belief, model, y, k=k))
        belief = records[-1].posterior
    return records


RECORD_FIELDS = ("mu_p", "C_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e")


def assert_same_run(actual: list, expected: list, rtol: float) -> None:
    for k, (a, e) in enumerate(zip(actual, expected, strict=True), start=1):
        for name in RECORD_FIELDS:
            a_value, e_value = getattr(a, name), getattr(e, name)
            error = np.max(np.abs(a_value - e_value)) / np.max(np.abs(e_value))
            assert error <= rtol, f"step {k} {name}: normwise relative difference {error:.3g} > {rtol:.3g}"


def run_condition(records: list) -> float:
    """The largest condition number of C_y over a run: what one update amplifies rounding by."""
    return max(np.linalg.cond(r.C_y) for r in records)


@pytest.fixture(scope="module")
def measurements() -> np.ndarray:
    return REFERENCE.simulate(STEPS, np.random.default_rng(SEED))[1]


# -- (a) f and h, (b) Jacobians ---------------------------------------------------------------

@pytest.mark.parametrize("form", list(FORMS))
def test_f_and_h_equal_the_numpy_model(form):
    model, x = FORMS[form], random_states(np.random.default_rng(SEED), BATCH)
    for k in (1, 2):
        assert_close(model.f(x, k), REFERENCE.f(x, k), algebra_rtol())
        assert_close(model.h(x, k), REFERENCE.h(x, k), algebra_rtol())


@pytest.mark.parametrize("form", ["sympy", "sympy.casadi_function"])
def test_exact_jacobians_of_casadi_and_sympy_agree(form):
    model, x = FORMS[form], random_states(np.random.default_rng(SEED), BATCH)
    assert model.f_jacobian(x).shape == (BATCH, 4, 4) and model.h_jacobian(x).shape == (BATCH, 5, 4)
    assert_close(model.f_jacobian(x), CASADI.f_jacobian(x), algebra_rtol())
    assert_close(model.h_jacobian(x), CASADI.h_jacobian(x), algebra_rtol())
    assert_close(model.h_jacobian(x[0]), CASADI.h_jacobian(x[0])[None], algebra_rtol())


def test_numpy_jacobians_agree_within_the_central_difference_error():
    x = random_states(np.random.default_rng(SEED), BATCH)
    assert_close(REFERENCE.f_jacobian(x), CASADI.f_jacobian(x), algebra_rtol())      # F, exact both ways
    position = [m.sensors[0].measure.jacobian(x) for m in (REFERENCE, CASADI)]
    assert_close(*position, algebra_rtol())                                          # H, exact both ways
    error = np.abs(REFERENCE.h_jacobian(x) - CASADI.h_jacobian(x))
    assert np.all(error <= fd_tolerance(REFERENCE, x))


# -- (c) EKF and UKF -----------------------------------------------------------------------------

@pytest.mark.parametrize("form", list(FORMS))
def test_ukf_runs_agree(form, measurements):
    expected = run(ukf_step, REFERENCE, measurements)
    assert_same_run(run(ukf_step, FORMS[form], measurements), expected,
                    algebra_rtol(run_condition(expected)))


@pytest.mark.parametrize("form", ["sympy", "sympy.casadi_function"])
def test_ekf_runs_of_casadi_and_sympy_agree(form, measurements):
    expected = run(ekf_step, CASADI, measurements)
    assert_same_run(run(ekf_step, FORMS[form], measurements), expected,
                    algebra_rtol(run_condition(expected)))


def test_ekf_run_of_numpy_agrees_within_the_propagated_jacobian_error(measurements):
    """First order in the Jacobian error δJ. The update is invariant to rescaling the measurement,
    so work in units of the noise (R is diagonal): J_w = R^{-1/2} J, C_w = R^{-1/2} C_y R^{-1/2} =
    J_w C_p J_wᵀ + I. With ρ = max over rows i of max_j |δJ_ij| / max_j |J_ij| (the central-
    difference bound of fd_tolerance at the points where the EKF linearises h, the predicted
    means), C_w and the gain K = C_p J_wᵀ C_w⁻¹ change relatively by at most ρ (1 + 2 κ), κ the
    largest cond(C_w) of the run; a stable filter does not amplify earlier errors, so after T steps
    the records differ relatively by at most T ρ (1 + 2 κ)."""
    expected = run(ekf_step, CASADI, measurements)
    points = np.array([r.mu_p for r in expected])
    noise_std = np.sqrt(np.diag(REFERENCE.R))
    assert np.array_equal(REFERENCE.R, np.diag(noise_std**2))
    rho = np.max(fd_tolerance(REFERENCE, points).max(-1) / np.abs(CASADI.h_jacobian(points)).max(-1))
    kappa = max(np.linalg.cond(r.C_y / np.outer(noise_std, noise_std)) for r in expected)
    rtol = max(algebra_rtol(run_condition(expected)), STEPS * rho * (1.0 + 2.0 * kappa))
    assert_same_run(run(ekf_step, REFERENCE, measurements), expected, rtol)


# -- (d) bad input ---------------------------------------------------------------------------------

def test_casadi_function_with_the_wrong_output_size_names_the_sensor():
    x = ca.SX.sym("x", 4)
    wrong = replace(REFERENCE.sensors[1], measure=ca.Function("h", [x], [x[:3]]))
    with pytest.raises(InputError, match=r"sensor 1 \(range-bearing\) measure.*output 0.*2 entries"):
        StateSpaceModel(F, REFERENCE.Q, [REFERENCE.sensors[0], wrong], REFERENCE.prior_mean,
                        REFERENCE.prior_cov)
    with pytest.raises(InputError, match=r"sensor 2 \(range\) measure.*1 entries"):
        _rebuilt(StateSpaceModel.from_casadi, x, x, [x[:2], x[:2], x[:2]])


def test_casadi_function_producing_nan_names_the_part():
    x = ca.SX.sym("x", 4)
    with pytest.raises(InputError, match="sensor 2 \\(range\\) measure returned NaN"):
        _rebuilt(StateSpaceModel.from_casadi, x, x, [x[:2], x[:2], ca.log(x[0] - 1e3)])
    with pytest.raises(InputError, match="sensor 0 measure jacobian returned NaN or inf"):  # d√|x|/dx at 0
        StateSpaceModel.from_casadi(x, x, REFERENCE.Q, [Sensor(ca.sqrt(ca.fabs(x[0])), 1.0)], np.zeros(4),
                                    np.eye(4))


def test_casadi_symbol_outside_the_state_and_bare_expression_are_refused():
    x, z = ca.SX.sym("x", 4), ca.SX.sym("z")
    with pytest.raises(InputError, match=r"sensor 0 \(position\) measure is not a casadi expression.*\[z\]"):
        _rebuilt(StateSpaceModel.from_casadi, x, x, [x[:2] * z, x[:2], x[0]])
    with pytest.raises(InputError, match="transition is a casadi SX, not a casadi.Function"):
        StateSpaceModel(x, REFERENCE.Q, REFERENCE.sensors, REFERENCE.prior_mean, REFERENCE.prior_cov)


def test_sympy_symbol_that_is_not_a_state_names_the_sensor():
    px, py, vx, vy = states = sp.symbols("p_x p_y v_x v_y", real=True)
    z = sp.Symbol("z")
    with pytest.raises(InputError, match=r"sensor 1 \(range-bearing\) measure uses \['z'\]"):
        _rebuilt(StateSpaceModel.from_sympy, states, states, [[px, py], [px + z, py], [px]])


def test_sympy_expression_without_a_translation_names_the_part():
    px, py, vx, vy = states = sp.symbols("p_x p_y v_x v_y", real=True)
    g = sp.Function("g")
    with pytest.raises(InputError, match=r"sensor 2 \(range\) measure jacobian cannot be translated"):
        _rebuilt(StateSpaceModel.from_sympy, states, states, [[px, py], [px, py], [g(px)]])
    with pytest.raises(InputError, match=r"sensor 2 \(range\) measure jacobian raised NameError.*DiracDelta"):
        _rebuilt(StateSpaceModel.from_sympy, states, states, [[px, py], [px, py], [sp.sign(px)]])
    model = _rebuilt(StateSpaceModel.from_sympy, states, states, [[px, py], [px, py], [sp.Max(px, py)]])
    with pytest.raises(InputError, match=r"sensor 2 \(range\) measure uses \['Max'\]"):
        model.sensors[2].measure.casadi_function()


# -- (e) time-varying model ----------------------------------------------------------------------

DRIFT, SENSOR_SPEED = 0.5, 10.0


def numpy_time_varying() -> StateSpaceModel:
    """x_k = F x_{k−1} + a(k), a(k) = DRIFT [0, 0, cos k, sin k]; y_k = ‖p − s(k)‖ with a sensor
    moving along the x axis, s(k) = (100 − SENSOR_SPEED k, 0)."""
    drift = lambda k: DRIFT * np.array([0.0, 0.0, np.cos(k), np.sin(k)])  # noqa: E731
    measure = lambda x, k: np.hypot(x[:, 0] - (100.0 - SENSOR_SPEED * k), x[:, 1])[:, None]  # noqa: E731
    return StateSpaceModel(lambda x, k: x @ F.T + drift(k), REFERENCE.Q, [Sensor(measure, 1.0)],
                           REFERENCE.prior_mean, REFERENCE.prior_cov)


def casadi_time_varying() -> StateSpaceModel:
    x, k = ca.SX.sym("x", 4), ca.SX.sym("k")
    drift = DRIFT * ca.vertcat(0.0, 0.0, ca.cos(k), ca.sin(k))
    measure = ca.sqrt((x[0] - (100.0 - SENSOR_SPEED * k)) ** 2 + x[1] ** 2)
    return StateSpaceModel.from_casadi(x, ca.mtimes(ca.DM(F), x) + drift, REFERENCE.Q,
                                       [Sensor(measure, 1.0)], REFERENCE.prior_mean,
                                       REFERENCE.prior_cov, step=k)


def sympy_time_varying() -> StateSpaceModel:
    px, py, vx, vy = states = sp.symbols("p_x p_y v_x v_y", real=True)
    k = sp.Symbol("k", integer=True)
    drift = DRIFT * sp.Matrix([0, 0, sp.cos(k), sp.sin(k)])
    measure = sp.sqrt((px - (100 - SENSOR_SPEED * k)) ** 2 + py**2)
    return StateSpaceModel.from_sympy(states, sp.Matrix(F) * sp.Matrix(states) + drift, REFERENCE.Q,
                                      [Sensor([measure], 1.0)], REFERENCE.prior_mean,
                                      REFERENCE.prior_cov, step=k)


def test_time_varying_model_agrees_across_forms_and_steps():
    numpy_model, x = numpy_time_varying(), random_states(np.random.default_rng(SEED), BATCH)
    sym = sympy_time_varying()
    forms = [casadi_time_varying(), sym, sympy_via_casadi(sym)]
    for k in (1, 2):
        for model in forms:
            assert_close(model.f(x, k), numpy_model.f(x, k), algebra_rtol())
            assert_close(model.h(x, k), numpy_model.h(x, k), algebra_rtol())
            assert_close(model.h_jacobian(x, k), forms[0].h_jacobian(x, k), algebra_rtol())
    for value in (numpy_model.f, numpy_model.h, forms[0].h_jacobian):
        step_1, step_2 = value(x, 1), value(x, 2)
        assert np.max(np.abs(step_1 - step_2)) > algebra_rtol() * np.max(np.abs(step_1))
