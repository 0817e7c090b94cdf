"""Covariance intersection (CI, Julier & Uhlmann 1997) and inverse covariance intersection
(ICI, Noack et al. 2017) with trace- or determinant-optimal weights.

CI: P⁻¹ = Σ_m ω_m P_m⁻¹, x = P Σ_m ω_m P_m⁻¹ x_m, ω on the simplex, minimising tr P or det P.
P is consistent (P ⪰ true error covariance) for every cross-correlation between the local errors.

* Two estimates (closed form up to a scalar root, :mod:`gpfverify.fusion.pairwise`): with
  Vᵀ P_1 V = I, Vᵀ P_2 V = diag(μ), the information is V diag(q) Vᵀ with q_i = ω + (1 − ω)/μ_i,
  so tr P = Σ c_i/q_i and log det P = const − Σ log q_i are convex in ω; the optimum is an endpoint
  exactly when the derivative keeps its sign on [0, 1], else the derivative's root.
* N estimates: the criterion is minimised over the simplex by Newton's method with an active set
  (:func:`_ci_weights_newton`; SLSQP from scipy when it does not converge, or on request), with
  the analytic gradient and Hessian (:func:`_ci_objective`), in coordinates whitened by the mean
  information (:func:`_whitened_information`), where with S' = Σ_m ω_m I'_m the objective is
  −log det S' (det) or tr(M S'⁻¹) (trace) and its gradient −tr(S'⁻¹ I'_m) or
  −tr(S'⁻¹ M S'⁻¹ I'_m). ``solver="cvxpy"`` solves the same problem as a conic program instead
  (DPP, built once per (N, D, criterion), Clarabel, SCS when Clarabel fails;
  :func:`_ci_weights_cvxpy`), trace: min tr M X s.t.
  [[X, I], [I, Σ ω_m I'_m]] ⪰ 0; det: max log det Σ ω_m I'_m. The weights are clipped to the
  simplex and compared with every vertex (single estimate), so an optimum at an endpoint is
  returned exactly. Both criteria are convex in ω, so the returned weights are certified by the
  KKT condition on the simplex, with S = Σ ω_m I_m and g_m = ∂(−criterion)/∂ω_m:

      det:   g_m = tr(S⁻¹ I_m)       ≤ Σ_k ω_k g_k = D
      trace: g_m = tr(S⁻¹ I_m S⁻¹)   ≤ Σ_k ω_k g_k = tr(S⁻¹)

  (every g_m ≤ their ω-weighted mean forces equality where ω_m > 0). :class:`SolverError` is
  raised when the best candidate's relative violation exceeds
  ``tolerances.kkt_reject_tol(cond S)`` (a solver-accuracy floor plus the rounding of the
  gradients at S's condition number).

ICI (two estimates): P⁻¹ = P_1⁻¹ + P_2⁻¹ − (ωP_1 + (1 − ω)P_2)⁻¹, x = P(K x_1 + L x_2) with
K = P_1⁻¹ − ω(ωP_1 + (1 − ω)P_2)⁻¹, L = P_2⁻¹ − (1 − ω)(ωP_1 + (1 − ω)P_2)⁻¹. In the joint basis
q_i = 1 + 1/μ_i − 1/t_i with t_i = ω + (1 − ω)μ_i (1/q_i and −log q_i are convex in ω). For N
estimates ICI is applied sequentially in the given order (the rule is defined for pairs).
"""

from __future__ import annotations

from functools import lru_cache
from collections.abc import Sequence

import numpy as np

from gpfverify.errors import InputError, NumericalError, SolverError
from gpfverify.filters.records import Gaussian
from gpfverify.fusion.estimates import (FusedEstimate, Information, checked_estimates,
                                        information_form, weighted_information_fusion, wrapped)
from gpfverify.fusion.quiet import solver_output_discarded
from gpfverify.fusion.pairwise import (criterion_derivative, joint_diagonalise,
                                       minimise_convex_on_unit_interval)
