"""The tolerances of gpfverify.tolerances pinned from both sides against independent routes: each
holds where it must (covers the error or the deviation it is for) and is no looser than its stated
design (the probability it was derived for, the peer library's own decision).

* ``numpy_rank_tol`` is numpy.linalg.matrix_rank's default: a singular value placed between
  σ₁·min(M, N)·eps and σ₁·max(M, N)·eps of a rectangular matrix is counted as numpy counts it
  (a permuted diagonal, whose singular values are exact);
* ``bounded_mean_atol``'s Hoeffding tail 2 exp(−2 n t² / w²) is exactly the two-sided normal tail
  of its ``sigmas`` (scipy.stats.norm), and ``monte_carlo_atol`` is ``sigmas`` standard errors;
* ``learned_model_rtol`` is ``sigmas`` relative standard deviations of a variance estimated from n
  Gaussian samples (scipy.stats.chi2: sd(χ²_n / n) = √(2/n));
* ``algebra_rtol`` covers the error of an SPD solve measured in 40-digit arithmetic (mpmath) at
  the drawn condition numbers, and ``kkt_reject_tol`` adds exactly that rounding to the solver floor.
"""

import mpmath
import numpy as np
import scipy.stats
from hypothesis import given
from hypothesis import strategies as st

from gpfverify.strategies import spd_matrices
from gpfverify.strategies.matrices import float_arrays, log_uniform, unit_floats
from gpfverify.tolerances import (ALGEBRA_RTOL, EPS, KKT_REJECT_TOL, algebra_rtol, bounded_mean_atol,
                                  kkt_reject_tol, learned_model_rtol, monte_carlo_atol, numpy_rank_tol)


@given(rows=st.integers(2, 6), extra=st.integers(1, 6), wide=st.booleans(), where=unit_floats(0.1, 0.9), data=st.data())
def test_numpy_rank_tol_decides_as_numpy_matrix_rank_between_the_two_shape_factors(rows, extra, wide, where, data):
    small, large = rows, rows + extra
    shape = (small, large) if wide else (large, small)
    # the last singular value sits between σ₁ min(M, N) eps and σ₁ max(M, N) eps (log-interpolated)
    low, high = min(shape) * EPS, max(shape) * EPS
    last = float(np.exp(np.log(low) + where * (np.log(high) - np.log(low))))
    s = np.array([1.0] * (small - 1) + [last])
    # a permuted rectangular diagonal: its singular values are s exactly (no rounding to blur the placement)
    matrix = np.zeros(shape)
    matrix[np.arange(small), np.arange(small)] = s
    matrix = matrix[data.draw(st.permutations(range(shape[0])))][:, data.draw(st.permutations(range(shape[1])))]
    computed = np.linalg.svd(matrix, compute_uv=False)
    tol = numpy_rank_tol(computed, matrix.shape)
    assert int(np.sum(computed > tol)) == np.linalg.matrix_rank(matrix) == small - (last <= tol)
    assert (last > tol) == (last > high)  # the larger of the two dimensions decides
    assert tol == computed.max() * max(shape) * EPS


@given(width=log_uniform(1e-3, 1e3), n=st.integers(1, 10**6), sigmas=unit_floats(1.0, 8.0))
def test_bounded_mean_atol_is_hoeffding_at_the_normal_tail_of_its_sigmas(width, n, sigmas):
    t = bounded_mean_atol(width, n, sigmas)
    hoeffding_tail = 2.0 * np.exp(-2.0 * n * t * t / (width * width))
    normal_tail = 2.0 * scipy.stats.norm.sf(sigmas)
    assert abs(hoeffding_tail - normal_tail) <= 1e-9 * normal_tail
    std = width / 2.0
    assert np.isclose(monte_carlo_atol(std, n, sigmas), sigmas * std / np.sqrt(n), rtol=4 * EPS, atol=0)


@given(n=st.integers(2, 10**6), sigmas=unit_floats(1.0, 8.0))
def test_learned_model_rtol_is_sigmas_relative_standard_deviations_of_a_variance_estimate(n, sigmas):
    relative_sd = scipy.stats.chi2(n).std() / n  # sd of the mean of n squared standard normals
    assert abs(learned_model_rtol(n, sigmas) - sigmas * relative_sd) <= 1e-12 * sigmas * relative_sd


@given(dim=st.integers(2, 5), condition=log_uniform(1.0, 1e12), data=st.data())
def test_algebra_rtol_covers_an_spd_solve_measured_in_high_precision(dim, condition, data):
    a = data.draw(spd_matrices(dim, condition, 1.0), label="A")
    b = data.draw(float_arrays((dim,), -1.0, 1.0).filter(lambda v: np.abs(v).max() > 0.1), label="b")
    x = np.linalg.solve(a, b)
    with mpmath.workdps(40):
        exact = mpmath.lu_solve(mpmath.matrix(a.tolist()), mpmath.matrix(b.tolist()))
        error = max(abs(mpmath.mpf(float(xi)) - e) for xi, e in zip(x, exact))
        size = max(abs(e) for e in exact)
    kappa = np.linalg.cond(a)
    assert float(error / size) <= algebra_rtol(kappa)
    assert algebra_rtol(kappa) == max(ALGEBRA_RTOL, 1e3 * EPS * max(kappa, 1.0))
    assert np.isclose(kkt_reject_tol(kappa), KKT_REJECT_TOL + 1e3 * EPS * max(kappa, 1.0), rtol=4 * EPS, atol=0)
