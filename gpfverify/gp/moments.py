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

Evaluated in centred form, Cov = β_aᵀ(Q^{ab} − q_a q_bᵀ)β_b + δ_ab[α_a² − (‖L_a⁻¹q_a‖²
+ tr(K_a⁻¹(Q^{aa} − q_a q_aᵀ)))] (L_a the Cholesky factor of K_a), with Q^{ab}_ij = q_ai q_bj exp(d_ij)
and the small exponent d_ij formed directly (see :func:`_centred_second_moments`), so that
Q − q_a q_bᵀ = q_ai q_bj expm1(d_ij). Algebraically the same as eq. 10, but no quantity is a
difference of nearly equal large numbers. With long lengthscales and a large signal variance (a GP
fitted to a nearly linear map) the entries of Q are of order α⁴ ≈ 1e13 while the covariance is of
order one: eq. 10 evaluated as written lost every digit there (an eigenvalue of −2 where
quadrature gives +1.4).

Σ may be singular: no formula inverts it. With Ξ = Λ_a⁻¹ + Λ_b⁻¹ and S = Ξ^½ΣΞ^½,
|R| = |S + I| and R⁻¹Σ = Ξ^{-½}(S + I)⁻¹SΞ^{-½}, both from the PD matrix S + I. Likewise
(Σ + Λ_a)⁻¹ = Λ_a^{-½}(B + I)⁻¹Λ_a^{-½} with B = Λ_a^{-½}ΣΛ_a^{-½}; log-determinants are Σ log1p of
eigenvalues.
"""

from __future__ import annotations

import functools
import threading
from dataclasses import dataclass

import numpy as np

from gpfverify.gp.fused import EXPM1_SAFE, centred_sums, first_moments as fused_first_moments
from gpfverify.linalg import symmetrize


@dataclass(frozen=True)
class MomentMatch:
    """Moments of the latent f(x), x ~ N(μ, Σ): ``mean`` (E,), ``cov`` (E, E) including the
    model-uncertainty diagonal (no observation noise), ``cross_cov`` (D, E) = Cov[x, f(x)]."""

    mean: np.ndarray
    cov: np.ndarray
    cross_cov: np.ndarray


def _shifted(scaled: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For symmetric PSD ``scaled`` = S (…, D, D): ((S + I)⁻¹, (S + I)⁻¹S, log|S + I|), batched,
    from one eigendecomposition S = V diag(λ) Vᵀ: (S + I)⁻¹ = V diag(1/(1 + λ)) Vᵀ,
    (S + I)⁻¹S = V diag(λ/(1 + λ)) Vᵀ and log|S + I| = Σ log1p(λ). When S is tiny (input variance
    far below the lengthscales) none of them is formed as a difference of numbers near 1."""
    eigval, eigvec = np.linalg.eigh(scaled)
    eigval = np.clip(eigval, 0.0, None)  # S is PSD: negative eigenvalues are rounding
    eigvec_t = np.swapaxes(eigvec, -1, -2)
    inv = symmetrize((eigvec / (1.0 + eigval)[..., None, :]) @ eigvec_t)
    ratio = symmetrize((eigvec * (eigval / (1.0 + eigval))[..., None, :]) @ eigvec_t)
    return inv, ratio, np.sum(np.log1p(eigval), axis=-1)


@dataclass(frozen=True)
class _FirstMoments:
    """One GP's mean (E,), cross-covariance (D, E), log q (E, n) and the per-point exponent
    t_ai = ν_iᵀ(Λ_a⁻¹ − (Σ + Λ_a)⁻¹)ν_i (E, n) with log|B_a + I| (E,) and q = exp(log q) (E, n),
    reused by the second moments."""

    mean: np.ndarray
    cross_cov: np.ndarray
    log_q: np.ndarray
    t: np.ndarray
    b_logdet: np.ndarray
    q: np.ndarray