from gpfverify.linalg import Cholesky, cholesky, symmetrize
from gpfverify.tolerances import CI_NEWTON_JOIN_TOL, CI_NEWTON_MAX_STEPS, CI_NEWTON_TOL, SLSQP_FTOL, kkt_reject_tol

CRITERIA = ("trace", "det")
#: Armijo's sufficient-decrease fraction of the line search in :func:`_ci_weights_newton`
ARMIJO_FRACTION = 1e-4


def _check_criterion(criterion: str) -> None:
    if criterion not in CRITERIA:
        raise InputError(f"criterion must be one of {CRITERIA}, got {criterion!r}")


def _two_sensor_ci(first, second, criterion: str) -> FusedEstimate:
    jd = joint_diagonalise(first, second)
    mu = jd.ratios

    def q(w):
        return w + (1.0 - w) / mu

    omega = minimise_convex_on_unit_interval(
        criterion_derivative(criterion, jd.column_norms, q, lambda w: 1.0 - 1.0 / mu))
    return jd.fuse(q(omega), np.full_like(mu, omega), (1.0 - omega) / mu, [omega, 1.0 - omega])


def criterion_value(cov: np.ndarray, criterion: str) -> float:
    """tr P or log det P."""
    return float(np.trace(cov)) if criterion == "trace" else cholesky(cov, "fused cov").logdet()


@lru_cache(maxsize=32)
def _ci_problem(n: int, d: int, criterion: str, solver: str):
    """The DPP problem over ω for N whitened information matrices of size D and the trace's
    weight matrix M (see :func:`_ci_weights_cvxpy`), built once per solver (a problem is only ever
    solved by one solver) and re-solved without warm start, so a solve depends on its parameter
    values alone, not on what the process solved before. cvxpy is imported here, only when
    ``solver="cvxpy"`` is asked for (about a second and a half of start-up)."""
    import cvxpy as cp

    mats = [cp.Parameter((d, d), symmetric=True) for _ in range(n)]
    weight = cp.Parameter((d, d), PSD=True)
    omega = cp.Variable(n, nonneg=True)
    total = sum(omega[m] * mats[m] for m in range(n))
    if criterion == "trace":
        x = cp.Variable((d, d), symmetric=True)
        eye = np.eye(d)
        problem = cp.Problem(cp.Minimize(cp.trace(weight @ x)),
                             [cp.bmat([[x, eye], [eye, total]]) >> 0, cp.sum(omega) == 1])
    else:
        problem = cp.Problem(cp.Maximize(cp.log_det(total)), [cp.sum(omega) == 1])
    return problem, mats, weight, omega


def _whitened_information(info: Information) -> tuple[np.ndarray, np.ndarray]:
    """The information matrices in coordinates where their mean Ā = Σ_m I_m / N = L Lᵀ is the
    identity, I'_m = L⁻¹ I_m L⁻ᵀ, and the trace's weight matrix M = L⁻¹ L⁻ᵀ (normalised to tr M = D).

    With S' = Σ ω_m I'_m = L⁻¹ S L⁻ᵀ, log det S = log det S' + const and tr S⁻¹ ∝ tr(M S'⁻¹); ω is
    unchanged. Without it, components in different units (variances 30 and 0.05) leave the
    optimisers a badly scaled problem and answers that fail the KKT certificate."""
    d = info.matrices.shape[1]
    sym = 0.5 * (info.matrices + np.swapaxes(info.matrices, 1, 2))
    lower = cholesky(sym.mean(axis=0), "mean information", allow_jitter=False).factor
    half = np.linalg.solve(lower, np.eye(d))  # L⁻¹
    weight = symmetrize(half @ half.T)
    return symmetrize(half @ sym @ half.T), weight * (d / np.trace(weight))


