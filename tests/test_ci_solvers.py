"""CI of more than two estimates by Newton's method (the default) and by SLSQP against an
independent conic program written here with cvxpy and Clarabel in the original coordinates, the
default's fallback on SLSQP, and the KKT certificate's refusal of weights that are not optimal."""

import cvxpy as cp
import numpy as np
import pytest

from gpfverify.errors import NumericalError
from gpfverify.filters.records import Gaussian
from gpfverify.fusion import ci
from gpfverify.fusion.ci import covariance_intersection, criterion_value
from gpfverify.tolerances import SOLVER_TOL


def _estimates(seed: int, n: int, d: int) -> list[Gaussian]:
    """N estimates whose covariances have eigenvalues spread by 20 in random orientations."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        q, _ = np.linalg.qr(rng.normal(size=(d, d)))
        out.append(Gaussian(rng.normal(size=d), (q * np.geomspace(1.0, 20.0, d)) @ q.T))
    return out


def _conic_weights(estimates, criterion: str) -> np.ndarray:
    """Oracle: the CI weights from a semidefinite (trace) or log-det (det) program, by Clarabel."""
    infos = [np.linalg.inv(e.cov) for e in estimates]
    d = infos[0].shape[0]
    omega = cp.Variable(len(infos), nonneg=True)
    total = sum(omega[m] * infos[m] for m in range(len(infos)))
    if criterion == "trace":
        x = cp.Variable((d, d), symmetric=True)
        problem = cp.Problem(cp.Minimize(cp.trace(x)),
                             [cp.bmat([[x, np.eye(d)], [np.eye(d), total]]) >> 0, cp.sum(omega) == 1])
    else:
        problem = cp.Problem(cp.Maximize(cp.log_det(total)), [cp.sum(omega) == 1])
    problem.solve(solver=cp.CLARABEL)
    assert problem.status == "optimal"
    return np.clip(omega.value, 0.0, None) / np.clip(omega.value, 0.0, None).sum()


def _fused_cov(estimates, weights) -> np.ndarray:
    return np.linalg.inv(sum(w * np.linalg.inv(e.cov) for w, e in zip(weights, estimates)))


@pytest.mark.parametrize("solver", ["auto", "newton", "slsqp"])
@pytest.mark.parametrize("criterion", ["trace", "det"])
@pytest.mark.parametrize("seed, n, d", [(0, 3, 2), (1, 3, 3), (2, 4, 3), (3, 5, 4), (4, 6, 5)])
def test_solver_weights_agree_with_a_conic_program(solver, criterion, seed, n, d):
    estimates = _estimates(seed, n, d)
    fused = covariance_intersection(estimates, criterion, solver=solver)
    oracle = _conic_weights(estimates, criterion)
    value = criterion_value(fused.cov, criterion)
    oracle_value = criterion_value(_fused_cov(estimates, oracle), criterion)
    assert value <= oracle_value + SOLVER_TOL * abs(oracle_value)
    # at a smooth minimum the argmin is only as accurate as the square root of the objective
    np.testing.assert_allclose(fused.weights, oracle, atol=np.sqrt(SOLVER_TOL))
    scale = np.abs(fused.cov).max()
    np.testing.assert_allclose(fused.cov, _fused_cov(estimates, oracle), rtol=0.0,
                               atol=np.sqrt(SOLVER_TOL) * scale)


def test_the_cases_above_include_interior_optima():
    """Guards the comparison above against only ever seeing vertices."""
    weights = [covariance_intersection(_estimates(s, n, d), c).weights
               for s, n, d in [(0, 3, 2), (2, 4, 3), (4, 6, 5)] for c in ("trace", "det")]
    assert sum(int(np.sum(w > 0.0) >= 2) for w in weights) >= 4


@pytest.mark.parametrize("criterion", ["trace", "det"])
def test_weights_that_fail_the_optimality_condition_are_refused(criterion, monkeypatch):
    """A solver answer that is not optimal (here the uniform weights, on a problem whose optimum
    lies elsewhere) and no optimal vertex: the KKT certificate refuses the result."""
    estimates = _estimates(2, 4, 3)
    optimum = covariance_intersection(estimates, criterion).weights
    uniform = np.full(4, 0.25)
    assert np.abs(optimum - uniform).max() > 0.1 and np.all(optimum < 1.0)
    monkeypatch.setattr(ci, "_ci_weights_newton_batch",
                        lambda mats, weight, criterion: (np.tile(uniform, (len(mats), 1)), np.ones(len(mats), bool)))
    with pytest.raises(NumericalError, match="optimality condition"):
        covariance_intersection(estimates, criterion)


@pytest.mark.parametrize("criterion", ["trace", "det"])
def test_the_default_falls_back_on_slsqp_when_newton_does_not_converge(criterion, monkeypatch):
    estimates = _estimates(2, 4, 3)
    slsqp = covariance_intersection(estimates, criterion, solver="slsqp")
    monkeypatch.setattr(ci, "_ci_weights_newton_batch",
                        lambda mats, weight, criterion: (np.full(mats.shape[:2], np.nan), np.zeros(len(mats), bool)))
    fallen_back = covariance_intersection(estimates, criterion)
    # the same SLSQP on the information formed by the Newton route's factorisations: to its tolerance
    np.testing.assert_allclose(fallen_back.weights, slsqp.weights, rtol=SOLVER_TOL, atol=SOLVER_TOL)
    with pytest.raises(NumericalError, match="optimality condition"):  # "newton" alone has only the vertices
        covariance_intersection(estimates, criterion, solver="newton")


@pytest.mark.parametrize("criterion", ["trace", "det"])
def test_duplicated_estimates_share_the_optimal_weight(criterion):
    """Two copies of one estimate make the Hessian singular; the optimum of {a, a, b} is that of
    {a, b} with a's weight split between the copies in any way, the fused estimate unchanged."""
    a = Gaussian(np.zeros(2), np.diag([1.0, 4.0]))
    b = Gaussian(np.ones(2), np.diag([4.0, 1.0]))
    pair = covariance_intersection([a, b], criterion)
    triple = covariance_intersection([a, a, b], criterion)
    assert triple.weights is not None and pair.weights is not None
    np.testing.assert_allclose(triple.weights[0] + triple.weights[1], pair.weights[0], atol=np.sqrt(SOLVER_TOL))
    np.testing.assert_allclose(triple.cov, pair.cov, rtol=SOLVER_TOL)
    np.testing.assert_allclose(triple.mean, pair.mean, atol=SOLVER_TOL)


