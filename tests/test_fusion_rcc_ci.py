"""RCC-CI: primal against the explicitly solved dual, the bound against optimal CI, the centre in
the intersection, closed-form cases (symmetric configurations, the smallest intersecting size),
equivariance, the empty-intersection error/fallback, the SCS fallback, and bitwise independence of
earlier solves (the direct Clarabel route against cvxpy's is tested in test_fusion_conic.py)."""

import cvxpy as cp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gpfverify.errors import InputError, SolverError
from gpfverify.filters.records import Gaussian
from gpfverify.fusion import conic
from gpfverify.fusion import rcc_ci as rcc
from gpfverify.fusion.ci import covariance_intersection, criterion_value
from gpfverify.fusion.synthetic import random_spd
from gpfverify.strategies.estimates import correlated_estimates
from gpfverify.strategies.profiles import scaled_examples
from gpfverify.tolerances import SOLVER_TOL

#: x* maximises a strongly concave objective: its accuracy is the square root of the objective's.
ARGMAX_TOL = np.sqrt(SOLVER_TOL)


def _estimates(seed, n, d, spread=0.5):
    rng = np.random.default_rng(seed)
    return [Gaussian(spread * rng.normal(size=d), random_spd(rng, d)) for _ in range(n)]


def _size(ests):
    return max(np.sqrt(np.linalg.eigvalsh(e.cov)[-1]) for e in ests)


def _mahalanobis2(x, e):
    r = x - e.mean
    return float(r @ np.linalg.solve(e.cov, r))


CASES = [(0, 2, 2), (1, 2, 3), (2, 3, 2), (3, 4, 3), (4, 3, 6)]


@pytest.mark.parametrize("seed, n, d", CASES)
def test_primal_and_dual_agree(seed, n, d):
    ests = _estimates(seed, n, d)
    res = rcc.rcc_ci(ests)
    dual = rcc.rcc_ci_dual(ests)
    assert res.c == rcc.default_size(d)
    assert dual.value == pytest.approx(res.primal_value, rel=SOLVER_TOL, abs=SOLVER_TOL * _size(ests) ** 2)
    scale = _size(ests) * np.sqrt(res.c)
    assert res.discrepancy <= ARGMAX_TOL * scale
    np.testing.assert_allclose(dual.mean, res.mean, atol=ARGMAX_TOL * scale)
    np.testing.assert_allclose(dual.alpha / dual.alpha.sum(), res.weights, atol=ARGMAX_TOL)


@pytest.mark.parametrize("seed, n, d", CASES)
def test_bound_is_never_tighter_than_optimal_ci(seed, n, d):
    ests = _estimates(seed, n, d)
    res = rcc.rcc_ci(ests)
    assert np.all(res.weights >= 0) and res.weights.sum() == pytest.approx(1.0)
    for criterion in ("trace", "det"):
        best = criterion_value(covariance_intersection(ests, criterion).cov, criterion)
        assert criterion_value(res.cov, criterion) >= best - SOLVER_TOL * abs(best)


@pytest.mark.parametrize("seed, n, d", CASES)
@pytest.mark.parametrize("c", [None, 30.0])
def test_centre_lies_in_the_intersection(seed, n, d, c):
    ests = _estimates(seed, n, d, spread=1.0)
    res = rcc.rcc_ci(ests, c=c)
    for e in ests:
        assert _mahalanobis2(res.primal_mean, e) <= res.c * (1 + SOLVER_TOL)
        assert _mahalanobis2(res.mean, e) <= res.c * (1 + ARGMAX_TOL)


def test_symmetric_pair_fuses_to_the_midpoint():
    p = random_spd(np.random.default_rng(1), 2)
    ests = [Gaussian(np.array([1.0, -0.5]), p), Gaussian(np.array([-1.0, 0.5]), p)]
    res = rcc.rcc_ci(ests, c=40.0)
    np.testing.assert_allclose(res.weights, [0.5, 0.5], atol=ARGMAX_TOL)
    np.testing.assert_allclose(res.mean, [0.0, 0.0], atol=ARGMAX_TOL)
    np.testing.assert_allclose(res.cov, p, rtol=ARGMAX_TOL)


