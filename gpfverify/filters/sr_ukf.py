"""Square-root unscented Kalman filter (van der Merwe & Wan, ICASSP 2001; seed 001 §1.2), batched
over a leading axis (the particles of a UPF).

The covariance is carried as its lower Cholesky factor S (P = S Sᵀ, positive diagonal). With the
scaled sigma points of :mod:`gpfverify.filters.sigma_points` (weights w_m, w_c; c = √(D + λ)):

* sigma points          χ_0 = μ, χ_{±i} = μ ± c S_{:,i}
* time update           Y_i = f(χ_i),  μ⁻ = Σ w_m,i Y_i
                        S⁻ = qr([√w_c,1 (Y_{1:2D} − μ⁻), √Q])ᵀ                 (QR of the deviations)
                        S⁻ = cholupdate(S⁻, √|w_c,0| (Y_0 − μ⁻), sign w_c,0)  (rank one, ±)
* measurement update    sigma points redrawn from (μ⁻, S⁻); Z_i = h(χ_i), ẑ = Σ w_m,i Z_i
                        S_y = qr([√w_c,1 (Z_{1:2D} − ẑ), √R])ᵀ, then cholupdate with Z_0 − ẑ
                        P_xz = Σ w_c,i (χ_i − μ⁻)(Z_i − ẑ)ᵀ,  K = P_xz S_y⁻ᵀ S_y⁻¹   (two solves)
                        μ = μ⁻ + K (y − ẑ),  S = cholupdate(S⁻, K S_y, −1)   (one downdate per column)

Every factor is normalised to a positive diagonal, so it *is* the Cholesky factor of the UKF's
covariance and both filters draw the same sigma points: the SR-UKF equals the UKF to rounding,
including negative zeroth weights.

Downdate failure policy (documented, never silent): a rank-one downdate that would make a
diagonal entry non-positive means that, in floating point, S Sᵀ − x xᵀ is not positive definite.
The affected batch entries are recomputed from the explicit matrix with
:func:`gpfverify.linalg.cholesky`, which adds the smallest jitter of
:data:`~gpfverify.tolerances.JITTER_STEPS` that works and reports it (``jitter`` of the result);
if none works a :class:`~gpfverify.errors.NumericalError` names the step. A negative zeroth weight
whose downdate fails in exact arithmetic (the UKF covariance itself is indefinite) ends the same way.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from collections.abc import Callable, Sequence

import numpy as np

from gpfverify.angles import difference, weighted_mean, wrap_components
from gpfverify.errors import InputError
from gpfverify.filters.records import StepRecord
from gpfverify.filters.sigma_points import SigmaParams, weighted_outer
from gpfverify.filters.ukf import map_points
from gpfverify.linalg import cholesky, symmetrize
from gpfverify.models.system import StateSpaceModel, require_model
from gpfverify.runtime import one_blas_thread

#: whether :func:`cholupdate` runs its column loop compiled (numba, the optional ``fast`` extra,
#: imported on first use); the same operations either way, equal to rounding. Set False to take the
#: numpy loop (tests run both).
compiled = importlib.util.find_spec("numba") is not None

#: f(points (M, D), k) -> (M, D'): a transition or measurement function vectorised over points.
PointMap = Callable[[np.ndarray, int], np.ndarray]


@dataclass(frozen=True)
class SqrtGaussian:
    """N(mean, sqrt_cov sqrt_covᵀ): mean (..., D), sqrt_cov (..., D, D) lower, positive diagonal."""

    mean: np.ndarray
    sqrt_cov: np.ndarray

    @property
    def cov(self) -> np.ndarray:
        return self.sqrt_cov @ np.swapaxes(self.sqrt_cov, -1, -2)


@dataclass(frozen=True)
class SqrtStepRecord:
    """One SR-UKF cycle: the :class:`~gpfverify.filters.records.StepRecord` quantities with square
    roots in place of covariances. ``S_p``, ``S_y``, ``S_e`` lower factors of C_p, C_y, C_e;
    ``jitter`` the largest jitter a fallback recomputation needed (0 if none)."""

    mu_p: np.ndarray
    S_p: np.ndarray
    mu_y: np.ndarray
    S_y: np.ndarray
    C_xy: np.ndarray
    mu_e: np.ndarray
    S_e: np.ndarray
    jitter: float = 0.0

    @property
    def posterior(self) -> SqrtGaussian:
        return SqrtGaussian(self.mu_e, self.S_e)

    def to_record(self) -> StepRecord:
        """The same step with covariances S Sᵀ (for comparison with the UKF)."""
        def square(s):
            return s @ np.swapaxes(s, -1, -2)

        return StepRecord(self.mu_p, square(self.S_p), self.mu_y, square(self.S_y), self.C_xy,
                          self.mu_e, square(self.S_e), self.jitter)


# -- factor algebra -----------------------------------------------------------------------------

def positive_diagonal(factor: np.ndarray) -> np.ndarray:
    """Flip the sign of columns of a lower factor so its diagonal is ≥ 0 (L Lᵀ is unchanged)."""
    signs = np.where(np.diagonal(factor, axis1=-2, axis2=-1) < 0, -1.0, 1.0)
    return factor * signs[..., None, :]


def qr_factor(columns: np.ndarray) -> np.ndarray:
    """Lower factor S with S Sᵀ = A Aᵀ for A = ``columns`` (..., D, M), M ≥ D: the transposed
    R of a QR decomposition of Aᵀ, with positive diagonal (batched)."""
    r = np.linalg.qr(np.swapaxes(columns, -1, -2), mode="r")  # (..., D, D) upper
    return positive_diagonal(np.swapaxes(r, -1, -2))


def cholupdate(factor: np.ndarray, vector: np.ndarray, sign: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Rank-one update (sign = +1) or downdate (sign = −1) of lower Cholesky factors, batched:
    returns (L', failed) with L'L'ᵀ = L Lᵀ + sign · x xᵀ for ``factor`` (..., D, D) and ``vector``
    (..., D). ``failed`` (...) marks entries where a downdate met a non-positive pivot
    r² = L_kk² − x_k²; their L' rows are not meaningful (see the module's failure policy).

    Column k: r = √(L_kk² + sign x_k²), c = r/L_kk, s = x_k/L_kk, L_kk ← r,
    L_{k+1:,k} ← (L_{k+1:,k} + sign s x_{k+1:})/c, x_{k+1:} ← c x_{k+1:} − s L_{k+1:,k}.
    """
    lower = np.array(factor, dtype=float, order="C", copy=True)  # C order: the reshapes below are views
    x = np.array(vector, dtype=float, order="C", copy=True)
    dim = lower.shape[-1]
    if compiled and lower.shape[:-2] == x.shape[:-1]:
        from gpfverify.filters.sr_ukf_kernels import cholupdate_in_place

        cholupdate_in_place(lower.reshape(-1, dim, dim), x.reshape(-1, dim), float(sign))  # views: in place
    else:
        _cholupdate_loop(lower, x, sign)
    # a non-positive pivot leaves a zero/NaN diagonal or inf/NaN entries below it
    diagonal = np.diagonal(lower, axis1=-2, axis2=-1)
    failed = ~(np.all(diagonal > 0, axis=-1) & np.all(np.isfinite(lower), axis=(-2, -1)))
    return lower, failed


