"""Stable linear algebra shared by every module: symmetrisation, Cholesky with reported jitter,
solves instead of inverses, numerical rank. Ground floor: imports only errors and tolerances."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from gpfverify.errors import NumericalError
from gpfverify.tolerances import JITTER_STEPS, numpy_rank_tol

_ddot = sla.blas.ddot
_dgejsv = sla.lapack.dgejsv


def symmetrize(a: np.ndarray) -> np.ndarray:
    """(A + Aᵀ)/2 over the last two axes (a new array; exactly symmetric)."""
    a = np.asarray(a)
    return 0.5 * (a + a.swapaxes(-1, -2))


def matmul_for(a: np.ndarray) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """The matrix product for operands stacked like ``a``: ``ndarray.dot`` when ``a`` is one
    matrix or vector (the left operand must then be an ndarray), ``np.matmul`` for a stack. For
    single matrices they make the same BLAS call (the same bits), but ``@`` first sets up a
    generalized-ufunc iterator, and ``np.dot`` a Python-level dispatch, each costing more than the
    product of the small matrices of a filter step."""
    return np.ndarray.dot if a.ndim <= 2 else np.matmul


def rows_times(x: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """x @ matrix for vectors x (..., n) and one matrix (n, m): one vector–matrix product per row
    of a stack (a stacked product, one BLAS call each), so that each row's result is the same
    whatever else is in the stack. A 2-D product (rows, n) @ (n, m) lets BLAS pick its kernel by the
    number of rows, and a row's last bits then depend on how many others came with it (measured:
    a row of 5, 8, 16, 33 or 64 entries differed between stacks of 1, 3 and 64)."""
    if x.ndim == 1:
        return x.dot(matrix)
    return np.matmul(x[..., None, :], matrix)[..., 0, :]


def all_finite(*arrays: np.ndarray) -> bool:
    """Whether every entry of every (real) array is finite.

    One sum of squares per array (BLAS ``ddot`` over its memory, in whatever order it is laid out)
    decides the common case: a NaN or ±inf entry makes it NaN or +inf, so a finite total proves
    every entry finite. Only a non-finite total (a non-finite entry, or finite entries whose
    squares overflow, |a| ≳ 1e154) is checked entry by entry, so the answer is exact either way.
    scipy's ``ddot``, not ``ndarray.dot``: it is cheaper and raises no overflow warning."""
    total = 0.0
    for a in arrays:
        flat = a.ravel("K")  # a view of any contiguous array, C or Fortran order
        if flat.size:
            total += _ddot(flat, flat)
    return math.isfinite(total) or all(bool(np.isfinite(a).all()) for a in arrays)


def _fortran_view(factor: np.ndarray) -> tuple[np.ndarray, bool]:
    """A Fortran-ordered view of a lower-triangular factor that BLAS/LAPACK read without copying it,
    and whether it is L (as ``potrf`` returns it) rather than Lᵀ (the transpose of a C-ordered L, an
    upper factor)."""
    if factor.flags.f_contiguous:
        return factor, True
    return factor.T, False


def lower_solve(factor: np.ndarray, b: np.ndarray, transpose: bool = False) -> np.ndarray:
    """L⁻¹ b (``transpose``: L⁻ᵀ b) for one lower-triangular ``factor`` L and b (n,) or (n, m), by
    BLAS trsv / trsm on the factor's Fortran-ordered view (a C-ordered L is solved as its upper
    transpose). Not scipy's ``solve_triangular``: it calls LAPACK's ``trtrs``, which OpenBLAS runs
    on all its threads whatever the size — on a loaded machine a 4 × 4 solve with two right-hand
    sides waited about 30 ms for a second thread. A single column (n, 1) goes to trsv as well:
    OpenBLAS's trsm takes 2.5 times as long for it (54 against 21 µs at n = 300), and the GP-UKF
    asks for one column at every prediction (the GP variance at the mean)."""
    view, lower = _fortran_view(factor)
    trans = int(transpose == lower)  # a view holding Lᵀ solves L x = b as its transposed system
    if np.ndim(b) == 1:
        return sla.blas.dtrsv(view, b, lower=int(lower), trans=trans)
    if np.shape(b)[1] == 1:
        return sla.blas.dtrsv(view, b[:, 0], lower=int(lower), trans=trans)[:, None]
    return sla.blas.dtrsm(1.0, view, b, lower=int(lower), trans_a=trans)


