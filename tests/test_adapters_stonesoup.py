"""``gpfverify.adapters.stonesoup`` against Stone Soup itself.

* The converted model is the Stone Soup model: its functions equal the measurement equations written
  here by hand (mapping, offsets), its angle outputs are where Stone Soup puts a ``Bearing`` or an
  ``Elevation``, a linear model becomes its matrix.
* gpfverify's KF, EKF and UKF on the converted model equal Stone Soup's own predictors and updaters on
  the Stone Soup model at every step, to rounding: each sensor's filter and the centralized filter on
  the stacked measurement (Stone Soup's combined measurement model), with a bearing whose sigma
  points straddle ±π. For the UKF the sigma-point parameters are matched and the weighted mean of an
  angle made Stone Soup's (atan2 of the weighted sines and cosines, written here): that is the one
  documented difference of definition (docs/ecosystem.md); without it the two differ by the
  difference of the two means, which is measured in benchmarks/results/adapters.md.
* Detections over time become the measurements file ``check --measurements`` reads; run_fusion's
  results become Stone Soup tracks on which Stone Soup's OSPA metric equals the distance computed here
  and its plotter draws.
* ``gpfverify check SYSTEM.py:NAME`` accepts Stone Soup objects as they are.
"""

from __future__ import annotations

import datetime
import re
import json

import numpy as np
import pytest
from stonesoup.models.measurement.linear import LinearGaussian
from stonesoup.models.measurement.nonlinear import (CartesianToBearingRange, CartesianToElevationBearingRange,
                                                    CombinedReversibleGaussianMeasurementModel)
from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, ConstantVelocity
from stonesoup.predictor.kalman import ExtendedKalmanPredictor, KalmanPredictor, UnscentedKalmanPredictor
from stonesoup.types.array import StateVector
from stonesoup.types.detection import Detection
from stonesoup.types.groundtruth import GroundTruthPath, GroundTruthState
from stonesoup.types.hypothesis import SingleHypothesis
from stonesoup.types.state import GaussianState
from stonesoup.updater.kalman import ExtendedKalmanUpdater, KalmanUpdater, UnscentedKalmanUpdater

import gpfverify.filters.sigma_points
from gpfverify.adapters import stonesoup as adapter
from gpfverify.angles import wrap
from gpfverify.errors import InputError
from gpfverify.filters.families import gaussian_family
from gpfverify.filters.records import Gaussian
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.model_fusion import run_fusion
from gpfverify.models import Sensor, StateSpaceModel
from gpfverify.tolerances import algebra_rtol

DT = datetime.timedelta(seconds=1)
START = datetime.datetime(2024, 1, 1, 12, 0, 0)
#: a sensor west of the origin and one east of it: the target, near the origin heading west, is seen
#: by the eastern sensor at a bearing near ±π, and crosses it
WEST, EAST = (-300.0, 40.0), (250.0, 0.0)


def cv_model(q: float = 0.05):
    return CombinedLinearGaussianTransitionModel([ConstantVelocity(q), ConstantVelocity(q)])


def bearing_range(at, bearing_sd: float = 0.02, range_sd: float = 2.0):
    return CartesianToBearingRange(ndim_state=4, mapping=(0, 2), noise_covar=np.diag([bearing_sd**2, range_sd**2]),
                                   translation_offset=StateVector(list(at)))


def prior_state():
    return GaussianState(StateVector([5.0, -3.0, 1.0, 0.2]), np.diag([25.0, 1.0, 25.0, 1.0]), timestamp=START)


def system(measurement_models):
    return adapter.state_space_model(cv_model(), measurement_models, prior_state(), DT)


def atan2_mean(points, weights, circular):
    """Stone Soup's weighted mean of angles (``Angle.average``): atan2(Σ w sin a, Σ w cos a); other
    components the plain weighted mean."""
    points = np.asarray(points, dtype=float)
    mean = np.einsum("s,...se->...e", weights, points)
    for i in circular:
        mean[..., i] = np.arctan2(np.einsum("s,...s->...", weights, np.sin(points[..., i])),
                                  np.einsum("s,...s->...", weights, np.cos(points[..., i])))
    return mean