def _cholupdate_loop(lower: np.ndarray, x: np.ndarray, sign: float) -> None:
    """The column loop of :func:`cholupdate` in numpy, vectorised over the batch, in place (the
    reference of the compiled loop, and the path without numba)."""
    dim = lower.shape[-1]
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for k in range(dim):
            diag = lower[..., k, k]
            xk = x[..., k]
            r = np.sqrt(diag * diag + sign * xk * xk)  # NaN when the pivot r² < 0
            c = (r / diag)[..., None]
            s = (xk / diag)[..., None]
            lower[..., k, k] = r
            column = (lower[..., k + 1:, k] + sign * s * x[..., k + 1:]) / c
            lower[..., k + 1:, k] = column
            x[..., k + 1:] = c * x[..., k + 1:] - s * column


def _recompute(cov: np.ndarray, lower: np.ndarray, failed: np.ndarray, what: str) -> tuple[np.ndarray, float]:
    """Replace the failed entries of ``lower`` by Cholesky factors of ``cov`` (with reported jitter)."""
    if not np.any(failed):
        return lower, 0.0
    out = lower.copy()
    jitter = 0.0
    indices = list(zip(*np.nonzero(failed))) if failed.ndim else [()]
    for index in indices:
        chol = cholesky(cov[index], what)
        out[index] = chol.factor
        jitter = max(jitter, chol.jitter)
    return out, jitter


