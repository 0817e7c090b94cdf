"""Moments of GP stacks (several GPs, each with its own training set) at a Gaussian input, in the
regimes of :func:`gpfverify.strategies.gp_stacks`: ordinary, near-linear (the expm1 path), inputs
much wider than the lengthscales, and training points far from μ (the log-space branch).

Oracles, independent of :mod:`gpfverify.gp.moments` (no shared code beyond β and K⁻¹):

* **textbook eq. 8–11 and 20 in log space**: q_ai, Q^{ab}_ij from their closed forms evaluated
  term by term with ``numpy.linalg`` (log q, log Q, then exp), E[f_a f_b] = β_aᵀQ^{ab}β_b
  (+ α_a² − Σ_ij (K_a⁻¹)_ij Q^{aa}_ji on the diagonal), Cov = E − M_aM_b, and
  Cov[x, f_a] = Σ(Σ + Λ_a)⁻¹ Σ_i β_ai q_ai ν_i. Tolerance: algebra_rtol(κ) times the sum of the
  absolute values of the terms each entry is built from (κ the worst condition number of K_a,
  Σ + Λ_a and R), so cancellation in the textbook form is allowed for, a wrong term is not;
* **linearisation** (near-linear GPs): for outputs a ≠ b, Cov_ab = Σ_ij β_ai β_bj q_ai q_bj
  expm1(d_ij) and its first-order part in Σ is J_a Σ J_bᵀ with J_a = Σ_i β_ai k_a(x_i, μ) ν_iᵀΛ_a⁻¹
  (the gradient of the GP mean at μ). With δ_ij ≥ |d_ij| and ε_ai ≥ |log(q_ai/k_a(x_i, μ))| the
  bounds of the docstring of :func:`_linearisation_bound` (log|I + X| ≤ tr X, R⁻¹Σ ⪯ Σ,
  Λ⁻¹ − (Σ + Λ)⁻¹ ⪯ Λ⁻¹ΣΛ⁻¹), |Cov_ab − J_aΣJ_bᵀ| ≤ Σ_ij|β_aiβ_bj| k k [4(δ_ij + ε_ai + ε_bj)²
  + algebra_rtol(κ) δ_ij] when every argument is ≤ 0.1 — the second term is the rounding a
  cancellation-free evaluation of expm1(d) allows; exp(d) − 1 loses eps·1 instead of eps·δ.
"""

import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

from gpfverify.gp.moments import moment_match_stack
from gpfverify.strategies import gp_stacks
from gpfverify.strategies.profiles import scaled_examples
from gpfverify.tolerances import algebra_rtol

#: every test here runs on the fused kernel (numba) and on the numpy reference path
pytestmark = pytest.mark.usefixtures("moment_path")

#: smallest normal double: below it (subnormals) relative precision is lost, errors are absolute
TINY = float(np.finfo(float).tiny)


def _outputs(gps):
    """(gp index, output index) of every stacked output, in stack order."""
    return [(g, a) for g, gp in enumerate(gps) for a in range(gp.output_dim)]


def _log_kernel_at_mu(gp, a, nu):
    return np.log(gp.signal_var[a]) - 0.5 * np.sum(nu**2 / gp.lengthscales[a] ** 2, axis=1)


