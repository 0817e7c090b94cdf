"""errors / validate / linalg / tolerances: the ground floor every module stands on."""

import numpy as np
import pytest

from gpfverify.errors import InputError, NumericalError
from gpfverify.linalg import (Cholesky, cholesky, graded_svd, lower_solve, numerical_rank, right_solve_spd,
                              solve_spd)
from gpfverify.tolerances import algebra_rtol, monte_carlo_atol
from gpfverify.validate import as_covariance, as_matrix, as_vector


def _spd(seed, n, cond=10.0):
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(n, n)))
    return q @ np.diag(np.geomspace(1.0, 1.0 / cond, n)) @ q.T


def test_cholesky_solve_and_inverse_agree_with_numpy():
    a = _spd(0, 12, cond=1e4)
    chol = cholesky(a)
    b = np.random.default_rng(1).normal(size=(12, 3))
    tol = algebra_rtol(1e4)
    assert chol.jitter == 0.0
    np.testing.assert_allclose(chol.solve(b), np.linalg.solve(a, b), rtol=tol, atol=tol)
    for factor in (chol.factor, np.ascontiguousarray(chol.factor)):  # LAPACK's order and C order
        inverse = Cholesky(factor, 0.0).inverse()
        np.testing.assert_allclose(inverse, np.linalg.inv(a), rtol=tol, atol=tol * 1e4)
        np.testing.assert_array_equal(inverse, inverse.T)
    assert chol.logdet() == pytest.approx(np.linalg.slogdet(a)[1], rel=tol)
    np.testing.assert_allclose(solve_spd(a, b), np.linalg.solve(a, b), rtol=tol, atol=tol)
    np.testing.assert_allclose(right_solve_spd(b.T, a), np.linalg.solve(a, b).T, rtol=tol, atol=tol)


def test_solves_of_an_empty_system_are_empty():
    """A second stage whose patch lies off the image solves a 0 × 0 system: the answer is empty."""
    assert solve_spd(np.zeros((0, 0)), np.zeros(0)).shape == (0,)
    assert right_solve_spd(np.zeros((3, 0)), np.zeros((0, 0))).shape == (3, 0)


def test_cholesky_is_numpys_factor_to_rounding():
    """The factor comes from LAPACK's potrf directly: lower triangular with exact zeros above the
    diagonal, and numpy's factor to the rounding of a condition-1e3 factorisation (numpy and scipy
    link LAPACK builds that round differently on some processors, so not to the bit)."""
    for n in (1, 2, 5, 40):
        a = _spd(n, n, cond=1e3)
        a = (a + a.T) / 2  # exactly symmetric, as cholesky makes its argument
        factor = cholesky(a).factor
        assert not np.triu(factor, 1).any()
        tol = algebra_rtol(1e3)
        np.testing.assert_allclose(factor, np.linalg.cholesky(a), rtol=tol, atol=tol * np.abs(factor).max())


def test_whiten_is_the_triangular_solve():
    """L⁻¹b for one right-hand side (as a vector and as one column) and for several, against
    scipy's triangular solve, with the factor in LAPACK's Fortran order (as :func:`cholesky`
    returns it) and in C order; a column comes back as a column."""
    import scipy.linalg as sla

    chol = cholesky(_spd(7, 30, cond=1e4))
    assert chol.factor.flags.f_contiguous
    b = np.random.default_rng(7).normal(size=(30, 3))
    for factor in (chol.factor, np.ascontiguousarray(chol.factor)):
        for rhs in (b[:, 0], b[:, :1], b):
            expected = sla.solve_triangular(factor, rhs, lower=True)
            whitened = Cholesky(factor, chol.jitter).whiten(rhs)
            assert whitened.shape == rhs.shape
            np.testing.assert_allclose(whitened, expected, rtol=algebra_rtol(1e2), atol=0)
            transposed = lower_solve(factor, rhs, transpose=True)
            assert transposed.shape == rhs.shape
            np.testing.assert_allclose(transposed, sla.solve_triangular(factor, rhs, lower=True, trans="T"),
                                       rtol=algebra_rtol(1e2), atol=0)