@dataclass(frozen=True)
class Cholesky:
    """Lower Cholesky factor of ``A + jitter * I``; ``jitter`` is 0 unless one was needed."""

    factor: np.ndarray
    jitter: float

    def solve(self, b: np.ndarray) -> np.ndarray:
        """(A + jitter I)⁻¹ b by two triangular solves (LAPACK ``potrs`` called directly: the same
        bits as scipy's ``cho_solve``, a tenth of its overhead at filter sizes)."""
        if self.factor.shape[0] == 0:  # an empty system (potrs refuses it)
            return np.zeros(np.shape(b))
        x, info = sla.lapack.dpotrs(self.factor, b, lower=1)
        if info != 0:
            raise NumericalError(f"solve with a Cholesky factor failed (potrs info={info})")
        return x

    def whiten(self, b: np.ndarray) -> np.ndarray:
        """L⁻¹ b for b (n,) or (n, m) (:func:`lower_solve`)."""
        return lower_solve(self.factor, b)

    def logdet(self) -> float:
        return 2.0 * float(np.sum(np.log(np.diag(self.factor))))

    def inverse(self) -> np.ndarray:
        """Explicit inverse from the factor (LAPACK potri), for caching outside a hot path
        (e.g. a GP's training matrix) or where the whole inverse is needed (evidence gradients)."""
        view, lower = _fortran_view(self.factor)
        inv, info = sla.lapack.dpotri(view, lower=lower)
        if info != 0:
            raise NumericalError(f"inverse from Cholesky factor failed (potri info={info})")
        filled = inv if lower else inv.T  # its lower triangle holds the inverse
        return np.tril(filled) + np.tril(filled, -1).T


def cholesky(a: np.ndarray, name: str = "matrix", allow_jitter: bool = True) -> Cholesky:
    """Cholesky factor of a symmetric matrix, adding the smallest jitter from
    :data:`~gpfverify.tolerances.JITTER_STEPS` (relative to the mean diagonal) that makes it work.

    Raises :class:`NumericalError` naming ``name`` when none does.
    """
    a = symmetrize(np.asarray(a, dtype=float))
    n = a.shape[0]
    scale = 0.0  # the mean |diagonal|, computed only when a jitter is tried (most factorisations need none)
    steps = JITTER_STEPS if allow_jitter else (0.0,)
    for rel in steps:
        if rel and not scale:
            scale = float(np.mean(np.abs(np.diag(a)))) if n else 1.0
            scale = scale if scale > 0 else 1.0
        jitter = rel * scale
        # LAPACK potrf directly: numpy's cholesky gives the same factor (to rounding: the two may link
        # different LAPACK builds) at four times the overhead
        factor, info = sla.lapack.dpotrf(a + jitter * np.eye(n) if jitter else a, lower=1, clean=1)
        if info == 0 and all_finite(factor):
            return Cholesky(factor, jitter)
    raise NumericalError(f"{name} is not positive definite (Cholesky failed even with jitter "
                         f"{steps[-1]:g} x mean diagonal)")


def cholesky_batched(a: np.ndarray, name: str) -> np.ndarray:
    """Lower Cholesky factors of a stack of symmetric matrices (..., n, n), without jitter.

    Raises :class:`NumericalError` naming ``name`` (and the first failing batch index and its
    smallest eigenvalue) when a matrix is not finite or not positive definite. A single matrix
    goes to LAPACK ``potrf`` directly (numpy's wrapper costs more than the factorisation at the
    sizes of a filter step).
    """
    if not all_finite(a):
        raise NumericalError(f"{name} contains NaN or inf")
    return cholesky_symmetric(symmetrize(a), name)


def cholesky_symmetric(sym: np.ndarray, name: str) -> np.ndarray:
    """:func:`cholesky_batched` of matrices the caller has already symmetrised (LAPACK reads only
    the lower triangle), without the finiteness check in front: a NaN or ±inf entry either fails
    the factorisation (then the error says so) or comes out in the factor, which the caller checks
    instead (the factor of a finite matrix is finite, |L_ij| ≤ √A_ii)."""
    if sym.ndim == 2:
        factor, info = sla.lapack.dpotrf(sym, lower=1, clean=1)
        if info == 0:
            return factor
    else:
        try:
            return np.linalg.cholesky(sym)
        except np.linalg.LinAlgError:
            pass
    if not all_finite(sym):
        raise NumericalError(f"{name} contains NaN or inf")
    flat = sym.reshape((-1,) + sym.shape[-2:])
    lowest = np.linalg.eigvalsh(flat)[:, 0]
    first = int(np.argmin(lowest))
    index = tuple(int(i) for i in np.unravel_index(first, sym.shape[:-2]))
    where = f" at batch index {index}" if sym.ndim > 2 else ""
    raise NumericalError(f"{name} is not positive definite{where} (min eigenvalue {lowest[first]:.3g})")