def test_equivariant_under_translation_and_scaling():
    ests = _estimates(7, 3, 2)
    base = rcc.rcc_ci(ests)
    shift, s = np.array([300.0, -40.0]), 20.0
    moved = rcc.rcc_ci([Gaussian(s * e.mean + shift, s**2 * e.cov) for e in ests])
    np.testing.assert_allclose(moved.mean, s * base.mean + shift, atol=ARGMAX_TOL * s * _size(ests) * 10)
    np.testing.assert_allclose(moved.weights, base.weights, atol=ARGMAX_TOL)


def test_empty_intersection_is_a_clear_error_or_a_documented_enlargement():
    far = [Gaussian(np.zeros(2), np.eye(2)), Gaussian(np.array([10.0, 0.0]), np.eye(2))]
    # two unit balls 10 apart meet first at the midpoint, squared distance 5² = 25
    assert rcc.smallest_intersecting_size(far) == pytest.approx(25.0, rel=SOLVER_TOL)
    with pytest.raises(SolverError, match=r"do not intersect at size c = 9\.21\d* \(the default, the 0\.99 quantile "
                                          r"of chi-square with 2 degrees of freedom\); the smallest size at which "
                                          r"they do is c = 25(\.0*)?$"):
        rcc.rcc_ci(far)
    with pytest.raises(SolverError, match=r"do not intersect at size c = 3; the smallest size at which they do is "
                                          r"c = 25(\.0*)?$"):
        rcc.rcc_ci(far, c=3.0)
    res = rcc.rcc_ci(far, on_empty="enlarge")
    assert res.enlarged and res.c == pytest.approx(rcc.EMPTY_GROWTH * 25.0, rel=SOLVER_TOL)
    np.testing.assert_allclose(res.mean, [5.0, 0.0], atol=ARGMAX_TOL * 10)


@pytest.mark.parametrize("on_empty", ["error", "enlarge"])
def test_a_solver_that_finds_no_centre_where_the_ellipsoids_meet_says_so(monkeypatch, on_empty):
    """A primal that reports infeasibility at a size where the ellipsoids do meet (c_min below the
    size tried: a badly scaled problem) is a solver failure, and the message names the size tried —
    the default χ²_D(0.99) quantile when none was given — and the smallest that works, which is
    below it, never a size above the smallest one as if it were too small."""
    ests = _estimates(2, 3, 2)
    c_min = rcc.smallest_intersecting_size(ests)
    default = rcc.default_size(ests[0].mean.shape[0])
    assert c_min < default  # these ellipsoids meet at the default size
    infeasible = conic.ConicSolution("infeasible", float("nan"), (), ())
    monkeypatch.setattr(rcc, "_solve_parametrised", lambda *args: infeasible)
    with pytest.raises(SolverError) as raised:
        rcc.rcc_ci(ests, on_empty=on_empty)
    message = str(raised.value)
    assert f"no centre at size c = {default:.6g} (the default" in message
    assert f"intersect for every c >= {c_min:.6g}" in message
    assert "not an empty intersection" in message


def test_problem_is_compiled_once_and_re_solved():
    rcc.rcc_ci(_estimates(0, 2, 5))
    before = rcc._clarabel_program.cache_info()
    for seed in range(3):
        rcc.rcc_ci(_estimates(seed, 2, 5))
    after = rcc._clarabel_program.cache_info()
    assert after.hits == before.hits + 3 and after.misses == before.misses


def test_this_cvxpy_is_compiled():
    """On the cvxpy the project runs against, the compiled route is the one taken."""
    assert conic._MISSING_INTERNALS is None
    assert rcc._clarabel_program(rcc._primal_problem, 3, 4) is not None


def _cannot_reproduce(monkeypatch):
    def refuse(program):
        raise ValueError("the compiled map does not reproduce cvxpy's conic data")
    monkeypatch.setattr(conic.ClarabelProgram, "compile", refuse)


def _internals_moved(monkeypatch):
    monkeypatch.setattr(conic, "_MISSING_INTERNALS", ImportError("No module named 'cvxpy.cvxcore.python'"))


def _attribute_renamed(monkeypatch):
    monkeypatch.setattr(conic, "CLARABEL", object())  # the compiler's view of the interface lost DIMS


