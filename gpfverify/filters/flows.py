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

Angle outputs of the measurement (``model.circular``, bearings) are handled by evaluating h on
the branch nearest z (:func:`~gpfverify.filters.likelihoods.unwrapped_measurement`). Angle state
components (``model.circular_state``) are flowed on one branch around their circular mean
(:func:`on_one_branch`) and wrapped to (−π, π] afterwards; the estimate is their circular mean.

Both steps take and return :class:`~gpfverify.filters.resampling.Particles` with equal weights
(the flows neither weight nor resample); the EDH belief carries the parallel EKF covariance in
``Particles.ekf_cov``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gpfverify.angles import difference, wrap_components
from gpfverify.errors import InputError
from gpfverify.filters import runs
from gpfverify.filters.likelihoods import sample_transition, unwrapped_measurement
from gpfverify.filters.resampling import Particles, ParticleStep, moments_from_weights
from gpfverify.linalg import cholesky, symmetrize
from gpfverify.models.system import StateSpaceModel, require_model


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


def particle_moments(particles: np.ndarray, circular_state: Sequence[int] = ()) -> tuple[np.ndarray, np.ndarray]:
    """Equal-weight mean (..., D) and covariance (..., D, D) of particles (..., N, D) (1/N
    normalisation, as in the gain); angle components ``circular_state`` averaged on the circle with
    wrapped deviations (:func:`~gpfverify.filters.resampling.moments_from_weights`)."""
    n = particles.shape[-2]
    if len(circular_state):
        return moments_from_weights(particles, np.full(particles.shape[:-1], 1.0 / n), circular_state)
    mean = particles.mean(axis=-2)
    dev = particles - mean[..., None, :]
    return mean, symmetrize(dev.swapaxes(-1, -2) @ dev / n)


def on_one_branch(particles: np.ndarray, circular_state: Sequence[int]) -> np.ndarray:
    """The particles with their angle components moved by multiples of 2π to the branch around
    their circular mean, so that the flow's linear algebra (means, Cov(X, h(X)), x̄) sees one
    contiguous cloud instead of one cut at ±π; the flow's result is wrapped back."""
    if not len(circular_state):
        return particles
    mean, _ = particle_moments(particles, circular_state)
    return mean[..., None, :] + difference(particles, mean[..., None, :], circular_state)


def _flow_step(x: np.ndarray, mean: np.ndarray, cov: np.ndarray, **extras) -> ParticleStep:
    """The record of a flow step with estimate (mean, cov): equally weighted particles (with the
    optional ``extras`` of :class:`Particles`), N_eff = N, no resampling."""
    posterior = Particles.equally_weighted(x, **extras)
    n = float(x.shape[-2])
    if x.ndim == 2:
        return ParticleStep(posterior, posterior, mean, cov, n, False)
    return ParticleStep(posterior, posterior, mean, cov, np.full(x.shape[0], n), np.zeros(x.shape[0], bool))


def _check_inputs(particles, z, model, rng: runs.Streams | None = None) -> tuple[np.ndarray, np.ndarray]:
    """particles (N, D) with N ≥ 2 and z (L,) — or (B, N, D) and (B, L) for B runs, checked against
    ``rng`` when given — for a StateSpaceModel; InputError naming the argument otherwise."""
    require_model(model, StateSpaceModel, "a particle flow")
    x, z = runs.particle_inputs(particles, z, model, rng, ("particles", "z"))
    if x.shape[-2] < 2:
        raise InputError(f"particles: a flow needs at least 2 particles, got {x.shape[-2]}")
    return np.array(x), z


def _measurement_cov(model) -> np.ndarray:
    """R, checked positive definite once per update; the λ-loop then uses small dense solves
    (the scipy wrappers cost more than the L × L solve itself)."""
    cholesky(model.R, "R", allow_jitter=False)
    return model.R


def ie_pff_update(particles: np.ndarray, model, z: np.ndarray, k: int,
                  step_sizes: np.ndarray) -> np.ndarray:
    """Flow predicted particles (N, D) to the posterior of measurement z (L,) (seed 003 eq. 27, 36);
    or the particles (B, N, D) of B runs with their measurements (B, L)."""
    steps = _check_steps(step_sizes)
    x, z = _check_inputs(particles, z, model)
    R = _measurement_cov(model)
    n = x.shape[-2]
    z = z[..., None, :]
    for dlam in steps:
        hx = unwrapped_measurement(model, z[..., 0, :], x, k)  # (..., N, L)
        h_mean = hx.mean(axis=-2, keepdims=True)
        cross = (x - x.mean(axis=-2, keepdims=True)).swapaxes(-1, -2) @ (hx - h_mean) / n  # Cov(X, h(X))
        gain = np.linalg.solve(R, cross.swapaxes(-1, -2)).swapaxes(-1, -2)  # K = Cov(X, h) R⁻¹
        x = x + dlam * (z - 0.5 * (hx + h_mean)) @ gain.swapaxes(-1, -2)
    return x