def inverse_lower_factors(spd: np.ndarray, name: str) -> np.ndarray:
    """L⁻¹ of the lower Cholesky factor L of every matrix of a stack (..., n, n) (symmetrised first;
    no jitter): LAPACK ``potrf`` then ``trtri`` on each matrix, n³/3 + n³/3 flops, where a dense
    solve of L against the identity (LU with pivoting of a triangular matrix, then n right-hand
    sides) costs about 8n³/3. A loop over the stack's matrices (a batch's fusions, not a matrix's
    components): each matrix's result is the same bits whatever else is in the stack.

    Raises :class:`NumericalError` naming ``name`` as :func:`cholesky_batched` does when a matrix
    is not finite or not positive definite."""
    if not all_finite(spd):
        raise NumericalError(f"{name} contains NaN or inf")
    sym = symmetrize(spd)
    flat = sym.reshape((-1,) + sym.shape[-2:])
    out = np.empty_like(flat)
    for i, matrix in enumerate(flat):
        factor, info = sla.lapack.dpotrf(matrix, lower=1, clean=1)
        if info == 0:
            inverse, info = sla.lapack.dtrtri(factor, lower=1)
        if info != 0:
            cholesky_symmetric(sym, name)  # raises, saying which matrix and its smallest eigenvalue
            raise NumericalError(f"{name} is not positive definite")
        out[i] = inverse
    return out.reshape(sym.shape)


def sampling_factor(cov: np.ndarray) -> np.ndarray:
    """A factor L with L Lᵀ = cov (to rounding) of a positive semidefinite covariance, for drawing
    x = L z, z ~ N(0, I): numpy's lower Cholesky factor when cov is positive definite (the draws of
    ``rng.multivariate_normal(..., method="cholesky")``), else V diag(√max(λ, 0)) from cov = V Λ Vᵀ
    (a singular covariance, e.g. noise that drives some states only, has no Cholesky factor)."""
    try:
        return np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        lam, vec = np.linalg.eigh(symmetrize(cov))
        return vec * np.sqrt(np.clip(lam, 0.0, None))


def solve_lower(factor: np.ndarray, b: np.ndarray) -> np.ndarray:
    """L⁻¹ b for lower-triangular factors L (..., n, n) and right-hand sides b (..., n, m) with the
    same batch axes, by LU with partial pivoting (LAPACK ``gesv``): numpy's dense solve for a
    stack, and for a single factor the same ``gesv`` called directly (numpy's wrapper costs more
    than the solve at the sizes of a filter step; the numbers are the same bits). Not scipy's
    ``trtrs``/``solve_triangular``: with threaded BLAS on a busy machine its triangular solve of a
    few columns wakes BLAS threads, and its mean time was orders of magnitude above numpy's solve
    for a 2 × 5 right-hand side."""
    if factor.ndim == 2:
        _, _, x, info = sla.lapack.dgesv(factor, b)
        if info == 0:
            return x
    return np.linalg.solve(factor, b)


def solve_spd(a: np.ndarray, b: np.ndarray, name: str = "matrix") -> np.ndarray:
    """a⁻¹ b for symmetric positive definite ``a`` (no jitter: a failure is an error)."""
    return cholesky(a, name, allow_jitter=False).solve(b)


def right_solve_spd(b: np.ndarray, a: np.ndarray, name: str = "matrix") -> np.ndarray:
    """b a⁻¹ for symmetric positive definite ``a``, as (a⁻¹ bᵀ)ᵀ."""
    return solve_spd(a, np.asarray(b).T, name).T


