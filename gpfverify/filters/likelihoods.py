"""Densities a particle filter needs from a :class:`~gpfverify.models.StateSpaceModel`:

* :func:`gaussian_logpdf` / :func:`whitened_gaussian_logpdf`: the one Gaussian log density,
  log N(r; 0, C) = −½ |L⁻¹ r|² − ½ log|C| − (L/2) log 2π, C = L Lᵀ;
* transition: log p(x_k | x_{k−1}) — the model's ``transition_logpdf`` hook when it has one
  (non-Gaussian process noise), else N(x_k; f(x_{k−1}, k), Q); draws come from
  :meth:`~gpfverify.models.StateSpaceModel.sample_transition`;
* measurement: log p(y_k | x_k) = log N(r; 0, R), r = ``model.residual(y_k, h(x_k, k))``, the
  difference with the angle outputs (``model.circular``) wrapped to (−π, π];
* :func:`unwrapped_measurement`: h(x) moved to the branch nearest y (y − r), so that flows and
  moment computations see a continuous measurement function (bearings near ±π).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gpfverify.angles import difference
from gpfverify.errors import GpfverifyError
from gpfverify.filters import runs
from gpfverify.linalg import cholesky, cholesky_batched

LOG_2PI = float(np.log(2.0 * np.pi))


def whitened_gaussian_logpdf(white: np.ndarray, log_det: np.ndarray | float) -> np.ndarray:
    """log N(r; 0, C) from the whitened residual L⁻¹ r (..., L) and log|C|:
    −½ (|L⁻¹ r|² + log|C| + L log 2π)."""
    return -0.5 * (np.sum(white * white, axis=-1) + log_det + white.shape[-1] * LOG_2PI)


#: Cholesky factors of the covariances seen by :func:`gaussian_logpdf`, keyed by their contents
#: (a model's Q and R are the same at every step: factorised once, never stale)
_FACTORS: dict[tuple, tuple[np.ndarray, float]] = {}
_FACTORS_MAX = 64


def _factor(cov: np.ndarray) -> tuple[np.ndarray, float]:
    """(L, log|C|) of C = L Lᵀ (:func:`~gpfverify.linalg.cholesky`, jitter as there)."""
    cov = np.ascontiguousarray(cov, dtype=float)
    key = (cov.shape, cov.tobytes())
    found = _FACTORS.get(key)
    if found is None:
        chol = cholesky(cov, "covariance")
        found = (chol.factor, chol.logdet())
        if len(_FACTORS) >= _FACTORS_MAX:
            _FACTORS.clear()
        _FACTORS[key] = found
    return found


#: widest residual whitened by forward substitution over its components (:func:`_whiten_rows`)
SUBSTITUTION_MAX_DIM = 8


def _whiten_rows(factor: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """L⁻¹ r for every row r of ``rows`` (N, L): for a few components, forward substitution over
    them, each step vectorised over the N rows (numpy's dense solve copies the L × N right-hand
    side and runs LAPACK on it: 33 µs for N = 2000, L = 1, against about 3 µs); for more, that
    solve. Not BLAS trsm: OpenBLAS runs a solve with thousands of right-hand sides on all its
    threads, which a busy machine makes 10–40 times slower."""
    dim = rows.shape[1]
    if dim > SUBSTITUTION_MAX_DIM:
        return np.linalg.solve(factor, rows.T).T
    white = np.empty_like(rows)
    for i in range(dim):
        white[:, i] = (rows[:, i] - white[:, :i] @ factor[i, :i]) / factor[i, i]
    return white


def gaussian_logpdf(residuals: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """log N(r; 0, C) for residuals (..., L) and one covariance C (L, L)."""
    factor, logdet = _factor(cov)
    white = _whiten_rows(factor, residuals.reshape(-1, residuals.shape[-1]))
    return whitened_gaussian_logpdf(white, logdet).reshape(residuals.shape[:-1])


def batched_gaussian_logpdf(residuals: np.ndarray, covs: np.ndarray, name: str) -> np.ndarray:
    """log N(r_i; 0, C_i) for residuals (N, L) and one covariance per row (N, L, L)."""
    chol = cholesky_batched(covs, name)
    white = np.linalg.solve(chol, residuals[..., None])[..., 0]
    return whitened_gaussian_logpdf(white, 2.0 * np.sum(np.log(np.diagonal(chol, axis1=-2, axis2=-1)), axis=-1))


def transition_logpdf(model, x_new: np.ndarray, x_prev: np.ndarray, k: int) -> np.ndarray:
    """log p(x_new | x_prev) per particle, (N,) or (B, N) for particles (..., N, D); angle state
    components (``model.circular_state``) of x_new − f(x_prev) wrapped."""
    if model.transition_logpdf is not None:
        d = x_new.shape[-1]
        flat = model.transition_logpdf(x_new.reshape(-1, d), x_prev.reshape(-1, d), k)
        return np.asarray(flat).reshape(x_new.shape[:-1])
    predicted = runs.evaluate_runs(model.f, x_prev, k, model.state_dim)
    return gaussian_logpdf(difference(x_new, predicted, model.circular_state), model.Q)


def sample_transition(model, x_prev: np.ndarray, k: int, rng: runs.Streams) -> np.ndarray:
    """Draws x_k ~ p(x_k | x_{k−1}) (:meth:`~gpfverify.models.StateSpaceModel.sample_transition`)
    for particles (N, D) of one run, or (B, N, D) of B runs each from its own Generator; a run
    whose draw fails (its particles left the model's domain) gets NaN."""
    if not isinstance(rng, Sequence):
        return model.sample_transition(x_prev, k, rng)
    out = np.full(x_prev.shape, np.nan)
    for b, (x, g) in enumerate(zip(x_prev, rng)):
        if np.isfinite(x).all():
            try:
                out[b] = model.sample_transition(x, k, g)
            except GpfverifyError:
                pass
    return out


def measurement_loglik(model, y: np.ndarray, x: np.ndarray, k: int) -> np.ndarray:
    """log p(y | x_i) for particles x (N, D) and y (L,) — or x (B, N, D) and y (B, L) of B runs —
    under Gaussian measurement noise R, angle outputs wrapped."""
    predicted = runs.evaluate_runs(model.h, x, k, model.measurement_dim)
    return gaussian_logpdf(model.residual(y[..., None, :], predicted), model.R)


def unwrapped_measurement(model, y: np.ndarray, x: np.ndarray, k: int) -> np.ndarray:
    """h(x_i, k) on the branch nearest y: y − residual(y, h(x_i)); equals h(x_i) (to rounding)
    for outputs that are not angles. x (..., N, D) with y (..., L)."""
    y = y[..., None, :]
    return y - model.residual(y, runs.evaluate_runs(model.h, x, k, model.measurement_dim))
