"""The compiled loops of :mod:`gpfverify.gp.fused` (numba; imported on first use, so that importing
the package does not import numba). The formulas and the bit-for-bit contract with
:func:`gpfverify.gp.fused.expm1_reference` are stated there."""

from __future__ import annotations

import numba
import numpy as np

from gpfverify.gp.fused import (_SHIFTER_BITS, INV_LN2, LN2_HI, LN2_LO, LOWEST, SHIFTER,
                                _expm1_reduced)

#: the row loops' unroll width: four partial sums per reduction, combined at the end of each row
_LANES = 4

_jit = numba.njit(cache=True, nogil=True, boundscheck=False, error_model="numpy")
#: the reduced-argument polynomial of :mod:`gpfverify.gp.fused`, compiled
_expm1_reduced_compiled = _jit(_expm1_reduced)

@_jit
def _expm1_row(d: np.ndarray, scale_bits: np.ndarray, scale: np.ndarray) -> None:
    """d ← expm1(d) in place (d ≤ 700); ``scale_bits``/``scale`` are one buffer's int64 and
    float64 views, as long as d."""
    n = d.size
    for j in range(n):
        x = max(d[j], LOWEST)
        t = x * INV_LN2 + SHIFTER
        k = t - SHIFTER
        r = (x - k * LN2_HI) - k * LN2_LO
        d[j] = _expm1_reduced_compiled(r)
        scale[j] = t
    for j in range(n):
        scale_bits[j] = (scale_bits[j] - _SHIFTER_BITS + 1023) << 52
    for j in range(n):
        s = scale[j]
        d[j] = s * d[j] + (s - 1.0)

@_jit
def _dot(x: np.ndarray, y: np.ndarray) -> float:
    """Σ_j x_j y_j with :data:`_LANES` partial sums (a fixed order: the same bits every call)."""
    n = x.size
    s0 = s1 = s2 = s3 = 0.0
    end = n - n % _LANES
    for j in range(0, end, _LANES):
        s0 += x[j] * y[j]
        s1 += x[j + 1] * y[j + 1]
        s2 += x[j + 2] * y[j + 2]
        s3 += x[j + 3] * y[j + 3]
    for j in range(end, n):
        s0 += x[j] * y[j]
    return (s0 + s1) + (s2 + s3)

@_jit
def centred_sums(z_a: np.ndarray, row: np.ndarray, z_b_t: np.ndarray, col: np.ndarray, u: np.ndarray,
                 v: np.ndarray, q_a: np.ndarray, k_inv: np.ndarray, diagonal: np.ndarray,
                 cov: np.ndarray, trace: np.ndarray) -> None:
    """Both sums of the module docstring for a batch of inputs b and output pairs p:
    z_a (B, P, n_a, D), row (B, P, n_a), z_b_t (B, P, D, n_b), col (B, P, n_b), u (B, P, n_a),
    v (B, P, n_b), q_a (B, P, n_a); k_inv (E, n_a, n_a) and diagonal (P,) the output a of a
    diagonal pair (−1 otherwise). Writes cov (B, P) and trace (B, P) (zero off the diagonal
    pairs). Every exponent must be at most :data:`EXPM1_SAFE` (see :func:`gpfverify.gp.fused.centred_sums`).

    A diagonal pair is the pair (a, a) of one GP: its exponents are symmetric (d_ij = d_ji), as are
    u = v and K_a⁻¹, so only j ≥ i is formed and the terms off the main diagonal count twice."""
    batch, pairs, n_a, dim = z_a.shape
    n_b = z_b_t.shape[3]
    d = np.empty(n_b)
    scale = np.empty(n_b)
    scale_bits = scale.view(np.int64)
    weighted = np.empty(n_b)
    for b in range(batch):
        for p in range(pairs):
            a = diagonal[p]
            total = 0.0
            total_trace = 0.0
            for i in range(n_a):
                start = i if a >= 0 else 0  # a diagonal pair: the upper triangle j ≥ i
                width = n_b - start
                row_d = d[:width]
                r_i = row[b, p, i]
                for j in range(width):
                    row_d[j] = col[b, p, start + j] + r_i
                for k in range(dim):
                    z = z_a[b, p, i, k]
                    for j in range(width):
                        row_d[j] += z * z_b_t[b, p, k, start + j]
                _expm1_row(row_d, scale_bits[:width], scale[:width])
                if a < 0:
                    total += u[b, p, i] * _dot(row_d, v[b, p])
                    continue
                total += u[b, p, i] * (row_d[0] * v[b, p, i] + 2.0 * _dot(row_d[1:], v[b, p, i + 1:]))
                for j in range(width):
                    weighted[j] = k_inv[a, i, start + j] * q_a[b, p, start + j]
                total_trace += q_a[b, p, i] * (row_d[0] * weighted[0] + 2.0 * _dot(row_d[1:], weighted[1:width]))
            cov[b, p] = total
            trace[b, p] = total_trace

@_jit
def expm1_compiled(x: np.ndarray) -> np.ndarray:
    """The compiled expm1 of a 1-D array (x ≤ 700), for testing the kernel's arithmetic."""
    out = x.copy()
    scale = np.empty(x.size)
    _expm1_row(out, scale.view(np.int64), scale)
    return out


