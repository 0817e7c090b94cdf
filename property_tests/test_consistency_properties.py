"""Filter consistency tests (gpfverify.consistency) against scipy.stats and against simulation.

* the two-sided χ² interval is scipy.stats.chi2's quantile pair, and its χ² probability is the level;
* the p-value of the count outside the interval is scipy.stats.binom's exact upper tail, and the
  verdict rejects exactly when it is at most α, naming the side with more values outside;
* NEES and NIS are the quadratic forms eᵀP⁻¹e solved here with scipy (angle components of any
  branch give the same values), averaged over the right axis with the right degrees of freedom;
* simulated consistent errors: each average lies inside its interval with probability `level`,
  and the binomial verdict rejects at most α of the time (it is exact or conservative);
* conservativeness: the statistic is the largest generalised eigenvalue of (Ê, P) computed here
  (the per-run form through scipy's Cholesky factors), its direction the top generalised
  eigenvector, and at Σ = P the bound is exceeded at most 1 − level of the time.

Frequencies of simulated events are compared with Hoeffding's bound
(:func:`~gpfverify.tolerances.bounded_mean_atol`): an indicator lies in [0, 1].
"""

import numpy as np
import scipy.linalg as sla
import scipy.stats
from hypothesis import given, settings
from hypothesis import strategies as st

from gpfverify.consistency import (CONSISTENT, OPTIMISTIC, PESSIMISTIC, ChiSquareTest, Consistency, chi2_interval,
                                   conservativeness)
from gpfverify.strategies import mixed_angle_states, scaled_examples, spd_matrices
from gpfverify.strategies.matrices import float_arrays, log_uniform, unit_floats
from gpfverify.tolerances import ALGEBRA_RTOL, EPS, algebra_rtol, bounded_mean_atol

levels = unit_floats(0.5, 0.995)
REPEATS = 400


def _rng(seed):
    return np.random.default_rng(seed)


@given(dof=st.integers(1, 500), divisor=log_uniform(0.1, 100.0), level=levels)
def test_chi2_interval_is_scipys_two_sided_quantile_pair(dof, divisor, level):
    lower, upper = chi2_interval(dof, divisor, level)
    tail = (1.0 - level) / 2.0
    want = (scipy.stats.chi2.ppf(tail, dof) / divisor, scipy.stats.chi2.isf(tail, dof) / divisor)
    np.testing.assert_allclose((lower, upper), want, rtol=algebra_rtol(), atol=0)
    inside = scipy.stats.chi2.cdf(upper * divisor, dof) - scipy.stats.chi2.cdf(lower * divisor, dof)
    assert abs(inside - level) <= algebra_rtol()


@st.composite
def counted_tests(draw):
    """A ChiSquareTest whose n values have `above` above and `below` below [1, 2] (the rest inside)."""
    n = draw(st.integers(1, 60))
    above = draw(st.integers(0, n))
    below = draw(st.integers(0, n - above))
    values = np.concatenate([np.full(above, 3.0), np.full(below, 0.5), np.full(n - above - below, 1.5)])
    values = values[draw(st.permutations(range(n)))] if n > 1 else values
    level = draw(levels)
    return ChiSquareTest("ANEES", values, 1.0, 2.0, 1, 1, 1, level), above, below


@given(drawn=counted_tests(), alpha=st.one_of(st.none(), unit_floats(1e-4, 0.5)))
def test_binomial_p_value_is_the_exact_upper_tail_and_the_verdict_follows_it(drawn, alpha):
    test, above, below = drawn
    n, outside, level = test.values.size, above + below, test.level
    want = 1.0 if outside == 0 else scipy.stats.binom.sf(outside - 1, n, 1.0 - level)
    assert abs(test.p_value() - want) <= algebra_rtol() * want
    assert (test.n_above, test.n_below) == (above, below)
    threshold = 1.0 - level if alpha is None else alpha
    verdict = test.verdict(alpha)
    if want > threshold * (1.0 + 2 * ALGEBRA_RTOL):
        assert verdict == CONSISTENT
    elif want < threshold * (1.0 - 2 * ALGEBRA_RTOL):
        assert verdict == (OPTIMISTIC if above >= below else PESSIMISTIC)
    if n == 1 and alpha is None:  # one value: exactly the interval test
        assert (verdict == CONSISTENT) == (outside == 0)


@st.composite
def normalised_errors(draw):
    """(R, T, D) errors, (R, T, D, D) covariances, angle components and 2π multiples."""
    runs, steps, dim = draw(st.integers(1, 4)), draw(st.integers(1, 4)), draw(st.integers(1, 3))
    covs = np.stack([draw(spd_matrices(dim, 1e3, log_uniform(1e-3, 10.0))) for _ in range(runs * steps)])
    covs = covs.reshape(runs, steps, dim, dim)
    errors = draw(float_arrays((runs, steps, dim), -3.0, 3.0))
    circular = tuple(i for i in range(dim) if draw(st.booleans()))
    turns = np.zeros((runs, steps, dim))
    for i in circular:
        turns[..., i] = draw(float_arrays((runs, steps), -3, 3)).round()
    means = draw(float_arrays((runs, steps, dim), -10.0, 10.0))
    return errors, covs, circular, turns, means