def test_default_n_sensor_ci_imports_neither_cvxpy_nor_scipy_optimize():
    """The default route for more than two estimates is Newton's method: neither cvxpy nor
    scipy.optimize (a quarter of a second of start-up each or more) is imported."""
    import subprocess
    import sys

    code = ("import sys, numpy as np\n"
            "from gpfverify.filters.records import Gaussian\n"
            "from gpfverify.fusion.ci import covariance_intersection\n"
            "e = [Gaussian(np.zeros(2), np.diag([1.0 + m, 2.0 - 0.5 * m])) for m in range(3)]\n"
            "covariance_intersection(e, 'det')\n"
            "print('cvxpy' in sys.modules, 'scipy.optimize' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False False"


@pytest.mark.parametrize("criterion", ["trace", "det"])
def test_newton_gradient_and_hessian_match_finite_differences(criterion):
    """Oracle for the derivatives Newton's method steps with: central differences of the
    criterion's value, step h, whose error is O(h²) times the third derivative (order one in the
    whitened coordinates) plus the value's rounding over h."""
    from gpfverify.fusion.estimates import checked_estimates, information_form

    info = information_form(checked_estimates(_estimates(3, 5, 4)))
    mats, weight = ci._whitened_information(info)
    w = np.array([0.1, 0.3, 0.2, 0.25, 0.15])
    _, grad, hess = ci._ci_objective(mats, weight, w, criterion)
    h = 1e-5
    eye = np.eye(w.size)

    def value(x):
        return ci._ci_objective_value(mats, weight, x, criterion)

    def grad_fd(x):
        return np.array([(value(x + h * e) - value(x - h * e)) / (2 * h) for e in eye])

    # truncation h² times the third derivative (order ten here) ~ 1e-9, rounding eps |f| / h ~ 1e-10
    np.testing.assert_allclose(grad, grad_fd(w), rtol=1e-7, atol=1e-7)
    hess_fd = np.array([(ci._ci_objective(mats, weight, w + h * e, criterion)[1]
                         - ci._ci_objective(mats, weight, w - h * e, criterion)[1]) / (2 * h) for e in eye])
    np.testing.assert_allclose(hess, hess_fd, rtol=1e-7, atol=1e-7)