def stonesoup_run(predictor, updater, measurement_model, ys):
    """Stone Soup's own filter over the measurements ys (T, l): posterior means and covariances."""
    state, means, covs = prior_state(), [], []
    for t, y in enumerate(ys, start=1):
        prediction = predictor.predict(state, timestamp=START + t * DT)
        detection = Detection(StateVector(y), timestamp=prediction.timestamp, measurement_model=measurement_model)
        state = updater.update(SingleHypothesis(prediction, detection))
        means.append(np.asarray(state.state_vector, dtype=float).ravel())
        covs.append(np.asarray(state.covar, dtype=float))
    return np.array(means), np.array(covs)


def gpfverify_run(family, model, ys, params=SigmaParams()):
    chosen = gaussian_family(family, params)
    belief, means, covs = Gaussian(model.prior_mean, model.prior_cov), [], []
    for k, y in enumerate(ys, start=1):
        belief = chosen.step(belief, model, y, k=k).posterior
        means.append(belief.mean)
        covs.append(belief.cov)
    return np.array(means), np.array(covs)


def crossing_measurements(model, steps=12, seed=5):
    """A simulated run in which the eastern sensor's bearing crosses ±π (checked)."""
    rng = np.random.default_rng(seed)
    x0 = np.array([5.0, -3.0, -3.0, 0.6])  # y crosses 0 near step 5: the eastern bearing passes ±π
    truth, ys = model.simulate(steps, rng, x0=x0)
    return truth, ys


def assert_filters_agree(ours, theirs, model):
    means, covs = ours
    ref_means, ref_covs = theirs
    rtol = algebra_rtol(max(np.linalg.cond(c) for c in ref_covs))
    mean_scale = np.abs(ref_means).max() + np.sqrt(np.abs(ref_covs).max())
    diff = means - ref_means
    if model.circular_state:
        diff[:, list(model.circular_state)] = wrap(diff[:, list(model.circular_state)])
    np.testing.assert_allclose(diff, 0.0, rtol=0, atol=rtol * mean_scale)
    np.testing.assert_allclose(covs, ref_covs, rtol=0, atol=rtol * np.abs(ref_covs).max())


# -- the converted model ----------------------------------------------------------------------------

def test_the_model_is_the_stone_soup_model_written_by_hand():
    west, east = bearing_range(WEST), bearing_range(EAST)
    model = system([west, east, LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.eye(2))])
    assert model.sensor_circular == ((0,), (0,), ())
    x = np.random.default_rng(0).normal(scale=50.0, size=(7, 4))
    for sensor, (sx, sy) in zip(model.sensors[:2], (WEST, EAST)):  # bearing first, then range
        expected = np.stack([np.arctan2(x[:, 2] - sy, x[:, 0] - sx), np.hypot(x[:, 0] - sx, x[:, 2] - sy)], axis=1)
        got = model.measures[model.sensors.index(sensor)](x)
        np.testing.assert_allclose(wrap(got[:, 0] - expected[:, 0]), 0.0, atol=algebra_rtol() * np.pi)
        np.testing.assert_allclose(got[:, 1], expected[:, 1], rtol=algebra_rtol())
    np.testing.assert_array_equal(model.transition.matrix, np.kron(np.eye(2), [[1.0, 1.0], [0.0, 1.0]]))
    position = model.sensor_model(2).linear_matrices()[1]
    np.testing.assert_array_equal(position, [[1, 0, 0, 0], [0, 0, 1, 0]])  # the mapping (0, 2)
    np.testing.assert_allclose(model.Q, cv_model().covar(time_interval=DT), rtol=0, atol=0)
    np.testing.assert_array_equal(model.R[:2, :2], np.diag([0.02**2, 2.0**2]))


