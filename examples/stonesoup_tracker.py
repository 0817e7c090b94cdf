"""A Stone Soup tracker as ``gpfverify check`` takes it: a constant-velocity target in the plane seen by
two bearing-range radars, written with Stone Soup's own models. ``tracker`` holds the objects a Stone
Soup script has anyway — its predictor (with the transition model), the radars' measurement models,
the prior and the time between scans; gpfverify finds each by its type. The eastern radar sees the
target at a bearing near ±π, which crosses the cut when the target passes y = 0 (Stone Soup marks the
bearing as an angle, a ``Bearing``; so does gpfverify).

    gpfverify check examples/stonesoup_tracker.py:tracker --steps 40 --out out/stonesoup-check

Run as a script, it simulates the target and the radars' detections with Stone Soup and writes them
as the measurements file ``gpfverify check --measurements`` reads (docs/ecosystem.md):

    python examples/stonesoup_tracker.py out/stonesoup-measurements.npz
"""

import datetime
import sys

import numpy as np
from stonesoup.models.measurement.nonlinear import CartesianToBearingRange
from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, ConstantVelocity
from stonesoup.predictor.kalman import UnscentedKalmanPredictor
from stonesoup.types.array import StateVector
from stonesoup.types.state import GaussianState

SCAN = datetime.timedelta(seconds=1)
START = datetime.datetime(2024, 1, 1, 12, 0, 0)

cv = CombinedLinearGaussianTransitionModel([ConstantVelocity(0.05), ConstantVelocity(0.05)])  # [x, vx, y, vy]
radars = [CartesianToBearingRange(ndim_state=4, mapping=(0, 2), noise_covar=np.diag([0.01**2, 2.0**2]),
                                  translation_offset=StateVector(at))  # [bearing, range]
          for at in ([-300.0, 40.0], [250.0, 0.0])]
prior = GaussianState([0.0, 1.0, -20.0, 1.0], np.diag([25.0, 0.5, 25.0, 0.5]), timestamp=START)

tracker = {"predictor": UnscentedKalmanPredictor(cv), "measurement_models": radars, "prior": prior,
           "time_interval": SCAN}


def simulate(steps: int, seed: int = 1):
    """The target's path and one detection per radar and scan, drawn by Stone Soup's models."""
    from stonesoup.types.detection import Detection
    from stonesoup.types.groundtruth import GroundTruthPath, GroundTruthState

    rng = np.random.default_rng(seed)
    state = StateVector([0.0, 1.0, -20.0, 1.0])
    path, scans = GroundTruthPath(), []
    for k in range(1, steps + 1):
        time = START + k * SCAN
        state = cv.function(GaussianState(state, np.eye(4)), time_interval=SCAN) + StateVector(
            rng.multivariate_normal(np.zeros(4), cv.covar(time_interval=SCAN)))
        truth = GroundTruthState(state, timestamp=time)
        path.append(truth)
        scans.append((time, {Detection(radar.function(truth, noise=StateVector(
            rng.multivariate_normal(np.zeros(2), radar.covar()))), timestamp=time, measurement_model=radar)
            for radar in radars}))
    return path, scans


if __name__ == "__main__":
    from gpfverify.adapters.stonesoup import write_measurements

    path, scans = simulate(40)
    print(write_measurements(sys.argv[1], scans, radars, truth=path, time_interval=SCAN))
