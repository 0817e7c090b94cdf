"""The compiled loops of :mod:`gpfverify.gp.fused` (numba; imported on first use, so that importing
the package does not import numba). The formulas, and how the compiled expm1 relates to
:func:`gpfverify.gp.expm1.expm1_reference`, are stated there."""

from __future__ import annotations

import numba
import numba.extending
import numpy as np
from llvmlite import ir

from gpfverify import numba_target
from gpfverify.gp.expm1 import _SHIFTER_BITS, INV_LN2, LN2_HI, LN2_LO, LOWEST, SHIFTER, _expm1_reduced

numba_target.configure()

#: the unroll width of :func:`_dot`: four partial sums, combined at the end (a fixed order)
_LANES = 4

_jit = numba.njit(cache=True, nogil=True, boundscheck=False, error_model="numpy")
#: the same, allowing a multiply and an add to fuse into one FMA (one rounding instead of two; no
#: other reordering): the exponential's polynomial and the n² loop are FMA chains
_jit_fma = numba.njit(cache=True, nogil=True, boundscheck=False, error_model="numpy", fastmath={"contract"})
#: the reduced-argument polynomial of :mod:`gpfverify.gp.fused`, compiled
_expm1_reduced_compiled = _jit_fma(_expm1_reduced)

@numba.extending.intrinsic
def _float_bits(typingctx, value):
    """The IEEE bits of a float64 as an int64 (a register reinterpretation, which the loop
    vectoriser keeps in vector registers)."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))
    return numba.types.int64(numba.types.float64), codegen

@numba.extending.intrinsic
def _bits_float(typingctx, bits):
    """The float64 whose IEEE bits are the int64 ``bits``."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())
    return numba.types.float64(numba.types.int64), codegen

#: the address of BLAS ``dtrsv`` in scipy's BLAS (scipy.linalg.cython_blas): the routine
#: :func:`scipy.linalg.blas.dtrsv` calls, so that a compiled loop calling it gets that call's bits
TRSV = numba.extending.get_cython_function_address("scipy.linalg.cython_blas", "dtrsv")

@numba.extending.intrinsic
def _call_trsv(typingctx, address, uplo, trans, diag, n, a, lda, x, incx):
    """A call of the Fortran BLAS routine at ``address`` (an integer) with trsv's eight arguments,
    each the address of its value (integers too): the routine's address is an argument rather than a
    constant of the compiled code, so numba can cache the code across processes."""
    def codegen(context, builder, signature, args):
        pointer = ir.IntType(8).as_pointer()
        routine = builder.inttoptr(args[0], ir.FunctionType(ir.VoidType(), [pointer] * 8).as_pointer())
        builder.call(routine, [builder.inttoptr(arg, pointer) for arg in args[1:]])
        return context.get_dummy_value()
    return numba.types.void(address, uplo, trans, diag, n, a, lda, x, incx), codegen

@_jit_fma
def _expm1(value: float) -> float:
    """expm1(value) for value ≤ 700 by :func:`gpfverify.gp.expm1.expm1_reference`'s steps, a
    multiply and an add fused where the processor has FMA; a scalar function that loops calling it
    vectorise whole."""
    x = max(value, LOWEST)
    t = x * INV_LN2 + SHIFTER
    k = t - SHIFTER
    r = (x - k * LN2_HI) - k * LN2_LO
    p = _expm1_reduced_compiled(r)
    scale = _bits_float((_float_bits(t) - _SHIFTER_BITS + 1023) << 52)  # 2ᵏ
    return scale * p + (scale - 1.0)

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
def _shifted(scaled: np.ndarray, inv: np.ndarray, ratio: np.ndarray) -> float:
    """:func:`gpfverify.gp.moments._shifted` for one D × D matrix S: writes (S + I)⁻¹ into ``inv``
    and (S + I)⁻¹S into ``ratio`` (each symmetrised, from S = V diag(λ) Vᵀ with λ clipped at 0) and
    returns log|S + I| = Σ log1p(λ)."""
    eigval, eigvec = np.linalg.eigh(scaled)
    dim = eigval.size
    logdet = 0.0
    for k in range(dim):
        eigval[k] = max(eigval[k], 0.0)
        logdet += np.log1p(eigval[k])
    for k in range(dim):
        for m in range(dim):
            s_inv, s_ratio = 0.0, 0.0
            for r in range(dim):
                vv = eigvec[k, r] * eigvec[m, r]
                s_inv += vv / (1.0 + eigval[r])
                s_ratio += vv * (eigval[r] / (1.0 + eigval[r]))
            inv[k, m], ratio[k, m] = s_inv, s_ratio
    for k in range(dim):
        for m in range(k + 1, dim):
            inv[k, m] = inv[m, k] = 0.5 * (inv[k, m] + inv[m, k])
            ratio[k, m] = ratio[m, k] = 0.5 * (ratio[k, m] + ratio[m, k])
    return logdet