def _weighted_information_factor(mats: np.ndarray, w: np.ndarray) -> Cholesky:
    """The Cholesky factor of S' = Σ_m ω_m I'_m (no jitter: S' is positive definite on the simplex)."""
    return cholesky(np.tensordot(w, mats, axes=1), "weighted information", allow_jitter=False)


def _ci_objective(mats: np.ndarray, weight: np.ndarray, w: np.ndarray, criterion: str
                  ) -> tuple[float, np.ndarray, np.ndarray]:
    """The criterion f(ω) in whitened coordinates (module docstring), its gradient and its Hessian.

    With S' = Σ_m ω_m I'_m and A_m = S'⁻¹ I'_m:
    det:   f = −log det S',  ∂f/∂ω_m = −tr A_m,             ∂²f/∂ω_m∂ω_k = tr(A_m A_k);
    trace: f = tr(M S'⁻¹),   ∂f/∂ω_m = −tr(B A_m) (B = S'⁻¹ M),  ∂²f/∂ω_m∂ω_k = tr(B A_m A_k) + tr(B A_k A_m).
    """
    factor = _weighted_information_factor(mats, w)
    inv = factor.inverse()
    solved = np.einsum("ij,mjk->mik", inv, mats)  # A_m
    if criterion == "det":
        return -factor.logdet(), -np.einsum("mii->m", solved), np.einsum("mij,kji->mk", solved, solved)
    b = inv @ weight
    pair = np.einsum("ij,mjk,lki->ml", b, solved, solved)
    return float(np.sum(weight * inv)), -np.einsum("ij,mji->m", b, solved), pair + pair.T


def _ci_weights_newton(info: Information, criterion: str) -> list[np.ndarray]:
    """Newton's method on the simplex with an active set, in whitened coordinates; [] when it
    does not converge in :data:`CI_NEWTON_MAX_STEPS` steps.

    On the support F (the weights kept positive) each step solves the equality-constrained Newton
    system [[H_FF, 1], [1ᵀ, 0]] [d_F; ν] = [−∇f_F; 0] (least squares: duplicated estimates make H
    singular) and moves along d by a backtracking (Armijo) line search; a step that would make a
    weight negative stops at the boundary and drops it from F. When the squared Newton decrement
    dᵀHd falls to :data:`CI_NEWTON_TOL` the weights are optimal on F, and the weight outside F
    whose partial derivative is below −ν by the most (the KKT multiplier of ω ≥ 0 negative) joins
    F; with none, the weights are the optimum. Each objective is convex on the simplex, so the
    answer is the one SLSQP or the conic program approaches, in a handful of steps, and without
    scipy.optimize's import (about a quarter of a second of every ``check``'s start-up)."""
    mats, weight = _whitened_information(info)
    n = mats.shape[0]
    w = np.full(n, 1.0 / n)
    free = np.ones(n, dtype=bool)
    for _ in range(CI_NEWTON_MAX_STEPS):
        f, grad, hess = _ci_objective(mats, weight, w, criterion)
        support = np.flatnonzero(free)
        k = support.size
        system = np.zeros((k + 1, k + 1))
        system[:k, :k] = hess[np.ix_(support, support)]
        system[:k, k] = system[k, :k] = 1.0
        solution = np.linalg.lstsq(system, np.concatenate([-grad[support], [0.0]]), rcond=None)[0]
        step = np.zeros(n)
        step[support] = solution[:k]
        slope = float(grad @ step)  # ≤ 0: H is positive semidefinite
        if float(step @ hess @ step) <= CI_NEWTON_TOL * max(1.0, abs(f)) or slope >= 0.0:
            nu = solution[k]
            outside = np.flatnonzero(~free)
            slack = grad[outside] + nu  # the multipliers of ω_m ≥ 0 outside F
            if outside.size == 0 or slack.min() >= -CI_NEWTON_JOIN_TOL * max(1.0, abs(nu)):
                return [w]
            free[outside[np.argmin(slack)]] = True
            continue
        shrinking = step < 0.0
        reach = np.full(n, np.inf)
        reach[shrinking] = -w[shrinking] / step[shrinking]  # where each falling weight reaches 0
        t = min(1.0, float(reach.min()))
        while t >= CI_NEWTON_TOL and (_ci_objective_value(mats, weight, np.clip(w + t * step, 0.0, None), criterion)
                                      > f + ARMIJO_FRACTION * t * slope):
            t *= 0.5
        if t < CI_NEWTON_TOL <= reach.min():
            return [w]  # no descent left at the rounding level: the certificate decides
        blocking = reach <= t
        w = np.clip(w + t * step, 0.0, None)
        w[blocking] = 0.0
        free &= ~blocking
        w /= w.sum()
    return []


