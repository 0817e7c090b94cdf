"""The scalar benchmark of Deisenroth, Huber, Hanebeck (ICML 2009, §5), also SPEC §4 last bullet:

    x_1 = f(x_0) + w,  f(x) = 0.5 x + 25 x / (1 + x²),  w ~ N(0, 0.2²)
    y_1 = g(x_1) + v,  g(x) = 5 sin(2x),                v ~ N(0, 0.01²)
    x_0 ~ N(μ_0, 0.5²), one predict–update step per test case.

Training (for GP-ADF and GP-UKF): 100 inputs x ~ U[−10, 10] with noisy targets f(x) + w for the
transition GP and, from a second independent draw, 100 inputs with targets g(x) + v for the
measurement GP. Test: 200 prior means μ_0 ~ U[−10, 10] (interpretation: drawn uniformly, so that
averages over test cases estimate the expectation over that range), a true x_0 drawn from each
prior, then x_1 and y_1 drawn from the model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gpfverify.models import Sensor, StateSpaceModel


def transition(x: np.ndarray) -> np.ndarray:
    """f(x) = 0.5 x + 25 x / (1 + x²), elementwise."""
    return 0.5 * x + 25.0 * x / (1.0 + x * x)


def transition_derivative(x: np.ndarray) -> np.ndarray:
    """f'(x) = 0.5 + 25 (1 − x²) / (1 + x²)²."""
    return 0.5 + 25.0 * (1.0 - x * x) / (1.0 + x * x) ** 2


def measurement(x: np.ndarray) -> np.ndarray:
    """g(x) = 5 sin(2x), elementwise."""
    return 5.0 * np.sin(2.0 * x)


def measurement_derivative(x: np.ndarray) -> np.ndarray:
    """g'(x) = 10 cos(2x)."""
    return 10.0 * np.cos(2.0 * x)


@dataclass(frozen=True)
class ScalarSetting:
    """Every number of the benchmark (defaults: Deisenroth et al. 2009)."""

    prior_std: float = 0.5
    system_noise_std: float = 0.2
    measurement_noise_std: float = 0.01
    domain: float = 10.0  # training inputs and prior means on [−domain, domain]
    train_points: int = 100
    test_points: int = 200

    def model(self, prior_mean: float = 0.0) -> StateSpaceModel:
        """The true model, for the UKF and EKF (vectorised over (N, 1) states), with the prior
        N(prior_mean, prior_std²) of one test case (μ_0 = ``prior_mean``)."""
        sensor = Sensor(lambda x: measurement(x), np.array([[self.measurement_noise_std**2]]),
                        jacobian=lambda x: measurement_derivative(x).reshape(1, 1), name="5 sin(2x)")
        return StateSpaceModel(
            lambda x: transition(x), np.array([[self.system_noise_std**2]]), [sensor], prior_mean,
            self.prior_std**2, transition_jacobian=lambda x: transition_derivative(x).reshape(1, 1),
            name="scalar benchmark")


@dataclass(frozen=True)
class TrainingData:
    """Inputs (n, 1) and targets (n,) of the transition GP and of the measurement GP."""

    transition_inputs: np.ndarray
    transition_targets: np.ndarray
    measurement_inputs: np.ndarray
    measurement_targets: np.ndarray


@dataclass(frozen=True)
class EvaluationCases:
    """prior_mean, x0, x1, y1: each (N,)."""

    prior_mean: np.ndarray
    x0: np.ndarray
    x1: np.ndarray
    y1: np.ndarray


def draw_training_data(setting: ScalarSetting, rng: np.random.Generator) -> TrainingData:
    n, a = setting.train_points, setting.domain
    xf = rng.uniform(-a, a, size=(n, 1))
    xg = rng.uniform(-a, a, size=(n, 1))
    return TrainingData(
        xf, transition(xf[:, 0]) + setting.system_noise_std * rng.standard_normal(n),
        xg, measurement(xg[:, 0]) + setting.measurement_noise_std * rng.standard_normal(n))


def draw_cases(setting: ScalarSetting, rng: np.random.Generator) -> EvaluationCases:
    m = setting.test_points
    mu0 = rng.uniform(-setting.domain, setting.domain, size=m)
    x0 = mu0 + setting.prior_std * rng.standard_normal(m)
    x1 = transition(x0) + setting.system_noise_std * rng.standard_normal(m)
    y1 = measurement(x1) + setting.measurement_noise_std * rng.standard_normal(m)
    return EvaluationCases(mu0, x0, x1, y1)
