"""The 1-D nonlinear benchmarks of the particle-flow experiment (seed 003 §3.1).

The seed's model equation was lost in extraction; we use the two standard univariate benchmarks.

**UNGM** — univariate nonstationary growth model (Kitagawa 1996; Gordon, Salmond & Smith 1993),
for the Gaussian cases of Table 1:

    x_k = x_{k−1}/2 + 25 x_{k−1} / (1 + x_{k−1}²) + 8 cos(1.2 k) + w_k,  w_k ~ N(0, Q)
    y_k = x_k² / 20 + v_k,                                              v_k ~ N(0, R)

(or, as an interpretation of the lost model, the one-to-one y_k = x_k + v_k with the same dynamics)

**Gamma benchmark** — van der Merwe, Doucet, de Freitas & Wan (2000), for the Γ(3, 2) case (Fig. 2):

    x_k = 1 + sin(ω π (k − 1)) + φ₁ x_{k−1} + w_k,   w_k ~ Γ(shape 3, rate 2)
    y_k = φ₂ x_k² + v_k  (k ≤ 30),   y_k = φ₃ x_k − 2 + v_k  (k > 30),   v_k ~ N(0, R)

with ω = 0.04, φ₁ = 0.5, φ₂ = 0.2, φ₃ = 0.5. Γ(3, 2) is read as shape 3 and *rate* 2 (scale 1/2:
mean 1.5, variance 0.75), the convention of van der Merwe et al., whose Gaussian filters use the
process-noise variance 3/4. The Gaussian approximation a Gaussian filter uses is ``f`` shifted by
the noise mean and Q = the noise variance; particle filters sample and weight the gamma noise exactly.

**The same benchmark with Gaussian noise** (:func:`vdm_gaussian_model`), a reading of the lost
model of Table 1: §3.1 runs its gamma case on this model, so its Gaussian cases may use it too,
with w_k ~ N(0, Q) in place of the gamma noise.

Priors (interpretation; the seed gives none): x₀ ~ N(0, 1) for the UNGM and x₀ ~ N(1, 3/4) for the
van der Merwe benchmark.
"""

from __future__ import annotations

import numpy as np
from scipy.special import gammaln

from gpfverify.errors import InputError
from gpfverify.models import Sensor, StateSpaceModel

#: prior mean and variance of x₀
UNGM_PRIOR = (0.0, 1.0)
GAMMA_PRIOR = (1.0, 0.75)
GAMMA_OMEGA, GAMMA_PHI1, GAMMA_PHI2, GAMMA_PHI3 = 0.04, 0.5, 0.2, 0.5
#: measurement switches from quadratic to linear after this step
GAMMA_SWITCH_STEP = 30


def _ungm_drift(x: np.ndarray, k: int) -> np.ndarray:
    return 0.5 * x + 25.0 * x / (1.0 + x * x) + 8.0 * np.cos(1.2 * k)


#: the UNGM's measurement functions: Kitagawa's two-peaked x²/20, and a one-to-one reading
UNGM_MEASUREMENTS = ("quadratic", "linear")


def ungm_model(Q: float, R: float, measurement: str = "quadratic") -> StateSpaceModel:
    """The UNGM with process-noise variance Q, measurement-noise variance R and prior N(0, 1);
    ``measurement`` "quadratic" is yₖ = xₖ²/20 (which cannot tell x from −x: the posterior is
    two-peaked), "linear" the one-to-one yₖ = xₖ with the same dynamics."""
    if measurement == "quadratic":
        sensor = Sensor(lambda x, k: x * x / 20.0, np.array([[float(R)]]),
                        jacobian=lambda x, k: np.array([[x[0] / 10.0]]), name="x²/20")
    elif measurement == "linear":
        sensor = Sensor(lambda x, k: x, np.array([[float(R)]]), jacobian=lambda x, k: np.ones((1, 1)), name="x")
    else:
        raise InputError(f"measurement must be one of {list(UNGM_MEASUREMENTS)}, got {measurement!r}")
    return StateSpaceModel(
        _ungm_drift, np.array([[float(Q)]]), [sensor], UNGM_PRIOR[0], UNGM_PRIOR[1],
        transition_jacobian=lambda x, k: np.array([[0.5 + 25.0 * (1.0 - x[0] ** 2) / (1.0 + x[0] ** 2) ** 2]]),
        name="UNGM")


def _vdm_drift(x: np.ndarray, k: int) -> np.ndarray:
    return 1.0 + np.sin(GAMMA_OMEGA * np.pi * (k - 1)) + GAMMA_PHI1 * x


def _vdm_h(x: np.ndarray, k: int) -> np.ndarray:
    return GAMMA_PHI2 * x * x if k <= GAMMA_SWITCH_STEP else GAMMA_PHI3 * x - 2.0


def _vdm_h_jacobian(x: np.ndarray, k: int) -> np.ndarray:
    return np.array([[2.0 * GAMMA_PHI2 * x[0] if k <= GAMMA_SWITCH_STEP else GAMMA_PHI3]])


def _vdm_sensor(R: float) -> Sensor:
    return Sensor(_vdm_h, np.array([[float(R)]]), jacobian=_vdm_h_jacobian, name="switching")


def _vdm_jacobian(x: np.ndarray, k: int) -> np.ndarray:
    return np.array([[GAMMA_PHI1]])


def gamma_logpdf(w: np.ndarray, shape: float, rate: float) -> np.ndarray:
    """log Γ(w; shape, rate) = shape log rate − log Γ(shape) + (shape − 1) log w − rate w, −∞ for w ≤ 0."""
    out = np.full(np.shape(w), -np.inf)
    pos = w > 0
    out[pos] = (shape * np.log(rate) - gammaln(shape) + (shape - 1.0) * np.log(w[pos]) - rate * w[pos])
    return out


def gamma_benchmark_model(R: float, shape: float = 3.0, rate: float = 2.0) -> StateSpaceModel:
    """The van der Merwe et al. (2000) benchmark with Γ(shape, rate) process noise and prior N(1, 3/4)."""
    noise_mean, noise_var = shape / rate, shape / rate**2

    def sampler(x_prev, k, rng):
        return _vdm_drift(x_prev, k) + rng.gamma(shape, 1.0 / rate, size=x_prev.shape)

    def logpdf(x_new, x_prev, k):
        return gamma_logpdf(x_new - _vdm_drift(x_prev, k), shape, rate)[:, 0]

    return StateSpaceModel(
        lambda x, k: _vdm_drift(x, k) + noise_mean, np.array([[noise_var]]), [_vdm_sensor(R)],
        GAMMA_PRIOR[0], GAMMA_PRIOR[1], transition_jacobian=_vdm_jacobian,
        transition_sampler=sampler, transition_logpdf=logpdf, name="gamma benchmark")


def vdm_gaussian_model(Q: float, R: float) -> StateSpaceModel:
    """The van der Merwe et al. (2000) benchmark with Gaussian process noise w_k ~ N(0, Q) in place
    of the gamma noise, measurement-noise variance R and prior N(1, 3/4)."""
    return StateSpaceModel(_vdm_drift, np.array([[float(Q)]]), [_vdm_sensor(R)], GAMMA_PRIOR[0], GAMMA_PRIOR[1],
                           transition_jacobian=_vdm_jacobian, name="van der Merwe benchmark, Gaussian noise")