def _ci_objective_value(mats: np.ndarray, weight: np.ndarray, w: np.ndarray, criterion: str) -> float:
    """f(ω) alone (see :func:`_ci_objective`)."""
    factor = _weighted_information_factor(mats, w)
    return -factor.logdet() if criterion == "det" else float(np.sum(weight * factor.inverse()))


def _ci_weights_slsqp(info: Information, criterion: str) -> list[np.ndarray]:
    """SLSQP's weights from the uniform start (module docstring); [] when it fails."""
    from scipy.optimize import minimize  # 0.3 s to import; the Newton route needs none

    mats, weight = _whitened_information(info)
    n = mats.shape[0]

    def objective(w: np.ndarray) -> tuple[float, np.ndarray]:
        return _ci_objective(mats, weight, w, criterion)[:2]

    try:
        result = minimize(objective, np.full(n, 1.0 / n), jac=True, method="SLSQP",
                          bounds=[(0.0, 1.0)] * n,
                          constraints=[{"type": "eq", "fun": lambda w: w.sum() - 1.0,
                                        "jac": lambda w: np.ones(n)}],
                          options={"ftol": SLSQP_FTOL, "maxiter": 100 * n})
    except NumericalError:  # a trial point outside the simplex left S' singular
        return []
    w = np.clip(result.x, 0.0, None)
    return [w / w.sum()] if result.success and w.sum() > 0.0 else []


def _ci_weights_cvxpy(info: Information, criterion: str) -> list[np.ndarray]:
    """Solver weights: Clarabel's, or SCS's when Clarabel fails; [] when both fail. The solver
    sees the problem in the coordinates of :func:`_whitened_information`."""
    import cvxpy as cp

    n, d = info.matrices.shape[:2]
    whitened, weight = _whitened_information(info)
    for solver in (cp.CLARABEL, cp.SCS):
        problem, mats, weight_param, omega = _ci_problem(n, d, criterion, solver)
        for param, mat in zip(mats, whitened):
            param.value = mat
        weight_param.value = weight
        try:
            with solver_output_discarded():
                problem.solve(solver=solver, warm_start=False)
        except cp.SolverError:
            continue
        if problem.status in ("optimal", "optimal_inaccurate") and omega.value is not None:
            w = np.clip(omega.value, 0.0, None)
            return [w / w.sum()]
    return []


def kkt_violation(info: Information, weights: np.ndarray, criterion: str) -> float:
    """Relative violation max_m g_m / (Σ_k ω_k g_k) − 1 of the optimality condition on the simplex
    (module docstring); ≤ 0 up to rounding at the optimum."""
    total = symmetrize(np.tensordot(weights, info.matrices, axes=1))
    inv = cholesky(total, "weighted information", allow_jitter=False).inverse()
    if criterion == "det":
        grads = np.einsum("ij,mji->m", inv, info.matrices)
    else:
        grads = np.einsum("ij,mjk,ki->m", inv, info.matrices, inv)
    return float(grads.max() / (weights @ grads) - 1.0)