@_jit
def _projected(x_t: np.ndarray, centre: np.ndarray, scale: np.ndarray, a_mat: np.ndarray, scaled: np.ndarray,
               projected: np.ndarray, quadratic: np.ndarray) -> None:
    """For the points x_t (D, n), one per column: scaled[k, i] = (x_ki − centre_k)·scale_k,
    projected[k, i] = Σ_m scaled[m, i] A_mk and quadratic[i] = Σ_k projected[k, i] scaled[k, i]
    (each sum in index order from 0), the points innermost in every loop (vectorised)."""
    dim, n = x_t.shape
    for k in range(dim):
        shift, factor = centre[k], scale[k]
        for i in range(n):
            scaled[k, i] = (x_t[k, i] - shift) * factor
    projected[:] = 0.0
    for k in range(dim):
        for m in range(dim):
            coefficient = a_mat[m, k]
            for i in range(n):
                projected[k, i] += scaled[m, i] * coefficient
    quadratic[:] = 0.0
    for k in range(dim):
        for i in range(n):
            quadratic[i] += projected[k, i] * scaled[k, i]

@_jit
def _column_square(columns: np.ndarray, i: int) -> float:
    """‖columns[:, i]‖², the sum in index order from 0."""
    total = 0.0
    for k in range(columns.shape[0]):
        total += columns[k, i] * columns[k, i]
    return total

