"""Relaxed-Chebyshev-centre covariance intersection (RCC-CI; Wang & Li, IEEE TAES 48(1) 2012),
as an SDP in cvxpy. The original paper's text was not available; this is the formulation of
SPEC §3, after Eldar, Beck & Teboulle (2008), "A minimax Chebyshev estimator for bounded error
estimation" (the relaxed Chebyshev centre, RCC).

Set. Each local estimate (x_m, P_m) defines the ellipsoid E_m = {x : (x − x_m)ᵀP_m⁻¹(x − x_m) ≤ c},
written f_m(x) = xᵀA_m x + 2b_mᵀx + d_m ≤ 0 with A_m = P_m⁻¹, b_m = −P_m⁻¹x_m,
d_m = x_mᵀP_m⁻¹x_m − c. The fused estimate is a centre of ∩_m E_m.

Primal (RCC). max_{Δ, x} tr(Δ) − ‖x‖²  s.t.  tr(A_mΔ) + 2b_mᵀx + d_m ≤ 0 (m = 1..N),
[[Δ, x], [xᵀ, 1]] ⪰ 0. Its maximiser x* is the RCC; it lies in ∩E_m because xᵀA_m x ≤ tr(A_mΔ).

Dual. min_{α ≥ 0} b_αᵀA_α⁻¹b_α − d_α  s.t.  A_α ⪰ I, with A_α = Σα_mA_m, b_α = Σα_m b_m,
d_α = Σα_m d_m (Lagrangian of the primal; strong duality when ∩E_m has an interior point). The RCC
is x = −A_α⁻¹b_α = (Σα_mP_m⁻¹)⁻¹Σα_mP_m⁻¹x_m — a CI-form estimate — and the fused bound is
P = (Σω_mP_m⁻¹)⁻¹ with ω = α/Σα (SPEC §3). The α are read from the primal's constraint duals;
:func:`rcc_ci_dual` solves the dual SDP explicitly (Schur complement for b_αᵀA_α⁻¹b_α ≤ t) so the two
can be cross-checked. The returned ``mean`` is the CI-form one; ``primal_mean`` is x*.

Routes. ``route="conic"`` (the default, the reference) solves the primal SDP above with Clarabel:
each interior-point iteration factors a system over the (D + 1) × (D + 1) PSD cone's entries,
O(D⁶). ``route="newton"`` solves the dual over the N weights instead
(:mod:`gpfverify.fusion.rcc_dual`). Derivation, from the primal as :func:`_primal_problem` states it
(objective tr(MΔ) − xᵀMx, M = I in the Euclidean metric, diag(W) in the scaled one): with α_m ≥ 0
the multipliers of the ellipsoid constraints and Δ = xxᵀ + Z, Z ⪰ 0 (the PSD constraint by its
Schur complement), the Lagrangian is tr((M − A_α)Z) − xᵀA_αx − 2b_αᵀx − d_α; its supremum over
Z ⪰ 0 is finite (zero) iff A_α ⪰ M, and over x it is attained at x = −A_α⁻¹b_α, giving

    min over α ≥ 0 of  b_αᵀA_α⁻¹b_α − d_α   subject to  Σ_m α_m A_m ⪰ M

(Eldar, Beck & Teboulle 2008, the RCC's dual; SPEC §3), whose minimiser gives the same α, the
CI-form estimate and the bound as above, and x* = −A_α⁻¹b_α. It is solved in the same normalised
coordinates (the same data as the conic route, whitened by the mean of the A_m with triangular
solves) by a barrier method with Newton steps over the N weights, O(N D³) per iteration with
Cholesky factorisations and triangular solves only; g(α) < 0 at a feasible α certifies that the
ellipsoids do not intersect (the primal's objective is nonnegative wherever it is feasible). The
two routes agree to the conic solution's accuracy (tests/test_fusion_rcc_newton.py; measured about
1e-5 relative on the weights, the mean and the covariance, the differences being Clarabel's: against
Clarabel run to a 1e-13 gap they were 1e-8 – 1e-10 in most drawn cases). A Newton solve that does
not converge is done again by the conic route.

Size c. A documented parameter; the default is the χ²_D quantile at :data:`DEFAULT_CONFIDENCE`,
i.e. each E_m is the 99 % confidence region of its local estimate. If the ellipsoids do not
intersect (c < c_min, the smallest size at which they do) the solver reports infeasibility and
``on_empty`` decides: "error" raises :class:`~gpfverify.errors.SolverError` stating c_min, "enlarge"
uses c = :data:`EMPTY_GROWTH` · c_min and records it.

Numerics. The RCC is equivariant under translations and isotropic scalings, so the problem is
solved in coordinates ξ = (x − x̄)/s with x̄ the mean of the x_m and s² = c · max_m λ_max(P_m): every
ellipsoid then has semi-axes ≤ 1. It is not equivariant under other linear maps (the Euclidean
‖x‖² is part of the estimator), so ellipsoids in mixed units — metres and radians, semi-axes a
million apart — stay badly scaled; the primal is therefore solved after the change of variables
ξ = Tξ', Δ = TΔ'Tᵀ with T = L⁻ᵀ, L Lᵀ the mean of the normalised A_m: the same problem (the
PSD constraint is congruent, the ellipsoid constraints are the same functions, so their multipliers
are unchanged), whose constraints TᵀA_mT are of order one, the units' spread moving into the
objective tr(TᵀT Δ') − ‖Tξ'‖². The problems are DPP (parameters A_m, b_m, d_m), built once per
(N, D, solver) and re-solved with new values; Clarabel by default, SCS when Clarabel fails. For
Clarabel the problem is compiled once into its conic data as an affine map of the parameters and
each solve calls Clarabel directly (:mod:`gpfverify.fusion.conic`: the same data and results as
cvxpy's route, bit for bit, without its per-solve overhead). Every solve is a function of its
inputs alone (a new solver object each time, no warm start from the previous solve), so a Monte
Carlo run gives the same bits whichever runs its process solved before (CONTRACT.md, Provenance).

Metric. The Chebyshev centre minimises the worst-case error in a norm of the state. The paper's
(SPEC §3) is the Euclidean ‖x‖² above (``metric="euclidean"``, the default): it adds the squared
errors of components in different units, so the estimate changes with the units of the state
components. ``metric="scaled"`` measures each component in its own scale, the square root of
the diagonal of the local estimates' mean information W = mean of the A_m: the error norm
ξᵀ diag(W) ξ, the primal max tr(diag(W) Δ) − ξᵀ diag(W) ξ, i.e. the Euclidean problem in the
coordinates u = diag(W)^½ ξ. A change of units multiplies each component and scales diag(W) to
match, so the centre, the multipliers α and the CI-form estimate move only with the units
(tests/test_rescaled_systems.py). (The full W would be unit-free too, but degenerate: tr(WΔ) is
then the mean of the constraints' quadratic terms, and the relaxation returns equal weights, the
convex combination's mean, whatever the ellipsoids.) The dual in that metric is the Euclidean dual
of the ellipsoids in u.

Failures. A size at which the ellipsoids do not intersect, and a solve that ends otherwise than
optimal (an iteration or time limit, a numerical failure), are reported with the size tried and the
smallest size at which the ellipsoids intersect, c_min (:func:`smallest_intersecting_size`).

Angles. Angle state components (``circular_state``) are put on one branch around the circular mean
of the local angles before the ellipsoids are formed (the RCC is translation equivariant, so the
fused angle is a weighted circular mean), and the fused angles of ``mean`` and ``primal_mean``
are wrapped to (−π, π] (:mod:`gpfverify.fusion.estimates`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from collections.abc import Sequence

import cvxpy as cp
import numpy as np
from scipy.stats import chi2

from gpfverify.angles import difference, wrap_components
from gpfverify.errors import InputError, SolverError
from gpfverify.filters.records import Gaussian
from gpfverify.fusion.conic import ClarabelProgram, ConicSolution, Parametrised, solve_with_cvxpy
from gpfverify.fusion.estimates import (FusedEstimate, checked_estimates, information_form,
                                        weighted_information_fusion)
from gpfverify.fusion.pairwise import joint_diagonalise, minimise_convex_on_unit_interval
from gpfverify.fusion.rcc_dual import DualSolution, lower_solve_stack, solve_dual, upper_solve_stack
from gpfverify.validate import as_positive

#: Confidence level whose χ²_D quantile is the default ellipsoid size c.
DEFAULT_CONFIDENCE = 0.99
#: The metrics in which the Chebyshev centre's error is measured (module docstring, "Metric").
METRICS = ("euclidean", "scaled")
#: With on_empty="enlarge", the size used is this multiple of the smallest intersecting size.
EMPTY_GROWTH = 2.0
SOLVED = ("optimal", "optimal_inaccurate")
#: The routes to the RCC: "conic", the semidefinite primal by Clarabel (SCS when Clarabel fails),
#: the default and the reference, and "newton", the dual over the N weights by a barrier method
#: (module docstring, "Routes").
ROUTES = ("newton", "conic")


@lru_cache(maxsize=64)
def default_size(dim: int) -> float:
    """χ²_D quantile at :data:`DEFAULT_CONFIDENCE` (cached: scipy's ppf costs as much as a solve)."""
    return float(chi2.ppf(DEFAULT_CONFIDENCE, dim))


def _size_words(c: float, given: bool, dim: int) -> str:
    """'size c = 15.1 (the default, the 0.99 quantile of χ²_5)' or 'size c = 3'."""
    return f"size c = {c:.6g}" + ("" if given else
                                  f" (the default, the {DEFAULT_CONFIDENCE:g} quantile of chi-square with {dim} "
                                  "degrees of freedom)")


@dataclass(frozen=True)
class RccCiResult:
    """``mean`` (CI form from the duals), ``cov`` = (Σω_mP_m⁻¹)⁻¹, ``weights`` ω (N,), ``alpha``
    (N,) dual multipliers (normalised problem), ``c`` the size used, ``primal_mean`` x*,
    ``primal_value`` = max tr(Δ) − ‖x‖² in original units (relaxed squared radius),
    ``enlarged`` whether on_empty="enlarge" changed c, ``circular_state`` the angle state
    components (wrapped in both means)."""

    mean: np.ndarray
    cov: np.ndarray
    weights: np.ndarray
    alpha: np.ndarray
    c: float
    primal_mean: np.ndarray
    primal_value: float
    enlarged: bool = False
    circular_state: tuple[int, ...] = ()

    @property
    def estimate(self) -> FusedEstimate:
        return FusedEstimate(self.mean, self.cov, self.weights)

    @property
    def discrepancy(self) -> float:
        """‖x* − x_CI-form‖ (angles on the circle): primal against dual centre (zero up to solver
        accuracy)."""
        return float(np.linalg.norm(difference(self.primal_mean, self.mean, self.circular_state)))


@dataclass(frozen=True)
class _Normalised:
    """The normalised problem of B runs (a leading run axis on every field, B = 1 for one fusion):
    ``centre`` x̄ (B, D), ``scale`` s (B,), ``A`` (B, N, D, D), ``b`` (B, N, D), ``d`` (B, N) and the
    primal's change of variables ``T`` (B, D, D), ξ = T ξ' (module docstring)."""

    centre: np.ndarray
    scale: np.ndarray
    A: np.ndarray
    b: np.ndarray
    d: np.ndarray
    T: np.ndarray

    def whitened(self) -> tuple[np.ndarray, np.ndarray]:
        """(TᵀA_mT (B, N, D, D), Tᵀb_m (B, N, D)): the ellipsoids in the coordinates ξ' = T⁻¹ξ (also
        of one fusion's problem, without the run axis)."""
        a = np.einsum("...ji,...mjk,...kl->...mil", self.T, self.A, self.T)
        return 0.5 * (a + np.swapaxes(a, -1, -2)), self.b @ self.T

    def metric_scale(self, metric: str) -> np.ndarray:
        """(B, D): the scale of each component in the error norm — 1 for the Euclidean metric, the
        square root of the diagonal of the mean of the A_m for the scaled one."""
        if metric == "scaled":
            return np.sqrt(np.diagonal(self.A.mean(axis=-3), axis1=-2, axis2=-1))
        return np.ones(self.A.shape[:-3] + self.A.shape[-1:])

    def primal_values(self, metric: str = "euclidean") -> list[np.ndarray]:
        """The primal's parameters, each with the leading run axis: TᵀA_mT, Tᵀb_m, d_m and the
        objective's K T and M = TᵀK²T, K = diag(:meth:`metric_scale`) (module docstring)."""
        n = self.A.shape[1]
        a, tb = self.whitened()
        scaled = self.metric_scale(metric)[..., :, None] * self.T
        objective = [scaled, np.swapaxes(scaled, -1, -2) @ scaled]
        return [*(a[:, m] for m in range(n)), *(tb[:, m] for m in range(n)), *(self.d[:, m] for m in range(n)),
                *objective]

    def one(self) -> _Normalised:
        """The first run's problem without the run axis (for one fusion)."""
        return _Normalised(*(getattr(self, f)[0] for f in ("centre", "scale", "A", "b", "d", "T")))


def _checked_size(c) -> float:
    """The ellipsoid size ``c``: a positive normal float (a subnormal c has lost its precision and
    its square root's reciprocal overflows the normalised problem); InputError otherwise."""
    c = float(as_positive(c, "c", shape=()))
    if c < np.finfo(float).tiny:
        raise InputError(f"c must be at least {np.finfo(float).tiny:.3g} (a normal floating-point number), "
                         f"got {c:.3g}")
    return c


def _normalised_data(means: np.ndarray, covs: np.ndarray, matrices: np.ndarray, c: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(x̄ (B, D), s (B,), A_m (B, N, D, D), b_m (B, N, D), d_m (B, N)) of the normalised problem
    (module docstring, "Numerics") of B runs' N estimates: means (B, N, D), covs (B, N, D, D), their
    information matrices (B, N, D, D) and sizes c (B,). One fusion is a run of one: one routine, so
    that a batch's problems are formed exactly as each alone would be; both routes' data."""
    centre = means.mean(axis=1)
    scale = np.sqrt(c * np.linalg.eigvalsh(covs)[..., -1].max(axis=1))
    a = matrices * (scale ** 2 / c)[:, None, None, None]
    xi = (means - centre[:, None, :]) / scale[:, None, None]
    b = -np.einsum("bmij,bmj->bmi", a, xi)
    d = np.einsum("bmi,bmij,bmj->bm", xi, a, xi) - 1.0
    return centre, scale, 0.5 * (a + np.swapaxes(a, -1, -2)), b, d


def _normalise(means: np.ndarray, covs: np.ndarray, matrices: np.ndarray, c: np.ndarray) -> _Normalised:
    """The normalised problem (:func:`_normalised_data`) with the primal's change of variables."""
    centre, scale, a, b, d = _normalised_data(means, covs, matrices, c)
    # T = L⁻ᵀ with L Lᵀ the mean of the A_m: TᵀA_mT are O(1) for ellipsoids of similar shape
    lower = np.linalg.cholesky(a.mean(axis=1))
    whitening = np.swapaxes(np.linalg.solve(lower, np.broadcast_to(np.eye(a.shape[-1]), lower.shape)), -1, -2)
    return _Normalised(centre, scale, a, b, d, whitening)


def _normalise_one(estimates, info, c: float, metric: str = "euclidean") -> tuple[_Normalised, list[np.ndarray]]:
    """:func:`_normalise` of one fusion (checked estimates, their :class:`Information`): the problem
    without the run axis and the primal's parameter values in ``metric``."""
    means = np.array([e.mean for e in estimates])[None]
    covs = np.array([e.cov for e in estimates])[None]
    batched = _normalise(means, covs, info.matrices[None], np.array([c]))
    return batched.one(), [v[0] for v in batched.primal_values(metric)]


@dataclass(frozen=True)
class _NewtonSolution:
    """The Newton route's answer for B runs: the dual's solution, the normalisation's ``centre`` x̄
    (B, D) and ``scale`` s (B,), and the primal centre ξ* = −A_α⁻¹b_α in normalised coordinates (B, D)."""

    dual: DualSolution
    centre: np.ndarray
    scale: np.ndarray
    xi: np.ndarray


def _newton_route(means: np.ndarray, covs: np.ndarray, matrices: np.ndarray, c: np.ndarray, metric: str
                  ) -> _NewtonSolution:
    """The dual of B runs' normalised problems (:func:`_normalised_data`, the conic route's data) by
    :func:`gpfverify.fusion.rcc_dual.solve_dual`, in the coordinates ξ' = Lᵀξ with L Lᵀ the mean of
    the A_m: the data L⁻¹A_mL⁻ᵀ (mean the identity), L⁻¹b_m, d_m and the metric L⁻¹K²L⁻ᵀ, every one by
    triangular solves with L (the dual is the same problem: b_αᵀA_α⁻¹b_α and the congruent LMI are
    unchanged, and so are the multipliers α)."""
    centre, scale, a, b, d = _normalised_data(means, covs, matrices, c)
    runs, n, dim = b.shape
    k = np.sqrt(np.diagonal(a.mean(axis=1), axis1=-2, axis2=-1)) if metric == "scaled" else np.ones((runs, dim))
    lower = np.linalg.cholesky(a.mean(axis=1))
    def side_by_side(mats: np.ndarray) -> np.ndarray:  # (B, N, D, D) -> [M_1 … M_N] (B, D, N·D)
        return np.swapaxes(mats, 1, 2).reshape(runs, dim, n * dim)

    def apart(wide: np.ndarray) -> np.ndarray:  # its inverse
        return np.swapaxes(wide.reshape(runs, dim, n, dim), 1, 2)

    half = apart(lower_solve_stack(lower, side_by_side(a)))  # L⁻¹A_m
    whitened = apart(lower_solve_stack(lower, side_by_side(np.swapaxes(half, 2, 3))))  # L⁻¹(L⁻¹A_m)ᵀ
    whitened = 0.5 * (whitened + np.swapaxes(whitened, -1, -2))
    rhs = np.concatenate([np.swapaxes(b, 1, 2), np.eye(dim) * k[:, None, :]], axis=2)  # [b_1 … b_N, K]
    solved = lower_solve_stack(lower, rhs)
    vectors = np.swapaxes(solved[..., :n], 1, 2)
    root = solved[..., n:]  # L⁻¹K
    metric_matrix = root @ np.swapaxes(root, -1, -2)
    dual = solve_dual(whitened, vectors, d, 0.5 * (metric_matrix + np.swapaxes(metric_matrix, -1, -2)))
    xi = -upper_solve_stack(np.swapaxes(lower, -1, -2), np.nan_to_num(dual.centre))
    return _NewtonSolution(dual, centre, scale, xi)


def _checked_route(route: str) -> str:
    if route not in ROUTES:
        raise InputError(f"the RCC-CI route must be one of {', '.join(ROUTES)}, got {route!r}")
    return route


def _checked_metric(metric: str) -> str:
    if metric not in METRICS:
        raise InputError(f"the RCC-CI metric must be one of {', '.join(METRICS)}, got {metric!r}")
    return metric


@lru_cache(maxsize=32)
def _primal_problem(n: int, dim: int, solver: str = cp.CLARABEL) -> Parametrised:
    """The DPP primal for N ellipsoids in D dimensions after the change of variables Δ = TΔ'Tᵀ,
    x = Tx' (module docstring, "Numerics"), built once per (N, D, solver): a problem is only ever
    solved (or compiled, for Clarabel) by one solver, so switching solvers never recompiles a
    shared object. Parameters TᵀA_1T..TᵀA_NT, Tᵀb_1..Tᵀb_N, d_1..d_N, T and M = TᵀT; the objective
    tr(Δ) − ‖x‖² is tr(MΔ') − s with ‖Tx'‖² ≤ s. Returns x' and the duals of the N ellipsoid
    constraints (the same constraints, written in x': their multipliers are the original ones)."""
    A = [cp.Parameter((dim, dim)) for _ in range(n)]  # symmetric by construction; unchecked is cheaper
    b = [cp.Parameter(dim) for _ in range(n)]
    d = [cp.Parameter() for _ in range(n)]
    T, M = cp.Parameter((dim, dim)), cp.Parameter((dim, dim))
    z = cp.Variable((dim + 1, dim + 1), PSD=True)
    s = cp.Variable()
    delta, x = z[:dim, :dim], z[:dim, dim]
    ellipsoids = [cp.trace(A[m] @ delta) + 2 * b[m] @ x + d[m] <= 0 for m in range(n)]
    problem = cp.Problem(cp.Maximize(cp.trace(M @ delta) - s),
                         [z[dim, dim] == 1, cp.sum_squares(T @ x) <= s] + ellipsoids)
    return Parametrised(problem, (*A, *b, *d, T, M), (x,), tuple(ellipsoids))


@lru_cache(maxsize=32)
def _dual_problem(n: int, dim: int, solver: str = cp.CLARABEL) -> Parametrised:
    """The DPP dual, as :func:`_primal_problem`; parameters A_1..A_N, b_1..b_N, d; returns α."""
    # symmetric by construction; symmetric=True would make cvxpy rewrite them, which compiling refuses
    A = [cp.Parameter((dim, dim)) for _ in range(n)]
    b = [cp.Parameter(dim) for _ in range(n)]
    d = cp.Parameter(n)
    alpha = cp.Variable(n, nonneg=True)
    t = cp.Variable()
    a_alpha = sum(alpha[m] * A[m] for m in range(n))
    b_alpha = cp.reshape(sum(alpha[m] * b[m] for m in range(n)), (dim, 1), order="F")
    schur = cp.bmat([[a_alpha, b_alpha], [b_alpha.T, cp.reshape(t, (1, 1), order="F")]])
    problem = cp.Problem(cp.Minimize(t - d @ alpha), [schur >> 0, a_alpha >> np.eye(dim)])
    return Parametrised(problem, (*A, *b, d), (alpha,), ())


@lru_cache(maxsize=32)
def _clarabel_program(build, n: int, dim: int) -> ClarabelProgram | None:
    """``build(n, dim)`` compiled once for direct Clarabel solves (:mod:`gpfverify.fusion.conic`), or
    None when this cvxpy's internals differ from those the compiler knows (it refuses whatever it
    cannot reproduce bit for bit, and modules it reads that are missing; an attribute they no
    longer have raises AttributeError): then Clarabel is called through cvxpy, the same numbers,
    slower."""
    try:
        return ClarabelProgram.compile(build(n, dim, cp.CLARABEL))
    except (ValueError, AttributeError):
        return None


def _solve_once(build, size: tuple[int, int], values: list, solver: str) -> ConicSolution:
    """One solve that depends on the parameter values alone: Clarabel through the compiled program
    (a new solver object each time), any other solver through cvxpy with ``warm_start=False`` (a new
    solver object instead of one updated from the previous solve; an updated Clarabel solver gave
    results differing in the last bits from a fresh one, so a run's numbers depended on what the
    process had solved before)."""
    program = _clarabel_program(build, *size) if solver == cp.CLARABEL else None
    if program is not None:
        return program.solve(values)
    return solve_with_cvxpy(build(*size, solver), values, solver)


def _solve_parametrised(build, size: tuple[int, int], values: list, solver: str, what: str) -> ConicSolution:
    """Solve the parametrised problem ``build(*size, solver)`` with parameter ``values``; if the
    solver fails, the same with SCS. Each attempt is a function of the values alone, so the path
    taken and the numbers returned do not depend on earlier solves in this process."""
    for use in [solver] + ([cp.SCS] if solver != cp.SCS else []):
        try:
            return _solve_once(build, size, values, use)
        except SolverError as exc:
            failure = exc
    raise SolverError(f"{what} failed: {failure}")


#: relative slack allowed when checking that an inaccurate solution lies in every ellipsoid
INACCURATE_SLACK = 1e-3


def _in_every_ellipsoid(norm: _Normalised, xi) -> bool:
    """Whether ξ satisfies f_m(ξ) = ξᵀA_mξ + 2b_mᵀξ + d_m ≤ 0 for every m, up to
    :data:`INACCURATE_SLACK` relative to the size of the terms (normalised coordinates)."""
    if xi is None or not np.all(np.isfinite(xi)):
        return False
    quad = np.einsum("i,mij,j->m", xi, norm.A, xi)
    lin = 2.0 * norm.b @ xi
    size = 1.0 + np.abs(quad) + np.abs(lin) + np.abs(norm.d)
    return bool(np.all(quad + lin + norm.d <= INACCURATE_SLACK * size))


def _centre(norm: _Normalised, solution: ConicSolution) -> np.ndarray | None:
    """The primal's centre ξ = Tx' in normalised coordinates (None when the solve returned none)."""
    if not solution.values or solution.values[0] is None:
        return None
    return norm.T @ solution.values[0]


def smallest_intersecting_size(estimates: Sequence, circular_state: Sequence[int] = ()) -> float:
    """c_min = min_x max_m (x − x_m)ᵀP_m⁻¹(x − x_m): the ellipsoids meet iff c ≥ c_min (angle
    components ``circular_state`` on one branch, as in :func:`rcc_ci`). Two estimates: the closed
    form of :func:`two_ellipsoid_size`; more: a conic program (:func:`conic_intersecting_size`)."""
    checked = checked_estimates(estimates, circular_state=circular_state)
    if len(checked) == 2:
        return two_ellipsoid_size(checked[0], checked[1])
    return conic_intersecting_size(checked)


def two_ellipsoid_size(first, second) -> float:
    """c_min of two ellipsoids by minimax duality: min_x max(q_1, q_2) = max_{λ∈[0,1]} min_x
    [λq_1 + (1 − λ)q_2] (convex quadratics), and the inner minimum is
    g(λ) = dᵀ(P_1/λ + P_2/(1 − λ))⁻¹d with d = x_1 − x_2. In the joint basis Vᵀ P_1 V = I,
    Vᵀ P_2 V = diag(μ) (:mod:`gpfverify.fusion.pairwise`), with u = Vᵀd,

        g(λ) = Σ_i u_i² λ(1 − λ) / ((1 − λ) + λμ_i),   g'(λ) = Σ_i u_i² ((1 − λ)² − λ²μ_i) / ((1 − λ) + λμ_i)²,

    concave, g'(0) = ‖u‖² ≥ 0 ≥ g'(1) = −Σ μ_i u_i²: c_min = g at the root of g' (Brent's method,
    :func:`~gpfverify.fusion.pairwise.minimise_convex_on_unit_interval` on −g). The conic program of
    :func:`conic_intersecting_size` gives the same number to its accuracy (tests/test_fusion_rcc_ci.py)."""
    jd = joint_diagonalise(first, second)
    mu = jd.ratios
    weights = (jd.u1 - jd.u2) ** 2  # u = Vᵀ(x_1 − x_2)

    def g(lam: float) -> float:
        return float(np.sum(weights * lam * (1.0 - lam) / ((1.0 - lam) + lam * mu)))

    def slope(lam: float) -> float:  # −g'(λ): the derivative of the convex −g
        return float(-np.sum(weights * ((1.0 - lam) ** 2 - lam ** 2 * mu) / ((1.0 - lam) + lam * mu) ** 2))

    return g(minimise_convex_on_unit_interval(slope))


def conic_intersecting_size(checked: Sequence) -> float:
    """c_min of any number of ellipsoids as the conic program min t s.t. ‖L_m⁻¹(x − x_m)‖² ≤ t
    (Clarabel through cvxpy)."""
    # c_min is invariant under x -> (x - x̄)/s with P_m -> P_m/s²: solve in those coordinates
    # (as the primal) so that the solver sees numbers of order one whatever the units
    centre = np.mean([e.mean for e in checked], axis=0)
    scale = float(np.sqrt(max(np.linalg.eigvalsh(e.cov)[-1] for e in checked)))
    x, t = cp.Variable(checked[0].mean.shape[0]), cp.Variable()
    cons = []
    for e in checked:
        cov, mean = e.cov / scale**2, (e.mean - centre) / scale
        whiten = np.linalg.solve(np.linalg.cholesky(cov), np.eye(e.mean.shape[0]))  # L⁻¹, P⁻¹ = L⁻ᵀL⁻¹
        cons.append(cp.sum_squares(whiten @ (x - mean)) <= t)
    try:
        solution = solve_with_cvxpy(Parametrised(cp.Problem(cp.Minimize(t), cons), (), (t,), ()), (), cp.CLARABEL)
    except SolverError as exc:
        raise SolverError(f"smallest intersecting size failed: {exc}") from None
    if solution.status not in SOLVED:
        raise SolverError(f"smallest intersecting size: solver status {solution.status}")
    return float(solution.values[0])


def rcc_ci(estimates: Sequence, c: float | None = None, on_empty: str = "error",
           solver: str = cp.CLARABEL, circular_state: Sequence[int] = (), metric: str = "euclidean",
           route: str = "conic") -> RccCiResult:
    """RCC-CI fusion of local estimates (see module docstring); ``c`` defaults to
    :func:`default_size`; ``circular_state``: the angle state components; ``metric`` the norm of
    the Chebyshev centre's error, "euclidean" (the paper's) or "scaled" (unit-free); ``route``
    "conic" (the semidefinite primal by ``solver``, the default and the reference) or "newton" (the
    dual over the weights, O(N D³) per iteration; module docstring, "Routes"). A Newton solve that
    does not converge is done again by the conic route."""
    checked = checked_estimates(estimates, circular_state=circular_state)
    metric = _checked_metric(metric)
    route = _checked_route(route)
    if on_empty not in ("error", "enlarge"):
        raise InputError(f"on_empty must be 'error' or 'enlarge', got {on_empty!r}")
    dim = checked[0].mean.shape[0]
    given = c is not None
    c = default_size(dim) if c is None else _checked_size(c)
    first = c
    info = information_form(checked)
    if route == "newton":
        result = _rcc_ci_newton(checked, info, c, given, on_empty, circular_state, metric)
        if result is not None:
            return result
    enlarged = False
    while True:
        norm, values = _normalise_one(checked, info, c, metric)
        tried = _tried_words(c, first, given, dim, enlarged)
        try:
            solution = _solve_parametrised(_primal_problem, (len(checked), dim), values, solver, "RCC-CI primal")
        except SolverError as exc:
            raise SolverError(f"RCC-CI: the solver failed at {tried} ({exc}); "
                              f"{_smallest_words(checked)}") from None
        status = solution.status
        if status == "optimal_inaccurate" and not _in_every_ellipsoid(norm, _centre(norm, solution)):
            status = "infeasible_inaccurate"  # a badly scaled empty intersection, not a centre
        if status in SOLVED:
            break
        if "infeasible" not in status:
            raise SolverError(f"RCC-CI: the primal ended with status {status} at {tried}; "
                              f"{_smallest_words(checked)}")
        c_min = smallest_intersecting_size(checked)
        if c >= c_min:  # they meet at this size: the solver, not the ellipsoids, failed
            raise SolverError(f"RCC-CI: the solver found no centre at {tried} (status {status}), although the "
                              f"local ellipsoids intersect for every c >= {c_min:.6g}: a badly scaled problem, "
                              "not an empty intersection")
        c, enlarged = _enlarged_size(c_min, tried, on_empty, enlarged)
    xi = _centre(norm, solution)
    assert xi is not None  # a solved status carries the primal's values
    alpha = np.clip(np.array(solution.duals, dtype=float), 0.0, None)
    if not alpha.sum() > 0:
        raise SolverError(f"RCC-CI: the dual multipliers are all zero at {tried}; {_smallest_words(checked)}")
    return _result(info, alpha, c, norm.centre + norm.scale * xi, float(solution.value * norm.scale**2), enlarged,
                   circular_state)


def _rcc_ci_newton(checked: Sequence, info, c: float, given: bool, on_empty: str, circular_state: Sequence[int],
                   metric: str) -> RccCiResult | None:
    """:func:`rcc_ci` by the Newton route; None when the dual's iterations do not converge (the
    conic route then solves it)."""
    dim = checked[0].mean.shape[0]
    first, enlarged = c, False
    means = np.array([e.mean for e in checked])[None]
    covs = np.array([e.cov for e in checked])[None]
    while True:
        solution = _newton_route(means, covs, info.matrices[None], np.array([c]), metric)
        status = solution.dual.status[0]
        if status == "optimal":
            break
        if status != "empty":
            return None
        c_min = smallest_intersecting_size(checked)
        if c >= c_min:  # a certificate of emptiness at a size where they meet: rounding; let the conic route say
            return None
        tried = _tried_words(c, first, given, dim, enlarged)
        c, enlarged = _enlarged_size(c_min, tried, on_empty, enlarged)
    return _result(info, solution.dual.alpha[0], c, solution.centre[0] + solution.scale[0] * solution.xi[0],
                   float(solution.dual.value[0] * solution.scale[0] ** 2), enlarged, circular_state)


def _tried_words(c: float, first: float, given: bool, dim: int, enlarged: bool) -> str:
    """The size an RCC-CI attempt used, for its messages."""
    return (f"size c = {c:.6g} ({EMPTY_GROWTH:g} × the smallest intersecting size, tried after "
            f"{_size_words(first, given, dim)} found none)" if enlarged else _size_words(c, given, dim))


def _enlarged_size(c_min: float, tried: str, on_empty: str, enlarged: bool) -> tuple[float, bool]:
    """(the size to try next, True) when the ellipsoids missed at ``tried`` and may be enlarged;
    else the SolverError saying they do not intersect."""
    if on_empty == "error" or enlarged:
        raise SolverError(f"RCC-CI: the local ellipsoids do not intersect at {tried}; "
                          f"the smallest size at which they do is c = {c_min:.6g}")
    return EMPTY_GROWTH * c_min, True


def _result(info, alpha: np.ndarray, c: float, primal: np.ndarray, value: float, enlarged: bool,
            circular_state: Sequence[int]) -> RccCiResult:
    """The RCC-CI result of multipliers ``alpha``: the CI form with ω = α/Σα, x* = ``primal``."""
    weights = alpha / alpha.sum()
    fused = weighted_information_fusion(info, weights)
    angles = tuple(sorted(circular_state))
    return RccCiResult(mean=wrap_components(fused.mean, angles), cov=fused.cov, weights=weights, alpha=alpha,
                       c=c, primal_mean=wrap_components(primal, angles), primal_value=value, enlarged=enlarged,
                       circular_state=angles)


def _smallest_words(checked: Sequence) -> str:
    """'the local ellipsoids intersect for every size c >= 3.2' (c_min), or why it is not known."""
    try:
        return f"the local ellipsoids intersect for every size c >= {smallest_intersecting_size(checked):.6g}"
    except SolverError as exc:
        return f"the smallest size at which the local ellipsoids intersect is not known either ({exc})"


@dataclass(frozen=True)
class RccCiBatch:
    """RCC-CI of B runs: ``mean`` (B, D) (CI form from the duals), ``cov`` (B, D, D), ``weights``
    ω (B, N), ``c`` (B,) the size used and ``enlarged`` (B,) whether it was enlarged."""

    mean: np.ndarray
    cov: np.ndarray
    weights: np.ndarray
    c: np.ndarray
    enlarged: np.ndarray


def rcc_ci_batch(means: np.ndarray, covs: np.ndarray, c: float | None = None, on_empty: str = "enlarge",
                 circular_state: Sequence[int] = (), metric: str = "euclidean", route: str = "conic") -> RccCiBatch:
    """:func:`rcc_ci` of B runs' N local estimates (means (B, N, D), covs (B, N, D, D), positive
    definite: a filter's outputs, not checked again) by Clarabel. The runs' problems are solved one
    by one — an interior-point method run on all of them at once would couple their iterations, and
    a run's answer would depend on its batch — but their data are formed at once
    (:meth:`~gpfverify.fusion.conic.ClarabelProgram.solve_raw_batch`: the same data as a solve of
    its own, from each run's information matrices formed as :func:`rcc_ci` forms them), and the
    CI-form estimates computed over the runs
    (:func:`gpfverify.fusion.batched.weighted_information_batch`). A run whose ellipsoids miss at
    c is solved again at :data:`EMPTY_GROWTH` · c_min (``on_empty="enlarge"``); a run whose solve
    ends otherwise than "optimal" or infeasible (an inaccurate or failed solve) is left to
    :func:`rcc_ci`, which checks it, retries with SCS or says why it cannot fuse. ``route="newton"``:
    the dual over the weights (:func:`gpfverify.fusion.rcc_dual.solve_dual`) for all runs at once,
    each with its own iterates (the same bits as alone); a run whose iterations do not converge is
    left to :func:`rcc_ci` by the conic route."""
    from gpfverify.fusion.batched import weighted_information_batch
    from gpfverify.fusion.estimates import on_one_branch_arrays

    if on_empty not in ("error", "enlarge"):
        raise InputError(f"on_empty must be 'error' or 'enlarge', got {on_empty!r}")
    metric = _checked_metric(metric)
    runs, n, dim = means.shape
    angles = tuple(sorted(circular_state))
    means = on_one_branch_arrays(means, angles)
    sizes = np.full(runs, default_size(dim) if c is None else _checked_size(c))
    enlarged = np.zeros(runs, dtype=bool)
    # each run's information as rcc_ci forms it (the same factorisations: the same problem data, and
    # so the same duals, as a solve of its own)
    forms = [information_form([Gaussian(m, v) for m, v in zip(run_means, run_covs)])
             for run_means, run_covs in zip(means, covs)]
    matrices, vectors = np.array([f.matrices for f in forms]), np.array([f.vectors for f in forms])
    weights = np.full((runs, n), np.nan)
    route = _checked_route(route)
    if route == "newton":
        alone = _newton_batch_weights(means, covs, matrices, sizes, enlarged, weights, on_empty, metric)
        program = None
        pending: list[int] = []
    else:
        program = _clarabel_program(_primal_problem, n, dim)
        alone = list(range(runs)) if program is None else []
        pending = [] if program is None else list(range(runs))
    while pending and program is not None:
        at = np.array(pending)
        raw = program.solve_raw_batch(_normalise(means[at], covs[at], matrices[at], sizes[at]).primal_values(metric))
        pending = []
        for run, solution in zip(at.tolist(), raw):
            if solution.status == "optimal":
                alpha = np.clip(np.concatenate([np.ravel(solution.z[i]) for i in program.dual_index]), 0.0, None)
                if alpha.sum() > 0:
                    weights[run] = alpha / alpha.sum()
                    continue
            elif "infeasible" in solution.status and on_empty == "enlarge" and not enlarged[run]:
                estimates = [Gaussian(m, v) for m, v in zip(means[run], covs[run])]
                c_min = smallest_intersecting_size(estimates)
                if sizes[run] < c_min:
                    sizes[run], enlarged[run] = EMPTY_GROWTH * c_min, True
                    pending.append(run)
                    continue
            alone.append(run)
    mean, cov = np.empty((runs, dim)), np.empty((runs, dim, dim))
    solved = np.flatnonzero(~np.isnan(weights[:, 0]))
    if solved.size:
        fused = weighted_information_batch(matrices[solved], vectors[solved], weights[solved])
        mean[solved], cov[solved] = fused.mean, fused.cov
    for run in sorted(alone):
        single = rcc_ci([Gaussian(m, v) for m, v in zip(means[run], covs[run])], c=c, on_empty=on_empty,
                        circular_state=angles, metric=metric)  # the conic route: checked, or why not
        mean[run], cov[run], weights[run], sizes[run], enlarged[run] = (single.mean, single.cov, single.weights,
                                                                        single.c, single.enlarged)
    return RccCiBatch(wrap_components(mean, angles), cov, weights, sizes, enlarged)


def _newton_batch_weights(means: np.ndarray, covs: np.ndarray, matrices: np.ndarray, sizes: np.ndarray,
                          enlarged: np.ndarray, weights: np.ndarray, on_empty: str, metric: str) -> list[int]:
    """The Newton route of :func:`rcc_ci_batch`: ``weights`` (and ``sizes``, ``enlarged`` where the
    ellipsoids missed and were enlarged) filled in place for every run it solves; returns the runs
    left to :func:`rcc_ci` (not converged, or missing where "error" is asked)."""
    pending, alone = list(range(len(means))), []
    while pending:
        at = np.array(pending)
        solution = _newton_route(means[at], covs[at], matrices[at], sizes[at], metric)
        pending = []
        for j, run in enumerate(at.tolist()):
            status = solution.dual.status[j]
            if status == "optimal":
                alpha = solution.dual.alpha[j]
                weights[run] = alpha / alpha.sum()
                continue
            if status == "empty" and on_empty == "enlarge" and not enlarged[run]:
                c_min = smallest_intersecting_size([Gaussian(m, v) for m, v in zip(means[run], covs[run])])
                if sizes[run] < c_min:
                    sizes[run], enlarged[run] = EMPTY_GROWTH * c_min, True
                    pending.append(run)
                    continue
            alone.append(run)
    return alone


@dataclass(frozen=True)
class RccCiDual:
    """Explicit dual solution: multipliers ``alpha`` (normalised problem), ``value`` in original
    units, and the centre −A_α⁻¹b_α in original coordinates."""

    alpha: np.ndarray
    value: float
    mean: np.ndarray


def rcc_ci_dual(estimates: Sequence, c: float | None = None, solver: str = cp.CLARABEL,
                circular_state: Sequence[int] = (), metric: str = "euclidean") -> RccCiDual:
    """Solve the RCC dual SDP (module docstring) for the cross-check against :func:`rcc_ci`; in the
    scaled metric, the Euclidean dual of the ellipsoids with each component in its scale."""
    checked = checked_estimates(estimates, circular_state=circular_state)
    metric = _checked_metric(metric)
    dim = checked[0].mean.shape[0]
    c = default_size(dim) if c is None else _checked_size(c)
    info = information_form(checked)
    norm, _ = _normalise_one(checked, info, c)
    k = norm.metric_scale(metric)  # the dual in u = K ξ: A_m → K⁻¹A_mK⁻¹, b_m → K⁻¹b_m
    data = [*(norm.A / np.outer(k, k)), *(norm.b / k), norm.d]
    solution = _solve_parametrised(_dual_problem, (len(checked), dim), data, solver, "RCC-CI dual")
    if solution.status not in SOLVED:
        raise SolverError(f"RCC-CI dual ended with status {solution.status}")
    a = np.clip(solution.values[0], 0.0, None)
    fused = weighted_information_fusion(info, a / a.sum())
    return RccCiDual(a, float(solution.value * norm.scale**2), wrap_components(fused.mean, circular_state))
