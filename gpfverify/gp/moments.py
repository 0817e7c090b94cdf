"""Exact moment matching of SE-ARD GPs at a Gaussian input (seed 000 eq. 8–11 and 20;
Deisenroth, Huber, Hanebeck, ICML 2009; Candela et al. 2003).

For x ~ N(μ, Σ), ν_i = x_i − μ, Λ_a = diag(ℓ_a²):

* q_ai = α_a² |ΣΛ_a⁻¹ + I|^{-1/2} exp(−½ ν_iᵀ(Σ + Λ_a)⁻¹ν_i),      mean M_a = β_aᵀ q_a   (eq. 8–9)
* Q^{ab}_ij = k_a(x_i, μ) k_b(x'_j, μ) |R|^{-1/2} exp(½ z_ijᵀ R⁻¹Σ z_ij),
  R = Σ(Λ_a⁻¹ + Λ_b⁻¹) + I, z_ij = Λ_a⁻¹ν_i + Λ_b⁻¹ν'_j                                  (eq. 11)
* E[f_a f_b] = β_aᵀ Q^{ab} β_b + δ_ab (α_a² − tr(K_a⁻¹ Q^{aa})),  Cov = E[f_a f_b] − M_a M_b (eq. 10)
* Cov[x, f_a] = Σ(Σ + Λ_a)⁻¹ Σ_i β_ai q_ai ν_i                                            (eq. 20)

Outputs a and b may belong to different GPs with different training inputs (x_i and x'_j): that is
how a stack of sensors' measurement GPs gets its cross-sensor blocks through the shared uncertain
input (seed 000 §3).

Σ may be singular: no formula inverts it. With Ξ = Λ_a⁻¹ + Λ_b⁻¹ and S = Ξ^½ΣΞ^½,
|R| = |S + I| and R⁻¹Σ = Ξ^{-½}(I − (S + I)⁻¹)Ξ^{-½}, both from the PD matrix S + I. Likewise
(Σ + Λ_a)⁻¹ = Λ_a^{-½}(B + I)⁻¹Λ_a^{-½} with B = Λ_a^{-½}ΣΛ_a^{-½}. All exponents are summed in log
space before a single ``exp``.
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


def _shifted_inverse(scaled: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For symmetric PSD ``scaled`` (…, D, D): ((scaled + I)⁻¹, log|scaled + I|), batched."""
    d = scaled.shape[-1]
    shifted = scaled + np.eye(d)
    chol = np.linalg.cholesky(shifted)
    logdet = 2.0 * np.sum(np.log(np.diagonal(chol, axis1=-2, axis2=-1)), axis=-1)
    inv = np.linalg.solve(shifted, np.broadcast_to(np.eye(d), shifted.shape))
    return symmetrize(inv), logdet


