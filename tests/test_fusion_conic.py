"""Direct Clarabel solves of compiled DPP problems: equal to cvxpy's own route (same problem, same
solver: the same status, and the same solution to the solver's tolerance — two routes to the
solver's data need not round alike on every processor) on solvable and infeasible cases of the RCC-CI primal and dual, independent
of earlier solves and of when the program was compiled, and refusing what it cannot map."""

import cvxpy as cp
import numpy as np
import pytest

from gpfverify.filters.records import Gaussian
from gpfverify.fusion import conic
from gpfverify.fusion import rcc_ci as rcc
from gpfverify.fusion.estimates import checked_estimates, information_form
from gpfverify.fusion.synthetic import random_spd
from gpfverify.tolerances import SOLVER_TOL


def _parameter_values(ests, c=None, dual=False):
    """The normalised RCC-CI parameters of ``ests`` in the order of the primal (dual) problem."""
    checked = checked_estimates(ests)
    c = rcc.default_size(checked[0].mean.shape[0]) if c is None else c
    norm, primal = rcc._normalise_one(checked, information_form(checked), c)
    return [*norm.A, *norm.b, norm.d] if dual else primal


def _cases(seed, count):
    """Random local estimates: general and diagonal covariances (exact zeros in the data), means
    from nearly equal to far apart (empty intersections at the default size)."""
    rng = np.random.default_rng(seed)
    for k in range(count):
        n, d = int(rng.integers(2, 5)), int(rng.integers(1, 6))
        spread = [0.1, 1.0, 4.0][k % 3]
        covs = [random_spd(rng, d) if k % 2 else np.diag(rng.uniform(0.5, 2.0, d)) for _ in range(n)]
        yield [Gaussian(spread * rng.normal(size=d), cov) for cov in covs]


def _bits(solution: conic.ConicSolution):
    arrays = [*solution.values, *solution.duals]
    return solution.status, np.float64(solution.value).tobytes(), [a.tobytes() for a in arrays]


def _assert_same_solution(compiled: conic.ConicSolution, reference: conic.ConicSolution):
    """The same status and, when there is a solution, the same objective and arrays to the
    solver's tolerance relative to their scale."""
    assert compiled.status == reference.status
    if not reference.values:
        assert not compiled.values and np.isnan(compiled.value)
        return
    assert compiled.value == pytest.approx(reference.value, rel=SOLVER_TOL, abs=SOLVER_TOL)
    for got, want in zip((*compiled.values, *compiled.duals), (*reference.values, *reference.duals), strict=True):
        np.testing.assert_allclose(got, want, rtol=SOLVER_TOL, atol=SOLVER_TOL * max(1.0, np.abs(want).max()))


@pytest.mark.parametrize("build, dual", [(rcc._primal_problem, False), (rcc._dual_problem, True)])
def test_compiled_clarabel_equals_cvxpy_clarabel(build, dual):
    statuses = set()
    for ests in _cases(3, 36):
        n, d = len(ests), ests[0].mean.shape[0]
        values = _parameter_values(ests, dual=dual)
        reference = conic.solve_with_cvxpy(build(n, d, "cvxpy route"), values, cp.CLARABEL)
        compiled = rcc._clarabel_program(build, n, d).solve(values)
        _assert_same_solution(compiled, reference)
        statuses.add(compiled.status)
    assert "optimal" in statuses and len(statuses) > 1  # solvable and unsolvable cases both met


def test_a_compiled_solve_is_independent_of_earlier_solves_and_of_the_compilation():
    cases = list(_cases(5, 8))
    target = _parameter_values(cases[0])
    n, d = len(cases[0]), cases[0][0].mean.shape[0]
    program = conic.ClarabelProgram.compile(rcc._primal_problem(n, d, "first compilation"))
    first = _bits(program.solve(target))
    for ests in cases[1:]:
        if (len(ests), ests[0].mean.shape[0]) == (n, d):
            program.solve(_parameter_values(ests, c=50.0))
    assert _bits(program.solve(target)) == first
    again = conic.ClarabelProgram.compile(rcc._primal_problem(n, d, "second compilation"))
    assert _bits(again.solve(target)) == first


def test_compile_refuses_parameters_cvxpy_rewrites():
    a = cp.Parameter((2, 2), symmetric=True, value=np.eye(2))
    x = cp.Variable(2)
    problem = cp.Problem(cp.Minimize(cp.sum_squares(x)), [a @ x >= 1])
    with pytest.raises(ValueError, match="rewrites some parameters"):
        conic.ClarabelProgram.compile(conic.Parametrised(problem, (a,), (x,), ()))

