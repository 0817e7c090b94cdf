"""Covariance intersection (CI, Julier & Uhlmann 1997) and inverse covariance intersection
(ICI, Noack et al. 2017) with trace- or determinant-optimal weights.

CI: P⁻¹ = Σ_m ω_m P_m⁻¹, x = P Σ_m ω_m P_m⁻¹ x_m, ω on the simplex, minimising tr P or det P.
P is consistent (P ⪰ true error covariance) for every cross-correlation between the local errors.

* Two estimates (closed form up to a scalar root, :mod:`gpfverify.fusion.pairwise`): with
  Vᵀ P_1 V = I, Vᵀ P_2 V = diag(μ), the information is V diag(q) Vᵀ with q_i = ω + (1 − ω)/μ_i,
  so tr P = Σ c_i/q_i and log det P = const − Σ log q_i are convex in ω; the optimum is an endpoint
  exactly when the derivative keeps its sign on [0, 1], else the derivative's root.
* N estimates: the criterion is minimised over the simplex by Newton's method with an active set
  (:func:`_ci_weights_newton_batch`; SLSQP from scipy when it does not converge, or on request), with
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

from dataclasses import dataclass
from functools import lru_cache
from collections.abc import Sequence

import numpy as np

from gpfverify.errors import InputError, NumericalError, SolverError
from gpfverify.filters.records import Gaussian
from gpfverify.fusion.estimates import (FusedEstimate, Information, checked_estimates, on_one_branch_arrays,
                                        information_form, weighted_information_fusion, wrapped)
from gpfverify.fusion.quiet import solver_output_discarded
from gpfverify.fusion.pairwise import (criterion_derivative, joint_diagonalise,
                                       minimise_convex_on_unit_interval)
from gpfverify.linalg import cholesky, inverse_lower_factors, symmetrize
from gpfverify.angles import wrap_components
from gpfverify.tolerances import (CI_NEWTON_JOIN_TOL, CI_NEWTON_MAX_STEPS, CI_NEWTON_TOL, SLSQP_FTOL, kkt_reject_tol,
                                   kkt_reject_tol_batch)
from gpfverify.validate import as_indices

CRITERIA = ("trace", "det")
#: Armijo's sufficient-decrease fraction of the line search in :func:`_ci_weights_newton_batch`
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
    """:func:`_whitened_information_batch` of one fusion's information matrices (N, D, D)."""
    mats, weight = _whitened_information_batch(info.matrices[None])
    return mats[0], weight[0]


def _whitened_information_batch(matrices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The information matrices (B, N, D, D) of B fusions in coordinates where their mean
    Ā = Σ_m I_m / N = L Lᵀ is the identity, I'_m = L⁻¹ I_m L⁻ᵀ, and the trace's weight matrix
    M = L⁻¹ L⁻ᵀ (normalised to tr M = D).

    With S' = Σ ω_m I'_m = L⁻¹ S L⁻ᵀ, log det S = log det S' + const and tr S⁻¹ ∝ tr(M S'⁻¹); ω is
    unchanged. Without it, components in different units (variances 30 and 0.05) leave the
    optimisers a badly scaled problem and answers that fail the KKT certificate."""
    d = matrices.shape[-1]
    sym = 0.5 * (matrices + np.swapaxes(matrices, -1, -2))
    half = _lower_inverse(sym.mean(axis=-3), "mean information")  # L⁻¹, (B, D, D)
    weight = symmetrize(half @ np.swapaxes(half, -1, -2))  # L⁻¹L⁻ᵀ, M up to its normalisation
    whitened = half[:, None] @ sym @ np.swapaxes(half, -1, -2)[:, None]
    whitened = 0.5 * (whitened + np.swapaxes(whitened, -1, -2))
    trace = np.trace(weight, axis1=-2, axis2=-1)
    return whitened, weight * (d / trace)[:, None, None]


def _lower_inverse(spd: np.ndarray, name: str) -> np.ndarray:
    """L⁻¹ of the lower Cholesky factor of every matrix of a stack (..., D, D) (no jitter:
    :class:`NumericalError` naming ``name`` when one is not positive definite;
    :func:`gpfverify.linalg.inverse_lower_factors`)."""
    return inverse_lower_factors(spd, name)


def _weighted(mats: np.ndarray, w: np.ndarray) -> np.ndarray:
    """S' = Σ_m ω_m I'_m for weights (..., N) and matrices (..., N, D, D): one vector–matrix product
    per fusion over the flattened matrices (BLAS), the sum in the estimates' order."""
    d = mats.shape[-1]
    flat = mats.reshape(mats.shape[:-2] + (d * d,))
    return np.matmul(w[..., None, :], flat)[..., 0, :].reshape(mats.shape[:-3] + (d, d))


