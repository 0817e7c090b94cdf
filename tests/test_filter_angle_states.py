"""Angle states in every Gaussian filter family: a heading θ and turn rate ω, two compasses and a
gyro, the heading crossing ±π. Oracles written here: the exact Kalman filter in numpy on the
*unwrapped* problem (headings as plain numbers beyond π), whose wrapped posterior every family
must reproduce on the wrapped data (the model is linear); the same run rotated by π and by angles
that move the cut; for the learned families, the update recomputed by hand from each record's
moments, and every predicted and posterior heading in (−π, π]."""

import numpy as np
import pytest

from gpfverify.angles import wrap
from gpfverify.filters.families import gaussian_family
from gpfverify.filters.records import Gaussian
from gpfverify.models import Sensor, StateSpaceModel, fit_gp_model
from gpfverify.tolerances import algebra_rtol

F = np.array([[1.0, 1.0], [0.0, 1.0]])
Q = np.diag([1e-3, 1e-4])
H = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
R = np.diag([0.04, 0.09, 0.01])
PRIOR_COV = np.diag([0.05, 0.01])
STEPS = 12


def heading_model(rotation: float = 0.0) -> StateSpaceModel:
    """θ_k = θ_{k−1} + ω_{k−1}, ω_k = ω_{k−1}; compasses read θ (angles), a gyro reads ω."""
    sensors = [Sensor(H[:1], R[:1, :1], circular=(0,), name="compass A"),
               Sensor(H[1:2], R[1:2, 1:2], circular=(0,), name="compass B"),
               Sensor(H[2:], R[2:, 2:], name="gyro")]
    return StateSpaceModel(F, Q, sensors, np.array([wrap(3.0 + rotation), 0.05]), PRIOR_COV,
                           circular_state=(0,), name="heading")


