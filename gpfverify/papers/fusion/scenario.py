"""The two experiments of the fusion paper (seed 000 §4): models, one simulated trajectory per run,
its training sets and its test segment.

* **1-D example** (eq. 42–43): x_{k+1} = 0.5 x_k + 25 x_k / (1 + x_k²) + w_k, w ~ N(0, σ²);
  y_k^m = 5 sin(2 x_k + z_m) + v_k^m, z = (0, π/4). 250 samples: the first 200 train, the last 50
  test. *Interpretations* (lost in the text): measurement noise variance 0.01 (the text shows
  "0.1²"), the filters' prior at step 200 N(0, 1) (the same authors use the identity for the 2-D
  prior), and the trajectory's own start x_1 ~ N(0, 1).
* **2-D constant turn** (eq. 46–47): x_{k+1} = F(Ω) x_k + w, F = [[cos Ω, −sin Ω], [sin Ω, cos Ω]],
  Q = 5 I; y^m = [‖x − z_m‖; arctan((x₂ − z_m2)/(x₁ − z_m1))] + v, R = diag(5, (0.1π/180)²).
  *Interpretation*: sensor positions z₁ = [−200, 200], z₂ = [200, 200] (a minus sign was lost).
  κ training samples from x_{−κ} ~ N(0, I), then 50 test samples.

Training sets from the trajectory's training part (n samples): the transition GP learns
x_τ ↦ x_{τ+1} on the n − 1 consecutive pairs, each sensor's measurement GP learns x_τ ↦ y_τ^m on
the n samples; the test part (the next T samples) is filtered.
"""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Callable

import numpy as np

from gpfverify.models import Sensor, StateSpaceModel

Vectorised = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class FusionScenario:
    """The system (a :class:`~gpfverify.models.StateSpaceModel`: x_{k+1} = f(x_k) + w,
    w ~ N(0, Q), observed by its sensors; its prior is the trajectory's start distribution) and
    the run's split: ``train`` samples followed by ``test`` samples."""

    model: StateSpaceModel
    train: int
    test: int

    @property
    def state_dim(self) -> int:
        return self.model.state_dim


@dataclass(frozen=True)
class FusionData:
    """One run's data. Training: ``transition_inputs`` (n−1, D) -> ``transition_targets`` (n−1, D);
    ``measurement_inputs`` (n, D) -> ``measurement_targets[m]`` (n, l_m). Test: ``test_states``
    (T, D), ``test_measurements[m]`` (T, l_m); ``last_train_state`` (D,) is x at step 0."""

    transition_inputs: np.ndarray
    transition_targets: np.ndarray
    measurement_inputs: np.ndarray
    measurement_targets: tuple[np.ndarray, ...]
    test_states: np.ndarray
    test_measurements: tuple[np.ndarray, ...]
    last_train_state: np.ndarray

    def stacked_test_measurements(self) -> np.ndarray:
        """y_k = [y_k¹; …; y_k^N] for every test step, (T, L)."""
        return np.concatenate(self.test_measurements, axis=1)


def simulate_data(scenario: FusionScenario, rng: np.random.Generator) -> FusionData:
    """Draw one trajectory of ``train + test`` samples and split it (see the module docstring)."""
    model = scenario.model
    total, d = scenario.train + scenario.test, scenario.state_dim
    states = np.empty((total, d))
    states[0] = rng.multivariate_normal(model.prior_mean, model.prior_cov)
    process = rng.multivariate_normal(np.zeros(d), model.Q, size=total - 1)
    for k in range(1, total):
        states[k] = model.f(states[k - 1:k])[0] + process[k - 1]
    measurements = [h(states) + rng.multivariate_normal(np.zeros(s.size), s.noise_cov, size=total)
                    for h, s in zip(model.measures, model.sensors)]
    n = scenario.train
    return FusionData(transition_inputs=states[:n - 1], transition_targets=states[1:n],
                      measurement_inputs=states[:n],
                      measurement_targets=tuple(y[:n] for y in measurements),
                      test_states=states[n:], test_measurements=tuple(y[n:] for y in measurements),
                      last_train_state=states[n - 1])


