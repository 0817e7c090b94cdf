"""A user's own system for ``gpfverify check``: a constant-velocity target in the plane seen by
three sensors — a position fix, a range-and-bearing radar (the bearing is an angle) and a range-only
beacon — written with numpy only.

    gpfverify check examples/three_sensor_system.py:tracker --steps 40 --runs 5 --out check-tracker
"""

import numpy as np

from gpfverify.models import Sensor, StateSpaceModel

DT, Q_ACCEL = 1.0, 0.05
RADAR, BEACON = np.array([100.0, 0.0]), np.array([-60.0, 80.0])

eye = np.eye(2)
F = np.block([[eye, DT * eye], [np.zeros((2, 2)), eye]])                        # x = [p_x, p_y, v_x, v_y]
Q = Q_ACCEL * np.block([[DT**3 / 3 * eye, DT**2 / 2 * eye], [DT**2 / 2 * eye, DT * eye]])


def radar(x):
    """[range, bearing] from the radar, (N, 4) -> (N, 2)."""
    dx, dy = x[:, 0] - RADAR[0], x[:, 1] - RADAR[1]
    return np.stack([np.hypot(dx, dy), np.arctan2(dy, dx)], axis=1)


def beacon(x):
    """Range from the beacon, (N, 4) -> (N, 1)."""
    return np.hypot(x[:, 0] - BEACON[0], x[:, 1] - BEACON[1])[:, None]


tracker = StateSpaceModel(
    transition=F, process_cov=Q,
    sensors=[Sensor(np.eye(2, 4), 4.0 * eye, name="position"),
             Sensor(radar, np.diag([1.0, 0.02**2]), circular=[1], name="range-bearing"),
             Sensor(beacon, [[1.0]], name="range")],
    prior_mean=[0.0, -40.0, 0.0, 4.0], prior_cov=np.diag([9.0, 9.0, 0.25, 0.25]),
    name="three-sensor tracker")