@_jit
def first_moments(x: np.ndarray, inv_ell: np.ndarray, log_signal_var: np.ndarray, beta: np.ndarray,
                  mu: np.ndarray, sigma: np.ndarray):
    """Eq. 8–9 and 20 for every output a of a GP at every input N(mu[b], sigma[b]), as
    :func:`gpfverify.gp.moments._first_moments` computes them: with B_a = Λ_a^{-½}ΣΛ_a^{-½} and
    s_i = Λ_a^{-½}ν_i, log q_ai = log α_a² − ½log|B_a + I| − ½ s_iᵀ(B_a + I)⁻¹s_i,
    t_ai = s_iᵀ(B_a + I)⁻¹B_a s_i, M_a = Σ_i β_ai q_ai and Cov[x, f_a] = ΣΛ_a^{-½}(B_a + I)⁻¹Λ_a^{-½}
    Σ_i β_ai q_ai ν_i.

    The GP's arrays carry a leading axis of G models: G = 1 (every input against one GP) or G = B
    (input b against GP b, a batch of Monte Carlo runs each with its own GP); what input b computes
    depends on its own input and GP alone. x (G, n, D), inv_ell (G, E, D) = 1/ℓ,
    log_signal_var (G, E), beta (G, E, n), mu (B, D), sigma (B, D, D); returns mean (B, E),
    cross_cov (B, D, E), log_q (B, E, n), t (B, E, n), b_logdet (B, E) and q = exp(log q) (B, E, n)."""
    batch, dim = mu.shape
    models, outputs, n = beta.shape
    mean, cross = np.zeros((batch, outputs)), np.zeros((batch, dim, outputs))
    log_q, t, b_logdet = np.empty((batch, outputs, n)), np.empty((batch, outputs, n)), np.empty((batch, outputs))
    q = np.empty((batch, outputs, n))
    scaled_sigma, b_inv, b_ratio = np.empty((dim, dim)), np.empty((dim, dim)), np.empty((dim, dim))
    weighted_nu, solved = np.empty(dim), np.empty(dim)
    x_all_t = np.ascontiguousarray(np.transpose(x, (0, 2, 1)))
    scaled, projected = np.empty((dim, n)), np.empty((dim, n))
    maha, quad = np.empty(n), np.empty(n)
    for b in range(batch):
        g = b if models > 1 else 0
        x_g, x_t = x[g], x_all_t[g]
        for a in range(outputs):
            for k in range(dim):
                for m in range(dim):
                    scaled_sigma[k, m] = sigma[b, k, m] * inv_ell[g, a, k] * inv_ell[g, a, m]
            logdet = _shifted(scaled_sigma, b_inv, b_ratio)
            b_logdet[b, a] = logdet
            weighted_nu[:] = 0.0
            total = 0.0
            _projected(x_t, mu[b], inv_ell[g, a], b_inv, scaled, projected, maha)  # s_iᵀ(B_a + I)⁻¹s_i
            _projected(x_t, mu[b], inv_ell[g, a], b_ratio, scaled, projected, quad)  # t_ai
            for i in range(n):
                value = log_signal_var[g, a] - 0.5 * logdet - 0.5 * maha[i]
                log_q[b, a, i], t[b, a, i] = value, quad[i]
                q[b, a, i] = np.exp(value)
                weight = beta[g, a, i] * q[b, a, i]
                total += weight
                for k in range(dim):
                    weighted_nu[k] += weight * (x_g[i, k] - mu[b, k])
            mean[b, a] = total
            for k in range(dim):
                acc = 0.0
                for m in range(dim):
                    acc += b_inv[k, m] * (inv_ell[g, a, m] * weighted_nu[m])
                solved[k] = inv_ell[g, a, k] * acc
            for k in range(dim):
                acc = 0.0
                for m in range(dim):
                    acc += sigma[b, k, m] * solved[m]
                cross[b, k, a] = acc
    return mean, cross, log_q, t, b_logdet, q

