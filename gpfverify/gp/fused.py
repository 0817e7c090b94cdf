"""Fused kernel for the n_a × n_b part of exact moment matching (seed 000 eq. 10–11), compiled by
numba when it is installed (the optional ``fast`` extra), with the O(n) and D × D algebra around it
(the first moments, eq. 8–9 and 20, and each output pair's R⁻¹Σ and log-determinants) compiled
too, so that one moment match is a few compiled calls rather than some hundred small numpy ones;
:mod:`gpfverify.gp.moments` evaluates the same quantities with numpy otherwise, and that path is the
reference this one is tested against.

For one output pair (a, b) at one input, with d_ij = z_iᵀw_j + r_i + c_j the small exponent of
:func:`gpfverify.gp.moments._centred_second_moments` and E_ij = expm1(d_ij):

* Cov[m_a, m_b] = Σ_i u_i Σ_j E_ij v_j,          u = β_a ∘ q_a, v = β_b ∘ q_b         (eq. 10–11)
* tr(K_a⁻¹Q^{aa}) = ‖L_a⁻¹q_a‖² + Σ_i q_i Σ_j (K_a⁻¹)_ij q_j E_ij   (diagonal pairs only; L_a the
  Cholesky factor of K_a, the whitening L_a⁻¹q_a solved row by row in the same pass)

One pass over (i, j) forms d_ij and its expm1 and adds it into per-column sums, row by row in
buffers that stay in cache: no n_a × n_b matrix is written, read back or multiplied. numpy's
``expm1`` costs 1.2 to 2 times its vectorised ``exp`` (by processor); here expm1 is evaluated by
:func:`~gpfverify.gp.expm1.expm1_reference`'s algorithm, which the compiler vectorises:

    k = round(x / ln 2),  r = (x − k·ln2_hi) − k·ln2_lo  (|r| ≤ ½ ln 2, Cody–Waite),
    p = expm1(r) ≈ r + r²·P(r),  P of degree 9 (Estrin's scheme): the Chebyshev fit of
        (expm1(r) − r)/r² on |r| ≤ ½ ln 2, within 4.1e-17 |expm1(r)| (0.18 machine epsilon),
    expm1(x) = 2ᵏ p + (2ᵏ − 1),

with k = 0 giving p itself (no cancellation near zero) and 2ᵏ built from the bits of the rounded
x/ln 2. Arguments are clamped below at −60 (expm1(−60) rounds to −1); above, the caller
guarantees x ≤ 700 (the kernel reports larger exponents and the caller takes the log-space path).
Accuracy: within 2 ulp of a correctly rounded expm1, both here and compiled (each tested against
mpmath). The compiled kernel lets a multiply and the add that follows it fuse into one FMA where
the processor has one (no other reordering): the polynomial and the n² loop are chains of such
pairs, and on a processor whose vector exp is fast (AVX-512) the whole moment match cost about
1.8 × numpy's exp unfused where fused it cost about 1.3 × (measured with the Taylor polynomial the
fit replaced; benchmarks/results/scale.md has the current ratio). On Intel processors with
AVX-512 LLVM prefers 256-bit vectors unless told otherwise; :mod:`gpfverify.numba_target` lets the kernel use the
512-bit ones numpy's exp uses (about 1.9 → 1.5 × numpy's exp on such a Xeon). An FMA rounds
once where the two operations round twice, so the compiled results differ from
:func:`~gpfverify.gp.expm1.expm1_reference` by rounding (the same inputs give the same bits on one machine).
"""

from __future__ import annotations

import importlib.util
import sys

import numpy as np

#: whether numba (the optional ``fast`` extra) is installed; it is imported only when the kernel is
#: first used (:mod:`gpfverify.gp.fused_kernels`), not with the package
AVAILABLE = importlib.util.find_spec("numba") is not None
#: whether :func:`centred_sums` uses the compiled kernel; set False to take the numpy reference path
#: everywhere (tests run both)
enabled = AVAILABLE
#: exponents above this are left to the caller's log-space path (exp(709.8) overflows)
EXPM1_SAFE = 700.0


def _kernels():
    """:mod:`gpfverify.gp.fused_kernels`, imported (and its kernels compiled or loaded from numba's
    cache) on the first call rather than with the package; later calls read it from ``sys.modules``
    without the import statement's own cost (about a µs, paid twice per moment match)."""
    kernels = sys.modules.get("gpfverify.gp.fused_kernels")
    if kernels is None:
        from gpfverify.gp import fused_kernels as kernels
    return kernels


