"""The RCC dual over the N ellipsoid weights, by a barrier method with Newton steps, for B problems
at once (:mod:`gpfverify.fusion.rcc_ci`, route "newton").

Problem. For each problem, matrices A_m (N, D, D) positive definite, vectors b_m (N, D), numbers
d_m (N) and a positive definite metric matrix M (D, D):

    min over α ≥ 0 of  g(α) = b_αᵀA_α⁻¹b_α − d_α   subject to  S(α) = A_α − M ⪰ 0,

A_α = Σα_mA_m, b_α = Σα_mb_m, d_α = Σα_md_m: the Lagrange dual of the relaxed Chebyshev centre
(the derivation is in :mod:`gpfverify.fusion.rcc_ci`'s docstring). g is convex (the matrix-fractional
function b_αᵀA_α⁻¹b_α of an affine map), with, for y = A_α⁻¹b_α and r_m = A_my − b_m,

    ∂g/∂α_m = 2b_mᵀy − yᵀA_my − d_m = −f_m(−y),        ∂²g/∂α_m∂α_k = 2 r_mᵀA_α⁻¹r_k,

f_m the m-th ellipsoid's function: the gradient is minus the ellipsoids' values at the centre
x = −y. The barrier ψ(α) = −Σ log α_m − log det S(α) has ∂ψ/∂α_m = −1/α_m − tr(S⁻¹A_m) and
∂²ψ/∂α_m∂α_k = δ_mk/α_m² + tr(S⁻¹A_mS⁻¹A_k). With S = L Lᵀ and A_m = R_mR_mᵀ (Cholesky, R_m once per
problem), Y_m = L⁻¹R_m and B_m = Y_mY_mᵀ = L⁻¹A_mL⁻ᵀ: tr(S⁻¹A_m) = ‖Y_m‖²_F and
tr(S⁻¹A_mS⁻¹A_k) = ⟨B_m, B_k⟩. One iteration costs two Cholesky factorisations (A_α, S), one
triangular solve with N·D right-hand sides and N products Y_mY_mᵀ — O(N D³) — and an N × N
Newton system; no inverse is formed.

Method. The central path α(μ) = argmin g + μψ (t = 1/μ) is followed from a strictly feasible
start: Newton steps on t·g + ψ until the squared Newton decrement is below :data:`CENTRED`
(a backtracking line search on the barrier function, the Cholesky attempt of S deciding
feasibility; within the quadratic region the full feasible step), then a predictor step to a
larger t along the path's tangent, dα/dμ = t²H⁻¹∇g (H the Newton Hessian at the centred point):
near the optimum the path is nearly straight in μ, so t grows by a factor κ that adapts to the
corrector steps the last prediction needed. It stops at μ = :data:`FINAL_MU` · max(g, 1) (relative
to the objective) with the decrement below :data:`FINISHED`. At a centred point, Z = μS⁻¹ and
x = −y are the primal's Δ − xxᵀ and centre, feasible, and the duality gap is μ(N + D).

Emptiness. The primal's objective tr(M(Δ − xxᵀ)) is nonnegative wherever it is feasible, so a
feasible α with g(α) < 0 proves the ellipsoids do not intersect (weak duality); the dual is then
unbounded and the barrier finds such an α. Such a problem is reported "empty"; one whose iterations
do not converge (or whose S stops factoring before the end: a problem whose answer is below the
rounding of its data) "failed".

Every problem has its own iterates, line search, t and stop, as if alone: a problem's arithmetic
does not depend on the others (every operation is per problem, and the kernels are chosen by D
alone), so a batch gives each problem the bits it gets alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from gpfverify.linalg import lower_solve, symmetrize

#: Squared Newton decrement at which a point counts as centred (a predictor step may follow).
CENTRED = 1e-2
#: Squared Newton decrement below which the full feasible Newton step is taken without a line search.
QUADRATIC = 0.25
#: Squared Newton decrement at the final t at which the iteration stops (the distance to the centre
#: in the local norm, whose unit there is of the order of μ: far below the answer's rounding).
FINISHED = 1e-4
#: The final barrier parameter μ relative to max(g, 1): α(μ) − α* = O(μ) on the central path.
FINAL_MU = 1e-11
#: The factor by which t grows at the first prediction; later ones aim at PREDICTED_DECREMENT.
FIRST_KAPPA = 10.0
#: The squared decrement a prediction aims to leave at the predicted point.
PREDICTED_DECREMENT = 0.25
#: The largest factor by which one prediction increases t.
MAX_KAPPA = 1e8
#: Armijo fraction of the line search.
ARMIJO = 1e-4
#: Fraction of the way to α = 0 that a step may go.
TO_BOUNDARY = 0.99
#: Iterations (Newton evaluations) allowed per problem.
MAX_ITERATIONS = 200
#: Halvings of a step allowed in a line search.
MAX_HALVINGS = 60
#: D at or below which triangular solves of a batch are stacked LU solves (numpy), above which
#: BLAS trsm per problem (the choice depends on D alone, so a problem's bits do not depend on its batch).
STACKED_DIM = 24


@dataclass(frozen=True)
class DualSolution:
    """``alpha`` (B, N), ``value`` g(α) (B,), ``centre`` y = A_α⁻¹b_α (B, D) (the primal centre is
    −y), ``status`` (B,) of "optimal", "empty" or "failed", ``iterations`` (B,), ``mu`` (B,) the
    final barrier parameter (the duality gap at a centred point is μ(N + D))."""

    alpha: np.ndarray
    value: np.ndarray
    centre: np.ndarray
    status: np.ndarray
    iterations: np.ndarray
    mu: np.ndarray


def cholesky_where(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lower Cholesky factors, whether each succeeded) of a stack (K, D, D) of symmetric matrices
    (a failed one's factor is NaN): the attempt that decides positive definiteness. Up to
    :data:`STACKED_DIM`, numpy's stacked factorisation, one matrix at a time when some fails (the
    same routine: the same bits); above, LAPACK ``potrf`` per matrix."""
    if s.shape[-1] > STACKED_DIM:  # LAPACK potrf per matrix (numpy's wrapper copies and transposes)
        out, ok = np.empty_like(s), np.ones(len(s), dtype=bool)
        for i, matrix in enumerate(s):
            out[i], info = sla.lapack.dpotrf(matrix, lower=1, clean=1)
            ok[i] = info == 0
        out[~ok] = np.nan
        return out, ok & np.isfinite(out).all(axis=(-2, -1))
    try:
        return np.linalg.cholesky(s), np.ones(len(s), dtype=bool)
    except np.linalg.LinAlgError:
        pass
    out, ok = np.full_like(s, np.nan), np.ones(len(s), dtype=bool)
    for i, matrix in enumerate(s):
        try:
            out[i] = np.linalg.cholesky(matrix[None])[0]
        except np.linalg.LinAlgError:
            ok[i] = False
    ok &= np.isfinite(out).all(axis=(-2, -1))
    return out, ok


