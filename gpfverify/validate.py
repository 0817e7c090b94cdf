"""Argument checks that turn bad input into :class:`~gpfverify.errors.InputError` naming the
argument. Ground floor: imports only :mod:`gpfverify.errors` and :mod:`gpfverify.tolerances`."""

from __future__ import annotations

import numpy as np

from gpfverify.errors import InputError
from gpfverify.tolerances import EPS

#: Relative asymmetry ||A - A^T|| / ||A|| accepted as rounding in a "symmetric" matrix.
SYMMETRY_RTOL = 1e-8
#: Relative negative eigenvalue -lambda_min / lambda_max accepted as rounding in a PSD matrix.
PSD_RTOL = 1e-10


def as_array(value, name: str, ndim: int | None = None, shape: tuple | None = None) -> np.ndarray:
    """A finite float array; ``shape`` entries of ``None`` match any size."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be numeric: {exc}") from None
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


def as_positive(value, name: str, shape: tuple | None = None) -> np.ndarray:
    arr = as_array(value, name, shape=shape)
    if np.any(arr <= 0):
        raise InputError(f"{name} must be strictly positive, got min {arr.min():.3g}")
    return arr


def as_covariance(value, name: str, dim: int | None = None, definite: bool = False) -> np.ndarray:
    """A symmetric positive semidefinite (``definite=True``: positive definite) matrix.

    Asymmetry up to :data:`SYMMETRY_RTOL` relative is accepted and removed; eigenvalues down to
    ``-PSD_RTOL * lambda_max`` count as rounding of a PSD matrix.
    """
    arr = as_matrix(value, name, dim, dim)
    if arr.shape[0] != arr.shape[1]:
        raise InputError(f"{name} must be square, got shape {arr.shape}")
    scale = max(float(np.abs(arr).max(initial=0.0)), np.finfo(float).tiny)
    asym = float(np.abs(arr - arr.T).max(initial=0.0))
    if asym > SYMMETRY_RTOL * scale:
        raise InputError(f"{name} is not symmetric (max |A - A^T| = {asym:.3g})")
    sym = 0.5 * (arr + arr.T)
    if sym.size == 0:
        return sym
    eig = np.linalg.eigvalsh(sym)
    floor = PSD_RTOL * max(abs(eig[-1]), EPS)
    if eig[0] < -floor:
        raise InputError(f"{name} is not positive semidefinite (min eigenvalue {eig[0]:.3g})")
    if definite and eig[0] <= max(floor, eig[-1] * sym.shape[0] * EPS):
        raise InputError(f"{name} is not positive definite (min eigenvalue {eig[0]:.3g})")
    return sym
