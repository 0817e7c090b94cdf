"""The one place tolerances come from.

Three tiers, after GPflow's expectation tests (see STYLE.md):

* exact algebra (two formulas for the same number): relative error of order ``eps * cond``;
  :func:`algebra_rtol` scales a floor of 1e-9 by the problem's condition number;
* deterministic quadrature against a closed form: :data:`QUADRATURE_RTOL`;
* convex solvers (interior point, default accuracy): :data:`SOLVER_TOL`;
* Monte Carlo against an expectation: :func:`monte_carlo_atol`, k standard errors computed
  from the sample itself.

No test or routine should carry a bare numerical tolerance of its own.
"""

from __future__ import annotations

import math

import numpy as np

EPS: float = float(np.finfo(float).eps)

#: Floor of the relative tolerance for two exact-algebra routes to the same number.
ALGEBRA_RTOL: float = 1e-9
#: Safety factor on eps * cond: a few solves and products each lose about eps * cond.
ALGEBRA_SAFETY: float = 1e3
#: Relative tolerance of high-order Gauss-Hermite quadrature against a closed form.
QUADRATURE_RTOL: float = 1e-6
#: Absolute/relative accuracy expected of interior-point solutions (Clarabel defaults ~1e-8).
SOLVER_TOL: float = 1e-5
#: Relative violation of a convex problem's first-order (KKT) condition above which a solver's
#: answer is rejected as wrong. Gradients at interior-point solutions on exponential cones are
#: accurate to ~1e-5–1e-4 (measured: 4e-5 for det-optimal CI weights), so this detects failures,
#: not the last digits.
KKT_REJECT_TOL: float = 1e-3
#: Change of a smooth convex objective (of order one, in whitened coordinates) between SLSQP
#: iterations at which it stops. Measured on 700 random CI problems (N ≤ 8, D ≤ 10, information
#: condition numbers up to 7e10): KKT violations at most 2e-5, 4e-7 for well-conditioned ones.
SLSQP_FTOL: float = 1e-14
#: Squared Newton decrement dᵀHd (relative to the objective, of order one in whitened coordinates) at
#: which Newton's method for CI weights stops: the objective is then within about this of its
#: minimum on the support, far below the KKT certificate's floor.
CI_NEWTON_TOL: float = 1e-14
#: A weight outside the support joins it when its KKT multiplier is below −CI_NEWTON_JOIN_TOL |ν|
#: (ν the multiplier of Σω = 1): far below the certificate's KKT_REJECT_TOL, far above the
#: gradients' rounding, so a weight whose gain is rounding never joins and leaves again.
CI_NEWTON_JOIN_TOL: float = 1e-9
#: Newton steps allowed for CI weights. Measured on 1400 random problems (N 3–8, D 1–10,
#: covariance eigenvalues spread up to 10⁵, scales 10⁻³–10³): at most 13, KKT violations at most
#: 3e-7; on 1000 with spreads up to 10⁸ and scales 10⁻⁶–10⁶: at most 21, every violation below
#: 4e-4 of what the certificate accepts, and never a worse objective than SLSQP's.
CI_NEWTON_MAX_STEPS: int = 100
#: How many standard errors a Monte Carlo estimate may stray (two-sided p ~ 6e-7 per check).
MONTE_CARLO_SIGMAS: float = 5.0
#: How far an observed order of convergence, log2(err(h) / err(h/2)), may be from the
#: theoretical order of a discretisation in its asymptotic range.
CONVERGENCE_ORDER_ATOL: float = 0.1
#: Asymmetry |A_ij - A_ji| / sqrt(A_ii A_jj) accepted as rounding in a "symmetric" matrix.
SYMMETRY_RTOL: float = 1e-8
#: Negative eigenvalue of a covariance's correlation matrix D^-1/2 A D^-1/2 (a unit-free number,
#: relative to its largest eigenvalue) accepted as rounding in a positive semidefinite matrix.
PSD_RTOL: float = 1e-10
#: Monte Carlo runs advanced together as arrays against the same runs one at a time (the contract
#: of an experiment's ``run_batch``): relative, for routes whose arrays differ in shape
PER_RUN_RTOL: float = 1e-10
#: Relative jitter steps tried, in order, when a Cholesky factorisation fails.
JITTER_STEPS: tuple[float, ...] = (0.0, 1e-12, 1e-10, 1e-8, 1e-6)


def algebra_rtol(condition_number: float = 1.0) -> float:
    """Relative tolerance for exact algebra on a problem with the given condition number:
    ``max(ALGEBRA_RTOL, ALGEBRA_SAFETY * eps * cond)``."""
    return float(algebra_rtols(float(condition_number)))


def algebra_rtols(condition_numbers) -> np.ndarray:
    """:func:`algebra_rtol` of every condition number of an array (infinite where one is)."""
    cond = np.asarray(condition_numbers, dtype=float)
    return np.where(np.isfinite(cond), np.maximum(ALGEBRA_RTOL, ALGEBRA_SAFETY * EPS * np.maximum(cond, 1.0)),
                    np.inf)