def _quadratic_forms(errors, covs):
    """eᵀ P⁻¹ e with scipy's SPD solve, entry by entry."""
    flat_e, flat_p = errors.reshape(-1, errors.shape[-1]), covs.reshape(-1, *covs.shape[-2:])
    out = [e @ sla.solve(p, e, assume_a="pos") for e, p in zip(flat_e, flat_p)]
    return np.array(out).reshape(errors.shape[:-1])


@given(drawn=normalised_errors(), level=levels)
def test_nees_and_nis_are_the_quadratic_forms_averaged_with_their_degrees_of_freedom(drawn, level):
    errors, covs, circular, turns, means = drawn
    # angle components within π of the mean, reported on any branch (2π multiples added)
    errors = errors.copy()
    for i in circular:
        errors[..., i] = np.clip(errors[..., i], -3.0, 3.0)
    truth = means + errors + 2.0 * np.pi * turns
    want = _quadratic_forms(errors, covs)
    cond = max(np.linalg.cond(p) for p in covs.reshape(-1, *covs.shape[-2:]))
    # truth − means rounds relative to the operands' size, wrapping an angle difference relative to
    # 2π; the form amplifies by 1/λ_min(P)
    size = np.abs(truth) + np.abs(means)
    size[..., list(circular)] += 2.0 * np.pi
    tol = algebra_rtol(cond) * np.einsum("...i,...i->...", size, size) / np.linalg.eigvalsh(covs)[..., 0]
    nees = Consistency.from_estimates(truth, means, covs, circular_state=circular)
    nis = Consistency.nis(truth, means, covs, circular=circular)
    for result, kind in ((nees, "NEES"), (nis, "NIS")):
        assert result.kind == kind and result.dim == errors.shape[-1]
        assert np.all(np.abs(result.values - want) <= tol), (result.values, want)
    if errors.shape[0] == 1:  # a single run given as (T, D)
        single = Consistency.from_estimates(truth[0], means[0], covs[0], circular_state=circular)
        np.testing.assert_array_equal(single.values, nees.values)
    runs, steps, dim = errors.shape
    for test, samples, axis in ((nees.average_over_runs(level), runs, 0), (nees.average_over_time(level), steps, 1)):
        assert test.values.shape == want.mean(axis=axis).shape
        assert np.all(np.abs(test.values - want.mean(axis=axis)) <= tol.max())
        assert (test.samples, test.dim, test.dof, test.level) == (samples, dim, samples * dim, level)
        tail = (1.0 - level) / 2.0
        dof = samples * dim
        bounds = (scipy.stats.chi2.ppf(tail, dof) / samples, scipy.stats.chi2.isf(tail, dof) / samples)
        np.testing.assert_allclose((test.lower, test.upper), bounds, rtol=algebra_rtol(), atol=0)


@settings(max_examples=scaled_examples(0.25))
@given(runs=st.integers(1, 6), steps=st.integers(1, 12), dim=st.integers(1, 3), level=levels,
       alpha=st.one_of(st.none(), unit_floats(0.01, 0.3)), seed=st.integers(0, 2**32 - 1), data=st.data())
def test_simulated_consistent_errors_fall_inside_at_the_level_and_are_rejected_at_most_alpha(
        runs, steps, dim, level, alpha, seed, data):
    """REPEATS independent sets of errors drawn from the covariances the filter reports: every
    average is inside its interval with probability `level` (it is exactly χ²(dof)/samples), and
    the verdict on the independent averages rejects with probability ≤ α (the binomial test is
    exact up to the discreteness of the count, which only makes it conservative)."""
    cov = data.draw(spd_matrices(dim, 1e2, log_uniform(1e-2, 10.0)), label="P")
    rng = _rng(seed)
    factor = np.linalg.cholesky(cov)
    inside, rejected = [], []  # per repeat: the fraction of averages inside, the fraction of rejections
    for _ in range(REPEATS):
        errors = rng.standard_normal((runs, steps, dim)) @ factor.T
        covs = np.broadcast_to(cov, (runs, steps, dim, dim))
        result = Consistency.from_estimates(errors, np.zeros_like(errors), covs)
        tests = (result.average_over_runs(level), result.average_over_time(level))
        inside.append(np.mean(np.concatenate([t.inside for t in tests])))
        rejected.append(np.mean([not t.passed(alpha) for t in tests]))
    # the averages of one repeat are dependent, the repeats independent: Hoeffding on the REPEATS
    # per-repeat fractions (each in [0, 1]; E = level, resp. ≤ α)
    assert abs(np.mean(inside) - level) <= bounded_mean_atol(1.0, REPEATS), (np.mean(inside), level)
    threshold = 1.0 - level if alpha is None else alpha
    assert np.mean(rejected) <= threshold + bounded_mean_atol(1.0, REPEATS), (np.mean(rejected), threshold)