def covariance_intersection(estimates: Sequence, criterion: str = "trace", solver: str = "auto",
                            circular_state: Sequence[int] = ()) -> FusedEstimate:
    """CI of N local estimates with trace- or det-optimal weights (see module docstring).

    ``solver``: "auto" (closed form for two, Newton's method for more), "closed-form" (two only),
    "newton", "slsqp" or "cvxpy" (any number); ``circular_state``: the angle state components.
    """
    return wrapped(_covariance_intersection(estimates, criterion, solver, circular_state), circular_state)


SOLVERS = ("auto", "closed-form", "newton", "slsqp", "cvxpy")


def _covariance_intersection(estimates: Sequence, criterion: str, solver: str,
                             circular_state: Sequence[int]) -> FusedEstimate:
    _check_criterion(criterion)
    checked = checked_estimates(estimates, circular_state=circular_state)
    if solver not in SOLVERS:
        raise InputError(f"solver must be one of {', '.join(SOLVERS)}, got {solver!r}")
    if len(checked) == 1:
        return FusedEstimate(checked[0].mean, checked[0].cov, np.ones(1))
    if solver == "closed-form" and len(checked) != 2:
        raise InputError("the closed-form CI weights need exactly two estimates")
    if solver in ("auto", "closed-form") and len(checked) == 2:
        return _two_sensor_ci(checked[0], checked[1], criterion)
    info = information_form(checked)
    if solver == "cvxpy":
        solved = _ci_weights_cvxpy(info, criterion)
    elif solver == "slsqp":
        solved = _ci_weights_slsqp(info, criterion)
    else:  # "auto" falls back on SLSQP should Newton's method not converge
        solved = _ci_weights_newton(info, criterion)
        if not solved and solver == "auto":
            solved = _ci_weights_slsqp(info, criterion)
    fused = [weighted_information_fusion(info, w) for w in solved + list(np.eye(len(checked)))]
    best = min(fused, key=lambda f: criterion_value(f.cov, criterion))
    if best.weights is None:  # weighted_information_fusion always records its weights
        raise SolverError("CI: the fused estimate carries no weights")
    violation = kkt_violation(info, best.weights, criterion)
    tol = kkt_reject_tol(np.linalg.cond(np.tensordot(best.weights, info.matrices, axes=1)))
    if violation > tol:
        raise SolverError(f"CI weights not optimal: the best candidate violates the {criterion} "
                          f"optimality condition by {violation:.3g} (relative; accepted {tol:.3g})")
    return best


def _two_sensor_ici(first, second, criterion: str) -> FusedEstimate:
    jd = joint_diagonalise(first, second)
    mu = jd.ratios

    def t(w):
        return w + (1.0 - w) * mu

    def q(w):
        return 1.0 + 1.0 / mu - 1.0 / t(w)

    omega = minimise_convex_on_unit_interval(
        criterion_derivative(criterion, jd.column_norms, q, lambda w: (1.0 - mu) / t(w) ** 2))
    tw = t(omega)
    return jd.fuse(q(omega), 1.0 - omega / tw, 1.0 / mu - (1.0 - omega) / tw, [omega, 1.0 - omega])


def inverse_covariance_intersection(estimates: Sequence, criterion: str = "trace",
                                    circular_state: Sequence[int] = ()) -> FusedEstimate:
    """ICI of N local estimates, pairwise in order; ``weights`` holds each pair's ω (N − 1,);
    ``circular_state``: the angle state components."""
    _check_criterion(criterion)
    checked = checked_estimates(estimates, circular_state=circular_state)
    fused: Gaussian | FusedEstimate = checked[0]
    omegas = []
    for nxt in checked[1:]:
        step = _two_sensor_ici(fused, nxt, criterion)
        assert step.weights is not None  # the pairwise ICI always records [ω, 1 − ω]
        omegas.append(step.weights[0])
        fused = step
    weights = np.array(omegas) if omegas else None
    return wrapped(FusedEstimate(fused.mean, fused.cov, weights), circular_state)