def kkt_reject_tol(condition_number: float) -> float:
    """Relative KKT violation above which a convex solver's answer is rejected: the solver-accuracy
    floor :data:`KKT_REJECT_TOL` plus the rounding of gradients computed through a matrix of the
    given condition number, ``ALGEBRA_SAFETY * eps * cond``."""
    return KKT_REJECT_TOL + ALGEBRA_SAFETY * EPS * max(float(condition_number), 1.0)


def kkt_reject_tol_batch(condition_numbers) -> np.ndarray:
    """:func:`kkt_reject_tol` of every condition number of an array."""
    return KKT_REJECT_TOL + ALGEBRA_SAFETY * EPS * np.maximum(np.asarray(condition_numbers, dtype=float), 1.0)


def monte_carlo_atol(sample_std, n_samples: int, sigmas: float = MONTE_CARLO_SIGMAS):
    """Absolute tolerance ``sigmas * std / sqrt(n)`` for a Monte Carlo mean, elementwise."""
    return sigmas * np.asarray(sample_std, dtype=float) / np.sqrt(n_samples)


def bounded_mean_atol(width: float, n_samples: int, sigmas: float = MONTE_CARLO_SIGMAS) -> float:
    """Absolute tolerance for the mean of ``n_samples`` independent draws of a variable confined to
    an interval of length ``width``, at the false-alarm probability of ``sigmas`` normal standard
    errors, p = erfc(sigmas / √2), by Hoeffding's inequality
    P(|mean − E| ≥ t) ≤ 2 exp(−2 n t² / width²):  t = width · sqrt(log(2 / p) / (2 n)).
    Needs no estimate of the variance (which a sample may put at 0 when it is merely small)."""
    p = math.erfc(sigmas / math.sqrt(2.0))
    return float(width) * float(np.sqrt(np.log(2.0 / p) / (2.0 * n_samples)))


def learned_model_rtol(n_train: int, sigmas: float = MONTE_CARLO_SIGMAS) -> float:
    """Relative tolerance for a filter on models *learned* from ``n_train`` noisy samples against
    the exact filter on the true model: ``sigmas * sqrt(2 / n_train)``, ``sigmas`` standard errors
    of a Gaussian variance estimated from ``n_train`` samples (the learned noise variances set the
    filter's covariances)."""
    return sigmas * float(np.sqrt(2.0 / n_train))


def rounding_bound(magnitude, operations: int):
    """First-order rounding bound of a computation: ``operations`` IEEE operations in sequence,
    each rounding by at most eps relative to the ``magnitude`` of what it handles (the sum of the
    operands' sizes, already multiplied by the condition numbers that amplify them; a number or an
    array of them). No floor: the bound of an exact computation on zeros is zero
    (docs/fusion-definitions.md derives the fusion step's magnitudes)."""
    return operations * EPS * np.asarray(magnitude, dtype=float)


def numpy_rank_tol(singular_values, shape) -> float:
    """numpy's ``matrix_rank`` default: ``S.max() * max(M, N) * eps``."""
    s = np.asarray(singular_values, dtype=float)
    return float(s.max(initial=0.0) * max(shape) * EPS)


#: Default threshold τ of the canonical rank rule (:class:`~gpfverify.fusion.exactness.RankRule`):
#: a sensor direction counts as carrying information about the state when its canonical
#: correlation ρ (a singular value of L_p⁻¹ C_xy L_y⁻ᵀ, unit-free, in [0, 1]) exceeds τ.
#: τ = sqrt(eps) ≈ 1.5e-8, because
#:
#: * ρ² is the fraction of the prior variance that the measurement removes along that canonical
#:   direction (posterior/prior = 1 − ρ²); for ρ ≤ sqrt(eps) that fraction is at most one ulp of
#:   1, i.e. below what a double-precision covariance can represent: the direction is
#:   informationless at working precision;
#: * dropping a direction with correlation ρ changes the fused mean by at most ρ prior standard
#:   deviations per unit (whitened) innovation, while keeping it amplifies the rounding of the
#:   reported μ_e^m (≈ eps, relative) by 1/ρ; the larger of the two, max(ρ, eps/ρ), is smallest
#:   at ρ = sqrt(eps);
#: * it stays far above the rounding of the computed correlations themselves (≈ eps times the
#:   condition of the equilibrated covariances: 1e-13 at condition 1e3), so exactly uncorrelated
#:   directions are never counted as rank.
CANONICAL_RANK_TOL: float = float(np.sqrt(EPS))
#: The largest rounding bound at which an exactness verdict is still decided: a gap per unit
#: whitened innovation of τ prior standard deviations is what the canonical rule itself treats as
#: no information (:data:`CANONICAL_RANK_TOL`). Where the arithmetic cannot resolve a gap this
#: small (a kernel computed in badly mixed units), the verdict is "not exact".
RESOLVABLE_GAP: float = CANONICAL_RANK_TOL