@st.composite
def claimed_errors(draw):
    runs, dim = draw(st.integers(1, 30)), draw(st.integers(1, 4))
    errors = draw(float_arrays((runs, dim), -3.0, 3.0))
    per_run = draw(st.booleans())
    scale = log_uniform(1e-2, 10.0)
    if per_run:
        covs = np.stack([draw(spd_matrices(dim, 1e2, scale)) for _ in range(runs)])
    else:
        covs = draw(spd_matrices(dim, 1e2, scale))
    return errors, covs


@given(drawn=claimed_errors(), level=levels)
def test_conservativeness_statistic_is_the_largest_generalised_eigenvalue(drawn, level):
    errors, covs = drawn
    runs, dim = errors.shape
    result = conservativeness(errors, covs, level)
    top: np.ndarray | None
    if covs.ndim == 2:  # Ê v = λ P v
        second = errors.T @ errors / runs
        values, vectors = sla.eigh(second, covs)
        top = vectors[:, -1] / np.linalg.norm(vectors[:, -1])
        cond = np.linalg.cond(covs)
    else:  # per-run Cholesky whitening z_r = L_r⁻¹ e_r
        white = np.stack([sla.solve_triangular(sla.cholesky(p, lower=True), e, lower=True)
                          for e, p in zip(errors, covs)])
        values = np.linalg.eigvalsh(white.T @ white / runs)
        top = None
        cond = max(np.linalg.cond(p) for p in covs)
    scale = max(values[-1], np.abs(errors).max() ** 2 / min(np.linalg.eigvalsh(covs).min(), 1.0))
    np.testing.assert_allclose(result.eigenvalues, values, rtol=0, atol=algebra_rtol(cond) * scale)
    assert result.statistic == result.eigenvalues[-1]
    assert (result.samples, result.dim, result.level) == (runs, dim, level)
    t = np.sqrt(-2.0 * np.log(1.0 - level))
    bound = (np.sqrt(runs) + np.sqrt(dim) + t) ** 2 / runs
    np.testing.assert_allclose(result.bound, bound, rtol=algebra_rtol(), atol=0)
    if top is None:
        assert result.direction is None
        return
    assert result.direction is not None
    # unit, its largest entry positive; the top eigenvector's direction when the top eigenvalue is
    # simple (angle ≤ perturbation / gap, the perturbation amplified by cond(P) through P's factor)
    assert abs(np.linalg.norm(result.direction) - 1.0) <= 10 * EPS * dim
    assert result.direction[np.argmax(np.abs(result.direction))] > 0
    gap = values[-1] - values[-2] if dim > 1 else np.inf
    err = algebra_rtol(cond) * scale * cond
    if gap > 1e3 * err:
        assert 1.0 - abs(result.direction @ top) <= err / gap + 10 * EPS * dim


@settings(max_examples=scaled_examples(0.25))
@given(runs=st.integers(1, 40), dim=st.integers(1, 4), level=levels, per_run=st.booleans(),
       seed=st.integers(0, 2**32 - 1), data=st.data())
def test_conservativeness_bound_is_exceeded_at_most_one_minus_level_at_the_boundary(
        runs, dim, level, per_run, seed, data):
    """Errors drawn exactly from the claimed covariances (Σ = P, the boundary of H0)."""
    scale = log_uniform(1e-2, 10.0)
    covs = (np.stack([data.draw(spd_matrices(dim, 1e2, scale)) for _ in range(runs)]) if per_run
            else data.draw(spd_matrices(dim, 1e2, scale), label="P"))
    factors = np.linalg.cholesky(covs)
    rng = _rng(seed)
    exceeded = []
    for _ in range(REPEATS):
        g = rng.standard_normal((runs, dim))
        errors = np.einsum("...ij,...j->...i", factors, g)
        exceeded.append(not conservativeness(errors, covs, level).passed)
    assert np.mean(exceeded) <= (1.0 - level) + bounded_mean_atol(1.0, REPEATS), (np.mean(exceeded), level)


@given(states=mixed_angle_states(), data=st.data())
def test_nees_wraps_the_angle_components_and_only_those(states, data):
    """States mixing angles near ±π and lengths whose differences exceed π: NEES is the quadratic
    form of the difference with the angle components wrapped and the lengths left as they are
    (wrapped here with numpy's remainder, :meth:`MixedStates.difference`)."""
    n, dim = states.first.shape
    covs = np.stack([data.draw(spd_matrices(dim, 1e2, log_uniform(1e-2, 1e2)), label="P") for _ in range(n)])
    nees = Consistency.from_estimates(states.first, states.second, covs, circular_state=states.angles)
    want = _quadratic_forms(states.difference(), covs)
    cond = max(np.linalg.cond(p) for p in covs)
    size = np.abs(states.first) + np.abs(states.second) + 2.0 * np.pi
    tol = algebra_rtol(cond) * np.einsum("...i,...i->...", size, size) / np.linalg.eigvalsh(covs)[..., 0]
    np.testing.assert_allclose(nees.values.ravel(), want, rtol=0, atol=tol.max())