def first_moments(x: np.ndarray, lengthscales: np.ndarray, signal_var: np.ndarray, beta: np.ndarray,
                  mu: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, ...] | None:
    """(mean (B, E), cross_cov (B, D, E), log q (B, E, n), t (B, E, n), log|B_a + I| (B, E), q (B, E, n)) of a
    GP at the inputs N(mu[b], sigma[b]) by :func:`gpfverify.gp.fused_kernels.first_moments`, or None when the
    compiled path is off (the caller's numpy path, :func:`gpfverify.gp.moments._first_moments`,
    computes the same to rounding). The GP's arrays carry a leading axis of G models, 1 or B (input b
    against model b): training inputs x (G, n, D), lengthscales (G, E, D), signal variances (G, E),
    β (G, E, n)."""
    if not enabled:
        return None
    return _kernels().first_moments(x, 1.0 / lengthscales, np.log(signal_var), beta, mu, sigma)


def whitened(factors_t: np.ndarray, vectors: np.ndarray) -> np.ndarray | None:
    """L_ga⁻¹ vectors[g, a] (G, E, n) for the Cholesky factors L_ga given transposed as factors_t
    (G, E, n, n, C-ordered), by BLAS dtrsv called from one compiled loop
    (:func:`gpfverify.gp.fused_kernels.whitened`): the routine and arguments of
    :func:`gpfverify.linalg.lower_solve` for one vector, so the same bits, without a Python call per
    model and output; None when the compiled path is off."""
    if not enabled:
        return None
    kernels = _kernels()
    vectors = np.ascontiguousarray(vectors)
    out = np.empty_like(vectors)
    kernels.whitened(kernels.TRSV, np.ascontiguousarray(factors_t), vectors, out)
    return out


def centred_sums(x_a: np.ndarray, x_b: np.ndarray, mu: np.ndarray, sigma: np.ndarray, ell_a: np.ndarray,
                 ell_b: np.ndarray, b_logdet_a: np.ndarray, b_logdet_b: np.ndarray, ia: np.ndarray,
                 ib: np.ndarray, t_a: np.ndarray, t_b: np.ndarray, q_a: np.ndarray, q_b: np.ndarray,
                 beta_a: np.ndarray, beta_b: np.ndarray, k_inv: np.ndarray, factors_t: np.ndarray,
                 diagonal: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(Cov (B, P), trace (B, P), computed (B,)) of the output pairs (ia[p], ib[p]) by the fused
    kernel, its O(n) inputs formed by :func:`gpfverify.gp.fused_kernels.prepare` (arguments as there,
    every GP array with its leading axis of G models, k_inv and factors_t (G, E_a, n_a, n_a) and
    ``diagonal`` as in :func:`gpfverify.gp.fused_kernels.centred_sums`), or None when numba is not
    installed. ``computed[b]`` is False for an input at which an exponent exceeds
    :data:`EXPM1_SAFE` (its row of Cov and trace is left unset; the caller's numpy path handles it):
    the bound d_ij ≤ max_i r_i + max_j c_j + max_i ‖z_i‖ · max_j ‖w_j‖ (Cauchy–Schwarz) clears an
    input before any exponent is formed; an input it does not clear has its largest exponent formed
    (:func:`gpfverify.gp.fused_kernels.largest_exponents`, the kernel's sums to rounding, far below
    the 9 units between EXPM1_SAFE and the compiled expm1's overflow). Both decide per input, so the
    same input always takes the same path whatever else is in the batch."""
    if not enabled:
        return None
    fused_kernels = _kernels()
    *prepared, bound = fused_kernels.prepare(x_a, x_b, mu, sigma, ell_a, ell_b, b_logdet_a, b_logdet_b,
                                             ia, ib, t_a, t_b, q_a, q_b, beta_a, beta_b)
    computed = bound <= EXPM1_SAFE
    if not computed.all():
        unsure = np.flatnonzero(~computed)
        z_a, row, z_b_t, col = prepared[:4]
        computed[unsure] = fused_kernels.largest_exponents(z_a, row, z_b_t, col, unsure) <= EXPM1_SAFE
    shape = (mu.shape[0], ia.size)
    cov, trace = np.empty(shape), np.empty(shape)
    if computed.all():
        fused_kernels.centred_sums(*prepared, k_inv, factors_t, diagonal, cov, trace)
    elif computed.any():
        keep = np.flatnonzero(computed)
        per_model = k_inv.shape[0] > 1
        part_cov, part_trace = np.empty((keep.size, ia.size)), np.empty((keep.size, ia.size))
        fused_kernels.centred_sums(*(a[keep] for a in prepared), k_inv[keep] if per_model else k_inv,
                                   factors_t[keep] if per_model else factors_t, diagonal, part_cov, part_trace)
        cov[keep], trace[keep] = part_cov, part_trace
    return cov, trace, computed
