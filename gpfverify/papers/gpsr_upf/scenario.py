"""SINS/GPS integrated navigation (seed 001 §2–3): a generated flight, the 15-state φ-angle error
model in ENU, the true and the approximate ("inaccurate") model, and GPS measurements.

State (filter units chosen for conditioning; the SI matrices are scaled by T = diag(units)):

    x = [φ_E, φ_N, φ_U (arcmin), δv_E, δv_N, δv_U (m/s), δp_E, δp_N, δp_U (m),
         ε_x, ε_y, ε_z (°/h, gyro drift), ∇_x, ∇_y, ∇_z (mg, accelerometer bias)]

Position errors are kept in local metres (δp_E = (R_N + h) cos L δλ, δp_N = (R_M + h) δL,
δp_U = δh) instead of the paper's (δL, δλ, δh), a linear change of variables.

Continuous error dynamics (first order; Titterton & Weston ch. 12, Qin Yongyuan's φ-angle form),
with ω_in = ω_ie + ω_en, ω_ie = [0, Ω cos L, Ω sin L], ω_en = [−v_N/(R_M+h), v_E/(R_N+h),
v_E tan L/(R_N+h)]:

    φ̇  = −ω_in × φ + δω_in(δv, δp) − C_b^n ε + w_g
    δv̇ = f^n × φ − (2ω_ie + ω_en) × δv + v × (2δω_ie + δω_en)(δv, δp) + δg(δh) + C_b^n ∇ + w_a
    δṗ = δv
    ε̇  = −ε/T_g + w_ε,   ∇̇ = −∇/T_a + w_∇

(terms of order v/R² in the position derivatives of ω_en are dropped; δg = [0, 0, 2g/R δh]).
Discretised at Δt = 1 s by Φ_k = I + F(t_k)Δt and Q = G Q_c Gᵀ Δt (‖FΔt‖ ≪ 1 apart from the
exact position–velocity integration), plus a small position noise floor (numerical integration of
the position, and it keeps Q positive definite for the particle filters' transition density).

Model mismatch (the paper does not say how its model is inaccurate; our choice, physical and
manoeuvre dependent):

* transition: the approximate model evaluates the f^n × φ coupling with the level, unaccelerated
  specific force f̂^n = [0, 0, g] ("stale" cruise specific force). It is exact in straight level
  cruise and wrong during take-off, climb, acceleration and the turn; the residual is
  Δt (f^n − f̂^n) × φ in the velocity rows only.
* accelerometer scale factor (``accel_scale_ppm``, default 0, so absent): the accelerometers read
  (1 + s) times the specific force on every axis, which the SINS integrates; the true model gains
  the forcing Δt s f^n in the velocity rows (an isotropic scale factor turns with the body, so it
  does not depend on the attitude), which the approximate model lacks. Unlike the f^n × φ
  mismatch it does not scale with the attitude error, so it is not small whatever the filter
  knows of φ: in cruise it is a vertical acceleration error s g, beyond the accelerometer-bias
  state's σ = 0.1 mg for s above about 100 ppm, and in manoeuvres it follows the acceleration. The
  residual the GP learns is then Δt ((f^n − f̂^n) × φ + s f^n).
* process noise (``accel_noise_scale``, default 1, so absent): the flight's accelerometer white
  noise is this multiple of the value the filters' model assumes, so the velocity block of the true
  Q is the model's times its square — a mis-specified Q, the error seed 001 says its GP learns
  ("獲取系統的回歸模型及系統噪聲協方差"): the residual's targets carry the true noise, which the
  GP's noise variance learns, while the model keeps the nominal Q.
* measurement: z = [δp; δv] + v (SINS minus GPS) is linear and known, so it is the same in both
  models. (A GPS antenna lever arm would be a measurement mismatch; in a trial with a 3 m lever arm
  under 10 m GPS noise the measurement-residual GP learned nothing useful, so it is left out.)

Noise (seed 001 §3; items marked *interpretation* are not given in the paper): gyro constant drift
0.01°/h and first-order Markov drift 0.01°/h lumped into one Markov state per axis, stationary
σ = 0.01√2 °/h, T_g = 3600 s (*interpretation*); accelerometer bias 1e-4 g constant + 1e-5 g
random lumped likewise, T_a = 1800 s (*interpretation*); gyro angle random walk 0.001°/√h and
accelerometer white noise 1e-5 g/√Hz (*interpretation*); GPS position noise 10 m (paper), GPS
velocity noise 0.1 m/s (*interpretation*). Initial errors: velocity 0.5 m/s, position 10 m
(paper); attitude 1′, 1′, 3′ (E, N, U; *interpretation*).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from gpfverify.errors import InputError
from gpfverify.models import Sensor, StateSpaceModel

STATE_DIM = 15
MEAS_DIM = 6
ATTITUDE, VELOCITY, POSITION = slice(0, 3), slice(3, 6), slice(6, 9)
GYRO, ACCEL = slice(9, 12), slice(12, 15)

EARTH_RATE = 7.292115e-5  # rad/s
EQUATORIAL_RADIUS = 6378137.0  # m
ECCENTRICITY_SQ = 0.00669438
G0 = 9.7803267714  # m/s²
ARCMIN = np.pi / (180.0 * 60.0)  # rad
DEG_PER_HOUR = np.pi / 180.0 / 3600.0  # rad/s
MILLI_G = 1e-3 * G0  # m/s²
#: filter units -> SI, per state
UNITS = np.array([ARCMIN] * 3 + [1.0] * 6 + [DEG_PER_HOUR] * 3 + [MILLI_G] * 3)


def _schedule(knots: tuple) -> tuple[np.ndarray, np.ndarray]:
    t, v = zip(*knots)
    return np.array(t, float), np.array(v, float)


@dataclass(frozen=True)
class FlightProfile:
    """Piecewise-linear schedules (time s, value) of longitudinal acceleration (m/s²), pitch (°) and
    turn rate (°/s): take-off roll and climb 0–200 s, cruise, acceleration and a coordinated turn
    500–600 s, cruise to the end (seed 001 §3)."""

    acceleration: tuple = ((0, 0), (2, 2.5), (38, 2.5), (40, 0.5), (60, 0.5), (62, 0.2), (178, 0.2),
                           (180, 0), (500, 0), (505, 0.4), (595, 0.4), (600, 0), (1e9, 0))
    pitch_deg: tuple = ((0, 0), (40, 0), (50, 8), (180, 8), (195, 0), (1e9, 0))
    turn_rate_deg: tuple = ((0, 0), (505, 0), (510, 1.8), (590, 1.8), (595, 0), (1e9, 0))
    heading0_deg: float = 45.0


@dataclass(frozen=True)
class SinsGpsConfig:
    """Everything that defines the scenario; see the module docstring for the sources."""

    duration: float = 1000.0
    dt: float = 1.0
    substeps: int = 10
    latitude0_deg: float = 34.0
    longitude0_deg: float = 109.0
    height0: float = 1000.0
    profile: FlightProfile = field(default_factory=FlightProfile)
    gyro_markov_deg_h: float = 0.01 * np.sqrt(2.0)
    gyro_corr_time: float = 3600.0
    accel_markov_g: float = float(np.hypot(1e-4, 1e-5))
    accel_corr_time: float = 1800.0
    gyro_arw_deg_sqrt_h: float = 0.001
    accel_white_g_sqrt_hz: float = 1e-5
    position_floor: float = 0.05  # m per step
    gps_position_sd: float = 10.0
    gps_velocity_sd: float = 0.1
    initial_attitude_arcmin: tuple = (1.0, 1.0, 3.0)
    initial_velocity_sd: float = 0.5
    initial_position_sd: float = 10.0
    accel_scale_ppm: float = 0.0
    accel_noise_scale: float = 1.0

    @property
    def steps(self) -> int:
        return int(round(self.duration / self.dt))

    def initial_cov(self) -> np.ndarray:
        """Prior covariance of the error state (filter units)."""
        sd = np.concatenate([self.initial_attitude_arcmin, [self.initial_velocity_sd] * 3,
                             [self.initial_position_sd] * 3,
                             [self.gyro_markov_deg_h] * 3, [self.accel_markov_g * 1e3] * 3])
        return np.diag(sd**2)

    def measurement_cov(self) -> np.ndarray:
        return np.diag([self.gps_position_sd**2] * 3 + [self.gps_velocity_sd**2] * 3)


@dataclass(frozen=True)
class Flight:
    """Nominal trajectory sampled at the filter steps k = 0..K: time (K+1,), latitude, longitude
    (rad), height (m), velocity ENU (K+1, 3), attitude [yaw, pitch, roll] (K+1, 3) rad (yaw
    clockwise from north), specific force f^n (K+1, 3), body-to-nav DCM C_b^n (K+1, 3, 3)."""

    time: np.ndarray
    latitude: np.ndarray
    longitude: np.ndarray
    height: np.ndarray
    velocity: np.ndarray
    attitude: np.ndarray
    specific_force: np.ndarray
    cbn: np.ndarray

    def manoeuvring(self, tol: float = 0.05) -> np.ndarray:
        """(K+1,) True where the specific force departs from level cruise by more than ``tol`` m/s²."""
        level = np.array([0.0, 0.0, 1.0]) * gravity(self.latitude, self.height)[:, None]
        return np.linalg.norm(self.specific_force - level, axis=1) > tol


def gravity(latitude, height):
    """Normal gravity (m/s²), Somigliana-type closed form with the free-air correction."""
    s2 = np.sin(latitude) ** 2
    return G0 * (1 + 0.00193185138639 * s2) / np.sqrt(1 - ECCENTRICITY_SQ * s2) - 3.086e-6 * height


def radii(latitude, height):
    """(R_M + h, R_N + h): meridian and prime-vertical radii of curvature plus height."""
    w = np.sqrt(1 - ECCENTRICITY_SQ * np.sin(latitude) ** 2)
    return EQUATORIAL_RADIUS * (1 - ECCENTRICITY_SQ) / w**3 + height, EQUATORIAL_RADIUS / w + height


def body_to_nav(yaw, pitch, roll) -> np.ndarray:
    """C_b^n = R_z(−yaw) R_x(pitch) R_y(roll) for body axes (right, forward, up) and ENU, batched."""
    cy, sy, cp, sp, cr, sr = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    one, zero = np.ones_like(yaw), np.zeros_like(yaw)
    rz = np.stack([np.stack([cy, sy, zero], -1), np.stack([-sy, cy, zero], -1), np.stack([zero, zero, one], -1)], -2)
    rx = np.stack([np.stack([one, zero, zero], -1), np.stack([zero, cp, -sp], -1), np.stack([zero, sp, cp], -1)], -2)
    ry = np.stack([np.stack([cr, zero, sr], -1), np.stack([zero, one, zero], -1), np.stack([-sr, zero, cr], -1)], -2)
    return rz @ rx @ ry


def _earth_rates(lat, height, vel):
    rm, rn = radii(lat, height)
    w_ie = np.stack([np.zeros_like(lat), EARTH_RATE * np.cos(lat), EARTH_RATE * np.sin(lat)], -1)
    w_en = np.stack([-vel[..., 1] / rm, vel[..., 0] / rn, vel[..., 0] * np.tan(lat) / rn], -1)
    return w_ie, w_en


def generate_flight(config: SinsGpsConfig = SinsGpsConfig()) -> Flight:
    """Integrate the profile on a grid of ``substeps`` per filter step and sample it."""
    p = config.profile
    fine_dt = config.dt / config.substeps
    t = np.arange(config.steps * config.substeps + 1) * fine_dt
    accel = np.interp(t, *_schedule(p.acceleration))
    pitch = np.radians(np.interp(t, *_schedule(p.pitch_deg)))
    turn_rate = np.radians(np.interp(t, *_schedule(p.turn_rate_deg)))
    speed = np.concatenate([[0.0], np.cumsum(0.5 * (accel[1:] + accel[:-1]) * fine_dt)])
    yaw = np.radians(p.heading0_deg) + np.concatenate(
        [[0.0], np.cumsum(0.5 * (turn_rate[1:] + turn_rate[:-1]) * fine_dt)])
    vel = np.stack([speed * np.cos(pitch) * np.sin(yaw), speed * np.cos(pitch) * np.cos(yaw),
                    speed * np.sin(pitch)], -1)
    lat, lon, h = (np.empty_like(t) for _ in range(3))
    lat[0], lon[0], h[0] = np.radians(config.latitude0_deg), np.radians(config.longitude0_deg), config.height0
    for i in range(t.size - 1):  # trapezoidal position integration
        v_mid = 0.5 * (vel[i] + vel[i + 1])
        rm, rn = radii(lat[i], h[i])
        lat[i + 1] = lat[i] + v_mid[1] / rm * fine_dt
        lon[i + 1] = lon[i] + v_mid[0] / (rn * np.cos(lat[i])) * fine_dt
        h[i + 1] = h[i] + v_mid[2] * fine_dt
    roll = np.arctan2(speed * turn_rate, gravity(lat, h))  # coordinated turn
    w_ie, w_en = _earth_rates(lat, h, vel)
    vdot = np.gradient(vel, fine_dt, axis=0)
    f_n = vdot + np.cross(2 * w_ie + w_en, vel) + np.stack([0 * h, 0 * h, gravity(lat, h)], -1)
    idx = np.arange(0, t.size, config.substeps)
    att = np.stack([yaw, pitch, roll], -1)[idx]
    return Flight(t[idx], lat[idx], lon[idx], h[idx], vel[idx], att, f_n[idx],
                  body_to_nav(att[:, 0], att[:, 1], att[:, 2]))


def _cross_matrix(v: np.ndarray) -> np.ndarray:
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def error_dynamics(flight: Flight, k: int, specific_force: np.ndarray, config: SinsGpsConfig) -> np.ndarray:
    """Continuous-time F (15, 15) in SI units at step k, with the given specific force f^n."""
    lat, h, v, cbn = flight.latitude[k], flight.height[k], flight.velocity[k], flight.cbn[k]
    rm, rn = radii(lat, h)
    w_ie, w_en = _earth_rates(lat, h, v)
    d_w_dv = np.array([[0, -1 / rm, 0], [1 / rn, 0, 0], [np.tan(lat) / rn, 0, 0]])  # ∂ω_en/∂δv
    d_wie_dpn = np.array([0, -EARTH_RATE * np.sin(lat), EARTH_RATE * np.cos(lat)]) / rm  # ∂ω_ie/∂δp_N
    d_wen_dpn = np.array([0, 0, v[0] / (rn * np.cos(lat) ** 2)]) / rm  # ∂ω_en/∂δp_N
    F = np.zeros((STATE_DIM, STATE_DIM))
    F[ATTITUDE, ATTITUDE] = -_cross_matrix(w_ie + w_en)
    F[ATTITUDE, VELOCITY] = d_w_dv
    F[ATTITUDE, 7] = d_wie_dpn + d_wen_dpn
    F[ATTITUDE, GYRO] = -cbn
    F[VELOCITY, ATTITUDE] = _cross_matrix(specific_force)
    F[VELOCITY, VELOCITY] = _cross_matrix(v) @ d_w_dv - _cross_matrix(2 * w_ie + w_en)
    F[VELOCITY, 7] = _cross_matrix(v) @ (2 * d_wie_dpn + d_wen_dpn)
    F[5, 8] = 2 * gravity(lat, h) / np.sqrt(rm * rn)
    F[VELOCITY, ACCEL] = cbn
    F[POSITION, VELOCITY] = np.eye(3)
    F[GYRO, GYRO] = -np.eye(3) / config.gyro_corr_time
    F[ACCEL, ACCEL] = -np.eye(3) / config.accel_corr_time
    return F


def process_noise(config: SinsGpsConfig) -> np.ndarray:
    """Discrete Q (15, 15) in SI units: G Q_c Gᵀ Δt plus the position floor. The white sensor
    noises are isotropic, so C_b^n Q_c C_b^nᵀ = Q_c and Q does not depend on the attitude."""
    dt = config.dt
    arw = config.gyro_arw_deg_sqrt_h * np.pi / 180 / 60  # rad/√s
    vrw = config.accel_white_g_sqrt_hz * G0  # m/s/√s
    q = np.zeros((STATE_DIM, STATE_DIM))
    q[ATTITUDE, ATTITUDE] = arw**2 * dt * np.eye(3)
    q[VELOCITY, VELOCITY] = vrw**2 * dt * np.eye(3)
    q[POSITION, POSITION] = config.position_floor**2 * np.eye(3)
    gyro_sd = config.gyro_markov_deg_h * DEG_PER_HOUR
    accel_sd = config.accel_markov_g * G0
    q[GYRO, GYRO] = 2 * gyro_sd**2 / config.gyro_corr_time * dt * np.eye(3)
    q[ACCEL, ACCEL] = 2 * accel_sd**2 / config.accel_corr_time * dt * np.eye(3)
    return q


@dataclass(frozen=True)
class SinsGpsModels:
    """True and approximate models in filter units (prior N(0, P₀) of the config), plus the exogenous
    inputs the GP residuals use.

    transitions_true / transitions_approx (K, 15, 15): Φ used to go from step k−1 to k (row k−1);
    forcing_true (K, 15): the true model's input term u (row k−1; zero without an accelerometer
    scale factor), so that x_k = Φ_true x_k−1 + u + w; transition_inputs (K+1, 3): f^n − f̂^n
    (m/s²) at each step."""

    true: StateSpaceModel
    approx: StateSpaceModel
    transitions_true: np.ndarray
    transitions_approx: np.ndarray
    forcing_true: np.ndarray
    transition_inputs: np.ndarray

    def residual(self, previous: np.ndarray) -> np.ndarray:
        """(K, 15) the true minus the approximate model's prediction from the states ``previous``
        (K, 15) of steps 0..K−1: (Φ_true − Φ_approx) x + u."""
        return np.einsum("kij,kj->ki", self.transitions_true - self.transitions_approx, previous) + self.forcing_true


def measurement_matrix() -> np.ndarray:
    """z = [δp; δv] (SINS minus GPS position and velocity)."""
    H = np.zeros((MEAS_DIM, STATE_DIM))
    H[0:3, POSITION] = np.eye(3)
    H[3:6, VELOCITY] = np.eye(3)
    return H


def build_models(flight: Flight, config: SinsGpsConfig = SinsGpsConfig()) -> SinsGpsModels:
    steps = flight.time.size - 1
    scale, unscale = UNITS[None, :], 1.0 / UNITS[:, None]
    level = np.zeros((flight.time.size, 3))
    level[:, 2] = gravity(flight.latitude, flight.height)
    eye = np.eye(STATE_DIM)
    phi_true = np.empty((steps, STATE_DIM, STATE_DIM))
    phi_approx = np.empty_like(phi_true)
    for k in range(steps):
        phi_true[k] = eye + unscale * error_dynamics(flight, k, flight.specific_force[k], config) * scale * config.dt
        phi_approx[k] = eye + unscale * error_dynamics(flight, k, level[k], config) * scale * config.dt
    Q = process_noise(config) / np.outer(UNITS, UNITS)
    white = config.accel_white_g_sqrt_hz * config.accel_noise_scale
    true_Q = process_noise(replace(config, accel_white_g_sqrt_hz=white)) / np.outer(UNITS, UNITS)
    H = measurement_matrix()
    R = config.measurement_cov()
    P0 = config.initial_cov()

    forcing = np.zeros((steps, STATE_DIM))
    # x_k = Φ x_k−1 + Δt s f^n(t_k−1): the scale-factor error's velocity increment over the step
    forcing[:, VELOCITY] = config.accel_scale_ppm * 1e-6 * flight.specific_force[:-1] * config.dt

    def transition(table, offset):
        return lambda x, k: np.einsum("ij,nj->ni", table[k - 1], x) + offset[k - 1]

    def model(table, offset, noise, name):
        return StateSpaceModel(transition(table, offset), noise, [Sensor(H, R, name="GPS position and velocity")],
                               np.zeros(STATE_DIM), P0, transition_jacobian=lambda x, k: table[k - 1], name=name)

    true = model(phi_true, forcing, true_Q, "true SINS error model")
    approx = model(phi_approx, np.zeros_like(forcing), Q, "level-flight SINS error model")
    return SinsGpsModels(true, approx, phi_true, phi_approx, forcing, flight.specific_force - level)


def _training_steps(manoeuvring: np.ndarray, count: int, share: float, rng: np.random.Generator) -> np.ndarray:
    """``count`` distinct steps, a manoeuvre step drawn with total probability ``share`` (renormalised
    when the flight has no steps of one kind)."""
    if count > manoeuvring.size:
        raise InputError(f"cannot draw {count} training steps from a flight of {manoeuvring.size} steps")
    n_man = int(manoeuvring.sum())
    weight = np.where(manoeuvring, share / max(n_man, 1), (1 - share) / max(manoeuvring.size - n_man, 1))
    return rng.choice(manoeuvring.size, size=count, replace=False, p=weight / weight.sum())


@dataclass(frozen=True)
class TrainingSet:
    """Transition training data: states x_i (n, 15), true next states (n, 15), the approximate
    model's prediction from the same states (n, 15), exogenous inputs f^n − f̂^n (n, 3)."""

    states: np.ndarray
    next_true: np.ndarray
    next_approx: np.ndarray
    inputs: np.ndarray