def test_elevation_and_bearing_are_angle_outputs_in_three_dimensions():
    radar = CartesianToElevationBearingRange(ndim_state=6, mapping=(0, 2, 4), noise_covar=np.diag([1e-4, 1e-4, 1.0]),
                                             translation_offset=StateVector([10.0, -5.0, 2.0]))
    cv3 = CombinedLinearGaussianTransitionModel([ConstantVelocity(0.1)] * 3)
    prior = GaussianState(StateVector([100.0, 1.0, 50.0, 0.0, 30.0, 0.5]), np.eye(6))
    model = adapter.state_space_model(cv3, [radar], prior, DT)
    assert model.sensor_circular == ((0, 1),)  # Elevation, Bearing; range is not an angle
    x = np.array([[100.0, 1.0, 50.0, 0.0, 30.0, 0.5], [-20.0, 0.0, -40.0, 0.0, 3.0, 0.0]])
    d = x[:, [0, 2, 4]] - [10.0, -5.0, 2.0]
    rho = np.linalg.norm(d, axis=1)
    expected = np.stack([np.arcsin(d[:, 2] / rho), np.arctan2(d[:, 1], d[:, 0]), rho], axis=1)
    np.testing.assert_allclose(model.h(x), expected, rtol=algebra_rtol(), atol=algebra_rtol() * np.pi)


# -- the filters against Stone Soup's -----------------------------------------------------------------

def test_the_kalman_filter_equals_stone_soups():
    sensors = [LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.diag([4.0, 9.0])),
               LinearGaussian(ndim_state=4, mapping=(1, 3), noise_covar=np.diag([0.5, 0.5]))]
    model = system(sensors)
    _, ys = model.simulate(15, np.random.default_rng(2))
    combined = LinearGaussian(ndim_state=4, mapping=(0, 2, 1, 3), noise_covar=np.diag([4.0, 9.0, 0.5, 0.5]))
    assert_filters_agree(gpfverify_run("kf", model, ys),
                         stonesoup_run(KalmanPredictor(cv_model()), KalmanUpdater(combined), combined, ys), model)
    for m, mm in enumerate(sensors):
        block = model.blocks[m]
        assert_filters_agree(gpfverify_run("kf", model.sensor_model(m), ys[:, block]),
                             stonesoup_run(KalmanPredictor(cv_model()), KalmanUpdater(mm), mm, ys[:, block]), model)


def test_the_ekf_equals_stone_soups_with_its_jacobian_across_the_bearing_cut():
    """Step by step from Stone Soup's previous posterior: Stone Soup's Jacobian of a nonlinear model is a
    forward difference with step 1e8 ulp (at least 1e-8), whose rounding (≈ eps/1e-8 relative) turns
    rounding-level differences of two recursions into differences of 1e-8 in the Jacobian and more in
    the posterior; from the same belief the two filters compute the same numbers."""
    sensors = [bearing_range(WEST), bearing_range(EAST)]
    model = system(sensors)
    truth, ys = crossing_measurements(model)
    east = ys[:, model.blocks[1]]
    assert np.any(east[:, 0] > 3.0) and np.any(east[:, 0] < -3.0)  # the eastern bearing crosses ±π
    ekf = gaussian_family("ekf")
    for m, mm in enumerate(sensors):
        block, sensor_model = model.blocks[m], model.sensor_model(m)
        ref_means, ref_covs = stonesoup_run(ExtendedKalmanPredictor(cv_model()), ExtendedKalmanUpdater(mm), mm,
                                            ys[:, block])
        beliefs = [Gaussian(model.prior_mean, model.prior_cov)] + [Gaussian(*b) for b in zip(ref_means, ref_covs)]
        steps = [ekf.step(b, sensor_model, y, k=k).posterior for k, (b, y) in enumerate(zip(beliefs, ys[:, block]), 1)]
        assert_filters_agree((np.array([s.mean for s in steps]), np.array([s.cov for s in steps])),
                             (ref_means, ref_covs), model)