def _first_moments(gp, mu: np.ndarray, sigma: np.ndarray) -> _FirstMoments:
    """Eq. 8–9 and 20 for every output of one GP."""
    nu = gp.X - mu
    inv_ell = 1.0 / gp.lengthscales  # (E, D)
    b_inv, b_ratio, b_logdet = _shifted(sigma * inv_ell[:, :, None] * inv_ell[:, None, :])
    nu_scaled = nu[None, :, :] * inv_ell[:, None, :]  # Λ^{-½}ν, (E, n, D)
    maha = np.sum((nu_scaled @ b_inv) * nu_scaled, axis=-1)  # νᵀ(Σ+Λ)⁻¹ν, (E, n)
    t = np.sum((nu_scaled @ b_ratio) * nu_scaled, axis=-1)  # νᵀ(Λ⁻¹ − (Σ+Λ)⁻¹)ν
    log_q = np.log(gp.signal_var)[:, None] - 0.5 * b_logdet[:, None] - 0.5 * maha  # (E, n)
    q = np.exp(log_q)
    mean = np.einsum("en,en->e", gp.beta, q)
    weighted_nu = (gp.beta * q) @ nu  # Σ_i β_ai q_ai ν_i, (E, D)
    solved = inv_ell * np.einsum("edk,ek->ed", b_inv, inv_ell * weighted_nu)  # (Σ+Λ_a)⁻¹ w
    return _FirstMoments(mean, sigma @ solved.T, log_q, t, b_logdet, q)


class _Workspace(threading.local):
    """Per-thread scratch array for the (B, P, n_a, n_b) exponent matrices of the numpy path,
    reused across calls: a fresh array of that size (7 MB at n = 300, E = 4) costs page faults on
    every call, about half the time of its exponentials."""

    buffer: np.ndarray = np.empty(0)

    def take(self, shape: tuple[int, ...]) -> np.ndarray:
        size = int(np.prod(shape))
        if self.buffer.size < size:
            self.buffer = np.empty(size)
        return self.buffer[:size].reshape(shape)


_WORKSPACE = _Workspace()
#: Largest number of n_a·n_b entries (over the batch and output pairs) formed at once
_CHUNK_ENTRIES = 1 << 22


_FIELDS = ("mean", "cross_cov", "log_q", "t", "b_logdet", "q")


def _stack_firsts(firsts: list[_FirstMoments]) -> _FirstMoments:
    """The first moments of a batch of inputs, each field with a leading batch axis."""
    return _FirstMoments(*(np.stack([getattr(f, name) for f in firsts]) for name in _FIELDS))


def _model_arrays(gp) -> tuple[np.ndarray, ...]:
    """(X, lengthscales, signal_var, β, K⁻¹, Lᵀ) of a GP with a leading axis of models: 1 for one
    GP (views), B for a :class:`~gpfverify.gp.batch.GaussianProcessBatch` (run b's GP at b)."""
    arrays = (gp.X, gp.lengthscales, gp.signal_var, gp.beta, gp.K_inv, gp.factors_t)
    return arrays if getattr(gp, "runs", None) is not None else tuple(a[None] for a in arrays)


def _member(gp, b: int):
    """The GP input b is matched against: run b's of a batch, else the one GP."""
    return gp.members[b] if getattr(gp, "runs", None) is not None else gp


def _first_moments_batch(gp, mu: np.ndarray, sigma: np.ndarray) -> _FirstMoments:
    """A GP's first moments at a batch of inputs N(mu[b], sigma[b]) (input b against run b's GP for
    a batch of GPs), each field with a leading batch axis: by the compiled kernel when it is
    enabled, else input by input with :func:`_first_moments` (the reference)."""
    x, lengthscales, signal_var, beta, _, _ = _model_arrays(gp)
    compiled = fused_first_moments(x, lengthscales, signal_var, beta, mu, sigma)
    if compiled is not None:
        return _FirstMoments(*compiled)
    return _stack_firsts([_first_moments(_member(gp, b), mu[b], sigma[b]) for b in range(mu.shape[0])])


def _batch_part(first: _FirstMoments, part) -> _FirstMoments:
    return _FirstMoments(*(getattr(first, name)[part] for name in _FIELDS))