def textbook_moments(gps, mu, sigma):
    """(mean, cov, cross_cov, scale of mean, scale of cov, κ) from eq. 8–11, 20 term by term."""
    d = mu.shape[0]
    outs = _outputs(gps)
    log_q, means, cross, mean_scale, kappa = [], [], [], [], 1.0
    for g, a in outs:
        gp = gps[g]
        lam = np.diag(gp.lengthscales[a] ** 2)
        nu = gp.X - mu
        shifted = sigma + lam
        kappa = max(kappa, np.linalg.cond(shifted), np.linalg.cond(gp.K_inv[a]))
        maha = np.einsum("id,id->i", nu, np.linalg.solve(shifted, nu.T).T)
        _, logdet = np.linalg.slogdet(sigma @ np.linalg.inv(lam) + np.eye(d))
        lq = np.log(gp.signal_var[a]) - 0.5 * logdet - 0.5 * maha
        q = np.exp(lq)
        log_q.append(lq)
        means.append(gp.beta[a] @ q)
        mean_scale.append(np.abs(gp.beta[a]) @ q)
        cross.append(sigma @ np.linalg.solve(shifted, nu.T @ (gp.beta[a] * q)))
    total = len(outs)
    cov, cov_scale = np.zeros((total, total)), np.zeros((total, total))
    for p, (g, a) in enumerate(outs):
        for r, (h, b) in enumerate(outs):
            gp_a, gp_b = gps[g], gps[h]
            nu_a, nu_b = gp_a.X - mu, gp_b.X - mu
            xi = np.diag(1 / gp_a.lengthscales[a] ** 2 + 1 / gp_b.lengthscales[b] ** 2)
            big_r = sigma @ xi + np.eye(d)
            kappa = max(kappa, np.linalg.cond(big_r))
            za = nu_a / gp_a.lengthscales[a] ** 2
            zb = nu_b / gp_b.lengthscales[b] ** 2
            t = np.linalg.solve(big_r, sigma)  # R⁻¹Σ
            quad = (np.einsum("id,dk,ik->i", za, t, za)[:, None] + np.einsum("jd,dk,jk->j", zb, t, zb)[None, :]
                    + za @ (t + t.T) @ zb.T)
            _, logdet_r = np.linalg.slogdet(big_r)
            log_big_q = (_log_kernel_at_mu(gp_a, a, nu_a)[:, None] + _log_kernel_at_mu(gp_b, b, nu_b)[None, :]
                         - 0.5 * logdet_r + 0.5 * quad)
            big_q = np.exp(log_big_q)
            second = gp_a.beta[a] @ big_q @ gp_b.beta[b]
            scale = np.abs(gp_a.beta[a]) @ big_q @ np.abs(gp_b.beta[b]) + abs(means[p] * means[r])
            if g == h and a == b:
                second += gp_a.signal_var[a] - np.sum(gp_a.K_inv[a] * big_q.T)
                scale += gp_a.signal_var[a] + np.sum(np.abs(gp_a.K_inv[a]) * big_q.T)
            cov[p, r] = second - means[p] * means[r]
            cov_scale[p, r] = scale
    return (np.array(means), cov, np.column_stack(cross), np.array(mean_scale), cov_scale, kappa)


@given(case=gp_stacks())
@settings(max_examples=scaled_examples(1.5))
def test_stack_moments_equal_the_textbook_formulas(case):
    """Every block of the joint moments of a stack — within one GP and across GPs with different
    training sets — equals eq. 8–11, 20 evaluated term by term, in every regime."""
    event(f"regime: {case.regime}")
    got = moment_match_stack(list(case.gps), case.mu, case.sigma)
    mean, cov, cross, mean_scale, cov_scale, kappa = textbook_moments(case.gps, case.mu, case.sigma)
    tol = algebra_rtol(kappa)
    floor = TINY * sum(gp.X.shape[0] for gp in case.gps) ** 2  # below the normal range: absolute
    assert np.all(np.abs(got.mean - mean) <= tol * mean_scale + floor), (got.mean, mean)
    assert np.all(np.abs(got.cov - cov) <= tol * cov_scale + floor), (got.cov, cov, cov_scale)
    sigma_norm = np.linalg.norm(case.sigma, 2)
    # eq. 20: each column built from Σ_i β_ai q_ai ν_i; scale its terms' absolute sizes
    scales = []
    for g, a in _outputs(case.gps):
        gp = case.gps[g]
        nu = gp.X - case.mu
        q = np.exp(_log_q(gp, a, case.mu, case.sigma))
        scales.append(sigma_norm * np.linalg.norm(np.linalg.inv(case.sigma + np.diag(gp.lengthscales[a] ** 2)), 2)
                      * (np.abs(gp.beta[a] * q) @ np.linalg.norm(nu, axis=1)))
    assert np.all(np.abs(got.cross_cov - cross) <= tol * np.array(scales)[None, :] + floor), (got.cross_cov, cross)


