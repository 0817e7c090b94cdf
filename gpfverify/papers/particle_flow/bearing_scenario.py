"""Bearing-only tracking with one static sensor (seed 003 §3.2).

State [x, ẋ, y, ẏ], sampling period T = 1 s. The target moves at constant velocity (CV) for the
first ``switch_time`` seconds and then turns at a constant rate ω (CT), both linear:

    Φ_CV = [[1, T, 0, 0], [0, 1, 0, 0], [0, 0, 1, T], [0, 0, 0, 1]]
    Φ_CT = [[1, sin ωT/ω, 0, −(1 − cos ωT)/ω], [0, cos ωT, 0, −sin ωT],
            [0, (1 − cos ωT)/ω, 1, sin ωT/ω], [0, sin ωT, 0, cos ωT]]

    x_k = Φ_k x_{k−1} + w_k,  w_k ~ N(0, Q),  Q = diag(q_pos, q_vel, q_pos, q_vel)
    z_k = atan2(y_k − y_s, x_k − x_s) + v_k,   v_k ~ N(0, σ_θ²)

Readings of the seed (its parameter list was lost in extraction): the total duration is 60 s with
the turn from 40 s on; "distance noise variance r1 = 0.05, velocity variance r2 = 0.1" are read
as the process-noise variances of the position and velocity components (q_pos, q_vel — the
noise vector w = [w_xp, w_xv, w_yp, w_yv] is given per component); the bearing noise σ_θ was
lost and is a parameter. The filters know the mode schedule (CV then CT at the true ω).
The bearing is a circular output: residuals and simulated bearings are wrapped to (−π, π].
The model's prior is N(x₀, P₀), P₀ = diag(σ_p², σ_v², σ_p², σ_v²) (σ_p = 10 m, σ_v = 1 m/s by
default; an interpretation, the seed gives no prior).
"""

from __future__ import annotations

import numpy as np

from gpfverify.models import Sensor, StateSpaceModel

INITIAL_STATE = np.array([1000.0, 10.0, 1500.0, 15.0])
SENSOR = np.array([1355.33, 1736.23])


def cv_matrix(period: float) -> np.ndarray:
    return np.array([[1.0, period, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0],
                     [0.0, 0.0, 1.0, period], [0.0, 0.0, 0.0, 1.0]])


def ct_matrix(omega: float, period: float) -> np.ndarray:
    s, c = np.sin(omega * period), np.cos(omega * period)
    return np.array([[1.0, s / omega, 0.0, -(1.0 - c) / omega], [0.0, c, 0.0, -s],
                     [0.0, (1.0 - c) / omega, 1.0, s / omega], [0.0, s, 0.0, c]])


def prior_cov(std_pos: float, std_vel: float) -> np.ndarray:
    """P₀ = diag(σ_p², σ_v², σ_p², σ_v²)."""
    p, v = std_pos**2, std_vel**2
    return np.diag([p, v, p, v])


def bearing_model(q_pos: float, q_vel: float, bearing_std: float, omega: float = np.deg2rad(5.0),
                  switch_time: float = 40.0, period: float = 1.0, sensor: np.ndarray = SENSOR,
                  prior_std_pos: float = 10.0, prior_std_vel: float = 1.0,
                  initial_state: np.ndarray = INITIAL_STATE) -> StateSpaceModel:
    """The CV→CT bearing-only model with prior N(initial_state, :func:`prior_cov`); step k covers
    time ((k − 1)T, kT], CT once (k − 1)T ≥ switch."""
    transitions = (cv_matrix(period), ct_matrix(omega, period))
    sensor = np.asarray(sensor, dtype=float)

    def phi(k: int) -> np.ndarray:
        return transitions[int((k - 1) * period >= switch_time)]

    def h(x, k):
        return np.arctan2(x[:, 2] - sensor[1], x[:, 0] - sensor[0])[:, None]

    def h_jacobian(x, k):
        dx, dy = x[0] - sensor[0], x[2] - sensor[1]
        r2 = dx * dx + dy * dy
        return np.array([[-dy / r2, 0.0, dx / r2, 0.0]])

    return StateSpaceModel(
        lambda x, k: x @ phi(k).T, np.diag([q_pos, q_vel, q_pos, q_vel]).astype(float),
        [Sensor(h, np.array([[bearing_std**2]]), circular=(0,), jacobian=h_jacobian, name="bearing")],
        initial_state, prior_cov(prior_std_pos, prior_std_vel), transition_jacobian=lambda x, k: phi(k),
        name="bearing-only CV/CT")