def ie_pff_step(belief: Particles, model, z: np.ndarray, *, k: int = 1, rng: runs.Streams,
                step_sizes: np.ndarray) -> ParticleStep:
    """Predict particles through the transition (with process noise), then :func:`ie_pff_update`.
    The flow treats the particles as equally weighted (it neither weights nor resamples). For B
    runs: particles (B, N, D), z (B, L), one Generator per run."""
    require_model(model, StateSpaceModel, "IE-PFF")
    x, z = _check_inputs(belief.particles, z, model, rng)
    circular = model.circular_state
    x = ie_pff_update(on_one_branch(sample_transition(model, x, k, rng), circular), model, z, k, step_sizes)
    x = wrap_components(x, circular)
    return _flow_step(x, *particle_moments(x, circular))


def _jacobian_runs(jacobian, mean: np.ndarray, k: int, shape: tuple[int, int]) -> np.ndarray:
    """A model Jacobian at the mean (D,) of one run, or at the means (B, D) of B runs with NaN for
    a run where it fails (:func:`~gpfverify.filters.runs.isolate_runs`)."""
    if mean.ndim == 1:
        return jacobian(mean, k)
    return runs.isolate_runs(lambda part: jacobian(part, k), mean, shape)


def edh_update(particles: np.ndarray, P: np.ndarray, model, z: np.ndarray, k: int,
               step_sizes: np.ndarray) -> np.ndarray:
    """Move predicted particles (N, D) along the exact Daum–Huang flow with predicted covariance P
    (D, D); or B runs at once: particles (B, N, D), P (B, D, D), z (B, L)."""
    steps = _check_steps(step_sizes)
    x, z = _check_inputs(particles, z, model)
    R = _measurement_cov(model)
    x0_mean = x.mean(axis=-2)[..., None]  # (..., D, 1)
    eye = np.eye(x.shape[-1])
    shape = (model.measurement_dim, model.state_dim)
    lam_start = 0.0
    for dlam in steps:
        lam = lam_start + 0.5 * dlam
        mean = x.mean(axis=-2)
        H = _jacobian_runs(model.h_jacobian, mean, k, shape)
        e = unwrapped_measurement(model, z, mean[..., None, :], k)[..., 0, :] - (H @ mean[..., None])[..., 0]
        PHt = P @ H.swapaxes(-1, -2)
        A = -0.5 * PHt @ np.linalg.solve(lam * H @ PHt + R, H)
        b = (eye + 2 * lam * A) @ ((eye + lam * A) @ (PHt @ np.linalg.solve(R, (z - e)[..., None])) + A @ x0_mean)
        x = x + dlam * (x @ A.swapaxes(-1, -2) + b.swapaxes(-1, -2))
        lam_start += dlam
    return x


def ekf_covariance_predict(P: np.ndarray, mean: np.ndarray, model, k: int) -> np.ndarray:
    """P_k|k−1 = F P Fᵀ + Q, F = ∂f/∂x at ``mean`` (per run for P (B, D, D), mean (B, D))."""
    F = _jacobian_runs(model.f_jacobian, mean, k, (model.state_dim, model.state_dim))
    return symmetrize(F @ P @ F.swapaxes(-1, -2) + model.Q)


def ekf_covariance_update(P: np.ndarray, mean: np.ndarray, model, k: int) -> np.ndarray:
    """P_k|k = P − P Hᵀ (H P Hᵀ + R)⁻¹ H P, H = ∂h/∂x at ``mean`` (Joseph-free, symmetrised; per
    run for P (B, D, D), mean (B, D))."""
    H = _jacobian_runs(model.h_jacobian, mean, k, (model.measurement_dim, model.state_dim))
    PHt = P @ H.swapaxes(-1, -2)
    return symmetrize(P - PHt @ np.linalg.solve(H @ PHt + model.R, PHt.swapaxes(-1, -2)))


def edh_step(belief: Particles, model, z: np.ndarray, *, k: int = 1, rng: runs.Streams,
             step_sizes: np.ndarray) -> ParticleStep:
    """Predict particles and the parallel EKF covariance (``belief.ekf_cov``), flow, update the
    covariance; the posterior carries the updated covariance in ``ekf_cov``. For B runs:
    particles (B, N, D), ekf_cov (B, D, D), z (B, L), one Generator per run."""
    require_model(model, StateSpaceModel, "EDH")
    if belief.ekf_cov is None:
        raise InputError("belief.ekf_cov: EDH needs the parallel EKF covariance "
                         "(e.g. Particles.equally_weighted(particles, ekf_cov=prior_cov))")
    particles, z = _check_inputs(belief.particles, z, model, rng)
    circular = model.circular_state
    P_pred = ekf_covariance_predict(belief.ekf_cov, particle_moments(particles, circular)[0], model, k)
    x = edh_update(on_one_branch(sample_transition(model, particles, k, rng), circular), P_pred, model, z, k,
                   step_sizes)
    x = wrap_components(x, circular)
    mean, cov = particle_moments(x, circular)
    return _flow_step(x, mean, cov, ekf_cov=ekf_covariance_update(P_pred, mean, model, k))