def lower_solve_stack(factor: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """L⁻¹ R for lower-triangular factors (K, D, D) and right-hand sides (K, D, P): stacked (numpy)
    up to :data:`STACKED_DIM`, BLAS trsm per problem above."""
    if factor.shape[-1] <= STACKED_DIM:
        return np.linalg.solve(factor, rhs)
    return np.stack([lower_solve(f, r) for f, r in zip(factor, rhs)])


def _weighted(mats: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Σ_m α_m A_m for alpha (K, N) and mats (K, N, D, D): one vector–matrix product per problem
    (exactly symmetric when the A_m are: entries ij and ji are summed alike)."""
    d = mats.shape[-1]
    flat = mats.reshape(mats.shape[:-2] + (d * d,))
    return np.matmul(alpha[:, None, :], flat)[:, 0, :].reshape(mats.shape[:-3] + (d, d))


@dataclass(frozen=True)
class _Values:
    """Factors and values at α (K problems): ``ok`` where α > 0 and S ≻ 0 (A_α then too)."""

    ok: np.ndarray
    value: np.ndarray  # g
    phi_barrier: np.ndarray  # ψ
    a_factor: np.ndarray
    s_factor: np.ndarray
    z: np.ndarray  # F⁻¹ b_α


def _values(a: np.ndarray, b: np.ndarray, d: np.ndarray, metric: np.ndarray, alpha: np.ndarray) -> _Values:
    """g and ψ at α (cheap: the two Cholesky factorisations), for K problems."""
    positive = np.all(alpha > 0.0, axis=1)
    total = _weighted(a, alpha)
    s_factor, s_ok = cholesky_where(total - metric)
    a_factor, a_ok = cholesky_where(total)
    ok = positive & s_ok & a_ok
    b_alpha = np.matmul(alpha[:, None, :], b)[:, 0, :]
    with np.errstate(invalid="ignore", divide="ignore"):
        z = lower_solve_stack(np.where(ok[:, None, None], a_factor, np.eye(a.shape[-1])), b_alpha[..., None])[..., 0]
        value = np.sum(z * z, axis=1) - np.sum(alpha * d, axis=1)
        logdet = 2.0 * np.sum(np.log(np.diagonal(s_factor, axis1=-2, axis2=-1)), axis=1)
        psi = -np.sum(np.log(alpha), axis=1) - logdet
    return _Values(ok, np.where(ok, value, np.nan), np.where(ok, psi, np.nan), a_factor, s_factor, z)


def _row(v: _Values, j: int) -> _Values:
    """Problem j of ``v`` (a stack of one)."""
    return _Values(*(getattr(v, f)[j:j + 1] for f in ("ok", "value", "phi_barrier", "a_factor", "s_factor", "z")))


def _values_at(a, b, d, metric, alpha, at: np.ndarray, cache: dict[int, _Values]) -> _Values:
    """:func:`_values` of problems ``at`` at their current α: a step's own values where it left
    them in ``cache`` (taken out), computed for the others (the same routine: the same bits)."""
    missing = [i for i in at.tolist() if i not in cache]
    if missing:
        fresh = _values(a[missing], b[missing], d[missing], metric[missing], alpha[missing])
        for j, i in enumerate(missing):
            cache[i] = _row(fresh, j)
    rows = [cache.pop(i) for i in at.tolist()]
    return _Values(*(np.concatenate([getattr(r, f) for r in rows])
                     for f in ("ok", "value", "phi_barrier", "a_factor", "s_factor", "z")))


def _derivatives(a: np.ndarray, stacked: np.ndarray, b: np.ndarray, d: np.ndarray, alpha: np.ndarray, v: _Values
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(∇g, ∇²g, ∇ψ, ∇²ψ, y) at feasible α (module docstring), for K problems."""
    k, n, dim = b.shape
    upper = np.swapaxes(v.a_factor, -1, -2)
    y = upper_solve_stack(upper, v.z)
    ay = np.matmul(a, y[:, None, :, None])[..., 0]  # A_m y (K, N, D)
    r = ay - b
    grad_g = np.sum(b * y[:, None, :], axis=2) - np.sum(r * y[:, None, :], axis=2) - d
    zr = lower_solve_stack(v.a_factor, np.swapaxes(r, -1, -2))  # F⁻¹ r (K, D, N)
    hess_g = 2.0 * np.matmul(np.swapaxes(zr, -1, -2), zr)
    half = lower_solve_stack(v.s_factor, stacked).reshape(k, dim, n, dim)
    half = np.swapaxes(half, 1, 2)  # Y_m (K, N, D, D)
    whitened = np.matmul(half, np.swapaxes(half, -1, -2))  # B_m
    flat = whitened.reshape(k, n, dim * dim)
    grad_psi = -1.0 / alpha - np.sum(half * half, axis=(-2, -1))
    hess_psi = np.matmul(flat, np.swapaxes(flat, -1, -2)) + np.eye(n) / alpha[:, :, None] ** 2
    return grad_g, hess_g, grad_psi, symmetrize(hess_psi), y


def upper_solve_stack(upper: np.ndarray, z: np.ndarray) -> np.ndarray:
    """U⁻¹ z for upper-triangular U = Fᵀ (K, D, D) and z (K, D)."""
    if upper.shape[-1] <= STACKED_DIM:
        return np.linalg.solve(upper, z[..., None])[..., 0]
    return np.stack([lower_solve(np.ascontiguousarray(np.swapaxes(u, -1, -2)), zz, transpose=True)
                     for u, zz in zip(upper, z)])


def _newton(hess: np.ndarray, grad: np.ndarray) -> np.ndarray:
    """−H⁻¹ ∇ for K N × N systems (positive definite: the barrier's Hessian is; one that rounding
    made singular, each alone, by the pseudo-inverse, the others by the same stacked solve)."""
    try:
        return -np.linalg.solve(hess, grad[..., None])[..., 0]
    except np.linalg.LinAlgError:
        out = np.empty_like(grad)
        for i in range(len(grad)):
            try:
                out[i] = -np.linalg.solve(hess[i:i + 1], grad[i:i + 1, :, None])[0, :, 0]
            except np.linalg.LinAlgError:
                out[i] = -np.linalg.pinv(hess[i]) @ grad[i]
        return out


def _feasible_start(a: np.ndarray, metric: np.ndarray) -> np.ndarray:
    """α = τ/N · 1 with Σ_m A_m / N = I (the data are whitened so) and τ the first of 2, 8, 32, …
    with τI − M ≻ 0 (a Cholesky attempt)."""
    k, n, dim = a.shape[:3]
    tau = np.full(k, 2.0)
    pending = np.arange(k)
    while pending.size:
        _, ok = cholesky_where(tau[pending, None, None] * np.eye(dim) - metric[pending])
        pending = pending[~ok]
        tau[pending] *= 4.0
    return np.repeat(tau[:, None] / n, n, axis=1)


def solve_dual(a: np.ndarray, b: np.ndarray, d: np.ndarray, metric: np.ndarray) -> DualSolution:
    """The dual (module docstring) of B problems: a (B, N, D, D) positive definite with mean the
    identity (whitened), b (B, N, D), d (B, N), metric (B, D, D) positive definite."""
    batch, n, dim = b.shape
    a = symmetrize(a)
    metric = symmetrize(metric)
    roots, roots_ok = cholesky_where(a.reshape(batch * n, dim, dim))
    # [R_1 … R_N] (B, D, N·D), each problem's block Fortran-ordered (BLAS reads it without a copy)
    stacked = np.swapaxes(np.ascontiguousarray(np.swapaxes(roots.reshape(batch, n, dim, dim), 2, 3))
                          .reshape(batch, n * dim, dim), 1, 2)
    cache: dict[int, _Values] = {}  # each problem's values at its current α, when a step computed them
    alpha = _feasible_start(a, metric)
    t = np.zeros(batch)
    kappa = np.full(batch, FIRST_KAPPA)
    predicted = np.full(batch, np.nan)  # whether a prediction led to the current point
    status = np.where(roots_ok.reshape(batch, n).all(axis=1), "running", "failed").astype(object)
    iterations = np.zeros(batch, dtype=int)
    value, mu = np.full(batch, np.nan), np.full(batch, np.nan)
    centre = np.full((batch, dim), np.nan)
    while True:
        at = np.flatnonzero(status == "running")
        if not at.size:
            break
        iterations[at] += 1
        over = iterations[at] > MAX_ITERATIONS
        status[at[over]] = "failed"
        at = at[~over]
        if not at.size:
            break
        cur = _values_at(a, b, d, metric, alpha, at, cache)
        lost = ~cur.ok  # a point that stopped factoring (rounding at the end of the path)
        status[at[lost]] = "failed"
        keep = ~lost
        at = at[keep]
        cur = _Values(*(getattr(cur, f)[keep] for f in ("ok", "value", "phi_barrier", "a_factor", "s_factor", "z")))
        if not at.size:
            continue
        grad_g, hess_g, grad_psi, hess_psi, y = _derivatives(a[at], stacked[at], b[at], d[at], alpha[at], cur)
        value[at], centre[at] = cur.value, y
        empty = cur.value < 0.0
        status[at[empty]] = "empty"
        first = t[at] == 0.0  # t from the start's gradients: the t at which the start is most central
        if first.any():
            f = np.flatnonzero(first)
            hinv_g = -_newton(hess_psi[f], grad_g[f])
            t[at[f]] = np.maximum(-np.sum(grad_psi[f] * hinv_g, axis=1) / np.sum(grad_g[f] * hinv_g, axis=1), 1e-12)
        tt = t[at]
        final_t = 1.0 / (FINAL_MU * np.maximum(np.abs(cur.value), 1.0))
        hess = hess_psi + tt[:, None, None] * hess_g
        grad = grad_psi + tt[:, None] * grad_g
        step = _newton(hess, grad)
        decrement = -np.sum(grad * step, axis=1)
        status[at[~np.isfinite(decrement) & ~empty]] = "failed"
        decrement = np.where(np.isfinite(decrement), decrement, np.inf)
        empty |= status[at] == "failed"  # neither moves on
        mu[at] = 1.0 / tt
        done = ~empty & (tt >= final_t) & (decrement <= FINISHED)
        status[at[done]] = "optimal"
        centred = ~empty & ~done & (decrement <= CENTRED) & (tt < final_t)
        move = ~empty & ~done
        # the decrement a prediction left tells how far the next may go: κ is scaled by
        # √(PREDICTED_DECREMENT / decrement found), at most ×100 and at least ÷10 at a time
        after = ~np.isnan(predicted[at])
        ratio = np.sqrt(PREDICTED_DECREMENT / np.maximum(decrement[after], 1e-300))
        kappa[at[after]] = np.clip(kappa[at[after]] * np.clip(ratio, 0.1, 100.0), 2.0, MAX_KAPPA)
        predicted[at] = np.nan
        pred = np.flatnonzero(centred)
        if pred.size:
            runs = at[pred]
            tangent = -tt[pred, None] * _newton(hess[pred], grad_g[pred])
            trying = np.ones(pred.size, dtype=bool)
            target = np.minimum(tt[pred] * kappa[runs], final_t[pred])
            while trying.any():
                look = np.flatnonzero(trying)
                trial = alpha[runs[look]] - (1.0 - tt[pred[look]] / target[look])[:, None] * tangent[look]
                v = _values(a[runs[look]], b[runs[look]], d[runs[look]], metric[runs[look]], trial)
                ok = v.ok
                for j in np.flatnonzero(ok).tolist():
                    cache[int(runs[look[j]])] = _row(v, j)
                last = kappa[runs[look]] <= 2.0  # no feasible prediction even to 2t: t doubled, α kept
                good = look[ok]
                alpha[runs[good]] = trial[ok]
                predicted[runs[good]] = 1.0
                t[runs[look[ok | last]]] = target[look[ok | last]]
                trying[look[ok | last]] = False
                bad = look[~ok & ~last]
                kappa[runs[bad]] = np.maximum(kappa[runs[bad]] / 10.0, 2.0)
                target[bad] = np.minimum(tt[pred[bad]] * kappa[runs[bad]], final_t[pred[bad]])
            move &= ~centred
        go = np.flatnonzero(move)
        if go.size:
            _line_search(a, b, d, metric, alpha, t, at[go], step[go], grad[go], decrement[go], cur, go, cache)
    return DualSolution(alpha, value, centre, status.astype(str), iterations, mu)


def _line_search(a, b, d, metric, alpha, t, runs, step, grad, decrement, cur: _Values, rows,
                 cache: dict[int, _Values]) -> None:
    """Damped Newton steps for ``runs`` (in place on alpha): the largest step ≤ 1 keeping α at
    :data:`TO_BOUNDARY` of the way to 0, halved until S factors and — outside the quadratic region —
    until the barrier function decreases by the Armijo fraction."""
    reach = np.where(step < 0.0, -alpha[runs] / np.where(step < 0.0, step, -1.0), np.inf).min(axis=1)
    s = np.minimum(1.0, TO_BOUNDARY * reach)
    phi0 = t[runs] * cur.value[rows] + cur.phi_barrier[rows]
    slope = np.sum(grad * step, axis=1)
    loose = decrement <= QUADRATIC
    searching = np.ones(runs.size, dtype=bool)
    for _ in range(MAX_HALVINGS):
        look = np.flatnonzero(searching)
        if not look.size:
            break
        trial = alpha[runs[look]] + s[look, None] * step[look]
        v = _values(a[runs[look]], b[runs[look]], d[runs[look]], metric[runs[look]], trial)
        phi = t[runs[look]] * v.value + v.phi_barrier
        accept = v.ok & (loose[look] | (phi <= phi0[look] + ARMIJO * s[look] * slope[look]))
        alpha[runs[look[accept]]] = trial[accept]
        for j in np.flatnonzero(accept).tolist():
            cache[int(runs[look[j]])] = _row(v, j)
        searching[look[accept]] = False
        s[look[~accept]] *= 0.5