def _whitened_by(mats: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(L_S⁻¹ (..., D, D), C_m = L_S⁻¹ I'_m L_S⁻ᵀ (..., N, D, D)) with S' = L_S L_Sᵀ = Σ ω_m I'_m
    (positive definite on the simplex: :class:`NumericalError` otherwise)."""
    inverse = _lower_inverse(_weighted(mats, w), "weighted information")
    return inverse, inverse[..., None, :, :] @ mats @ np.swapaxes(inverse, -1, -2)[..., None, :, :]


def _frobenius(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """⟨A_m, B⟩ = Σ_ij (A_m)_ij B_ij for matrices a (..., N, D, D) and one b (..., D, D): (..., N),
    one matrix–vector product of the flattened matrices (BLAS)."""
    d = a.shape[-1]
    flat_a = a.reshape(a.shape[:-2] + (d * d,))
    return (flat_a @ b.reshape(b.shape[:-2] + (d * d, 1)))[..., 0]


def _ci_objective(mats: np.ndarray, weight: np.ndarray, w: np.ndarray, criterion: str
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The criterion f(ω) in whitened coordinates (module docstring), its gradient and its Hessian,
    for fusions stacked on leading axes (mats (..., N, D, D), weight (..., D, D), w (..., N)).

    With S' = Σ_m ω_m I'_m = L Lᵀ, C_m = L⁻¹ I'_m L⁻ᵀ and W = L⁻¹ M L⁻ᵀ (every product a matrix
    product, O(N D³), and every sum over matrix entries one BLAS matrix–vector product, O(N² D²)):
    det:   f = −log det S' = −2 Σ log L_ii,   ∂f/∂ω_m = −tr C_m,    ∂²f/∂ω_m∂ω_k = ⟨C_m, C_k⟩;
    trace: f = tr(M S'⁻¹) = tr W,   ∂f/∂ω_m = −⟨W, C_m⟩,   ∂²f/∂ω_m∂ω_k = ⟨C_m W, C_k⟩ + ⟨C_k W, C_m⟩
    (tr(S'⁻¹ M S'⁻¹ I'_m) = tr(W C_m) and tr(S'⁻¹M S'⁻¹ I'_m S'⁻¹ I'_k) = tr(W C_m C_k))."""
    inverse, whitened = _whitened_by(mats, w)
    d = mats.shape[-1]
    flat = whitened.reshape(whitened.shape[:-2] + (d * d,))
    if criterion == "det":
        f = 2.0 * np.sum(np.log(np.diagonal(inverse, axis1=-2, axis2=-1)), axis=-1)  # −log det S' = log det L⁻²
        grad = -np.trace(whitened, axis1=-2, axis2=-1)
        return f, grad, flat @ np.swapaxes(flat, -1, -2)
    scaled = inverse @ weight @ np.swapaxes(inverse, -1, -2)  # W
    carried = (whitened @ scaled[..., None, :, :]).reshape(flat.shape)  # C_m W
    pair = carried @ np.swapaxes(flat, -1, -2)
    return (np.trace(scaled, axis1=-2, axis2=-1), -_frobenius(whitened, scaled), pair + np.swapaxes(pair, -1, -2))


def _ci_objective_value(mats: np.ndarray, weight: np.ndarray, w: np.ndarray, criterion: str) -> np.ndarray:
    """f(ω) alone (see :func:`_ci_objective`), for fusions stacked on leading axes."""
    inverse = _lower_inverse(_weighted(mats, w), "weighted information")
    if criterion == "det":
        return 2.0 * np.sum(np.log(np.diagonal(inverse, axis1=-2, axis2=-1)), axis=-1)
    return np.trace(inverse @ weight @ np.swapaxes(inverse, -1, -2), axis1=-2, axis2=-1)


def _newton_systems(hess: np.ndarray, grad: np.ndarray, free: np.ndarray) -> np.ndarray:
    """The equality-constrained Newton systems [[H_FF, 1], [1ᵀ, 0]] [d_F; ν] = [−∇f_F; 0] of B
    fusions padded to N + 1 unknowns (a weight outside the support F has the row d_m = 0), solved in
    the least-squares sense (duplicated estimates make H singular) by the pseudo-inverse: (B, N + 1)."""
    batch, n = grad.shape
    both = free[:, :, None] & free[:, None, :]
    system = np.zeros((batch, n + 1, n + 1))
    system[:, :n, :n] = np.where(both, hess, 0.0) + np.where(free, 0.0, 1.0)[:, :, None] * np.eye(n)
    system[:, :n, n] = system[:, n, :n] = free
    rhs = np.concatenate([np.where(free, -grad, 0.0), np.zeros((batch, 1))], axis=1)
    solution = (np.linalg.pinv(system) @ rhs[..., None])[..., 0]
    solution[:, :n] = np.where(free, solution[:, :n], 0.0)
    return solution


def _ci_weights_newton_batch(mats: np.ndarray, weight: np.ndarray, criterion: str) -> tuple[np.ndarray, np.ndarray]:
    """Newton's method on the simplex with an active set, in whitened coordinates, for B fusions at
    once — each with its own iterates, support, line search and stop, as if alone: a fusion's
    arithmetic does not depend on the others (every operation is per fusion). Returns the weights
    (B, N) and whether each converged in :data:`CI_NEWTON_MAX_STEPS` steps.

    On the support F (the weights kept positive) each step solves the equality-constrained Newton
    system (:func:`_newton_systems`) and moves along d by a backtracking (Armijo) line search; a step
    that would make a weight negative stops at the boundary and drops it from F. When the squared
    Newton decrement dᵀHd falls to :data:`CI_NEWTON_TOL` the weights are optimal on F, and the
    weight outside F whose partial derivative is below −ν by the most (the KKT multiplier of ω ≥ 0
    negative) joins F; with none, the weights are the optimum. Each objective is convex on the
    simplex, so the answer is the one SLSQP or the conic program approaches, in a handful of steps,
    and without scipy.optimize's import (about a quarter of a second of every ``check``'s start-up)."""
    batch, n = mats.shape[:2]
    w = np.full((batch, n), 1.0 / n)
    free = np.ones((batch, n), dtype=bool)
    running = np.ones(batch, dtype=bool)
    for _ in range(CI_NEWTON_MAX_STEPS):
        at = np.flatnonzero(running)
        if not at.size:
            break
        f, grad, hess = _ci_objective(mats[at], weight[at], w[at], criterion)
        solution = _newton_systems(hess, grad, free[at])
        step, nu = solution[:, :n], solution[:, n]
        slope = np.sum(grad * step, axis=1)  # ≤ 0: H is positive semidefinite
        decrement = np.einsum("bi,bij,bj->b", step, hess, step)
        optimal = (decrement <= CI_NEWTON_TOL * np.maximum(1.0, np.abs(f))) | (slope >= 0.0)
        for j in np.flatnonzero(optimal).tolist():
            run = at[j]
            outside = np.flatnonzero(~free[run])
            slack = grad[j, outside] + nu[j]  # the multipliers of ω_m ≥ 0 outside F
            if outside.size == 0 or slack.min() >= -CI_NEWTON_JOIN_TOL * max(1.0, abs(nu[j])):
                running[run] = False
            else:
                free[run, outside[np.argmin(slack)]] = True
        moving = np.flatnonzero(~optimal)
        if not moving.size:
            continue
        runs = at[moving]
        step, f, slope = step[moving], f[moving], slope[moving]
        reach = np.where(step < 0.0, -w[runs] / np.where(step < 0.0, step, -1.0), np.inf)
        nearest = reach.min(axis=1)
        t = np.minimum(1.0, nearest)
        searching = t >= CI_NEWTON_TOL
        while searching.any():  # halve t, run by run, until the Armijo condition holds
            look = np.flatnonzero(searching)
            trial = np.clip(w[runs[look]] + t[look, None] * step[look], 0.0, None)
            value = _ci_objective_value(mats[runs[look]], weight[runs[look]], trial, criterion)
            fails = value > f[look] + ARMIJO_FRACTION * t[look] * slope[look]
            t[look[fails]] *= 0.5
            searching[look[~fails]] = False
            searching &= t >= CI_NEWTON_TOL
        stalled = (t < CI_NEWTON_TOL) & (CI_NEWTON_TOL <= nearest)
        running[runs[stalled]] = False  # no descent left at the rounding level: the certificate decides
        go = np.flatnonzero(~stalled)
        runs, step, t, reach = runs[go], step[go], t[go], reach[go]
        blocking = reach <= t[:, None]
        moved = np.clip(w[runs] + t[:, None] * step, 0.0, None)
        moved[blocking] = 0.0
        free[runs] &= ~blocking
        w[runs] = moved / moved.sum(axis=1, keepdims=True)
    return w, ~running


def _ci_weights_slsqp(info: Information, criterion: str) -> list[np.ndarray]:
    """SLSQP's weights from the uniform start (module docstring); [] when it fails."""
    from scipy.optimize import minimize  # 0.3 s to import; the Newton route needs none

    mats, weight = _whitened_information(info)
    n = mats.shape[0]

    def objective(w: np.ndarray) -> tuple[float, np.ndarray]:
        value, grad, _ = _ci_objective(mats, weight, w, criterion)
        return float(value), grad

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
    return float(_kkt_violations(info.matrices[None], np.asarray(weights, dtype=float)[None], criterion)[0])


def _kkt_violations(matrices: np.ndarray, weights: np.ndarray, criterion: str) -> np.ndarray:
    """:func:`kkt_violation` of B fusions (matrices (B, N, D, D), weights (B, N)): with
    S = Σ ω_m I_m, g_m = ⟨S⁻¹, I_m⟩ (det) or ⟨S⁻¹S⁻¹, I_m⟩ (trace), each a matrix–vector product."""
    inverse = _lower_inverse(symmetrize(_weighted(matrices, weights)), "weighted information")
    inv = np.swapaxes(inverse, -1, -2) @ inverse  # S⁻¹
    grads = _frobenius(matrices, inv if criterion == "det" else inv @ inv)
    return grads.max(axis=-1) / np.sum(weights * grads, axis=-1) - 1.0


def covariance_intersection(estimates: Sequence, criterion: str = "trace", solver: str = "auto",
                            circular_state: Sequence[int] = ()) -> FusedEstimate:
    """CI of N local estimates with trace- or det-optimal weights (see module docstring).

    ``solver``: "auto" (closed form for two, Newton's method for more), "closed-form" (two only),
    "newton", "slsqp" or "cvxpy" (any number); ``circular_state``: the angle state components.
    """
    return wrapped(_covariance_intersection(estimates, criterion, solver, circular_state), circular_state)


SOLVERS = ("auto", "closed-form", "newton", "slsqp", "cvxpy")


def _checked_choice(criterion: str, solver: str, estimates: int) -> None:
    _check_criterion(criterion)
    if solver not in SOLVERS:
        raise InputError(f"solver must be one of {', '.join(SOLVERS)}, got {solver!r}")
    if solver == "closed-form" and estimates != 2:
        raise InputError("the closed-form CI weights need exactly two estimates")


def _newton_route(solver: str, estimates: int) -> bool:
    """Whether ``solver`` on ``estimates`` estimates takes Newton's method (batched over fusions)."""
    return estimates > 2 and solver in ("auto", "newton") or (estimates == 2 and solver == "newton")


def _covariance_intersection(estimates: Sequence, criterion: str, solver: str,
                             circular_state: Sequence[int]) -> FusedEstimate:
    checked = checked_estimates(estimates, circular_state=circular_state)
    _checked_choice(criterion, solver, len(checked))
    if len(checked) == 1:
        return FusedEstimate(checked[0].mean, checked[0].cov, np.ones(1))
    if solver in ("auto", "closed-form") and len(checked) == 2:
        return _two_sensor_ci(checked[0], checked[1], criterion)
    if _newton_route(solver, len(checked)):  # one fusion: a batch of one, the same route
        from gpfverify.fusion.batched import information_batch

        fused = _newton_ci(*information_batch(np.array([e.mean for e in checked])[None],
                                              np.array([e.cov for e in checked])[None]), criterion, solver)
        if fused.failures[0] is not None:
            raise SolverError(fused.failures[0])
        return FusedEstimate(fused.mean[0], fused.cov[0], fused.weights[0])
    info = information_form(checked)
    solved = _ci_weights_cvxpy(info, criterion) if solver == "cvxpy" else _ci_weights_slsqp(info, criterion)
    fused_all = [weighted_information_fusion(info, w) for w in solved + list(np.eye(len(checked)))]
    best = min(fused_all, key=lambda f: criterion_value(f.cov, criterion))
    if best.weights is None:  # weighted_information_fusion always records its weights
        raise SolverError("CI: the fused estimate carries no weights")
    violation = kkt_violation(info, best.weights, criterion)
    tol = kkt_reject_tol(np.linalg.cond(np.tensordot(best.weights, info.matrices, axes=1)))
    if violation > tol:
        raise SolverError(_not_optimal(criterion, violation, tol))
    return best


def _not_optimal(criterion: str, violation: float, tol: float) -> str:
    return (f"CI weights not optimal: the best candidate violates the {criterion} optimality condition by "
            f"{violation:.3g} (relative; accepted {tol:.3g})")


@dataclass(frozen=True)
class CiBatch:
    """CI of B fusions: ``mean`` (B, D), ``cov`` (B, D, D), ``weights`` (B, N), and per fusion why it
    could not be fused (``failures[b]``, None when it was; its rows are then NaN)."""

    mean: np.ndarray
    cov: np.ndarray
    weights: np.ndarray
    failures: tuple[str | None, ...]


def covariance_intersection_batch(means: np.ndarray, covs: np.ndarray, criterion: str = "trace",
                                  solver: str = "auto", circular_state: Sequence[int] = ()) -> CiBatch:
    """:func:`covariance_intersection` of B fusions of N estimates (means (B, N, D), covs (B, N, D, D),
    positive definite: a filter's outputs, not checked again). Newton's method runs on all of them
    at once, each with its own iterates (:func:`_ci_weights_newton_batch`), and the candidates and
    the certificate are evaluated over the fusions; a single fusion is a batch of one (the same
    routine, the same numbers). Two estimates with the closed form, and the other solvers, fuse
    one by one. A fusion that fails is reported in ``failures``, the others are kept."""
    from gpfverify.fusion.batched import information_batch

    runs, n, dim = means.shape
    _checked_choice(criterion, solver, n)
    angles = as_indices(circular_state, dim, "circular_state")
    means = on_one_branch_arrays(means, angles)
    if _newton_route(solver, n):
        fused = _newton_ci(*information_batch(means, covs), criterion, solver)
        return CiBatch(wrap_components(fused.mean, angles), fused.cov, fused.weights, fused.failures)
    out = CiBatch(np.full((runs, dim), np.nan), np.full((runs, dim, dim), np.nan), np.full((runs, n), np.nan),
                  tuple(None for _ in range(runs)))
    failures = list(out.failures)
    for b in range(runs):
        try:
            one = covariance_intersection([Gaussian(m, c) for m, c in zip(means[b], covs[b])], criterion, solver,
                                          angles)
        except (NumericalError, SolverError) as exc:
            failures[b] = str(exc)
            continue
        out.mean[b], out.cov[b], out.weights[b] = one.mean, one.cov, one.weights
    return CiBatch(out.mean, out.cov, out.weights, tuple(failures))


def _newton_ci(matrices: np.ndarray, vectors: np.ndarray, criterion: str, solver: str) -> CiBatch:
    """The Newton route of CI for B fusions' information (matrices (B, N, D, D), vectors (B, N, D)):
    the weights (SLSQP for a fusion where Newton does not converge and ``solver`` is "auto"), the
    best of them and of the vertices by the criterion, and the KKT certificate of the best."""
    from gpfverify.fusion.batched import weighted_information_batch

    runs, n, dim = vectors.shape
    failures: list[str | None] = [None] * runs
    try:
        mats, weight = _whitened_information_batch(matrices)
        solved, converged = _ci_weights_newton_batch(mats, weight, criterion)
    except NumericalError as exc:  # some fusion's information is singular: each alone says which
        if runs > 1:
            return _each_alone(matrices, vectors, criterion, solver)
        return CiBatch(np.full((1, dim), np.nan), np.full((1, dim, dim), np.nan), np.full((1, n), np.nan), (str(exc),))
    for b in np.flatnonzero(~converged).tolist():
        fallback = _ci_weights_slsqp(Information(matrices[b], vectors[b]), criterion) if solver == "auto" else []
        converged[b] = bool(fallback)
        solved[b] = fallback[0] if fallback else np.nan
    candidates = np.concatenate([solved[:, None], np.broadcast_to(np.eye(n), (runs, n, n))], axis=1)  # (B, N+1, N)
    usable = np.concatenate([converged[:, None], np.ones((runs, n), dtype=bool)], axis=1)
    candidates = np.where(usable[..., None], candidates, np.eye(n)[0])  # any vertex in place of a failed solve
    # each candidate's criterion from the factor of its information S = Σ ω_m I_m, S⁻¹ = L⁻ᵀL⁻¹:
    # tr S⁻¹ = ‖L⁻¹‖²_F, log det S⁻¹ = 2 Σ log (L⁻¹)_ii; the fused estimate of the best alone
    totals = np.matmul(candidates, matrices.reshape(runs, n, dim * dim)).reshape(runs, n + 1, dim, dim)
    half = _lower_inverse(totals, "fused information")
    if criterion == "trace":
        value = np.sum(half * half, axis=(-2, -1))
    else:
        value = 2.0 * np.sum(np.log(np.diagonal(half, axis1=-2, axis2=-1)), axis=-1)
    best = np.argmin(np.where(usable, value, np.inf), axis=1)
    pick = np.arange(runs), best
    weights = candidates[pick]
    fused = weighted_information_batch(matrices, vectors, weights)
    violation = _kkt_violations(matrices, weights, criterion)
    tol = kkt_reject_tol_batch(_spd_condition(_weighted(matrices, weights)))
    mean, cov = fused.mean, fused.cov
    for b in np.flatnonzero(violation > tol).tolist():
        failures[b] = _not_optimal(criterion, float(violation[b]), float(tol[b]))
        mean[b], cov[b], weights[b] = np.nan, np.nan, np.nan
    return CiBatch(mean, cov, weights, tuple(failures))


def _spd_condition(spd: np.ndarray) -> np.ndarray:
    """The 2-norm condition number of every symmetric positive definite matrix of a stack, λ_max/λ_min
    from its eigenvalues (its singular values: ``np.linalg.cond`` without the SVD)."""
    lam = np.abs(np.linalg.eigvalsh(symmetrize(spd)))
    with np.errstate(divide="ignore"):
        return lam.max(axis=-1) / lam.min(axis=-1)


def _each_alone(matrices: np.ndarray, vectors: np.ndarray, criterion: str, solver: str) -> CiBatch:
    """:func:`_newton_ci` of each fusion alone, a failure kept with its own message."""
    parts = [_newton_ci(matrices[b:b + 1], vectors[b:b + 1], criterion, solver) for b in range(len(matrices))]
    return CiBatch(np.concatenate([p.mean for p in parts]), np.concatenate([p.cov for p in parts]),
                   np.concatenate([p.weights for p in parts]), tuple(p.failures[0] for p in parts))


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