def rank_one_series(factor: np.ndarray, vectors: np.ndarray, sign: float, what: str) -> tuple[np.ndarray, float]:
    """Apply ``sign`` · v vᵀ for every column v of ``vectors`` (..., D, M) to the factors, one
    rank-one step per column; failed entries are recomputed from S Sᵀ + sign V Vᵀ (module policy).
    Returns (factor, jitter)."""
    lower = factor
    failed = np.zeros(factor.shape[:-2], dtype=bool)
    for j in range(vectors.shape[-1]):
        lower, bad = cholupdate(lower, vectors[..., :, j], sign)
        failed |= bad
    if np.any(failed):
        cov = symmetrize(factor @ np.swapaxes(factor, -1, -2) + sign * vectors @ np.swapaxes(vectors, -1, -2))
        return _recompute(cov, lower, failed, what)
    return lower, 0.0


def _batched_sqrt(root: np.ndarray, batch_shape: tuple, dim: int, name: str) -> np.ndarray:
    s = np.asarray(root, dtype=float)
    if s.shape[-2:] != (dim, dim):
        raise InputError(f"{name} must be ({dim}, {dim}) or batched (..., {dim}, {dim}), got {s.shape}")
    return np.broadcast_to(s, batch_shape + (dim, dim))


def unscented_sqrt_transform(points: np.ndarray, mapped: np.ndarray, noise_root: np.ndarray,
                             params: SigmaParams, what: str, circular_in: Sequence[int] = (),
                             circular_out: Sequence[int] = ()):
    """Mean, lower factor of the covariance (noise added) and cross covariance of mapped sigma
    points: points (..., 2D+1, D), mapped (..., 2D+1, L), noise_root (L, L) or (..., L, L).
    Returns (mean (..., L), sqrt_cov (..., L, L), cross (..., D, L), jitter).

    The scaled unscented weights w_c,1..2D are all equal (1/(2(D + λ)) > 0), so one √w_c,1 scales
    every deviation column of the QR; only w_c,0 may be negative. Angle components
    (``circular_in`` of the points, ``circular_out`` of the mapped points) get circular means and
    wrapped deviations, as in the UKF."""
    dim = points.shape[-1]
    wm, wc = params.weights(dim)
    mean_x = weighted_mean(points, wm, circular_in)
    mean = weighted_mean(mapped, wm, circular_out)
    dev = difference(mapped, mean[..., None, :], circular_out)
    out_dim = mapped.shape[-1]
    noise = _batched_sqrt(noise_root, mapped.shape[:-2], out_dim, "noise square root")
    columns = np.concatenate([np.sqrt(wc[1]) * np.swapaxes(dev[..., 1:, :], -1, -2), noise], axis=-1)
    sqrt_cov = qr_factor(columns)
    jitter = 0.0
    if wc[0] != 0.0:
        sqrt_cov, jitter = rank_one_series(sqrt_cov, np.sqrt(abs(wc[0])) * dev[..., 0, :, None],
                                           float(np.sign(wc[0])), what)
    cross = weighted_outer(wc, difference(points, mean_x[..., None, :], circular_in), dev)
    return mean, sqrt_cov, cross, jitter


def sigma_points_sqrt(mean: np.ndarray, sqrt_cov: np.ndarray, params: SigmaParams = SigmaParams()) -> np.ndarray:
    """Sigma points (..., 2D+1, D) from a lower factor: μ, μ ± √(D + λ) S_{:,i}."""
    dim = mean.shape[-1]
    offsets = np.sqrt(dim + params.lam(dim)) * np.swapaxes(sqrt_cov, -1, -2)
    return np.concatenate([mean[..., None, :], mean[..., None, :] + offsets,
                           mean[..., None, :] - offsets], axis=-2)