@pytest.mark.parametrize("alpha, beta, kappa", [(1.0, 0.0, 2.0), (0.5, 2.0, 1.0)])
def test_the_ukf_equals_stone_soups_across_the_bearing_cut(monkeypatch, alpha, beta, kappa):
    monkeypatch.setattr(gpfverify.filters.sigma_points, "weighted_mean", atan2_mean)
    params = SigmaParams(alpha, beta, kappa)
    sensors = [bearing_range(WEST), bearing_range(EAST)]
    model = system(sensors)
    _, ys = crossing_measurements(model)
    predictor = UnscentedKalmanPredictor(cv_model(), alpha=alpha, beta=beta, kappa=kappa)
    combined = CombinedReversibleGaussianMeasurementModel(sensors)
    central = stonesoup_run(predictor, UnscentedKalmanUpdater(combined, alpha=alpha, beta=beta, kappa=kappa),
                            combined, ys)
    assert_filters_agree(gpfverify_run("ukf", model, ys, params), central, model)
    for m, mm in enumerate(sensors):
        block = model.blocks[m]
        theirs = stonesoup_run(predictor, UnscentedKalmanUpdater(mm, alpha=alpha, beta=beta, kappa=kappa), mm,
                               ys[:, block])
        assert_filters_agree(gpfverify_run("ukf", model.sensor_model(m), ys[:, block], params), theirs, model)


def test_without_the_angle_flag_the_eastern_sensor_is_far_from_stone_soup(monkeypatch):
    """The other side: the same UKF with the bearing treated as a plain number is not Stone Soup's."""
    monkeypatch.setattr(gpfverify.filters.sigma_points, "weighted_mean", atan2_mean)
    east = bearing_range(EAST)
    model = system([east])
    _, ys = crossing_measurements(model)
    plain = StateSpaceModel(model.transition.matrix, model.Q,
                            [Sensor(model.measures[0], model.sensors[0].noise_cov, circular=())],
                            model.prior_mean, model.prior_cov)
    ours, _ = gpfverify_run("ukf", plain, ys)
    theirs, _ = stonesoup_run(UnscentedKalmanPredictor(cv_model(), alpha=1.0, beta=0.0, kappa=2.0),
                              UnscentedKalmanUpdater(east, alpha=1.0, beta=0.0, kappa=2.0), east, ys)
    assert np.abs(ours - theirs).max() > 1.0


# -- detections in, tracks out --------------------------------------------------------------------------

def test_detections_become_the_measurements_file_of_check(tmp_path):
    from gpfverify.experiments.check import logged_measurements

    sensors = [bearing_range(WEST), bearing_range(EAST)]
    model = system(sensors)
    truth, ys = crossing_measurements(model, steps=6)
    times = [START + t * DT for t in range(1, 7)]
    scans = [(time, {Detection(StateVector(y[model.blocks[m]]), timestamp=time, measurement_model=mm)
                     for m, mm in enumerate(sensors)}) for time, y in zip(times, ys)]
    path_truth = GroundTruthPath([GroundTruthState(StateVector(x), timestamp=time) for x, time in zip(truth, times)])
    path = adapter.write_measurements(tmp_path / "m.npz", scans, sensors, truth=path_truth, time_interval=DT)
    read_truth, read_ys = logged_measurements(str(path), model)
    np.testing.assert_array_equal(read_ys, ys)
    np.testing.assert_array_equal(read_truth, truth)
    # a sensor's own copy of its measurement model (as Stone Soup's sensors make one per scan) is recognised
    copy = bearing_range(EAST)
    again = adapter.measurements([Detection(StateVector(ys[0, 2:]), timestamp=times[0], measurement_model=copy),
                                  Detection(StateVector(ys[0, :2]), timestamp=times[0], measurement_model=sensors[0])],
                                 sensors)
    np.testing.assert_array_equal(again.y, ys[:1])


def test_a_missing_detection_or_a_foreign_model_is_refused():
    sensors = [bearing_range(WEST), bearing_range(EAST)]
    only_one = [Detection(StateVector([0.1, 10.0]), timestamp=START, measurement_model=sensors[0])]
    with pytest.raises(InputError, match=r"no detection from sensor\(s\) \[1\]"):
        adapter.measurements(only_one, sensors)
    stranger = bearing_range((0.0, 0.0))
    with pytest.raises(InputError, match="not one of the 2 given"):
        adapter.measurements(only_one + [Detection(StateVector([0.1, 10.0]), timestamp=START,
                                                   measurement_model=stranger)], sensors)
    uneven = [Detection(StateVector([0.1, 10.0]), timestamp=START + s * DT, measurement_model=sensors[0])
              for s in (0, 1, 3)]
    with pytest.raises(InputError, match="time steps"):
        adapter.measurements(uneven, sensors[:1])


