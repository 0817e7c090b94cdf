"""Strategies for matrices with a prescribed spectrum.

Every matrix is built from its factors, so it is valid by construction (no ``assume``):

* :func:`orthonormal_matrices` — Q from the QR factorisation of a drawn square matrix (Householder
  QR returns an orthogonal Q for *any* input, even a singular one);
* :func:`spd_matrices` — Q diag(λ) Qᵀ with λ_i = scale · max_condition^{u_i}, u_i ∈ [0, 1];
* :func:`matrices_with_singular_values` — U diag(s) Vᵀ with orthonormal U, V.

Drawn entries shrink towards 0, so a shrunk counterexample is as structured as the property allows
(Q → ±I, λ → scale).
"""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from gpfverify.errors import InputError
from gpfverify.linalg import symmetrize


#: Magnitudes below this are drawn as exactly 0. Squares of smaller numbers underflow (below
#: ~1e-154 ``x * x`` is subnormal or 0), so 2-norms and every rounding bound built on them stop
#: meaning anything; such values are not in the domain any property here is about.
TINY = 1e-100


def _flush_tiny(x: float) -> float:
    return 0.0 if abs(x) < TINY else x


def unit_floats(low: float = -1.0, high: float = 1.0) -> st.SearchStrategy[float]:
    """Finite floats in [low, high] with magnitude 0 or ≥ :data:`TINY` (no subnormals, no values
    whose square underflows)."""
    return st.floats(low, high, allow_nan=False, allow_infinity=False,
                     allow_subnormal=False).map(_flush_tiny)


def float_arrays(shape, low: float = -1.0, high: float = 1.0) -> st.SearchStrategy[np.ndarray]:
    """Float arrays of ``shape`` with entries in [low, high]."""
    return arrays(np.float64, shape, elements=unit_floats(low, high))


def as_strategy(value) -> st.SearchStrategy:
    """``value`` if it already is a strategy, else ``just(value)``."""
    return value if isinstance(value, st.SearchStrategy) else st.just(value)


@st.composite
def orthonormal_matrices(draw, rows: int, cols: int | None = None) -> np.ndarray:
    """(rows, cols) matrices with orthonormal columns (cols ≤ rows; default square).

    Guarantee: QᵀQ = I to rounding."""
    cols = rows if cols is None else cols
    if not 0 <= cols <= rows:
        raise InputError(f"orthonormal_matrices needs 0 <= cols <= rows, got {rows} x {cols}")
    if rows == 0:
        return np.zeros((0, cols))
    q, _ = np.linalg.qr(draw(float_arrays((rows, rows))))
    return q[:, :cols]


@st.composite
def log_uniform(draw, low: float, high: float) -> float:
    """A float in [low, high] (0 < low ≤ high), uniform in log scale; shrinks to ``low``."""
    if not 0 < low <= high:
        raise InputError(f"log_uniform needs 0 < low <= high, got {low}, {high}")
    return float(low * (high / low) ** draw(unit_floats(0.0, 1.0)))


@st.composite
def spd_matrices(draw, dim, max_condition: float = 1e3, scale=1.0) -> np.ndarray:
    """Symmetric positive definite (dim, dim) matrices with condition number ≤ ``max_condition``.

    Parameters: ``dim`` an int or a strategy of ints (≥ 0); ``max_condition`` ≥ 1; ``scale`` (> 0,
    float or strategy) the smallest eigenvalue. Eigenvalues lie in [scale, scale·max_condition]
    (to rounding, relative ``dim · eps · max_condition``); the matrix is exactly symmetric.
    """
    if max_condition < 1:
        raise InputError(f"max_condition must be >= 1, got {max_condition}")
    n = draw(as_strategy(dim))
    low = float(draw(as_strategy(scale)))
    if low <= 0:
        raise InputError(f"scale must be > 0, got {low}")
    q = draw(orthonormal_matrices(n))
    exponents = draw(float_arrays((n,), 0.0, 1.0))
    eigenvalues = low * max_condition ** exponents
    return symmetrize((q * eigenvalues) @ q.T)


@st.composite
def matrices_with_singular_values(draw, rows: int, cols: int, singular_values) -> np.ndarray:
    """U diag(s) Vᵀ (rows, cols) with the given non-negative singular values s (len ≤ min(rows,
    cols)); U and V are drawn orthonormal. Guarantee: the singular values of the result are
    exactly ``s`` plus zeros, to rounding of order eps · max(s)."""
    s = np.asarray(singular_values, dtype=float)
    if s.ndim != 1 or s.size > min(rows, cols) or np.any(s < 0):
        raise InputError(f"need at most {min(rows, cols)} non-negative singular values, got {s}")
    u = draw(orthonormal_matrices(rows, s.size))
    v = draw(orthonormal_matrices(cols, s.size))
    return (u * s) @ v.T


@st.composite
def spread_values(draw, count: int, largest: float, max_ratio: float) -> np.ndarray:
    """``count`` values in [largest / max_ratio, largest], sorted decreasingly, the first equal to
    ``largest`` (so the ratio of the extremes is ≤ max_ratio and the scale is known)."""
    if count == 0:
        return np.zeros(0)
    exponents = draw(float_arrays((count - 1,), 0.0, 1.0))
    values = largest * max_ratio ** (-exponents)
    return np.sort(np.concatenate([[largest], values]))[::-1]