def _log_q(gp, a, mu, sigma):
    nu = gp.X - mu
    lam = np.diag(gp.lengthscales[a] ** 2)
    maha = np.einsum("id,id->i", nu, np.linalg.solve(sigma + lam, nu.T).T)
    _, logdet = np.linalg.slogdet(sigma @ np.linalg.inv(lam) + np.eye(mu.shape[0]))
    return np.log(gp.signal_var[a]) - 0.5 * logdet - 0.5 * maha


def _linearisation_bound(gp_a, a, gp_b, b, mu, sigma, kappa):
    """Σ_ij |β_ai β_bj| k_ai k_bj [4(δ_ij + ε_ai + ε_bj)² + algebra_rtol(κ) δ_ij] with
    δ_ij = ½tr(ΣΞ) + ½‖Σ‖‖z_ij‖² + ½tr(ΣΛ_a⁻¹) + ½tr(ΣΛ_b⁻¹) + ½‖Σ‖(‖Λ_a⁻¹ν_i‖² + ‖Λ_b⁻¹ν_j‖²) ≥ |d_ij|
    and ε_ai = ½tr(ΣΛ_a⁻¹) + ½‖Σ‖‖Λ_a⁻¹ν_i‖² ≥ |log(q_ai / k_a(x_i, μ))|; None if an argument
    exceeds 0.1 (the bound's range)."""
    s = np.linalg.norm(sigma, 2)
    la, lb = 1 / gp_a.lengthscales[a] ** 2, 1 / gp_b.lengthscales[b] ** 2
    za, zb = (gp_a.X - mu) * la, (gp_b.X - mu) * lb
    eps_a = 0.5 * np.trace(sigma * la) + 0.5 * s * np.sum(za**2, axis=1)
    eps_b = 0.5 * np.trace(sigma * lb) + 0.5 * s * np.sum(zb**2, axis=1)
    z2 = np.sum((za[:, None, :] + zb[None, :, :]) ** 2, axis=-1)
    delta = 0.5 * np.trace(sigma * (la + lb)) + 0.5 * s * z2 + eps_a[:, None] + eps_b[None, :]
    total = delta + eps_a[:, None] + eps_b[None, :]
    if total.max() > 0.1:
        return None
    ka = np.exp(_log_kernel_at_mu(gp_a, a, gp_a.X - mu))
    kb = np.exp(_log_kernel_at_mu(gp_b, b, gp_b.X - mu))
    weight = np.abs(gp_a.beta[a] * ka)[:, None] * np.abs(gp_b.beta[b] * kb)[None, :]
    return float(np.sum(weight * (4 * total**2 + algebra_rtol(kappa) * delta)))


def _mean_gradient(gp, a, mu):
    """J_a = Σ_i β_ai k_a(x_i, μ) Λ_a⁻¹(x_i − μ), the gradient of the GP mean at μ."""
    nu = gp.X - mu
    k = np.exp(_log_kernel_at_mu(gp, a, nu))
    return (gp.beta[a] * k) @ (nu / gp.lengthscales[a] ** 2)


@given(case=gp_stacks(regime="near-linear", count=st.integers(1, 3)))
def test_near_linear_cross_covariances_are_the_linearisation(case):
    """Near-linear GPs (lengthscales ≫ the input spread): every covariance between two different
    outputs — of one GP or of two GPs with different training sets — is J_a Σ J_bᵀ within the
    second-order bound of :func:`_linearisation_bound`, which also bounds the rounding of the
    centred form (expm1) relative to the size of d, not to 1."""
    got = moment_match_stack(list(case.gps), case.mu, case.sigma)
    outs = _outputs(case.gps)
    kappa = max(np.linalg.cond(k) for gp in case.gps for k in gp.K_inv)
    checked = 0
    for p, (g, a) in enumerate(outs):
        for r, (h, b) in enumerate(outs):
            if p == r:
                continue
            bound = _linearisation_bound(case.gps[g], a, case.gps[h], b, case.mu, case.sigma, kappa)
            if bound is None:
                continue
            linear = _mean_gradient(case.gps[g], a, case.mu) @ case.sigma @ _mean_gradient(case.gps[h], b, case.mu)
            assert abs(got.cov[p, r] - linear) <= bound, (p, r, got.cov[p, r], linear, bound)
            checked += 1
    event(f"pairs checked: {min(checked, 3)}{'+' if checked > 3 else ''}")