def _centred_second_moments(gp_a, gp_b, ia: np.ndarray, ib: np.ndarray, first_a: _FirstMoments,
                            first_b: _FirstMoments, mu: np.ndarray, sigma: np.ndarray, diagonal: np.ndarray
                            ) -> tuple[np.ndarray, np.ndarray]:
    """Cov[m_a, m_b] = β_aᵀ (Q^{ab} − q_a q_bᵀ) β_b (B, P) for the output pairs (ia[p] of gp_a,
    ib[p] of gp_b) at a batch of inputs N(mu[b], sigma[b]) (mu (B, D), sigma (B, D, D), first
    moments with a leading batch axis; for batches of GPs, input b against run b's GPs), and the
    traces tr(K_a⁻¹Q^{aa}) = ‖L_a⁻¹q_a‖² + tr(K_a⁻¹(Q^{aa} − q_a q_aᵀ)) (B, P) of the pairs p with
    ``diagonal[p]`` = a ≥ 0 (the pair (a, a) of one GP; zero elsewhere) (eq. 10–11).

    The n_a × n_b sums go through the fused kernel (:mod:`gpfverify.gp.fused`) when it is enabled,
    else through numpy (:func:`_numpy_centred_second_moments`, the reference: the same sums to
    rounding); an input whose exponents the kernel cannot bound takes the numpy path alone, so what
    an input gets depends on it alone, not on the rest of the batch."""
    x_a, ell_a, _, beta_a, k_inv, factors_t = _model_arrays(gp_a)
    x_b, ell_b, _, beta_b, _, _ = _model_arrays(gp_b)
    fused = centred_sums(x_a, x_b, mu, sigma, ell_a, ell_b, first_a.b_logdet, first_b.b_logdet, ia, ib,
                         first_a.t, first_b.t, first_a.q, first_b.q, beta_a, beta_b, k_inv, factors_t, diagonal)
    if fused is not None:
        cov, traces, computed = fused
        if computed.all():
            return cov, traces
        rest = np.flatnonzero(~computed)
    else:
        cov, traces = np.empty((mu.shape[0], ia.size)), np.empty((mu.shape[0], ia.size))
        rest = np.arange(mu.shape[0])
    if getattr(gp_a, "runs", None) is None and getattr(gp_b, "runs", None) is None and fused is None:
        for part in _chunks(rest.size, ia.size * x_a.shape[1] * x_b.shape[1]):
            index = rest[part]
            cov[index], traces[index] = _numpy_centred_second_moments(
                gp_a, gp_b, ia, ib, _batch_part(first_a, index), _batch_part(first_b, index), mu[index],
                sigma[index], diagonal)
        return cov, traces
    for b in rest.tolist():  # one input at a time, against its own GPs
        one = slice(b, b + 1)
        cov[one], traces[one] = _numpy_centred_second_moments(
            _member(gp_a, b), _member(gp_b, b), ia, ib, _batch_part(first_a, one), _batch_part(first_b, one),
            mu[one], sigma[one], diagonal)
    return cov, traces