def training_set(config: SinsGpsConfig, headings_deg, points: int, rng: np.random.Generator,
                 manoeuvre_share: float = 0.8) -> TrainingSet:
    """Training data from separate training flights (the test flight's schedule flown from other
    initial headings): at steps k drawn from the flights (``manoeuvre_share`` of them from
    manoeuvres, the rest from cruise), an error state x ~ N(0, P₀) is propagated by the true model
    (as a reference navigation system would record it), x' = Φ_true,k x + w, w ~ N(0, Q).

    Error states are drawn from the prior rather than taken along one simulated error trajectory:
    along a single flight the attitude error hardly changes, so the residual Δt (f^n − f̂^n) × φ,
    which is linear in φ, would be seen at a handful of φ values only."""
    per_flight = np.full(len(headings_deg), points // len(headings_deg))
    per_flight[: points % len(headings_deg)] += 1
    chol0 = np.linalg.cholesky(config.initial_cov())
    parts = []
    for heading, count in zip(headings_deg, per_flight):
        cfg = replace(config, profile=replace(config.profile, heading0_deg=float(heading)))
        flight = generate_flight(cfg)
        models = build_models(flight, cfg)
        steps = _training_steps(flight.manoeuvring()[:-1], count, manoeuvre_share, rng)
        x = rng.standard_normal((count, STATE_DIM)) @ chol0.T
        noise = rng.standard_normal((count, STATE_DIM)) @ np.linalg.cholesky(models.true.Q).T
        next_true = np.einsum("nij,nj->ni", models.transitions_true[steps], x) + models.forcing_true[steps] + noise
        parts.append((x, next_true,
                      np.einsum("nij,nj->ni", models.transitions_approx[steps], x),
                      models.transition_inputs[steps]))
    return TrainingSet(*(np.concatenate(arrays) for arrays in zip(*parts)))
