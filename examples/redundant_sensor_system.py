"""A system whose second sensor has more outputs than the state has components (l = 3 > D = 2):
its cross covariance C_xy can never have full column rank, so Proposition 1's condition fails at
every step; ``gpfverify check`` shows when DMF is exact anyway and when it is not.

    gpfverify check examples/redundant_sensor_system.py:system --steps 30 --out check-redundant
"""

import numpy as np

from gpfverify.models import Sensor, StateSpaceModel

F = np.array([[1.0, 1.0], [0.0, 1.0]])
Q = np.array([[0.1, 0.05], [0.05, 0.1]])


def polar_and_sum(x):
    """[range, bearing, p + v] of the state (position p, velocity v): 3 outputs from 2 states."""
    return np.stack([np.hypot(x[:, 0], x[:, 1]), np.arctan2(x[:, 1], x[:, 0]), x[:, 0] + x[:, 1]], axis=1)


system = StateSpaceModel(
    transition=F, process_cov=Q,
    sensors=[Sensor(np.array([[1.0, 0.0]]), [[0.5]], name="position"),
             Sensor(polar_and_sum, np.diag([0.5, 0.01, 0.5]), circular=[1], name="polar and sum")],
    prior_mean=[5.0, 1.0], prior_cov=np.eye(2), name="redundant sensor")
