"""CI with more than two estimates in components of very different units (variances 30 and 0.05):
the solvers (Newton's method, SLSQP and the conic program) work in coordinates whitened by the mean information, and its weights are certified
and optimal against an independent search of the simplex; determinant-optimal weights do not
depend on the units."""

import numpy as np
import pytest

from gpfverify.filters.records import Gaussian
from gpfverify.fusion.ci import covariance_intersection
from gpfverify.tolerances import SOLVER_TOL

SCALES = np.sqrt(np.array([30.0, 30.0, 1.0, 0.05]))


def _estimates(units=np.ones(4)) -> list[Gaussian]:
    rng = np.random.default_rng(7)
    out = []
    for _ in range(3):
        a = np.eye(4) + 0.4 * rng.normal(size=(4, 4))
        cov = (SCALES[:, None] * (a @ a.T) * SCALES[None, :])
        out.append(Gaussian(units * rng.normal(size=4), units[:, None] * cov * units[None, :]))
    return out


def _grid_criterion(estimates, criterion: str) -> float:
    """Oracle: the least criterion over a grid of step 1/100 on the simplex, by numpy."""
    steps = np.linspace(0.0, 1.0, 101)
    w1, w2 = np.meshgrid(steps, steps, indexing="ij")
    keep = w1 + w2 <= 1.0 + 1e-12
    weights = np.stack([w1[keep], w2[keep], np.clip(1.0 - w1[keep] - w2[keep], 0.0, None)], axis=1)
    infos = np.stack([np.linalg.inv(e.cov) for e in estimates])
    total = np.einsum("gm,mij->gij", weights, infos)
    if criterion == "trace":
        return float(np.trace(np.linalg.inv(total), axis1=1, axis2=2).min())
    return float((-np.linalg.slogdet(total)[1]).min())


@pytest.mark.parametrize("solver", ["newton", "slsqp", "cvxpy"])
@pytest.mark.parametrize("criterion", ["trace", "det"])
def test_three_estimates_in_mixed_units_are_fused_optimally(criterion, solver):
    estimates = _estimates()
    fused = covariance_intersection(estimates, criterion, solver=solver)
    value = np.trace(fused.cov) if criterion == "trace" else np.linalg.slogdet(fused.cov)[1]
    best_on_grid = _grid_criterion(estimates, criterion)
    assert value <= best_on_grid + SOLVER_TOL * abs(best_on_grid)


@pytest.mark.parametrize("solver", ["newton", "slsqp", "cvxpy"])
def test_determinant_optimal_weights_do_not_depend_on_units(solver):
    units = np.array([1e3, 1.0, 1e-3, 1.0])
    plain = covariance_intersection(_estimates(), "det", solver=solver)
    moved = covariance_intersection(_estimates(units), "det", solver=solver)
    assert plain.weights is not None and moved.weights is not None
    assert np.allclose(plain.weights, moved.weights, rtol=0.0, atol=SOLVER_TOL)