def _first_moments(gp, mu: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean (E,) and cross-covariance (D, E) of one GP's outputs (eq. 8–9, 20)."""
    nu = gp.X - mu
    inv_ell = 1.0 / gp.lengthscales  # (E, D)
    b_inv, b_logdet = _shifted_inverse(sigma * inv_ell[:, :, None] * inv_ell[:, None, :])
    nu_scaled = nu[None, :, :] * inv_ell[:, None, :]  # Λ^{-½}ν, (E, n, D)
    maha = np.einsum("eid,edk,eik->ei", nu_scaled, b_inv, nu_scaled)  # νᵀ(Σ+Λ)⁻¹ν
    q = np.exp(np.log(gp.signal_var)[:, None] - 0.5 * b_logdet[:, None] - 0.5 * maha)  # (E, n)
    mean = np.einsum("en,en->e", gp.beta, q)
    weighted_nu = (gp.beta * q) @ nu  # Σ_i β_ai q_ai ν_i, (E, D)
    solved = inv_ell * np.einsum("edk,ek->ed", b_inv, inv_ell * weighted_nu)  # (Σ+Λ_a)⁻¹ w
    return mean, sigma @ solved.T


def _second_moments(gp_a, gp_b, ia: np.ndarray, ib: np.ndarray, mu: np.ndarray,
                    sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """β_aᵀ Q^{ab} β_b for the output pairs (ia[p] of gp_a, ib[p] of gp_b), and Q itself
    (P, n_a, n_b) for the trace terms (eq. 10–11)."""
    nu_a, nu_b = gp_a.X - mu, gp_b.X - mu
    inv_l2_a = 1.0 / gp_a.lengthscales[ia] ** 2  # (P, D)
    inv_l2_b = 1.0 / gp_b.lengthscales[ib] ** 2
    xi_half = np.sqrt(inv_l2_a + inv_l2_b)  # Ξ^½ diagonal, (P, D)
    outer = xi_half[:, :, None] * xi_half[:, None, :]
    s_inv, r_logdet = _shifted_inverse(sigma * outer)
    a_mat = (np.eye(sigma.shape[0]) - s_inv) / outer  # R⁻¹Σ, (P, D, D)
    za = nu_a[None, :, :] * inv_l2_a[:, None, :]  # Λ_a⁻¹ν_i, (P, n_a, D)
    zb = nu_b[None, :, :] * inv_l2_b[:, None, :]
    za_a = za @ a_mat
    # log Q_ij = row_i + col_j + z_aᵢᵀ A z_bⱼ with
    #   row_i = log α_a² − ½ ν_iᵀΛ_a⁻¹ν_i + ½ z_aᵢᵀ A z_aᵢ − ½ log|R|,  col_j likewise for b,
    # built by one matmul of augmented factors [z_a A, row, 1] · [z_b, 1, col]ᵀ (one pass over n²)
    row = (np.log(gp_a.signal_var[ia])[:, None] - 0.5 * np.einsum("pnd,nd->pn", za, nu_a)
           + 0.5 * np.sum(za_a * za, axis=-1) - 0.5 * r_logdet[:, None])
    col = (np.log(gp_b.signal_var[ib])[:, None] - 0.5 * np.einsum("pnd,nd->pn", zb, nu_b)
           + 0.5 * np.einsum("pnd,pdk,pnk->pn", zb, a_mat, zb))
    left = np.concatenate([za_a, row[:, :, None], np.ones_like(row)[:, :, None]], axis=-1)
    right = np.concatenate([zb, np.ones_like(col)[:, :, None], col[:, :, None]], axis=-1)
    big_q = left @ np.swapaxes(right, 1, 2)
    np.exp(big_q, out=big_q)
    q_beta_b = (big_q @ gp_b.beta[ib][:, :, None])[:, :, 0]
    return np.sum(gp_a.beta[ia] * q_beta_b, axis=-1), big_q


def moment_match_stack(gps, mu: np.ndarray, sigma: np.ndarray) -> MomentMatch:
    """Joint moments of the stacked outputs of several GPs (each with its own training set) at
    one Gaussian input; arguments are assumed checked."""
    firsts = [_first_moments(gp, mu, sigma) for gp in gps]
    mean = np.concatenate([m for m, _ in firsts])
    cross_cov = np.concatenate([c for _, c in firsts], axis=1)
    offsets = np.cumsum([0] + [gp.output_dim for gp in gps])
    cov = np.empty((offsets[-1], offsets[-1]))
    for g, gp_a in enumerate(gps):
        for h in range(g, len(gps)):
            gp_b = gps[h]
            if g == h:
                ia, ib = np.triu_indices(gp_a.output_dim)
            else:
                ia, ib = (idx.ravel() for idx in np.indices((gp_a.output_dim, gp_b.output_dim)))
            second, big_q = _second_moments(gp_a, gp_b, ia, ib, mu, sigma)
            if g == h:
                # model uncertainty α_a² − tr(K_a⁻¹Q^{aa}); both symmetric, so the trace is Σ of ∘
                diag = ia == ib
                n = gp_a.X.shape[0]
                trace = (gp_a.K_inv[ia[diag]].reshape(-1, 1, n * n)
                         @ big_q[diag].reshape(-1, n * n, 1))[:, 0, 0]
                second[diag] += gp_a.signal_var[ia[diag]] - trace
            rows, cols = offsets[g] + ia, offsets[h] + ib
            cov[rows, cols] = second - mean[rows] * mean[cols]
            cov[cols, rows] = cov[rows, cols]
    return MomentMatch(mean=mean, cov=cov, cross_cov=cross_cov)


def moment_match(gp, mu: np.ndarray, sigma: np.ndarray) -> MomentMatch:
    """Moments of one GP's outputs at N(mu, sigma) (see the module docstring)."""
    return moment_match_stack([gp], mu, sigma)