@_jit
def prepare(x_a: np.ndarray, x_b: np.ndarray, mu: np.ndarray, sigma: np.ndarray, ell_a: np.ndarray,
            ell_b: np.ndarray, b_logdet_a: np.ndarray, b_logdet_b: np.ndarray, ia: np.ndarray, ib: np.ndarray,
            t_a: np.ndarray, t_b: np.ndarray, first_q_a: np.ndarray, first_q_b: np.ndarray, beta_a: np.ndarray,
            beta_b: np.ndarray):
    """The inputs of :func:`centred_sums` for the output pairs (ia[p], ib[p]) at the inputs
    N(mu[b], sigma[b]) — the O(n) terms of :func:`gpfverify.gp.moments._centred_second_moments`:
    with Ξ = Λ_a⁻¹ + Λ_b⁻¹, S = Ξ^½ΣΞ^½, A = R⁻¹Σ = Ξ^{-½}(S + I)⁻¹SΞ^{-½} and
    const = ½(log|B_a + I| + log|B_b + I| − log|S + I|): z_a = Λ_a⁻¹ν_i A,
    row_i = −½t_ai + ½(Λ_a⁻¹ν_i)ᵀA(Λ_a⁻¹ν_i) + const, w_j = Λ_b⁻¹ν'_j, col_j = −½t_bj + ½w_jᵀAw_j,
    q_a, u = β_a ∘ q_a, v = β_b ∘ q_b — and, per input, the largest bound max_i row_i + max_j col_j +
    max_i ‖z_i‖ · max_j ‖w_j‖ (Cauchy–Schwarz) on any of its exponents.

    The GPs' arrays carry a leading axis of G models (1, or B: input b against GP b; see
    :func:`first_moments`): x_a (G, n_a, D), x_b (G, n_b, D), ell_a (G, E_a, D), ell_b (G, E_b, D) the
    lengthscales, beta_a (G, E_a, n_a), beta_b (G, E_b, n_b); mu (B, D), sigma (B, D, D),
    b_logdet_a (B, E_a), b_logdet_b (B, E_b), t_a/first_q_a (B, E_a, n_a), t_b/first_q_b (B, E_b, n_b)
    (the first moments' t and q). The bound is returned per input (B,)."""
    inv_l2_a, inv_l2_b = 1.0 / ell_a ** 2, 1.0 / ell_b ** 2  # Λ⁻¹ diagonals, (G, E, D)
    batch, dim = mu.shape
    models = x_a.shape[0]
    pairs = ia.size
    n_a, n_b = x_a.shape[1], x_b.shape[1]
    a_mat, const = np.empty((batch, pairs, dim, dim)), np.empty((batch, pairs))
    xi_half, scaled_sigma = np.empty(dim), np.empty((dim, dim))
    s_inv, s_ratio = np.empty((dim, dim)), np.empty((dim, dim))
    for b in range(batch):
        g = b if models > 1 else 0
        for p in range(pairs):
            for k in range(dim):
                xi_half[k] = np.sqrt(inv_l2_a[g, ia[p], k] + inv_l2_b[g, ib[p], k])
            for k in range(dim):
                for m in range(dim):
                    scaled_sigma[k, m] = sigma[b, k, m] * (xi_half[k] * xi_half[m])
            r_logdet = _shifted(scaled_sigma, s_inv, s_ratio)
            for k in range(dim):
                for m in range(dim):
                    a_mat[b, p, k, m] = s_ratio[k, m] / (xi_half[k] * xi_half[m])
            const[b, p] = 0.5 * (b_logdet_a[b, ia[p]] + b_logdet_b[b, ib[p]] - r_logdet)
    x_a_all_t = np.ascontiguousarray(np.transpose(x_a, (0, 2, 1)))
    x_b_all_t = np.ascontiguousarray(np.transpose(x_b, (0, 2, 1)))
    z_a = np.empty((batch, pairs, dim, n_a))
    z_b_t = np.empty((batch, pairs, dim, n_b))
    row, u, q_a = np.empty((batch, pairs, n_a)), np.empty((batch, pairs, n_a)), np.empty((batch, pairs, n_a))
    col, v = np.empty((batch, pairs, n_b)), np.empty((batch, pairs, n_b))
    scaled_a, quadratic_a = np.empty((dim, n_a)), np.empty(n_a)
    projected_b, quadratic_b = np.empty((dim, n_b)), np.empty(n_b)
    bound = np.full(batch, -np.inf)
    for b in range(batch):
        g = b if models > 1 else 0
        for p in range(pairs):
            a, e = ia[p], ib[p]
            _projected(x_a_all_t[g], mu[b], inv_l2_a[g, a], a_mat[b, p], scaled_a, z_a[b, p], quadratic_a)
            top_row, top_z = -np.inf, 0.0
            for i in range(n_a):
                row[b, p, i] = -0.5 * t_a[b, a, i] + 0.5 * quadratic_a[i] + const[b, p]
                q = first_q_a[b, a, i]
                q_a[b, p, i] = q
                u[b, p, i] = beta_a[g, a, i] * q
                top_row, top_z = max(top_row, row[b, p, i]), max(top_z, _column_square(z_a[b, p], i))
            _projected(x_b_all_t[g], mu[b], inv_l2_b[g, e], a_mat[b, p], z_b_t[b, p], projected_b, quadratic_b)
            top_col, top_w = -np.inf, 0.0
            for j in range(n_b):
                col[b, p, j] = -0.5 * t_b[b, e, j] + 0.5 * quadratic_b[j]
                v[b, p, j] = beta_b[g, e, j] * first_q_b[b, e, j]
                top_col, top_w = max(top_col, col[b, p, j]), max(top_w, _column_square(z_b_t[b, p], j))
            bound[b] = max(bound[b], top_row + top_col + np.sqrt(top_z * top_w))
    return z_a, row, z_b_t, col, u, v, q_a, bound