@dataclass(frozen=True)
class RankReport:
    """Numerical rank of a matrix with the evidence behind it."""

    rank: int
    singular_values: np.ndarray
    tol: float
    shape: tuple[int, int]

    @property
    def full_column_rank(self) -> bool:
        return self.rank == self.shape[1]

    @property
    def condition_number(self) -> float:
        s = self.singular_values
        if s.size == 0 or s[-1] == 0.0:
            return float("inf")
        return float(s[0] / s[-1])


def numerical_rank(a: np.ndarray, tol: float | None = None) -> RankReport:
    """Rank = number of singular values > ``tol``; default tol is numpy's ``matrix_rank`` rule
    ``S.max() * max(M, N) * eps``."""
    a = np.asarray(a, dtype=float)
    s = np.linalg.svd(a, compute_uv=False) if a.size else np.zeros(0)
    used = numpy_rank_tol(s, a.shape) if tol is None else float(tol)
    return RankReport(int(np.sum(s > used)), s, used, (a.shape[0], a.shape[1]))


def graded_svd(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The full SVD ``a = U diag(s) Vᵀ`` (U (m, m), s (min(m, n),) decreasing, Vᵀ (n, n)) by LAPACK's
    preconditioned one-sided Jacobi SVD ``dgejsv`` with row and column pivoting (Drmač and Veselić,
    SIAM J. Matrix Anal. Appl. 29, 2008), which computes it to high relative accuracy for a matrix
    graded on both sides, a = D₁ B D₂ with D₁, D₂ diagonal and B well conditioned — the form a
    covariance between variables in different units takes. numpy's SVD (LAPACK ``dgesdd``) is
    accurate only relative to σ_1: the singular directions of σ_i carry errors of about
    eps · σ_1/σ_i, and with components in metres and micrometres σ_1/σ_i grows as the square of the
    units' ratio. A wide matrix is transposed first (``dgejsv`` needs m ≥ n).

    The row pivoting (Björck's: rows ordered by non-increasing ∞-norm, what ``dgejsv`` does with
    JOBA = 'F') is applied here and ``dgejsv`` called with JOBA = 'C' on the sorted rows, which is
    the same factorisation: ``dgejsv`` applies its own row pivoting with LAPACK's
    ``dlaswp``, which OpenBLAS runs on all its threads whatever the size (on a loaded machine each
    call waited about 28 ms for a second thread)."""
    a = np.asarray(a, dtype=float)
    rows, cols = a.shape
    if not a.size or not np.any(a):
        return np.eye(rows), np.zeros(min(rows, cols)), np.eye(cols)
    tall = a if rows >= cols else a.T
    m, n = tall.shape
    order = np.argsort(-np.max(np.abs(tall), axis=1), kind="stable")
    # a workspace well above LAPACK's minimum: at the minimum dgejsv takes a path a thousand times slower
    sva, u_sorted, v, work, _, info = _dgejsv(tall[order], joba=0, jobu=1, jobv=0, jobr=0, jobt=0, jobp=0,
                                              lwork=2 * (m + n) ** 2 + 64)
    if info != 0:
        raise NumericalError(f"the Jacobi SVD (LAPACK dgejsv) failed with info = {info}")
    s = sva * (work[0] / work[1])  # dgejsv returns the singular values scaled to avoid overflow
    u = np.empty_like(u_sorted)
    u[order] = u_sorted            # the rows of U in a's order
    return (u, s, v.T) if rows >= cols else (v, s, u.T)


def equilibrated_cholesky(a: np.ndarray, name: str = "matrix") -> tuple[np.ndarray, np.ndarray]:
    """``(d, L)`` with ``a ≈ diag(d) L Lᵀ diag(d)``: ``d`` the square roots of the diagonal (1 where
    it is zero) and ``L`` the lower Cholesky factor of the correlation matrix ``a / (d dᵀ)``
    (jitter as :func:`cholesky`, now relative to a unit diagonal). Rescaling a coordinate of
    ``a`` rescales its ``d`` entry and leaves ``L`` unchanged up to rounding, so whitening by
    ``diag(d) L`` does not depend on units."""
    a = symmetrize(np.asarray(a, dtype=float))
    diag = np.diag(a).copy()
    d = np.sqrt(np.where(diag > 0, diag, 1.0))
    return d, cholesky(a / np.outer(d, d), name).factor


@dataclass(frozen=True)
class CanonicalCorrelations:
    """The SVD K = U diag(ρ) Vᵀ of the whitened cross covariance K = L_x⁻¹ C_xy L_y⁻ᵀ, where
    C_x = L_x L_xᵀ and C_y = L_y L_yᵀ with L = diag(d) L_c (:func:`equilibrated_cholesky`).

    ``correlations`` ρ (min(n, l),) decreasing; ``u`` (n, n) and ``v`` (l, l) orthogonal (full
    SVD); ``scale_x``/``factor_x`` and ``scale_y``/``factor_y`` the (d, L_c) pairs of C_x and C_y.
    When C_x and C_y are the marginal covariances of a joint Gaussian whose cross covariance is
    C_xy, ρ are its canonical correlations, in [0, 1]. They are invariant under any invertible
    linear change of coordinates of x and of y."""

    correlations: np.ndarray
    u: np.ndarray
    v: np.ndarray
    scale_x: np.ndarray
    factor_x: np.ndarray
    scale_y: np.ndarray
    factor_y: np.ndarray

    def whiten_x(self, a: np.ndarray) -> np.ndarray:
        """L_x⁻¹ a (a solve, no inverse)."""
        return lower_solve(self.factor_x, a / self.scale_x.reshape((-1,) + (1,) * (a.ndim - 1)))

    def x_dual(self, a: np.ndarray) -> np.ndarray:
        """L_x⁻ᵀ a."""
        out = lower_solve(self.factor_x, a, transpose=True)
        return out / self.scale_x.reshape((-1,) + (1,) * (out.ndim - 1))

    def y_from_whitened(self, b: np.ndarray) -> np.ndarray:
        """L_y⁻ᵀ b: whitened y-coordinates back to the dual (C_y⁻¹-scaled) space of w."""
        out = lower_solve(self.factor_y, b, transpose=True)
        return out / self.scale_y.reshape((-1,) + (1,) * (out.ndim - 1))

    def y_factor_times(self, b: np.ndarray) -> np.ndarray:
        """L_y b."""
        return self.scale_y.reshape((-1,) + (1,) * (b.ndim - 1)) * (self.factor_y @ b)

    def times_y_factor(self, g: np.ndarray) -> np.ndarray:
        """g L_y (g with l columns)."""
        return (g * self.scale_y) @ self.factor_y

    @property
    def whitening_condition(self) -> float:
        """cond(L_x,c) · cond(L_y,c): how much the two equilibrated whitenings can amplify rounding."""
        def cond(f):
            return float(np.linalg.cond(f)) if f.size else 1.0
        return cond(self.factor_x) * cond(self.factor_y)


def canonical_correlations(cov_x: np.ndarray, cov_y: np.ndarray, cross: np.ndarray,
                           names: tuple[str, str] = ("C_x", "C_y")) -> CanonicalCorrelations:
    """Canonical correlations of x and y from C_x (n, n), C_y (l, l) and C_xy (n, l): the singular
    values of L_x⁻¹ C_xy L_y⁻ᵀ, computed from the equilibrated factors by triangular solves."""
    dx, lx = equilibrated_cholesky(cov_x, names[0])
    dy, ly = equilibrated_cholesky(cov_y, names[1])
    scaled = np.asarray(cross, dtype=float) / np.outer(dx, dy)
    left = lower_solve(lx, scaled)                                                   # L_xc⁻¹ C
    k = lower_solve(ly, left.T).T                                                    # … L_yc⁻ᵀ
    u, s, vt = np.linalg.svd(k, full_matrices=True)
    return CanonicalCorrelations(s, u, vt.T, dx, lx, dy, ly)


def spd_condition(matrix: np.ndarray) -> float:
    """λ_max / λ_min of a symmetric positive (semi)definite matrix; ∞ when the computed smallest
    eigenvalue is not positive (numerically singular: no finite condition number describes it)."""
    eig = np.linalg.eigvalsh(matrix)
    return float(eig[-1] / eig[0]) if eig[0] > 0 else float("inf")


def correlation_condition(cov: np.ndarray) -> float:
    """:func:`spd_condition` of the correlation matrix of ``cov`` (D^{-½} cov D^{-½}, D its diagonal;
    zero variances left unscaled): invariant under a change of units of each component, and what
    governs the rounding of a Cholesky solve with ``cov`` (van der Sluis)."""
    diag = np.diag(cov)
    d = np.sqrt(np.where(diag > 0, diag, 1.0))
    return spd_condition(cov / np.outer(d, d))
