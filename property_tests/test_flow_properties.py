"""Particle flows (IE-PFF, EDH) against the exact linear-Gaussian posterior, on drawn models.

For a linear measurement both flows move the particles by affine maps, so the particles' (1/N)
mean and covariance follow a discretisation of the Kalman λ-path dx̄/dλ = P Hᵀ R⁻¹ (z − H x̄),
dP/dλ = −P Hᵀ R⁻¹ H P, whose end point λ = 1 is the Kalman update of the particles' own moments
(computed here in covariance form with scipy). The orders the integrators promise, checked:

* IE-PFF is explicit Euler: first order in Δλ;
* EDH evaluates A(λ), b(λ) at the middle of each λ-step but advances the particles by an Euler
  step from its start, which misses the A·dx/dλ term of the local error: also first order (the
  midpoint only removes the A'(λ), b'(λ) part of that term). Neither scheme is second order, so
  neither end point is held to it; what a first-order scheme with a smooth error expansion
  e(h) = C h + O(h²) does promise is that its Richardson extrapolation 2 x(h/2) − x(h) converges at
  second order — checked for both.

Steps start inside the asymptotic range, Δλ ρ ≤ 1/8 with ρ = λ_max(P Hᵀ R⁻¹ H) (drawn in
[0.05, 4]); errors are whitened by the particles' prior covariance. Each halving must shrink the
error by 2^(1 − CONVERGENCE_ORDER_ATOL) (the Richardson error by 2^(2 − CONVERGENCE_ORDER_ATOL)),
up to a rounding floor algebra_rtol(cond) per step.

Each EDH λ-step on its own: the particles advance by x ← x + Δλ (A x + b) with A(λ), b(λ) at the
step's middle, the coefficients here from the Gaussian λ-path in information form — P_λ =
(P⁻¹ + λ HᵀR⁻¹H)⁻¹, A = −½ P_λ HᵀR⁻¹H, m(λ) = P_λ (P⁻¹ x̄₀ + λ HᵀR⁻¹ z) and b = dm/dλ − A m with
dm/dλ = P_λ HᵀR⁻¹ (z − H m) (the exact flow carries the path's mean) — not the closed forms the
library writes.

The EDH step's parallel EKF covariance is the Kalman filter's covariance (information form here).
"""

import numpy as np
import scipy.linalg as sla
from hypothesis import given, settings
from hypothesis import strategies as st

from gpfverify.filters.flows import edh_step, edh_update, ie_pff_update, particle_moments, uniform_steps
from gpfverify.filters.resampling import Particles
from gpfverify.models import linear_model
from gpfverify.strategies import linear_gaussian_models, scaled_examples, spd_matrices
from gpfverify.strategies.matrices import float_arrays, log_uniform
from gpfverify.tolerances import CONVERGENCE_ORDER_ATOL, algebra_rtol


@st.composite
def flow_problems(draw):
    """(particles (N, D), H, R, z): particles whose (1/N) covariance is a drawn SPD P, R rescaled so
    that ρ = λ_max(P Hᵀ R⁻¹ H) is a drawn value in [0.05, 4], z within three innovation standard
    deviations (per whitened axis) of H x̄."""
    dim, size = draw(st.integers(1, 3)), draw(st.integers(1, 3))
    count = draw(st.integers(dim + 2, 12))
    P = draw(spd_matrices(dim, 1e2, log_uniform(1e-2, 1.0)), label="P")
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1), label="particle seed"))
    raw = rng.standard_normal((count, dim))
    raw -= raw.mean(axis=0)
    whitened = sla.solve_triangular(np.linalg.cholesky(raw.T @ raw / count), raw.T, lower=True).T
    mean = draw(float_arrays((dim,), -3.0, 3.0), label="mean")
    particles = mean + whitened @ np.linalg.cholesky(P).T
    H = draw(float_arrays((size, dim), -1.5, 1.5), label="H")
    H[np.arange(min(size, dim)), np.arange(min(size, dim))] += 2.0  # keeps ρ away from 0
    R = draw(spd_matrices(size, 1e2, 1.0), label="R")
    rho = float(np.max(np.linalg.eigvals(P @ H.T @ np.linalg.solve(R, H)).real))
    R = R * rho / draw(log_uniform(0.05, 4.0), label="ρ")
    S = H @ P @ H.T + R
    z = H @ mean + np.linalg.cholesky(S) @ draw(float_arrays((size,), -3.0, 3.0), label="z")
    return particles, H, R, z


def kalman_of_the_particles(particles, H, R, z):
    mean, P = particle_moments(particles)
    gain = sla.solve(H @ P @ H.T + R, H @ P, assume_a="pos").T
    return mean + gain @ (z - H @ mean), P - gain @ H @ P, P


def _rho(P, H, R):
    return float(np.max(np.linalg.eigvals(P @ H.T @ np.linalg.solve(R, H)).real))


FLOWS = {
    "IE-PFF": lambda x, P, model, z, steps: ie_pff_update(x, model, z, 1, steps),
    "EDH": lambda x, P, model, z, steps: edh_update(x, P, model, z, 1, steps),
}


