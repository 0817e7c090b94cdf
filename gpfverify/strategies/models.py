"""Gaussian processes with fixed hyperparameters, Gaussian inputs, linear-Gaussian models and
sigma-point parameters — the inputs of the GP and filter properties.

Hyperparameters are drawn from boxes that keep every matrix well conditioned by construction:
lengthscales in [0.5, 3] (inputs lie in [−3, 3]), signal variance α² in [0.1, 4], noise variance
σ² in [1e-3, 0.5], so cond(K_a) ≤ 1 + n α²/σ² ≤ 1 + 4000 n whatever the inputs (duplicates
included).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from hypothesis import strategies as st

from gpfverify.filters.records import Gaussian
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.gp import GaussianProcess
from gpfverify.linalg import symmetrize
from gpfverify.strategies.matrices import (as_strategy, float_arrays, log_uniform, orthonormal_matrices,
                                           spd_matrices, unit_floats)

INPUT_BOUND = 3.0
LENGTHSCALE_BOX = (0.5, 3.0)
SIGNAL_BOX = (0.1, 4.0)
NOISE_BOX = (1e-3, 0.5)


@st.composite
def log_uniform_arrays(draw, shape, low: float, high: float) -> np.ndarray:
    return low * (high / low) ** draw(float_arrays(shape, 0.0, 1.0))


@st.composite
def gaussian_processes(draw, input_dim=st.integers(1, 2), output_dim=st.integers(1, 3),
                       train_size=st.integers(1, 12)) -> GaussianProcess:
    """A :class:`~gpfverify.gp.GaussianProcess` with inputs in [−3, 3]^D, targets in [−3, 3] and
    hyperparameters in the module's boxes (dims and training size: ints or strategies;
    ``output_dim=None`` gives E = D, a transition model)."""
    d, e, n = draw(as_strategy(input_dim)), draw(as_strategy(output_dim)), draw(as_strategy(train_size))
    e = d if e is None else e
    x = draw(float_arrays((n, d), -INPUT_BOUND, INPUT_BOUND))
    y = draw(float_arrays((n, e), -INPUT_BOUND, INPUT_BOUND))
    return GaussianProcess(x, y, lengthscales=draw(log_uniform_arrays((e, d), *LENGTHSCALE_BOX)),
                           signal_var=draw(log_uniform_arrays((e,), *SIGNAL_BOX)),
                           noise_var=draw(log_uniform_arrays((e,), *NOISE_BOX)))


@st.composite
def psd_matrices(draw, dim: int, low: float, high: float, allow_singular: bool = True) -> np.ndarray:
    """Symmetric PSD (dim, dim) with eigenvalues in {0} ∪ [low, high] (0 only if
    ``allow_singular``): Q diag(λ) Qᵀ with Q orthonormal."""
    q = draw(orthonormal_matrices(dim))
    values = draw(log_uniform_arrays((dim,), low, high))
    if allow_singular:
        values = values * ~np.array(draw(st.lists(st.booleans(), min_size=dim, max_size=dim)), dtype=bool)
    return symmetrize((q * values) @ q.T)


@st.composite
def gaussian_inputs(draw, dim: int, max_variance: float = 1.0, allow_singular: bool = True,
                    min_variance: float = 1e-4) -> Gaussian:
    """N(μ, Σ) with μ ∈ [−3, 3]^dim and Σ PSD with eigenvalues in {0} ∪ [min_variance,
    max_variance] (log-uniform; 0 only if ``allow_singular``)."""
    return Gaussian(draw(float_arrays((dim,), -INPUT_BOUND, INPUT_BOUND)),
                    draw(psd_matrices(dim, min_variance, max_variance, allow_singular)))


@dataclass(frozen=True)
class LinearGaussianModel:
    """x_k = F x_{k−1} + w, w ~ N(0, Q); y_k = H x_k + v, v ~ N(0, R); a prior and one y."""

    F: np.ndarray
    H: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    prior: Gaussian
    y: np.ndarray


@st.composite
def linear_gaussian_models(draw, state_dim=st.integers(1, 4), measurement_dim=st.integers(1, 3),
                           max_condition: float = 1e3) -> LinearGaussianModel:
    """Linear-Gaussian models with F, H entries in [−1.5, 1.5], SPD Q, R and prior covariance of
    condition ≤ ``max_condition`` (scales log-uniform in [0.01, 1]), a prior mean and a measurement
    in [−5, 5]."""
    d, l = draw(as_strategy(state_dim)), draw(as_strategy(measurement_dim))
    return LinearGaussianModel(
        F=draw(float_arrays((d, d), -1.5, 1.5)), H=draw(float_arrays((l, d), -1.5, 1.5)),
        Q=draw(spd_matrices(d, max_condition, log_uniform(0.01, 1.0))),
        R=draw(spd_matrices(l, max_condition, log_uniform(0.01, 1.0))),
        prior=Gaussian(draw(float_arrays((d,), -5.0, 5.0)),
                       draw(spd_matrices(d, max_condition, log_uniform(0.01, 1.0)))),
        y=draw(float_arrays((l,), -5.0, 5.0)))


@st.composite
def sigma_params(draw, dim: int, min_alpha: float = 1e-3, max_alpha: float = 2.0,
                 max_beta: float = 3.0, min_spread: float = 0.5, max_kappa: float = 10.0) -> SigmaParams:
    """Scaled-unscented parameters valid for dimension ``dim``: α log-uniform in [min_alpha,
    max_alpha], β ∈ [0, max_beta], κ with D + κ ∈ [min_spread, D + max_kappa], so that
    D + λ = α²(D + κ) > 0 (every weight finite)."""
    alpha = draw(log_uniform(min_alpha, max_alpha))
    beta = draw(unit_floats(0.0, max_beta))
    kappa = draw(unit_floats(min_spread - dim, max_kappa))
    return SigmaParams(alpha=alpha, beta=beta, kappa=kappa)


#: Regimes of :func:`gp_stacks`: ordinary; ``near-linear`` (lengthscales 1e3–1e6 × the input range,
#: so every exponent d_ij of the centred second moments is tiny — the expm1 path); ``wide`` (input
#: covariance up to 100 ℓ²: inputs much wider than the lengthscales); ``far`` (one training point
#: of each GP 80–100 lengthscales from μ, the others near, Σ ≈ ℓ²: d_ij > 700 for the far point, so
#: exp(d) would overflow and the block is formed by the log-space branch, near entries included).
STACK_REGIMES = ("ordinary", "near-linear", "wide", "far")


@dataclass(frozen=True)
class GPStackCase:
    """Several GPs on one input space, each with its own training set, and a Gaussian input."""

    gps: tuple
    mu: np.ndarray
    sigma: np.ndarray
    regime: str


@st.composite
def gp_stacks(draw, regime=st.sampled_from(STACK_REGIMES), count=st.integers(1, 3),
              input_dim=st.integers(1, 2)) -> GPStackCase:
    """A stack of 1–3 GPs with *different* training sets (sizes 1–8, own inputs and targets) and
    1–2 outputs each, plus N(μ, Σ) in the given regime (see :data:`STACK_REGIMES`)."""
    kind, k, d = draw(as_strategy(regime)), draw(as_strategy(count)), draw(as_strategy(input_dim))
    mu = draw(float_arrays((d,), -INPUT_BOUND, INPUT_BOUND))
    gps = []
    for _ in range(k):
        n, e = draw(st.integers(1, 8)), draw(st.integers(1, 2))
        if kind == "near-linear":
            ell = draw(log_uniform_arrays((e, d), 1e3 * INPUT_BOUND, 1e6 * INPUT_BOUND))
        else:
            ell = draw(log_uniform_arrays((e, d), *LENGTHSCALE_BOX))
        x = draw(float_arrays((n, d), -INPUT_BOUND, INPUT_BOUND))
        if kind == "far":  # one point 80–100 of the largest lengthscale from μ
            direction = draw(float_arrays((d,), 0.5, 1.0))
            distance = draw(unit_floats(80.0, 100.0)) * ell.max()
            x = x.copy()
            x[0] = mu + distance * direction / np.linalg.norm(direction)
        y = draw(float_arrays((n, e), -INPUT_BOUND, INPUT_BOUND))
        gps.append(GaussianProcess(x, y, lengthscales=ell, signal_var=draw(log_uniform_arrays((e,), *SIGNAL_BOX)),
                                   noise_var=draw(log_uniform_arrays((e,), *NOISE_BOX))))
    ell_min = min(float(gp.lengthscales.min()) for gp in gps)
    if kind == "wide":
        sigma = draw(psd_matrices(d, 1.0 * ell_min**2, 100.0 * ell_min**2, allow_singular=False))
    elif kind == "far":
        sigma = draw(psd_matrices(d, 0.3 * ell_min**2, 1.0 * ell_min**2, allow_singular=False))
    else:
        sigma = draw(psd_matrices(d, 1e-4, 1.0, allow_singular=True))
    return GPStackCase(tuple(gps), mu, sigma, kind)


@dataclass(frozen=True)
class AngleModel:
    """A linear-Gaussian model whose state component 0 and measurement output 0 are angles:
    x_k = F x_{k−1} + w with F e_0 = e_0 (a turn of 2π in the angle moves nothing else), and
    y_k = H x_k + φ e_0 + v with H e_0 = e_0, the angle output wrapped to (−π, π] (``offset`` φ moves
    it across the cut). Beliefs are a batch: ``means`` (B, D), ``covs`` (B, D, D), ``ys`` (B, L)."""

    F: np.ndarray
    H: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    offset: float
    means: np.ndarray
    covs: np.ndarray
    ys: np.ndarray


@st.composite
def angle_models(draw, state_dim=st.integers(1, 3), measurement_dim=st.integers(1, 3),
                 batch=st.integers(1, 3), max_std: float = 0.05) -> AngleModel:
    """:class:`AngleModel` with a batch of beliefs whose predicted angle output sits within
    ``max_std``-scaled sigma-point spreads of ±π (the sigma points straddle the cut) and whose angle
    state sits within 0.2 of ±π; every covariance has standard deviations ≤ ``max_std`` (so sigma
    points of any valid (α, κ) with α²(D + κ) ≤ 4(D + 10) stay within π/2 of their mean)."""
    d, l, b = draw(as_strategy(state_dim)), draw(as_strategy(measurement_dim)), draw(as_strategy(batch))
    F = draw(float_arrays((d, d), -1.0, 1.0))
    F[:, 0] = 0.0
    F[0, 0] = 1.0
    H = draw(float_arrays((l, d), -1.0, 1.0))
    H[:, 0] = 0.0
    H[0, 0] = 1.0
    small = log_uniform(1e-5 * max_std**2, max_std**2 / 10.0)
    Q = draw(spd_matrices(d, 10.0, small))
    R = draw(spd_matrices(l, 10.0, small))
    covs = np.stack([draw(spd_matrices(d, 10.0, small)) for _ in range(b)])
    means = draw(float_arrays((b, d), -0.5, 0.5))
    means[:, 0] = np.pi + draw(float_arrays((b,), -0.2, 0.2))
    offset = float(np.pi - (H @ F @ means[0])[0] + draw(unit_floats(-0.1, 0.1)))
    noise = draw(float_arrays((b, l), -2.0 * max_std, 2.0 * max_std))
    ys = (means @ F.T) @ H.T + noise
    ys[:, 0] = np.pi - np.mod(np.pi - (ys[:, 0] + offset), 2.0 * np.pi)
    return AngleModel(F, H, Q, R, offset, means, covs, ys)


@st.composite
def batched_beliefs(draw, dim: int, batch=st.integers(2, 4), max_variance: float = 1.0) -> Gaussian:
    """A batch of B Gaussian beliefs: means (B, dim) in [−3, 3], covariances (B, dim, dim) SPD with
    condition ≤ 100 and eigenvalues ≤ ``max_variance``."""
    b = draw(as_strategy(batch))
    covs = [draw(spd_matrices(dim, 100.0, log_uniform(max_variance / 1e4, max_variance / 100.0)))
            for _ in range(b)]
    return Gaussian(draw(float_arrays((b, dim), -INPUT_BOUND, INPUT_BOUND)), np.stack(covs))