@_jit
def largest_exponents(z_a: np.ndarray, row: np.ndarray, z_b_t: np.ndarray, col: np.ndarray,
                      inputs: np.ndarray) -> np.ndarray:
    """max_{p,i,j} d_ij of each input b in ``inputs``: the exponents d_ij = r_i + c_j + Σ_k z_ik w_jk
    that :func:`centred_sums` forms, from :func:`prepare`'s z_a, row, z_b_t and col (shapes as
    there), each by the same sum to rounding (n_a n_b D multiply–adds per pair: a pass without the
    exponentials, for the inputs whose Cauchy–Schwarz bound is above the limit)."""
    pairs, dim, n_a = z_a.shape[1:]
    n_b = z_b_t.shape[3]
    largest = np.full(inputs.size, -np.inf)
    d = np.empty(n_b)
    for index in range(inputs.size):
        b = inputs[index]
        top = -np.inf
        for p in range(pairs):
            for i in range(n_a):
                r_i = row[b, p, i]
                for j in range(n_b):
                    d[j] = col[b, p, j] + r_i
                for k in range(dim):
                    z = z_a[b, p, k, i]
                    w = z_b_t[b, p, k]
                    for j in range(n_b):
                        d[j] += z * w[j]
                for j in range(n_b):
                    top = max(top, d[j])
        largest[index] = top
    return largest

@_jit
def whitened(trsv: int, factors_t: np.ndarray, vectors: np.ndarray, out: np.ndarray) -> None:
    """out[g, a] = L_ga⁻¹ vectors[g, a] for model g's output a: factors_t (G, E, n, n) the transposed
    Cholesky factors L_gaᵀ (C-ordered: each L_ga in the Fortran order BLAS reads), vectors and out
    (G, E, n), all C-contiguous; one call of BLAS dtrsv (at address ``trsv``, :data:`TRSV`) per model
    and output, as :func:`gpfverify.linalg.lower_solve` makes it for one vector."""
    models, outputs, n = vectors.shape
    flags = np.array([ord("L"), ord("N")], dtype=np.uint8)  # lower, no transpose (and a non-unit diagonal)
    sizes = np.array([n, 1], dtype=np.int32)  # n (also the leading dimension), the increment
    for g in range(models):
        for a in range(outputs):
            out[g, a] = vectors[g, a]
            # the flags' and sizes' addresses taken in the loop: the arrays stay alive through it
            lower, plain, size = flags.ctypes.data, flags.ctypes.data + 1, sizes.ctypes.data
            _call_trsv(trsv, lower, plain, plain, size, factors_t[g, a].ctypes.data, size, out[g, a].ctypes.data,
                       size + 4)