def test_fusion_results_are_stone_soup_tracks_for_its_metrics_and_plotter():
    import matplotlib
    matplotlib.use("Agg")
    from stonesoup.measures import Euclidean
    from stonesoup.metricgenerator.ospametric import OSPAMetric
    from stonesoup.plotter import Plotter

    sensors = [bearing_range(WEST), bearing_range(EAST)]
    model = system(sensors)
    truth, ys = crossing_measurements(model, steps=8)
    fused = run_fusion(model, ys, family="ukf", methods=("cmf", "dmf", "cc"))
    tracks = adapter.tracks(fused, START, DT)
    assert set(tracks) == {"cmf", "dmf", "cc", "sensor 0", "sensor 1"}
    cmf = tracks["cmf"]
    assert [s.timestamp for s in cmf] == [START + k * DT for k in range(1, 9)]
    np.testing.assert_array_equal(np.array([np.asarray(s.state_vector, float).ravel() for s in cmf]),
                                  fused.means("cmf"))
    path = GroundTruthPath([GroundTruthState(StateVector(x), timestamp=START + k * DT)
                            for k, x in enumerate(truth, start=1)])
    ospa = OSPAMetric(c=1e6, p=1, measure=Euclidean(mapping=[0, 2]))
    values = ospa.compute_OSPA_distance  # one track, one truth: OSPA is their position distance
    expected = np.hypot(*(fused.means("cmf")[:, [0, 2]] - truth[:, [0, 2]]).T)
    got = [values([s], [g]).value for s, g in zip(cmf, path)]
    np.testing.assert_allclose(got, expected, rtol=algebra_rtol())
    plotter = Plotter()
    plotter.plot_tracks(set(tracks.values()), [0, 2], uncertainty=True)
    assert len(plotter.ax.lines) >= len(tracks)


# -- check on Stone Soup objects -----------------------------------------------------------------------

SYSTEM_FILE = '''
import datetime
import numpy as np
from stonesoup.models.measurement.nonlinear import CartesianToBearingRange
from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, ConstantVelocity
from stonesoup.predictor.kalman import UnscentedKalmanPredictor
from stonesoup.types.array import StateVector
from stonesoup.types.state import GaussianState

cv = CombinedLinearGaussianTransitionModel([ConstantVelocity(0.05), ConstantVelocity(0.05)])
radars = [CartesianToBearingRange(ndim_state=4, mapping=(0, 2), noise_covar=np.diag([4e-4, 4.0]),
                                  translation_offset=StateVector(at)) for at in ([-300.0, 40.0], [250.0, 0.0])]
prior = GaussianState([5.0, -3.0, 1.0, 0.2], np.diag([25.0, 1.0, 25.0, 1.0]))
tracker = {"predictor": UnscentedKalmanPredictor(cv), "measurement_models": radars, "prior": prior,
           "time_interval": datetime.timedelta(seconds=1)}
no_interval = {"transition_model": cv, "measurement_models": radars, "prior": prior}
'''


