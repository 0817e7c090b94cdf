"""Argument checks that turn bad input into :class:`~gpfverify.errors.InputError` naming the
argument. Ground floor: imports only :mod:`gpfverify.errors` and :mod:`gpfverify.tolerances`."""

from __future__ import annotations

import numpy as np

from gpfverify.errors import InputError, NumericalError
from gpfverify.tolerances import EPS, PSD_RTOL, SYMMETRY_RTOL

__all__ = ["PSD_RTOL", "SYMMETRY_RTOL"]  # re-exported: the thresholds of covariance_defects

#: Array kinds (numpy dtype.kind) that are not real numbers, as named in messages.
_NOT_REAL = {"b": "booleans", "c": "complex numbers", "U": "text", "S": "bytes", "V": "structured records",
             "M": "dates", "m": "time spans"}


def _kind(value) -> str:
    """numpy's dtype kind of ``value`` as an array ("O" when it is not one, e.g. a ragged list)."""
    try:
        return np.asarray(value).dtype.kind
    except (TypeError, ValueError):
        return "O"


def real_floats(value, name: str) -> np.ndarray:
    """``value`` as a float array, refused (not converted) when it holds booleans, complex numbers
    (numpy would drop their imaginary parts) or text; no check of shape or finiteness."""
    kind = _kind(value)
    if kind in _NOT_REAL:
        raise InputError(f"{name} must be numeric (real numbers), got {_NOT_REAL[kind]}")
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be numeric: {exc}") from None


def as_array(value, name: str, ndim: int | None = None, shape: tuple | None = None) -> np.ndarray:
    """A finite float array; ``shape`` entries of ``None`` match any size. Booleans, complex
    numbers and text are refused, not converted."""
    arr = real_floats(value, name)
    if ndim is not None and arr.ndim != ndim:
        raise InputError(f"{name} must have {ndim} dimension(s), got shape {arr.shape}")
    if shape is not None:
        if arr.ndim != len(shape) or any(
            want is not None and got != want for got, want in zip(arr.shape, shape)
        ):
            want = tuple("?" if s is None else s for s in shape)
            raise InputError(f"{name} must have shape {want}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} contains NaN or inf")
    return arr


def as_vector(value, name: str, size: int | None = None) -> np.ndarray:
    return as_array(value, name, shape=(size,))


def as_matrix(value, name: str, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    return as_array(value, name, shape=(rows, cols))


def as_indices(value, count: int, name: str) -> tuple[int, ...]:
    """0-based indices into ``count`` components, sorted and unique; InputError naming ``name``."""
    try:
        items = list(value)
    except TypeError:
        raise InputError(f"{name} must be a list of 0-based indices, got {value!r}") from None
    for i in items:
        if isinstance(i, (bool, np.bool_)) or not isinstance(i, (int, np.integer)):
            raise InputError(f"{name} must hold integers, got {i!r}")
        if not 0 <= i < count:
            raise InputError(f"{name} index {i} is out of range for {count} component(s)")
    if len(set(items)) != len(items):
        raise InputError(f"{name} lists an index twice: {items}")
    return tuple(sorted(int(i) for i in items))


def as_positive(value, name: str, shape: tuple | None = None) -> np.ndarray:
    arr = as_array(value, name, shape=shape)
    if np.any(arr <= 0):
        raise InputError(f"{name} must be strictly positive, got min {arr.min():.3g}")
    return arr


def as_covariance(value, name: str, dim: int | None = None, definite: bool = False) -> np.ndarray:
    """A symmetric positive semidefinite (``definite=True``: positive definite) matrix, judged
    without units (:func:`covariance_defects`); the asymmetry of rounding is removed."""
    arr = as_matrix(value, name, dim, dim)
    if arr.shape[0] != arr.shape[1]:
        raise InputError(f"{name} must be square, got shape {arr.shape}")
    sym, bad, why = covariance_defects(arr[None], definite)
    if bad[0]:
        raise InputError(f"{name} {why(0)}")
    return sym[0]


def correlation_scale(stack: np.ndarray) -> np.ndarray:
    """(..., n) the scales s with A_ij / (s_i s_j) unit-free: s_i = sqrt(A_ii) where A_ii > 0; a
    component whose variance is zero or negative is measured on the matrix's largest standard
    deviation (1 for an all-zero matrix), so its entries are judged relative to the others."""
    diag = np.diagonal(stack, axis1=-2, axis2=-1)
    largest = diag.max(axis=-1, keepdims=True, initial=0.0)
    fallback = np.where(largest > 0, largest, 1.0)
    return np.sqrt(np.where(diag > 0, diag, fallback))


def covariance_defects(stack: np.ndarray, definite: bool = False):
    """The rule of :func:`as_covariance` applied to a stack of square matrices (..., n, n) at once:
    ``(symmetrised stack, bad (...,) bool, why)`` where ``why(index)`` says what is wrong with a
    bad matrix (``is not symmetric (max |A - A^T| = ...)``).

    The rule has no units: rescaling components (A -> S A S, S diagonal positive) never changes
    the verdict. It is applied to the correlation matrix R = D^-1/2 A D^-1/2 with D_ii = A_ii
    (:func:`correlation_scale` for zero variances): symmetric when max |R - R^T| <=
    ``SYMMETRY_RTOL``; positive semidefinite when R's least eigenvalue is >= -``PSD_RTOL`` times
    its largest; positive definite, in addition, when it exceeds that and n·eps times the largest.
    """
    s = correlation_scale(stack)
    unit = 1.0 / (s[..., :, None] * s[..., None, :])
    swapped = np.swapaxes(stack, -1, -2)
    asym_abs = np.abs(stack - swapped).max(axis=(-2, -1), initial=0.0)
    not_symmetric = (np.abs(stack - swapped) * unit).max(axis=(-2, -1), initial=0.0) > SYMMETRY_RTOL
    sym = 0.5 * (stack + swapped)
    if stack.shape[-1] == 0:
        return sym, not_symmetric, lambda i: f"is not symmetric (max |A - A^T| = {asym_abs[i]:.3g})"
    eig = np.linalg.eigvalsh(sym * unit)
    lo, hi = eig[..., 0], eig[..., -1]
    floor = PSD_RTOL * np.maximum(np.abs(hi), EPS)
    not_psd = lo < -floor
    not_pd = (lo <= np.maximum(floor, hi * stack.shape[-1] * EPS)) if definite else np.zeros_like(not_psd)

    def why(i) -> str:
        if not_symmetric[i]:
            return f"is not symmetric (max |A - A^T| = {asym_abs[i]:.3g})"
        kind = "semidefinite" if not_psd[i] else "definite"
        return f"is not positive {kind} (least eigenvalue of its correlation matrix {lo[i]:.3g})"

    return sym, not_symmetric | not_psd | not_pd, why


def computed_covariance(value, name: str) -> np.ndarray:
    """A covariance a computation produced, checked before anyone sees it: symmetric and positive
    semidefinite to rounding by the rule of :func:`covariance_defects`; :class:`NumericalError`
    naming ``name`` otherwise (a result that is not a covariance is never shown)."""
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise NumericalError(f"{name} holds a NaN or an inf")
    sym, bad, why = covariance_defects(arr[None])
    if bad[0]:
        raise NumericalError(f"{name} {why(0)}")
    return sym[0]
