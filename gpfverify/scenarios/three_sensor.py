"""The reference user system (SPEC §6): a 4-D constant-velocity target seen by three sensors —
position, range and bearing, range only.

    x = [p_x, p_y, v_x, v_y],   x_k = F x_{k−1} + w_k,  F = [[I, Δt I], [0, I]],
    Q = q [[Δt³/3 I, Δt²/2 I], [Δt²/2 I, Δt I]]                  (white-noise acceleration, full Q)
    sensor 0 (position):        y = [p_x, p_y] + v,              R_0 = diag(σ_p², σ_p²)
    sensor 1 (range-bearing):   y = [‖p − s_1‖, atan2(p_y − s_1y, p_x − s_1x)] + v,  bearing circular
    sensor 2 (range):           y = ‖p − s_2‖ + v

With the defaults the target starts at (0, −40) moving north at 4 m/s and passes west of sensor 1
at (100, 0): its bearing crosses the ±π cut at about k = 10.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from gpfverify.models import Sensor, StateSpaceModel

SENSOR_RANGE_BEARING = (100.0, 0.0)
SENSOR_RANGE = (-60.0, 80.0)


def cv_matrices(dt: float, q: float) -> tuple[np.ndarray, np.ndarray]:
    """F and the full white-noise-acceleration Q of the constant-velocity model."""
    eye = np.eye(2)
    F = np.block([[eye, dt * eye], [np.zeros((2, 2)), eye]])
    Q = q * np.block([[dt**3 / 3 * eye, dt**2 / 2 * eye], [dt**2 / 2 * eye, dt * eye]])
    return F, Q


def range_bearing(position) -> Callable[[np.ndarray], np.ndarray]:
    """x (N, 4) ↦ [‖p − s‖, atan2(p_y − s_y, p_x − s_x)] (N, 2)."""
    s = np.asarray(position, dtype=float)

    def measure(x):
        dx, dy = x[:, 0] - s[0], x[:, 1] - s[1]
        return np.stack([np.hypot(dx, dy), np.arctan2(dy, dx)], axis=1)

    return measure


def range_only(position) -> Callable[[np.ndarray], np.ndarray]:
    """x (N, 4) ↦ ‖p − s‖ (N, 1)."""
    s = np.asarray(position, dtype=float)
    return lambda x: np.hypot(x[:, 0] - s[0], x[:, 1] - s[1])[:, None]


def three_sensor_model(dt: float = 1.0, q: float = 0.05, position_std: float = 2.0,
                       range_std: float = 1.0, bearing_std: float = 0.02,
                       prior_mean=(0.0, -40.0, 0.0, 4.0), prior_std=(3.0, 3.0, 0.5, 0.5),
                       range_bearing_at=SENSOR_RANGE_BEARING, range_at=SENSOR_RANGE) -> StateSpaceModel:
    """The reference three-sensor tracker (module docstring)."""
    F, Q = cv_matrices(dt, q)
    H_position = np.eye(2, 4)
    sensors = (Sensor(H_position, position_std**2 * np.eye(2), name="position"),
               Sensor(range_bearing(range_bearing_at), np.diag([range_std**2, bearing_std**2]),
                      circular=(1,), name="range-bearing"),
               Sensor(range_only(range_at), [[range_std**2]], name="range"))
    return StateSpaceModel(F, Q, sensors, np.asarray(prior_mean, dtype=float),
                           np.diag(np.square(prior_std)), name="three-sensor tracker")