def unwrapped_run(seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Truth (T, 2) and measurements (T, 3) with the heading as a plain number (it passes π)."""
    rng = np.random.default_rng(seed)
    x = np.array([3.0, 0.05])
    truth, ys = [], []
    for _ in range(STEPS):
        x = F @ x + rng.multivariate_normal(np.zeros(2), Q)
        truth.append(x)
        ys.append(H @ x + rng.multivariate_normal(np.zeros(3), R))
    return np.array(truth), np.array(ys)


def kf_by_hand(ys: np.ndarray) -> np.ndarray:
    """The textbook Kalman filter on unwrapped numbers; posterior means (T, 2)."""
    mean, cov = np.array([3.0, 0.05]), PRIOR_COV.copy()
    out = []
    for y in ys:
        mean, cov = F @ mean, F @ cov @ F.T + Q
        s = H @ cov @ H.T + R
        gain = np.linalg.solve(s, H @ cov).T
        mean, cov = mean + gain @ (y - H @ mean), cov - gain @ s @ gain.T
        out.append(mean)
    return np.array(out)


def run_family(name: str, model, ys: np.ndarray) -> list:
    family = gaussian_family(name)
    belief = Gaussian(model.prior_mean, model.prior_cov)
    records = []
    for k, y in enumerate(ys, start=1):
        record = family.step(belief, model, y, k=k)
        records.append(record)
        belief = record.posterior
    return records


def close_on_circle(a, b, tol: float) -> None:
    d = np.asarray(a, float) - np.asarray(b, float)
    d[..., 0] = wrap(d[..., 0])
    assert np.all(np.abs(d) <= tol * np.pi), np.abs(d).max()


TOL = STEPS * algebra_rtol(np.linalg.cond(H @ PRIOR_COV @ H.T + R))
KNOWN_MODEL_FAMILIES = ["kf", "ekf", "ukf"]


@pytest.mark.parametrize("name", KNOWN_MODEL_FAMILIES)
def test_every_family_is_the_unwrapped_kalman_filter_wrapped(name):
    truth, ys = unwrapped_run()
    assert truth[:, 0].max() > np.pi  # the heading crosses the cut
    expected = kf_by_hand(ys)
    wrapped_ys = ys.copy()
    wrapped_ys[:, :2] = wrap(ys[:, :2])
    records = run_family(name, heading_model(), wrapped_ys)
    means = np.array([r.mu_e for r in records])
    for recorded in (means[:, 0], [r.mu_p[0] for r in records], [r.mu_y[:2] for r in records]):
        assert np.all((-np.pi < np.asarray(recorded)) & (np.asarray(recorded) <= np.pi))  # predictions too
    close_on_circle(means, expected, TOL)


def test_kf_predict_and_measurement_wrap_the_heading():
    from gpfverify.filters.kalman import kf_measurement, kf_predict

    prediction = kf_predict(Gaussian(np.array([3.1, 0.2]), PRIOR_COV), heading_model())
    assert prediction.mean[0] == pytest.approx(3.3 - 2 * np.pi)
    assert kf_measurement(prediction, heading_model()).mu_y[:2] == pytest.approx([3.3 - 2 * np.pi] * 2)


@pytest.mark.parametrize("rotation", [np.pi, 0.5, -2.0, 0.2, -0.15])
@pytest.mark.parametrize("name", KNOWN_MODEL_FAMILIES)
def test_every_family_is_equivariant_under_a_rotation_of_the_heading(name, rotation):
    _, ys = unwrapped_run()
    base, turned = ys.copy(), ys.copy()
    base[:, :2] = wrap(ys[:, :2])
    turned[:, :2] = wrap(ys[:, :2] + rotation)
    a = np.array([r.mu_e for r in run_family(name, heading_model(), base)])
    b = np.array([r.mu_e for r in run_family(name, heading_model(rotation), turned)])
    a[:, 0] = a[:, 0] + rotation
    close_on_circle(b, a, TOL)


@pytest.fixture(scope="module")
def learned_heading_model():
    """GPs learned from a trajectory whose heading stays below the cut (2.2 … 3.0)."""
    rng = np.random.default_rng(11)
    theta = np.linspace(2.2, 3.0, 60)
    omega = 0.05 + 0.01 * rng.standard_normal(60)
    x = np.column_stack([theta, omega])
    x_next = np.column_stack([theta + omega, omega]) + rng.normal(0, 0.01, (60, 2))
    y = x @ H.T + rng.normal(0, 0.05, (60, 3))
    return fit_gp_model(x, x_next, x, [y[:, :1], y[:, 1:2], y[:, 2:]], rng, restarts=1,
                        sensor_circular=[(0,), (0,), ()], circular_state=(0,))


@pytest.mark.parametrize("name", ["gp-adf", "gp-ukf"])
def test_learned_families_wrap_predicted_and_posterior_headings(name, learned_heading_model):
    """A belief just below π and compasses reading just past the cut (−3.13): every μ_p and μ_e
    heading lies in (−π, π], and μ_e is μ_p + C_xy C_y⁻¹ wrap(y − μ_y), wrapped — by hand."""
    model = learned_heading_model
    family = gaussian_family(name)
    belief = Gaussian(np.array([3.05, 0.05]), np.diag([0.01, 1e-4]))
    y = np.array([-3.13, -3.12, 0.05])
    for k in range(1, 4):
        record = family.step(belief, model, y, k=k)
        assert -np.pi < record.mu_p[0] <= np.pi and -np.pi < record.mu_e[0] <= np.pi
        innovation = y - record.mu_y
        innovation[:2] = wrap(innovation[:2])
        expected = record.mu_p + record.C_xy @ np.linalg.solve(record.C_y, innovation)
        close_on_circle(record.mu_e, expected, algebra_rtol(np.linalg.cond(record.C_y)))
        belief = record.posterior
    assert abs(wrap(belief.mean[0] - (-3.12))) < 0.2  # the heading followed the compasses across the cut


def _crossing_training(seed: int = 2):
    """A heading trajectory from 2.6 past π to 3.7 (wrapped, as the system simulates it), its
    compass and gyro readings."""
    rng = np.random.default_rng(seed)
    theta = np.linspace(2.6, 3.7, 60)
    x = np.column_stack([theta, 0.02 + 0.005 * rng.standard_normal(60)])
    y = x @ H.T + rng.normal(0.0, 0.02, (60, 3))
    x[:, 0] = wrap(x[:, 0])
    y[:, :2] = wrap(y[:, :2])
    return x, y


def _fit(x, y, circular_state=(0,), sensor_circular=((0,), (0,), ())):
    return fit_gp_model(x[:-1], x[1:], x, [y[:, :1], y[:, 1:2], y[:, 2:]], np.random.default_rng(0),
                        restarts=1, sensor_circular=sensor_circular, circular_state=circular_state)


def _predictions(model, theta):
    """Transition GP's heading prediction and compass GP's reading at (θ, ω = 0.02), inputs put on
    the training branch as the filters do."""
    state = model.on_training_branch(np.array([[theta, 0.02]]))
    heading, _ = model.transition.predict(state)
    compass, _ = model.sensors[0].predict(state)
    return heading[0, 0], compass[0, 0]


@pytest.mark.parametrize("theta", [3.0, 3.12, -3.13, -3.0, -2.75])
def test_a_trajectory_across_the_cut_is_learned_as_a_continuous_function(theta):
    """The oracle is the true system: θ_k = θ_{k−1} + ω, compass = θ. Near the cut, on both sides,
    the learned GPs must give these on the circle (within 0.05 rad; the learning noise is 0.02)."""
    model = _fit(*_crossing_training())
    heading, compass = _predictions(model, theta)
    assert abs(wrap(heading - (theta + 0.02))) < 0.05
    assert abs(wrap(compass - theta)) < 0.05


def test_the_same_data_learned_as_plain_numbers_is_far_off_at_the_cut():
    """The control: without the angle indices the compass readings' jump 3.14 → −3.14 is learned
    as data and the compass GP is off by a large fraction of a turn near the cut (the test above
    can fail)."""
    model = _fit(*_crossing_training(), circular_state=(), sensor_circular=((), (), ()))
    errors = [abs(wrap(_predictions(model, t)[1] - t)) for t in (3.12, -3.13)]
    assert min(errors) > 0.3


@pytest.mark.parametrize("name", ["gp-adf", "gp-ukf"])
def test_learned_families_track_a_heading_across_the_cut(name):
    """GPs learned from a trajectory crossing ±π; the filter started at 3.0 with compasses reading
    a heading that turns through the cut tracks it, every μ_p, μ_y and μ_e heading in (−π, π]."""
    x, y = _crossing_training()
    model = _fit(x, y)
    family = gaussian_family(name)
    belief = Gaussian(np.array([3.0, 0.02]), np.diag([0.01, 1e-4]))
    for k, truth in enumerate(wrap(3.0 + 0.02 * np.arange(1, 20)), start=1):
        record = family.step(belief, model, np.array([truth, truth, 0.02]), k=k)
        for value in (record.mu_p[0], record.mu_y[0], record.mu_y[1], record.mu_e[0]):
            assert -np.pi < value <= np.pi
        assert abs(wrap(record.mu_e[0] - truth)) < 0.05
        belief = record.posterior


def test_check_learns_a_system_whose_training_heading_crosses_the_cut(tmp_path, capsys):
    """``check --filter gp-adf --training FILE`` with a training trajectory crossing ±π: every
    fused heading it reports lies in (−π, π]."""
    import json

    from gpfverify.cli import main

    system = tmp_path / "heading.py"
    system.write_text(
        "import numpy as np\n"
        "from gpfverify.models import Sensor, StateSpaceModel\n"
        "system = StateSpaceModel(np.array([[1.0, 1.0], [0.0, 1.0]]), np.diag([1e-3, 1e-4]),\n"
        "    [Sensor(np.array([[1.0, 0.0]]), [[0.04]], circular=(0,)), Sensor(np.array([[1.0, 0.0]]), [[0.09]],\n"
        "     circular=(0,)), Sensor(np.array([[0.0, 1.0]]), [[0.01]])], [3.0, 0.02], np.diag([0.01, 1e-4]),\n"
        "    circular_state=(0,))\n")
    x, y = _crossing_training()
    training = tmp_path / "train.npz"
    np.savez(training, x=x, y=y)
    assert main(["check", f"{system}:system", "--filter", "gp-adf", "--training", str(training),
                 "--steps", "8", "--seed", "3", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    for step in result["per_step"]:
        for key in ("cmf_mean", "dmf_mean"):
            assert -np.pi < step[key][0] <= np.pi


@pytest.mark.parametrize("name", ["pf", "upf"])
def test_particle_filters_average_the_heading_on_the_circle(name):
    """The particle filters' estimate against the exact Kalman filter on the unwrapped problem,
    at every step while the particles straddle ±π: within one posterior standard deviation. A
    coarse bound (a recursive filter's Monte Carlo error is not σ/√N_eff; measured: below 0.5 σ
    with 4000 particles over eight seeds), aimed at a mean taken across the cut, off by about π."""
    from gpfverify.filters.pf import pf_step
    from gpfverify.filters.resampling import Particles
    from gpfverify.filters.upf import upf_step

    step = {"pf": pf_step, "upf": upf_step}[name]
    truth, ys = unwrapped_run()
    expected = kf_by_hand(ys)
    wrapped_ys = ys.copy()
    wrapped_ys[:, :2] = wrap(ys[:, :2])
    model = heading_model()
    rng = np.random.default_rng(8)
    belief = Particles.from_gaussian(model.prior_mean, model.prior_cov, 4000, rng)
    for k, (y, mean) in enumerate(zip(wrapped_ys, expected), start=1):
        result = step(belief, model, y, k=k, rng=rng)
        assert -np.pi < result.mean[0] <= np.pi
        atol = np.sqrt(np.diag(result.cov))
        gap = result.mean - mean
        gap[0] = wrap(gap[0])
        assert np.all(np.abs(gap) <= atol), (k, gap, atol)
        belief = result.posterior