def test_graded_svd_keeps_high_relative_accuracy_under_grading():
    """a = D₁ B D₂ with B of condition 10 and D₁, D₂ spanning 12 orders of magnitude (tall, wide,
    square, and of rank one less than full): every singular value to B's relative rounding against
    a 50-digit SVD (mpmath, an independent route), U and V orthogonal, and a = U S Vᵀ row by row to
    the rows' own size. numpy's SVD meets this for σ_1 only (its error is relative to σ_1)."""
    import mpmath

    rng = np.random.default_rng(11)
    mpmath.mp.dps = 50
    for rows, cols, rank in ((4, 2, 2), (2, 4, 2), (3, 3, 3), (4, 3, 2), (5, 1, 1)):
        left, _ = np.linalg.qr(rng.normal(size=(rows, rank)))
        right, _ = np.linalg.qr(rng.normal(size=(cols, rank)))
        core = (left * np.geomspace(1.0, 0.1, rank)) @ right.T                       # condition 10 on its range
        a = np.geomspace(1e-6, 1e6, rows)[:, None] * core * rng.permutation(np.geomspace(1e6, 1e-6, cols))
        u, s, vt = graded_svd(a)
        assert u.shape == (rows, rows) and s.shape == (min(rows, cols),) and vt.shape == (cols, cols)
        exact = sorted((float(x) for x in mpmath.svd_r(mpmath.matrix(a.tolist()), compute_uv=False)), reverse=True)
        tol = algebra_rtol(10.0 * max(rows, cols))
        np.testing.assert_allclose(s[:rank], exact[:rank], rtol=tol, atol=0)
        assert np.all(np.abs(s[rank:]) <= tol * s[rank - 1])                         # the lost direction
        np.testing.assert_allclose(u @ u.T, np.eye(rows), atol=algebra_rtol())
        np.testing.assert_allclose(vt @ vt.T, np.eye(cols), atol=algebra_rtol())
        rebuilt = (u[:, :s.size] * s) @ vt[:s.size]
        row_size = np.linalg.norm(a, axis=1, keepdims=True)
        assert np.all(np.abs(rebuilt - a) <= tol * row_size)


def test_cholesky_reports_jitter_and_fails_clearly():
    v = np.array([1.0, 2.0, 3.0])
    singular = np.outer(v, v)  # rank one: needs jitter
    chol = cholesky(singular, "S")
    assert chol.jitter > 0
    with pytest.raises(NumericalError, match="S is not positive definite"):
        cholesky(singular, "S", allow_jitter=False)
    with pytest.raises(NumericalError, match="B is not positive definite"):
        cholesky(-np.eye(3), "B")


@pytest.mark.parametrize("seed", range(4))
def test_numerical_rank_uses_numpys_rule_by_default(seed):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(5, 3)) @ rng.normal(size=(3, 4))  # rank 3
    report = numerical_rank(a)
    assert report.rank == np.linalg.matrix_rank(a) == 3
    assert not report.full_column_rank and report.shape == (5, 4)
    assert numerical_rank(a, tol=report.singular_values[0] * 2).rank == 0
    assert numerical_rank(rng.normal(size=(4, 2))).full_column_rank


def test_validate_names_the_argument():
    with pytest.raises(InputError, match="mu must have shape"):
        as_vector(np.zeros(3), "mu", 2)
    with pytest.raises(InputError, match="M contains NaN"):
        as_matrix([[1.0, np.nan]], "M")
    with pytest.raises(InputError, match="P is not symmetric"):
        as_covariance([[1.0, 0.5], [0.0, 1.0]], "P")
    with pytest.raises(InputError, match="P is not positive semidefinite"):
        as_covariance([[1.0, 2.0], [2.0, 1.0]], "P")
    with pytest.raises(InputError, match="P is not positive definite"):
        as_covariance([[1.0, 1.0], [1.0, 1.0]], "P", definite=True)
    np.testing.assert_array_equal(as_covariance([[1.0, 1.0], [1.0, 1.0]], "P"), np.ones((2, 2)))


def test_tolerances_scale_with_conditioning_and_sample_size():
    assert algebra_rtol(1.0) == 1e-9
    assert algebra_rtol(1e12) > algebra_rtol(1e3)
    assert algebra_rtol(float("inf")) == float("inf")
    assert monte_carlo_atol(2.0, 400) == pytest.approx(5 * 2.0 / 20)