def noise_sqrt(cov: np.ndarray) -> np.ndarray:
    """A square root A (A Aᵀ = cov) of a PSD noise covariance, singular allowed: the Cholesky
    factor when it exists, else V diag(√max(λ, 0)) from the eigen-decomposition (the QR of the
    time update needs any square root, not a triangular one)."""
    cov = symmetrize(np.asarray(cov, dtype=float))
    try:
        return np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        eig, vec = np.linalg.eigh(cov)
        return vec * np.sqrt(np.maximum(eig, 0.0))[..., None, :]


# -- the filter -----------------------------------------------------------------------------------

def sr_ukf_predict(belief: SqrtGaussian, f: PointMap, sqrt_Q: np.ndarray, k: int,
                   params: SigmaParams = SigmaParams(), circular_state: Sequence[int] = ()
                   ) -> tuple[SqrtGaussian, float]:
    """Time update: (μ⁻, S⁻) from (μ, S); ``sqrt_Q`` (D, D) or per batch entry (..., D, D)."""
    points = sigma_points_sqrt(belief.mean, belief.sqrt_cov, params)
    mean, sqrt_cov, _, jitter = unscented_sqrt_transform(points, map_points(lambda x: f(x, k), points), sqrt_Q,
                                                         params, "SR-UKF predicted covariance",
                                                         circular_state, circular_state)
    return SqrtGaussian(mean, sqrt_cov), jitter


def sr_ukf_update(prior: SqrtGaussian, h: PointMap, sqrt_R: np.ndarray, y: np.ndarray, k: int,
                  params: SigmaParams = SigmaParams(), circular: Sequence[int] = (),
                  circular_state: Sequence[int] = ()) -> SqrtStepRecord:
    """Measurement update with sigma points redrawn from the prior (μ⁻, S⁻); ``y`` (L,) or (..., L);
    the innovation y − ẑ is wrapped on the ``circular`` outputs."""
    points = sigma_points_sqrt(prior.mean, prior.sqrt_cov, params)
    mu_y, s_y, c_xy, jitter_y = unscented_sqrt_transform(points, map_points(lambda x: h(x, k), points), sqrt_R,
                                                         params, "SR-UKF innovation covariance",
                                                         circular_state, circular)
    # K = C_xy S_y⁻ᵀ S_y⁻¹, i.e. Kᵀ = S_y⁻ᵀ (S_y⁻¹ C_xyᵀ): two batched solves
    half = np.linalg.solve(s_y, np.swapaxes(c_xy, -1, -2))
    gain = np.swapaxes(np.linalg.solve(np.swapaxes(s_y, -1, -2), half), -1, -2)
    innovation = difference(np.asarray(y, dtype=float), mu_y, circular)
    mu_e = wrap_components(prior.mean + np.einsum("...dl,...l->...d", gain, innovation), circular_state)
    s_e, jitter_e = rank_one_series(prior.sqrt_cov, gain @ s_y, -1.0, "SR-UKF posterior covariance")
    return SqrtStepRecord(prior.mean, prior.sqrt_cov, mu_y, s_y, c_xy, mu_e, s_e, max(jitter_y, jitter_e))


@one_blas_thread
def sr_ukf_step(belief: SqrtGaussian, model, y: np.ndarray, *, k: int = 1,
                params: SigmaParams = SigmaParams()) -> SqrtStepRecord:
    """One SR-UKF cycle on a :class:`~gpfverify.models.StateSpaceModel` (additive noise;
    √Q, √R from :func:`noise_sqrt`; angle outputs and state components as in the UKF)."""
    require_model(model, StateSpaceModel, "the SR-UKF")
    prior, jitter_p = sr_ukf_predict(belief, model.f, noise_sqrt(model.Q), k, params, model.circular_state)
    record = sr_ukf_update(prior, model.h, noise_sqrt(model.R), y, k, params, model.circular,
                           model.circular_state)
    return SqrtStepRecord(record.mu_p, record.S_p, record.mu_y, record.S_y, record.C_xy, record.mu_e,
                          record.S_e, max(record.jitter, jitter_p))