@pytest.mark.parametrize("change", [_cannot_reproduce, _internals_moved, _attribute_renamed])
def test_a_cvxpy_the_compiler_cannot_reproduce_falls_back_to_cvxpy_with_the_same_numbers(monkeypatch, change):
    """compile refuses what it cannot reproduce exactly, a cvxpy without the modules it reads and
    one whose internals lost an attribute: the solve then goes through cvxpy's own Clarabel route,
    whose numbers the compiled route equals to the solver's tolerance (the same problem handed to the
same solver by two routes, which need not round alike on every processor)."""
    estimates = _estimates(4, 3, 4)
    compiled = rcc.rcc_ci(estimates)
    rcc._clarabel_program.cache_clear()
    change(monkeypatch)
    try:
        fallback = rcc.rcc_ci(estimates)
        assert rcc._clarabel_program(rcc._primal_problem, 3, 4) is None  # the fallback was taken
    finally:
        rcc._clarabel_program.cache_clear()
    for name in ("mean", "cov", "weights", "alpha", "primal_mean"):
        want = np.asarray(getattr(compiled, name))
        np.testing.assert_allclose(getattr(fallback, name), want, rtol=SOLVER_TOL,
                                   atol=SOLVER_TOL * max(1.0, np.abs(want).max()), err_msg=name)
    assert fallback.primal_value == pytest.approx(compiled.primal_value, rel=SOLVER_TOL, abs=SOLVER_TOL)


def _fail(*args):
    raise SolverError("the solver failed (status solver_error)")


def test_a_clarabel_failure_falls_back_to_scs_and_a_double_failure_is_reported(monkeypatch):
    ests = _estimates(2, 3, 2)
    scs = _bits(rcc.rcc_ci(ests, solver=cp.SCS))
    monkeypatch.setattr(conic.ClarabelProgram, "solve", _fail)
    assert _bits(rcc.rcc_ci(ests)) == scs
    monkeypatch.setattr(rcc, "solve_with_cvxpy", _fail)
    with pytest.raises(SolverError, match=r"RCC-CI primal failed: .*solver_error"):
        rcc.rcc_ci(ests)


def test_bad_arguments():
    ests = _estimates(0, 2, 2)
    with pytest.raises(InputError, match="c must be strictly positive"):
        rcc.rcc_ci(ests, c=-1.0)
    with pytest.raises(InputError, match="on_empty"):
        rcc.rcc_ci(ests, on_empty="ignore")


def _bits(res: rcc.RccCiResult) -> list[bytes]:
    return [np.asarray(v, dtype=float).tobytes() for v in
            (res.mean, res.cov, res.weights, res.alpha, res.c, res.primal_mean, res.primal_value)]


@settings(max_examples=scaled_examples(0.25))
@given(target=correlated_estimates(count=st.integers(2, 3), state_dim=st.integers(1, 3)),
       earlier=st.lists(st.integers(0, 2**32 - 1), min_size=1, max_size=3))
def test_a_solve_is_bitwise_independent_of_earlier_solves(target, earlier):
    """The contract's determinism across workers and --resume rests on this: the same inputs give
    the same bits whether the process has solved other problems of the same size before or not
    (a warm-started solver, or a fallback chosen by the cache's history, broke it)."""
    ests = list(target.estimates)
    n, d = len(ests), ests[0].mean.shape[0]
    rcc._primal_problem.cache_clear()
    rcc._clarabel_program.cache_clear()  # the first solve is the first of a newly compiled program
    first = _bits(rcc.rcc_ci(ests, on_empty="enlarge"))
    for seed in earlier:  # other problems of the same size, through the same cached problem
        rcc.rcc_ci(_estimates(seed, n, d), on_empty="enlarge")
    assert _bits(rcc.rcc_ci(ests, on_empty="enlarge")) == first


@pytest.mark.parametrize("dim, seed", [(1, 0), (2, 1), (3, 2), (5, 3)])
def test_two_ellipsoid_size_is_the_conic_programs(dim, seed):
    """The closed form of c_min for two ellipsoids (minimax duality, one scalar root) against the
    conic program min t s.t. both quadratics ≤ t, for ellipsoids apart, overlapping and nested."""
    rng = np.random.default_rng(seed)
    for spread in (0.1, 1.0, 30.0):
        a, b = rng.normal(size=(2, dim, dim))
        ests = [Gaussian(rng.normal(size=dim) * spread, a @ a.T + 0.1 * np.eye(dim)),
                Gaussian(rng.normal(size=dim) * spread, b @ b.T + 0.1 * np.eye(dim))]
        closed = rcc.two_ellipsoid_size(*ests)
        assert closed == pytest.approx(rcc.conic_intersecting_size(ests), rel=SOLVER_TOL, abs=SOLVER_TOL)