@settings(max_examples=scaled_examples(0.25))
@given(problem=flow_problems(), flow=st.sampled_from(sorted(FLOWS)))
def test_flow_end_points_converge_at_first_order_and_extrapolate_at_second_order(problem, flow):
    particles, H, R, z = problem
    dim = particles.shape[1]
    model = linear_model(np.eye(dim), H, np.eye(dim), R)
    mu_e, C_e, P = kalman_of_the_particles(particles, H, R, z)
    factor = np.linalg.cholesky(P)
    base = int(2 ** np.ceil(np.log2(8.0 * max(_rho(P, H, R), 1.0))))

    def error(count):
        mean, cov = particle_moments(FLOWS[flow](particles, P, model, z, uniform_steps(count)))
        white_mean = sla.solve_triangular(factor, mean - mu_e, lower=True)
        white_cov = sla.solve_triangular(factor, sla.solve_triangular(factor, cov - C_e, lower=True).T, lower=True)
        return np.concatenate([white_mean, white_cov.ravel()])

    e = [error(base * 2**j) for j in range(3)]
    size = 1.0 + np.linalg.norm(sla.solve_triangular(factor, particles.T, lower=True), axis=0).max()
    floor = algebra_rtol(np.linalg.cond(P) * np.linalg.cond(R)) * size * 4 * base
    first, second = 2.0 ** -(1.0 - CONVERGENCE_ORDER_ATOL), 2.0 ** -(2.0 - CONVERGENCE_ORDER_ATOL)
    norms = [np.linalg.norm(v) for v in e]
    assert norms[1] <= first * norms[0] + floor and norms[2] <= first * norms[1] + floor, norms
    richardson = [np.linalg.norm(2.0 * e[1] - e[0]), np.linalg.norm(2.0 * e[2] - e[1])]
    assert richardson[1] <= second * richardson[0] + floor, (richardson, norms)


@st.composite
def step_schedules(draw):
    """1–6 positive λ-steps of unequal sizes (ratios up to 10) summing to 1."""
    sizes = np.array(draw(st.lists(st.floats(0.1, 1.0), min_size=1, max_size=6), label="step sizes"))
    return sizes / sizes.sum()


def edh_coefficients_on_the_gaussian_path(lam, P, H, R, z, x0_mean):
    """A(λ), b(λ) of the exact flow of N(x̄₀, P) towards the posterior of z, from the λ-path in
    information form (module docstring)."""
    dim = P.shape[0]
    info_gain = H.T @ np.linalg.solve(R, np.column_stack([H, z]))  # [HᵀR⁻¹H, HᵀR⁻¹z]
    HtRinvH, HtRinvz = info_gain[:, :dim], info_gain[:, dim]
    to_path = np.eye(dim) + lam * P @ HtRinvH  # P_λ = (I + λ P HᵀR⁻¹H)⁻¹ P
    P_lam = np.linalg.solve(to_path, P)
    A = -0.5 * P_lam @ HtRinvH
    m = np.linalg.solve(to_path, x0_mean + lam * P @ HtRinvz)
    dm = P_lam @ (HtRinvz - HtRinvH @ m)
    return A, dm - A @ m


@settings(max_examples=scaled_examples(0.5))
@given(problem=flow_problems(), steps=step_schedules(), scale=log_uniform(0.5, 2.0))
def test_each_edh_step_is_the_euler_step_of_the_gaussian_path_flow_at_its_middle(problem, steps, scale):
    particles, H, R, z = problem
    dim = particles.shape[1]
    P = scale * particle_moments(particles)[1]  # the flow's covariance need not be the particles'
    model = linear_model(np.eye(dim), H, np.eye(dim), R)
    got = edh_update(particles, P, model, z, 1, steps)
    want, x0_mean, lam_start, size = particles.copy(), particles.mean(axis=0), 0.0, np.abs(particles).max()
    for dlam in steps:
        A, b = edh_coefficients_on_the_gaussian_path(lam_start + 0.5 * dlam, P, H, R, z, x0_mean)
        drift = want @ A.T
        want = want + dlam * (drift + b)
        lam_start += dlam
        size = max(size, np.abs(want).max(), np.abs(drift).max(), np.abs(b).max())  # what each step rounds
    tol = algebra_rtol(np.linalg.cond(P) * np.linalg.cond(R)) * len(steps)
    np.testing.assert_allclose(got, want, rtol=0, atol=tol * size)


@given(model=linear_gaussian_models(max_condition=1e2), seed=st.integers(0, 2**32 - 1), data=st.data())
def test_edh_step_carries_the_kalman_filters_covariance(model, seed, data):
    """P_k|k−1 = F P Fᵀ + Q and P_k|k its Kalman update (information form here): for a linear model
    the parallel EKF is the Kalman filter, whatever the particles."""
    dim = model.F.shape[0]
    particles = data.draw(float_arrays((data.draw(st.integers(2, 8), label="N"), dim), -3.0, 3.0), label="particles")
    system = linear_model(model.F, model.H, model.Q, model.R)
    belief = Particles.equally_weighted(particles, ekf_cov=model.prior.cov)
    step = edh_step(belief, system, model.y, rng=np.random.default_rng(seed), step_sizes=uniform_steps(4))
    C_p = model.F @ model.prior.cov @ model.F.T + model.Q
    info = np.linalg.inv(C_p) + model.H.T @ np.linalg.inv(model.R) @ model.H
    want = np.linalg.inv(info)
    tol = algebra_rtol(np.linalg.cond(C_p) * np.linalg.cond(model.R) * np.linalg.cond(info))
    np.testing.assert_allclose(step.posterior.ekf_cov, want, rtol=0, atol=tol * np.abs(C_p).max())