@_jit_fma
def centred_sums(z_a: np.ndarray, row: np.ndarray, z_b_t: np.ndarray, col: np.ndarray, u: np.ndarray,
                 v: np.ndarray, q_a: np.ndarray, k_inv: np.ndarray, factors_t: np.ndarray, diagonal: np.ndarray,
                 cov: np.ndarray, trace: np.ndarray) -> None:
    """Both sums of the module docstring for a batch of inputs b and output pairs p:
    z_a (B, P, D, n_a), row (B, P, n_a), z_b_t (B, P, D, n_b), col (B, P, n_b), u (B, P, n_a),
    v (B, P, n_b), q_a (B, P, n_a); k_inv (G, E, n_a, n_a), factors_t (G, E, n_a, n_a) the transposed
    Cholesky factors L_aᵀ of K_a (G models, as in :func:`first_moments`: 1, or B with input b
    against model b), and diagonal (P,) the output a of a diagonal pair (−1 otherwise). Writes
    cov (B, P) and, for the diagonal pairs, trace (B, P) = tr(K_a⁻¹Q^{aa}) = ‖L_a⁻¹q_a‖²
    + tr(K_a⁻¹(Q^{aa} − q_a q_aᵀ)) (zero off the diagonal pairs).
    Every exponent must be at most :data:`EXPM1_SAFE` (see :func:`gpfverify.gp.fused.centred_sums`).

    The sums run column-wise: acc_j = Σ_i u_i E_ij over the rows, then Cov = Σ_j acc_j v_j (and
    tr = Σ_j q_j Σ_i q_i E_ij (K_a⁻¹)_ij), so the pass that forms E_ij also accumulates it, with no
    reduction inside a row. A diagonal pair is the pair (a, a) of one GP: its exponents are
    symmetric (d_ij = d_ji), as are u = v and K_a⁻¹, so only j ≥ i is formed and the terms off the
    main diagonal count twice. The same pass whitens q_a: forward substitution by columns
    (x ← q_a; at row i, x_i ← x_i / L_ii, then x_j ← x_j − x_i L_ji for j > i, L_ji = (L_aᵀ)_ij a
    contiguous row), its rows interleaved with the exponentials' rows: one pass over the factor per
    input and output, with no call of its own."""
    batch, pairs, dim, n_a = z_a.shape
    n_b = z_b_t.shape[3]
    models = k_inv.shape[0]
    d = np.empty(n_b)
    acc, acc_trace, white = np.empty(n_b), np.empty(n_b), np.empty(n_a)
    last = dim - 1
    for b in range(batch):
        g = b if models > 1 else 0
        model_k_inv, model_factors_t = k_inv[g], factors_t[g]
        for p in range(pairs):
            a = diagonal[p]
            acc[:] = 0.0
            acc_trace[:] = 0.0
            white[:] = q_a[b, p]
            white_sq = 0.0
            for i in range(n_a):
                start = i if a >= 0 else 0  # a diagonal pair: the upper triangle j ≥ i
                width = n_b - start
                row_d = d[:width]
                r_i = row[b, p, i]
                # row_d ← d_ij − z_i,last w_j,last = r_i + c_j + Σ_{k<last} z_ik w_jk
                if last == 0:
                    for j in range(width):
                        row_d[j] = col[b, p, start + j] + r_i
                else:
                    z = z_a[b, p, 0, i]
                    for j in range(width):
                        row_d[j] = (col[b, p, start + j] + r_i) + z * z_b_t[b, p, 0, start + j]
                    for k in range(1, last):
                        z = z_a[b, p, k, i]
                        for j in range(width):
                            row_d[j] += z * z_b_t[b, p, k, start + j]
                z = z_a[b, p, last, i]
                w_last = z_b_t[b, p, last]
                if a < 0:  # acc_j += u_i E_ij
                    weight = u[b, p, i]
                    for j in range(width):
                        acc[j] += weight * _expm1(row_d[j] + z * w_last[j])
                    continue
                # a diagonal pair: E_ii once, E_ij (j > i) twice; row i of the whitening
                x_i = white[i] / model_factors_t[a, i, i]
                white_sq += x_i * x_i
                rest, factor_column = white[i + 1:], model_factors_t[a, i, i + 1:]
                for j in range(rest.size):
                    rest[j] -= x_i * factor_column[j]
                e = _expm1(row_d[0] + z * w_last[i])
                acc[i] += u[b, p, i] * e
                acc_trace[i] += q_a[b, p, i] * (e * model_k_inv[a, i, i])
                weight, weight_trace = 2.0 * u[b, p, i], 2.0 * q_a[b, p, i]
                for j in range(1, width):
                    e = _expm1(row_d[j] + z * w_last[i + j])
                    acc[i + j] += weight * e
                    acc_trace[i + j] += weight_trace * (e * model_k_inv[a, i, i + j])
            cov[b, p] = _dot(acc, v[b, p])
            trace[b, p] = white_sq + _dot(acc_trace, q_a[b, p]) if a >= 0 else 0.0

@_jit_fma
def expm1_compiled(x: np.ndarray) -> np.ndarray:
    """The compiled expm1 of a 1-D array (x ≤ 700), for testing the kernel's arithmetic."""
    out = np.empty_like(x)
    for j in range(x.size):
        out[j] = _expm1(x[j])
    return out