def _numpy_centred_second_moments(gp_a, gp_b, ia: np.ndarray, ib: np.ndarray, first_a: _FirstMoments,
                                  first_b: _FirstMoments, mu: np.ndarray, sigma: np.ndarray, diagonal: np.ndarray
                                  ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_centred_second_moments` in numpy for one GP pair (a, b) at a batch of inputs.

    Q_ij = q_ai q_bj exp(d_ij) with the small exponent
    d_ij = −½t_ai − ½t_bj + ½ z_ijᵀR⁻¹Σz_ij − ½log|R| + ½log|B_a + I| + ½log|B_b + I|,
    so Q − q_a q_bᵀ = q_ai q_bj expm1(d_ij) without cancellation."""
    inv_l2_a = 1.0 / gp_a.lengthscales[ia] ** 2  # (P, D)
    inv_l2_b = 1.0 / gp_b.lengthscales[ib] ** 2
    xi_half = np.sqrt(inv_l2_a + inv_l2_b)  # Ξ^½ diagonal, (P, D)
    outer = xi_half[:, :, None] * xi_half[:, None, :]
    _, s_ratio, r_logdet = _shifted(sigma[:, None] * outer)  # (B, P, D, D), (B, P)
    a_mat = s_ratio / outer  # R⁻¹Σ = Ξ^{-½}(S + I)⁻¹SΞ^{-½}, (B, P, D, D)
    const = 0.5 * (first_a.b_logdet[:, ia] + first_b.b_logdet[:, ib] - r_logdet)  # (B, P)
    nu_a, nu_b = gp_a.X - mu[:, None, :], gp_b.X - mu[:, None, :]  # (B, n, D)
    za = nu_a[:, None] * inv_l2_a[:, None, :]  # Λ_a⁻¹ν_i, (B, P, n_a, D)
    zb = nu_b[:, None] * inv_l2_b[:, None, :]
    za_a = za @ a_mat
    row = -0.5 * first_a.t[:, ia] + 0.5 * np.sum(za_a * za, axis=-1) + const[..., None]
    col = -0.5 * first_b.t[:, ib] + 0.5 * np.sum((zb @ a_mat) * zb, axis=-1)
    q_a, q_b = np.exp(first_a.log_q[:, ia]), np.exp(first_b.log_q[:, ib])  # (B, P, n)
    # d_ij by one matmul of augmented factors [z_a A, row, 1] · [z_b, 1, col]ᵀ (one pass over n²)
    left = np.concatenate([za_a, row[..., None], np.ones_like(row)[..., None]], axis=-1)
    right = np.concatenate([zb, np.ones_like(col)[..., None], col[..., None]], axis=-1)
    exponent = np.matmul(left, np.swapaxes(right, -1, -2),
                         out=_WORKSPACE.take(left.shape[:-1] + right.shape[-2:-1]))
    if exponent.max() <= EXPM1_SAFE:
        # Q − q_a q_bᵀ = diag(q_a) E diag(q_b), E = expm1(d): q folded into the weights
        centred = np.expm1(exponent, out=exponent)
        left_scale, right_scale = q_a, q_b
    else:
        centred = _log_space_centred(first_a.log_q[:, ia], first_b.log_q[:, ib], exponent)
        left_scale, right_scale = np.ones_like(q_a), np.ones_like(q_b)
    weighted_b = ((gp_b.beta[ib] * right_scale)[..., None, :] @ np.swapaxes(centred, -1, -2))[..., 0, :]
    cov = np.sum(gp_a.beta[ia] * left_scale * weighted_b, axis=-1)
    traces = _traces(gp_a.K_inv, centred, left_scale, right_scale, diagonal)
    return cov, traces + _whitened_squares(gp_a, first_a.q[:, ia], diagonal)


def _log_space_centred(log_q_a: np.ndarray, log_q_b: np.ndarray, exponent: np.ndarray) -> np.ndarray:
    """Q − q_a q_bᵀ entry by entry (B, P, n_a, n_b) where exp(d) would overflow and q_a q_b
    underflows (an input far wider than the lengthscales): q_ai q_bj exp(d_ij) in log space above
    :data:`EXPM1_SAFE`, q_ai q_bj expm1(d_ij) below."""
    log_base = log_q_a[..., :, None] + log_q_b[..., None, :]
    return np.where(exponent > EXPM1_SAFE, np.exp(np.minimum(log_base + exponent, EXPM1_SAFE)),
                    np.exp(log_base) * np.expm1(np.minimum(exponent, EXPM1_SAFE)))


def _traces(k_inv: np.ndarray, centred: np.ndarray, left: np.ndarray, right: np.ndarray,
            diagonal: np.ndarray) -> np.ndarray:
    """tr(K_a⁻¹ diag(left) C diag(right)) (B, P) for the pairs p with diagonal[p] = a ≥ 0, zero
    elsewhere; C = ``centred`` (B, P, n, n). K_a⁻¹ and C are symmetric there, so the trace is
    Σ_ij (K_a⁻¹)_ij left_i C_ij right_j: one elementwise product (into a scratch array) and one
    matrix–vector product."""
    batch, pairs, n, _ = centred.shape
    trace = np.zeros((batch, pairs))
    scratch = np.empty((n, n))
    for p in np.flatnonzero(diagonal >= 0):
        for b in range(batch):
            np.multiply(k_inv[diagonal[p]], centred[b, p], out=scratch)
            trace[b, p] = left[b, p] @ (scratch @ right[b, p])
    return trace


def _whitened_squares(gp, q: np.ndarray, diagonal: np.ndarray) -> np.ndarray:
    """‖L_a⁻¹q_a‖² (B, P) for the pairs p with diagonal[p] = a ≥ 0 (zero elsewhere), q (B, P, n) the
    pairs' first-output q: one BLAS trsv per input and pair (a batch's columns in one trsm would
    save a few µs per input but, with a multithreaded BLAS, leave its threads spinning for the
    rest of the call: twice the process CPU time, measured)."""
    squares = np.zeros(q.shape[:2])
    for p in np.flatnonzero(diagonal >= 0):
        chol = gp.choleskys[diagonal[p]]
        for b in range(q.shape[0]):
            whitened = chol.whiten(q[b, p])
            squares[b, p] = whitened @ whitened
    return squares


def _model_uncertainty(gp, traces: np.ndarray) -> np.ndarray:
    """E_x[σ_a²(x)] = α_a² − tr(K_a⁻¹Q^{aa}) for every output a at a batch of inputs: (B, E), from
    the traces (B, E) of :func:`_centred_second_moments`, there formed as (‖L_a⁻¹q_a‖²
    + tr(K_a⁻¹(Q^{aa} − q_a q_aᵀ))) so that no term is a difference of large numbers."""
    return gp.signal_var - traces


def _chunks(batch: int, entries_per_input: int) -> list[slice]:
    """Slices of the batch axis so that each chunk forms at most :data:`_CHUNK_ENTRIES` entries."""
    step = max(1, _CHUNK_ENTRIES // max(1, entries_per_input))
    if step >= batch:
        return [slice(None)]
    return [slice(i, min(i + step, batch)) for i in range(0, batch, step)]


@functools.lru_cache(maxsize=64)
def _block_pairs(outputs_a: int, outputs_b: int, same_gp: bool
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The output pairs (ia[p], ib[p]) of one block of the joint covariance — the upper triangle
    within one GP, every pair across two — ``diagonal[p]``: the output a of each pair (a, a) of one
    GP, whose covariance adds E_x[σ_a²(x)], −1 elsewhere, and the indices p of those pairs
    (read-only arrays, shared by calls)."""
    if same_gp:
        ia, ib = np.triu_indices(outputs_a)
        diagonal = np.where(ia == ib, ia, -1)
    else:
        ia, ib = (idx.ravel() for idx in np.indices((outputs_a, outputs_b)))
        diagonal = np.full(ia.size, -1)
    on_diagonal = np.flatnonzero(diagonal >= 0)
    for array in (ia, ib, diagonal, on_diagonal):
        array.flags.writeable = False
    return ia, ib, diagonal, on_diagonal


def moment_match_stack_batch(gps, mu: np.ndarray, sigma: np.ndarray) -> MomentMatch:
    """Joint moments of the stacked outputs of several GPs (each with its own training set) at a
    batch of Gaussian inputs N(mu[b], sigma[b]): mu (B, D), sigma (B, D, D); returns mean (B, E),
    cov (B, E, E), cross_cov (B, D, E). Arguments are assumed checked. Each input gets the same
    numbers as a call of its own (:func:`moment_match_stack`), to rounding; the small per-input
    algebra is done once for the whole batch. For :class:`~gpfverify.gp.batch.GaussianProcessBatch`
    members (one GP per Monte Carlo run, B of them), input b is matched against run b's GPs, and
    what it gets does not depend on the other runs in the batch (the same bits for any batch)."""
    batch = mu.shape[0]
    firsts = [_first_moments_batch(gp, mu, sigma) for gp in gps]
    mean = np.concatenate([f.mean for f in firsts], axis=-1)
    cross_cov = np.concatenate([f.cross_cov for f in firsts], axis=-1)
    offsets = [0]
    for gp in gps:
        offsets.append(offsets[-1] + gp.output_dim)
    cov = np.empty((batch, offsets[-1], offsets[-1]))
    for g, gp_a in enumerate(gps):
        for h in range(g, len(gps)):
            gp_b = gps[h]
            ia, ib, diagonal, on_diagonal = _block_pairs(gp_a.output_dim, gp_b.output_dim, g == h)
            pair_cov, traces = _centred_second_moments(gp_a, gp_b, ia, ib, firsts[g], firsts[h], mu, sigma,
                                                       diagonal)
            block = pair_cov.T  # (P, B): Cov[f_a, f_b] per output pair and input
            if on_diagonal.size:
                block[on_diagonal] += _model_uncertainty(gp_a, traces[:, on_diagonal]).T
            rows, cols = offsets[g] + ia, offsets[h] + ib
            cov[:, rows, cols] = block.T
            cov[:, cols, rows] = block.T
    return MomentMatch(mean=mean, cov=cov, cross_cov=cross_cov)


def moment_match_stack(gps, mu: np.ndarray, sigma: np.ndarray) -> MomentMatch:
    """Joint moments of the stacked outputs of several GPs (each with its own training set) at
    one Gaussian input; arguments are assumed checked."""
    mm = moment_match_stack_batch(gps, mu[None], sigma[None])
    return MomentMatch(mean=mm.mean[0], cov=mm.cov[0], cross_cov=mm.cross_cov[0])


def moment_match(gp, mu: np.ndarray, sigma: np.ndarray) -> MomentMatch:
    """Moments of one GP's outputs at N(mu, sigma) (see the module docstring)."""
    return moment_match_stack([gp], mu, sigma)


def moment_match_batch(gp, mu: np.ndarray, sigma: np.ndarray) -> MomentMatch:
    """Moments of one GP's outputs (or of a stack's, for a
    :class:`~gpfverify.gp.stack.GaussianProcessStack`) at many Gaussian inputs N(mu[b], sigma[b]):
    mu (B, D), sigma (B, D, D); mean (B, E), cov (B, E, E), cross_cov (B, D, E). Equal to
    :func:`moment_match` per input, to rounding; arguments are assumed checked."""
    return moment_match_stack_batch(list(getattr(gp, "gps", (gp,))), mu, sigma)