# -- 1-D example (eq. 42–43) -----------------------------------------------------------------------

def ungm_transition(x: np.ndarray) -> np.ndarray:
    """0.5 x + 25 x / (1 + x²), (N, 1) -> (N, 1) (eq. 42 without noise)."""
    return 0.5 * x + 25.0 * x / (1.0 + x * x)


def sine_sensor(phase: float) -> Vectorised:
    """x ↦ 5 sin(2x + phase), (N, 1) -> (N, 1) (eq. 43 without noise)."""
    return lambda x: 5.0 * np.sin(2.0 * x + phase)


UNGM_PHASES: tuple[float, float] = (0.0, np.pi / 4.0)


def ungm_scenario(system_noise_var: float, measurement_noise_var: float = 0.01,
                  start_var: float = 1.0, train: int = 200, test: int = 50,
                  phases: tuple[float, ...] = UNGM_PHASES) -> FusionScenario:
    """The 1-D two-sensor example with σ² = ``system_noise_var``."""
    sensors = tuple(Sensor(sine_sensor(p), [[measurement_noise_var]], name=f"sine, phase {p:.3g}")
                    for p in phases)
    model = StateSpaceModel(ungm_transition, [[system_noise_var]], sensors, np.zeros(1), [[start_var]],
                            name="UNGM 1-D")
    return FusionScenario(model, train, test)


# -- 2-D constant turn (eq. 46–47) -----------------------------------------------------------------

CT_SENSOR_POSITIONS: tuple[tuple[float, float], ...] = ((-200.0, 200.0), (200.0, 200.0))
CT_PROCESS_VAR = 5.0
CT_RANGE_VAR = 5.0
CT_BEARING_VAR = (0.1 * np.pi / 180.0) ** 2


def turn_matrix(omega: float) -> np.ndarray:
    """F(Ω) = [[cos Ω, −sin Ω], [sin Ω, cos Ω]]."""
    c, s = np.cos(omega), np.sin(omega)
    return np.array([[c, -s], [s, c]])


def range_bearing(position: np.ndarray) -> Vectorised:
    """x ↦ [‖x − z‖, arctan((x₂ − z₂)/(x₁ − z₁))] (eq. 47; arctan as written, not arctan2),
    (N, 2) -> (N, 2)."""
    z = np.asarray(position, dtype=float)

    def h(x: np.ndarray) -> np.ndarray:
        dx = x - z
        return np.stack([np.hypot(dx[:, 0], dx[:, 1]), np.arctan(dx[:, 1] / dx[:, 0])], axis=1)

    return h


def polar_to_cartesian(y: np.ndarray, position, side: float) -> np.ndarray:
    """Invert :func:`range_bearing` for one measurement [r, θ] (2,): z + side · r [cos θ, sin θ],
    where ``side`` = sign(x₁ − z₁) resolves arctan's π ambiguity (the side of the sensor the target
    is on)."""
    r, theta = y
    return np.asarray(position, dtype=float) + side * r * np.array([np.cos(theta), np.sin(theta)])


def sensor_side(position) -> float:
    """Side of sensor ``position`` on which the scenario's targets move: the origin's side,
    sign(0 − z₁) (trajectories started at N(0, I) stay within a few hundred metres of it)."""
    return float(np.sign(-position[0])) or 1.0


def ct_scenario(omega: float, train: int, test: int = 50,
                positions: tuple[tuple[float, float], ...] = CT_SENSOR_POSITIONS) -> FusionScenario:
    """The 2-D constant-turn example: κ = ``train`` training samples from x ~ N(0, I)."""
    R = np.diag([CT_RANGE_VAR, CT_BEARING_VAR])
    sensors = tuple(Sensor(range_bearing(np.array(z)), R, name=f"range-arctan at {z}") for z in positions)
    model = StateSpaceModel(turn_matrix(omega), CT_PROCESS_VAR * np.eye(2), sensors, np.zeros(2), np.eye(2),
                            name="2-D constant turn")
    return FusionScenario(model, train, test)
