"""Particle flows in pseudo-time λ ∈ [0, 1] that move predicted particles to the posterior
without weights or resampling.

**IE-PFF** — innovation-error particle flow (seed 003 §2.2–2.4, eq. 21–27 and 36; with the Galerkin
coordinate basis A = I it is the constant-gain feedback particle filter):

    dX_i/dλ = K (z − (h(X_i) + ĥ)/2),  ĥ = (1/N) Σ_j h(X_j),
    K = (1/N) Σ_j (X_j − x̄)(h(X_j) − ĥ)ᵀ R⁻¹                   (seed 003 eq. 35–36),

integrated by explicit Euler over λ-steps Δλ_1 … Δλ_m (Σ = 1), K and ĥ recomputed at every step.
For a linear-Gaussian model the particle mean and covariance follow
dx̄/dλ = P Hᵀ R⁻¹ (z − H x̄), dP/dλ = −P Hᵀ R⁻¹ H P, whose solution at λ = 1 is the Kalman
update; the Euler scheme reaches it to first order in Δλ.

**EDH** — Daum–Huang exact flow (Daum & Huang 2010; Ding & Coates 2012, as in Li & Coates 2017):

    dX_i/dλ = A(λ) X_i + b(λ),
    A(λ) = −½ P Hᵀ (λ H P Hᵀ + R)⁻¹ H,
    b(λ) = (I + 2λA)[(I + λA) P Hᵀ R⁻¹ (z − e) + A x̄₀],

H the Jacobian of h at the current particle mean x̄_λ, e = h(x̄_λ) − H x̄_λ, x̄₀ the predicted
particle mean before the flow, A and b evaluated at the midpoint of each λ-step. P is the
predicted covariance of a parallel EKF: P_k|k−1 = F P_k−1|k−1 Fᵀ + Q with F the Jacobian of f at
the previous posterior particle mean, and P_k|k = P_k|k−1 − P_k|k−1 Hᵀ S⁻¹ H P_k|k−1 with H at the
flowed mean (Ding & Coates 2012, Alg. 1).

Measurements on a circle (bearings) are handled by evaluating h on the branch nearest z
(:func:`~gpfverify.filters.likelihoods.unwrapped_measurement`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gpfverify.errors import InputError
from gpfverify.filters.likelihoods import sample_transition, unwrapped_measurement
from gpfverify.filters.models import NonlinearModel
from gpfverify.linalg import cholesky, right_solve_spd, symmetrize
from gpfverify.validate import as_matrix, as_vector


def uniform_steps(count: int) -> np.ndarray:
    """``count`` equal λ-steps Δλ = 1/count."""
    if count < 1:
        raise InputError(f"count must be at least 1, got {count}")
    return np.full(count, 1.0 / count)


def exponential_steps(count: int, ratio: float = 1.2) -> np.ndarray:
    """``count`` λ-steps growing geometrically, Δλ_j = Δλ_1 ratioʲ⁻¹, Σ Δλ_j = 1 (Li & Coates
    2017 use 29 steps with ratio 1.2): small first steps where the flow is stiff. With a fixed
    ratio > 1 the last step stays ≈ 1 − 1/ratio however many steps there are, so refining the
    schedule means ratio → 1 as well."""
    if count < 1:
        raise InputError(f"count must be at least 1, got {count}")
    if ratio <= 0:
        raise InputError(f"ratio must be positive, got {ratio}")
    exponents = np.arange(count, dtype=float) - (count - 1 if ratio > 1 else 0)
    steps = ratio ** exponents
    steps = steps / steps.sum()
    if np.any(steps <= 0):
        raise InputError(f"{count} steps with ratio {ratio} underflow: the first steps are zero")
    return steps


def _check_steps(step_sizes: np.ndarray) -> np.ndarray:
    steps = np.asarray(step_sizes, dtype=float)
    if steps.ndim != 1 or steps.size == 0 or np.any(steps <= 0) or not np.isclose(steps.sum(), 1.0):
        raise InputError("step_sizes must be positive λ-steps summing to 1")
    return steps


@dataclass(frozen=True)
class FlowEstimate:
    """Posterior estimate after a flow: particle mean (D,) and covariance (D, D)."""

    mean: np.ndarray
    cov: np.ndarray


def particle_moments(particles: np.ndarray) -> FlowEstimate:
    """Equal-weight mean and covariance (1/N normalisation, as in the gain)."""
    mean = particles.mean(axis=0)
    dev = particles - mean
    return FlowEstimate(mean, symmetrize(dev.T @ dev / particles.shape[0]))


def _check_inputs(particles, z, model: NonlinearModel) -> tuple[np.ndarray, np.ndarray]:
    """particles (N, D) with N ≥ 2 and z (L,), finite; InputError naming the argument otherwise."""
    x = np.array(as_matrix(particles, "particles", None, model.state_dim))
    if x.shape[0] < 2:
        raise InputError(f"particles: a flow needs at least 2 particles, got {x.shape[0]}")
    return x, as_vector(z, "z", model.measurement_dim)


def _measurement_cov(model: NonlinearModel) -> np.ndarray:
    """R, checked positive definite once per update; the λ-loop then uses small dense solves
    (the scipy wrappers cost more than the L × L solve itself)."""
    cholesky(model.R, "R", allow_jitter=False)
    return model.R


def ie_pff_update(particles: np.ndarray, model: NonlinearModel, z: np.ndarray, k: int,
                  step_sizes: np.ndarray) -> np.ndarray:
    """Flow predicted particles (N, D) to the posterior of measurement z (L,) (seed 003 eq. 27, 36)."""
    steps = _check_steps(step_sizes)
    x, z = _check_inputs(particles, z, model)
    R = _measurement_cov(model)
    n = x.shape[0]
    for dlam in steps:
        hx = unwrapped_measurement(model, z, x, k)  # (N, L)
        h_mean = hx.mean(axis=0)
        cross = (x - x.mean(axis=0)).T @ (hx - h_mean) / n  # (D, L) empirical Cov(X, h(X))
        gain = np.linalg.solve(R, cross.T).T  # K = Cov(X, h) R⁻¹
        x = x + dlam * (z - 0.5 * (hx + h_mean)) @ gain.T
    return x


def ie_pff_step(particles: np.ndarray, model: NonlinearModel, z: np.ndarray, k: int,
                rng: np.random.Generator, step_sizes: np.ndarray) -> tuple[np.ndarray, FlowEstimate]:
    """Predict particles through the transition (with process noise), then :func:`ie_pff_update`."""
    x = ie_pff_update(sample_transition(model, particles, k, rng), model, z, k, step_sizes)
    return x, particle_moments(x)


@dataclass(frozen=True)
class EDHBelief:
    """EDH state: particles (N, D) and the parallel EKF's posterior covariance (D, D)."""

    particles: np.ndarray
    cov: np.ndarray


