"""Exact moment matching of a SE-ARD GP at a Gaussian input (seed 000 eq. 8–11 and 20;
Deisenroth, Huber, Hanebeck, ICML 2009; Candela et al. 2003).

For x ~ N(μ, Σ), ν_i = x_i − μ, Λ_a = diag(ℓ_a²):

* q_ai = α_a² |ΣΛ_a⁻¹ + I|^{-1/2} exp(−½ ν_iᵀ(Σ + Λ_a)⁻¹ν_i),      mean M_a = β_aᵀ q_a   (eq. 8–9)
* Q^{ab}_ij = k_a(x_i, μ) k_b(x_j, μ) |R|^{-1/2} exp(½ z_ijᵀ R⁻¹Σ z_ij),
  R = Σ(Λ_a⁻¹ + Λ_b⁻¹) + I, z_ij = Λ_a⁻¹ν_i + Λ_b⁻¹ν_j                                  (eq. 11)
* E[f_a f_b] = β_aᵀ Q^{ab} β_b + δ_ab (α_a² − tr(K_a⁻¹ Q^{aa})),  Cov = E[f_a f_b] − M_a M_b (eq. 10)
* Cov[x, f_a] = Σ(Σ + Λ_a)⁻¹ Σ_i β_ai q_ai ν_i                                            (eq. 20)

Σ may be singular: no formula inverts it. With Ξ = Λ_a⁻¹ + Λ_b⁻¹ and S = Ξ^½ΣΞ^½,
|R| = |S + I| and R⁻¹Σ = Ξ^{-½}(I − (S + I)⁻¹)Ξ^{-½}, both from a Cholesky of the PD matrix
S + I. Likewise (Σ + Λ_a)⁻¹ = Λ_a^{-½}(B + I)⁻¹Λ_a^{-½} with B = Λ_a^{-½}ΣΛ_a^{-½}. All
exponents are summed in log space before a single ``exp``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gpfverify.linalg import symmetrize


@dataclass(frozen=True)
class MomentMatch:
    """Moments of the latent f(x), x ~ N(μ, Σ): ``mean`` (E,), ``cov`` (E, E) including the
    model-uncertainty diagonal (no observation noise), ``cross_cov`` (D, E) = Cov[x, f(x)]."""

    mean: np.ndarray
    cov: np.ndarray
    cross_cov: np.ndarray


def _sym_solve_factor(scaled: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For symmetric PSD ``scaled`` (…, D, D): ((scaled + I)⁻¹, log|scaled + I|), batched."""
    d = scaled.shape[-1]
    shifted = scaled + np.eye(d)
    chol = np.linalg.cholesky(shifted)
    logdet = 2.0 * np.sum(np.log(np.diagonal(chol, axis1=-2, axis2=-1)), axis=-1)
    inv = np.linalg.solve(shifted, np.broadcast_to(np.eye(d), shifted.shape))
    return symmetrize(inv), logdet


def moment_match(gp, mu: np.ndarray, sigma: np.ndarray) -> MomentMatch:
    """Moments of ``gp`` (a :class:`~gpfverify.gp.regression.GaussianProcess`) at N(mu, sigma);
    arguments are assumed checked (see ``GaussianProcess.predict_uncertain``)."""
    n_out = gp.output_dim
    nu = gp.X - mu  # (n, D)
    inv_ell = 1.0 / gp.lengthscales  # (E, D)
    log_sig = np.log(gp.signal_var)  # (E,)

    # --- mean and cross-covariance (eq. 8–9, 20) ---
    b_mat = sigma * inv_ell[:, :, None] * inv_ell[:, None, :]  # Λ^{-½}ΣΛ^{-½}, (E, D, D)
    b_inv, b_logdet = _sym_solve_factor(b_mat)
    nu_scaled = nu[None, :, :] * inv_ell[:, None, :]  # Λ^{-½}ν, (E, n, D)
    maha = np.einsum("eid,edk,eik->ei", nu_scaled, b_inv, nu_scaled)  # νᵀ(Σ+Λ)⁻¹ν
    q = np.exp(log_sig[:, None] - 0.5 * b_logdet[:, None] - 0.5 * maha)  # (E, n)
    mean = np.einsum("en,en->e", gp.beta, q)
    bq = gp.beta * q  # (E, n)
    weighted_nu = bq @ nu  # Σ_i β_ai q_ai ν_i, (E, D)
    # (Σ+Λ_a)⁻¹ w = Λ^{-½}(B+I)⁻¹Λ^{-½} w
    solved = inv_ell * np.einsum("edk,ek->ed", b_inv, inv_ell * weighted_nu)
    cross_cov = sigma @ solved.T  # (D, E)

    # --- second moments (eq. 10–11), all pairs a ≤ b at once ---
    ia, ib = np.triu_indices(n_out)
    xi = inv_ell[ia] ** 2 + inv_ell[ib] ** 2  # (P, D) diagonal of Λ_a⁻¹ + Λ_b⁻¹
    xi_half = np.sqrt(xi)
    s_mat = sigma * xi_half[:, :, None] * xi_half[:, None, :]  # Ξ^½ΣΞ^½
    s_inv, r_logdet = _sym_solve_factor(s_mat)
    d = sigma.shape[0]
    a_mat = (np.eye(d) - s_inv) / (xi_half[:, :, None] * xi_half[:, None, :])  # R⁻¹Σ, (P, D, D)
    z = nu[None, :, :] * inv_ell[:, None, :] ** 2  # Λ_a⁻¹ν_i, (E, n, D)
    za, zb = z[ia], z[ib]  # (P, n, D)
    za_a = za @ a_mat  # (P, n, D)
    # log k_a(x_i, μ) + ½ z_aᵀ A z_a per i, same per j, plus the cross term z_aᵀ A z_b
    half_sq = 0.5 * np.sum(nu_scaled * nu_scaled, axis=-1)  # ½ νᵀΛ⁻¹ν, (E, n)
    row = log_sig[ia][:, None] - half_sq[ia] + 0.5 * np.sum(za_a * za, axis=-1)
    col = log_sig[ib][:, None] - half_sq[ib] + 0.5 * np.einsum("pnd,pdk,pnk->pn", zb, a_mat, zb)
    log_q = row[:, :, None] + col[:, None, :] + za_a @ np.swapaxes(zb, 1, 2)
    log_q -= 0.5 * r_logdet[:, None, None]
    big_q = np.exp(log_q)  # (P, n, n)
    second = np.einsum("pi,pij,pj->p", gp.beta[ia], big_q, gp.beta[ib])
    diag = ia == ib
    # model uncertainty: α_a² − tr(K_a⁻¹ Q^{aa}) (both symmetric: trace = sum of the product)
    second[diag] += gp.signal_var[ia[diag]] - np.einsum("pij,pij->p", gp.K_inv[ia[diag]], big_q[diag])
    cov = np.empty((n_out, n_out))
    cov[ia, ib] = second - mean[ia] * mean[ib]
    cov[ib, ia] = cov[ia, ib]
    return MomentMatch(mean=mean, cov=cov, cross_cov=cross_cov)