def test_check_accepts_stone_soup_objects_as_they_are(tmp_path, capsys):
    from gpfverify.cli import main

    (tmp_path / "tracker.py").write_text(SYSTEM_FILE)
    assert main(["check", f"{tmp_path / 'tracker.py'}:tracker", "--steps", "4", "--methods", "cmf,dmf",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["steps"] == 4 and len(out["per_step"]) == 4
    assert [s["circular"] for s in out["sensors"]] == [[0], [0]]


def test_check_says_what_a_stone_soup_system_lacks(tmp_path):
    from gpfverify.systems import load_system

    (tmp_path / "tracker.py").write_text(SYSTEM_FILE)
    with pytest.raises(InputError, match=r"tracker.py:no_interval: .*exactly one datetime.timedelta"):
        load_system(f"{tmp_path / 'tracker.py'}:no_interval")


def test_the_objects_of_a_stone_soup_tracker_are_found_by_type():
    """A tracker's parts as a script has them: a hypothesiser holding the predictor (the transition
    model) and an updater without a model of its own (multi-sensor detections carry theirs), an
    initiator with the prior — and a measurement model of its own, which converts detections and is
    not a sensor — and the radars."""
    from stonesoup.hypothesiser.distance import DistanceHypothesiser
    from stonesoup.initiator.simple import SimpleMeasurementInitiator
    from stonesoup.measures import Mahalanobis

    radars = [bearing_range(WEST), bearing_range(EAST)]
    hypothesiser = DistanceHypothesiser(UnscentedKalmanPredictor(cv_model()), UnscentedKalmanUpdater(None),
                                        Mahalanobis())
    initiator = SimpleMeasurementInitiator(prior_state(), LinearGaussian(ndim_state=4, mapping=(0, 2),
                                                                         noise_covar=np.eye(2)))
    model = adapter.system_from_objects([hypothesiser, initiator, radars, DT])
    assert [s.name for s in model.sensors] == ["CartesianToBearingRange 0", "CartesianToBearingRange 1"]
    np.testing.assert_array_equal(model.prior_mean, np.asarray(prior_state().state_vector, float).ravel())
    x = np.random.default_rng(1).normal(size=(3, 4))
    np.testing.assert_array_equal(model.h(x), system(radars).h(x))


# -- what the user's models and detections do is the user's error ------------------------------------

FAILING_MODEL = '''
import datetime
import numpy as np
from stonesoup.models.measurement.nonlinear import CartesianToBearingRange
from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, ConstantVelocity
from stonesoup.types.state import GaussianState

class Broken(CartesianToBearingRange):
    def function(self, state, noise=False, **kwargs):
        raise ValueError("my model fails")

cv = CombinedLinearGaussianTransitionModel([ConstantVelocity(0.1), ConstantVelocity(0.1)])
tracker = {"transition_model": cv,
           "measurement_models": [Broken(ndim_state=4, mapping=(0, 2), noise_covar=np.diag([0.01, 1.0]))],
           "prior": GaussianState(np.array([[1.0], [0.1], [1.0], [0.1]]), np.eye(4)),
           "time_interval": datetime.timedelta(seconds=1)}
'''


def test_a_stone_soup_model_whose_function_raises_is_the_users_error(tmp_path, capsys):
    from gpfverify.cli import main

    (tmp_path / "tracker.py").write_text(FAILING_MODEL)
    assert main(["check", f"{tmp_path / 'tracker.py'}:tracker", "--steps", "3", "--json"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.splitlines() == [
        "gpfverify check: error: tracker.py:tracker: measurement model Broken: function raised ValueError: my "
        "model fails"], err


@pytest.mark.parametrize("values, what", [([0.1], "holds 1 value(s)"), ([0.1, 10.0, 3.0], "holds 3 value(s)"),
                                          ([0.1 + 1j, 10.0], "holds complex numbers")])
def test_a_detection_of_the_wrong_length_is_refused_not_split_across_sensors(tmp_path, values, what):
    """Three values from the first sensor and one from the second stack to the four values the two
    sensors measure: the values were split across the sensors at the wrong place, and check ran on
    shifted data. Now each detection must hold what its own model measures."""
    sensors = [bearing_range(WEST), bearing_range(EAST)]
    second = [0.2] if len(values) == 3 else [0.2, 20.0]  # with three first values, four in all
    detections = [Detection(StateVector(values), timestamp=START, measurement_model=sensors[0]),
                  Detection(StateVector(second), timestamp=START, measurement_model=sensors[1])]
    for write in (lambda: adapter.measurements(detections, sensors),
                  lambda: adapter.write_measurements(tmp_path / "m.npz", detections, sensors)):
        with pytest.raises(InputError, match=re.escape(f"the detection of sensor 0 at {START} {what}")):
            write()
    assert not (tmp_path / "m.npz").exists()