def edh_update(particles: np.ndarray, P: np.ndarray, model: NonlinearModel, z: np.ndarray, k: int,
               step_sizes: np.ndarray) -> np.ndarray:
    """Move predicted particles (N, D) along the exact Daum–Huang flow with predicted covariance P."""
    if model.h_jacobian is None:
        raise InputError("EDH needs model.h_jacobian")
    steps = _check_steps(step_sizes)
    x, z = _check_inputs(particles, z, model)
    R = _measurement_cov(model)
    x0_mean = x.mean(axis=0)
    eye = np.eye(x.shape[1])
    lam_start = 0.0
    for dlam in steps:
        lam = lam_start + 0.5 * dlam
        mean = x.mean(axis=0)
        H = np.atleast_2d(model.h_jacobian(mean, k))
        e = unwrapped_measurement(model, z, mean[None, :], k)[0] - H @ mean
        PHt = P @ H.T
        A = -0.5 * PHt @ np.linalg.solve(lam * H @ PHt + R, H)
        b = (eye + 2 * lam * A) @ ((eye + lam * A) @ (PHt @ np.linalg.solve(R, z - e)) + A @ x0_mean)
        x = x + dlam * (x @ A.T + b)
        lam_start += dlam
    return x


def ekf_covariance_predict(P: np.ndarray, mean: np.ndarray, model: NonlinearModel, k: int) -> np.ndarray:
    """P_k|k−1 = F P Fᵀ + Q, F = ∂f/∂x at ``mean``."""
    if model.f_jacobian is None:
        raise InputError("EDH needs model.f_jacobian")
    F = np.atleast_2d(model.f_jacobian(mean, k))
    return symmetrize(F @ P @ F.T + model.Q)


def ekf_covariance_update(P: np.ndarray, mean: np.ndarray, model: NonlinearModel, k: int) -> np.ndarray:
    """P_k|k = P − P Hᵀ (H P Hᵀ + R)⁻¹ H P, H = ∂h/∂x at ``mean`` (Joseph-free, symmetrised)."""
    H = np.atleast_2d(model.h_jacobian(mean, k))
    PHt = P @ H.T
    return symmetrize(P - right_solve_spd(PHt, H @ PHt + model.R, "HPHᵀ + R") @ PHt.T)


def edh_step(belief: EDHBelief, model: NonlinearModel, z: np.ndarray, k: int,
             rng: np.random.Generator, step_sizes: np.ndarray) -> tuple[EDHBelief, FlowEstimate]:
    """Predict particles and the parallel EKF covariance, flow, update the covariance."""
    prev_mean = belief.particles.mean(axis=0)
    P_pred = ekf_covariance_predict(belief.cov, prev_mean, model, k)
    x = edh_update(sample_transition(model, belief.particles, k, rng), P_pred, model, z, k, step_sizes)
    estimate = particle_moments(x)
    return EDHBelief(x, ekf_covariance_update(P_pred, estimate.mean, model, k)), estimate
