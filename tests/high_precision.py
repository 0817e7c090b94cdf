"""One fusion step recomputed in 50-digit arithmetic (mpmath), from the same double-precision
inputs: CMF (eq. 36) and eq. 35 with the Moore–Penrose inverse truncated at given ranks in C_xy^m's
own SVD, angle outputs and angle state components differenced and wrapped on the circle. The
difference to the double-precision results is the rounding of the double-precision step, up to
1e-50; an independent route (no code of gpfverify's fusion)."""

from __future__ import annotations

import mpmath
import numpy as np

from gpfverify.fusion.case import FusionCase

DIGITS = 50


def _matrix(a) -> mpmath.matrix:
    a = np.atleast_2d(np.asarray(a, dtype=float))
    return mpmath.matrix([[mpmath.mpf(float(x)) for x in row] for row in a])


def _vector(a) -> mpmath.matrix:
    return mpmath.matrix([mpmath.mpf(float(x)) for x in np.asarray(a, dtype=float).ravel()])


def _wrapped(v: mpmath.matrix, indices) -> mpmath.matrix:
    """v with the listed components brought into (−π, π]."""
    v = v.copy()
    for i in indices:
        while v[i] > mpmath.pi:
            v[i] -= 2 * mpmath.pi
        while v[i] <= -mpmath.pi:
            v[i] += 2 * mpmath.pi
    return v


def _moore_penrose(c: mpmath.matrix, rank: int) -> mpmath.matrix:
    u, s, vt = mpmath.svd_r(c, full_matrices=False)
    out = mpmath.zeros(c.cols, c.rows)
    for i in range(rank):
        out += (vt[i, :].T * (1 / s[i])) * u[:, i].T
    return out


def _floats(v: mpmath.matrix) -> np.ndarray:
    return np.array([float(x) for x in v])


def fused_means(case: FusionCase, ranks) -> tuple[np.ndarray, np.ndarray]:
    """(DMF mean, CMF mean) of ``case`` (which must carry y) in 50-digit arithmetic, eq. 35's inverse
    truncated at ``ranks`` (one per sensor), rounded to double at the end."""
    with mpmath.workdps(DIGITS):
        c = case.central
        gain = _matrix(c.C_xy) * mpmath.inverse(_matrix(c.C_y))
        mu_p = _vector(c.mu_p)
        cmf = _wrapped(mu_p + gain * _wrapped(_vector(case.y) - _vector(c.mu_y), c.circular), c.circular_state)
        parts = []
        for block, local, rank in zip(c.blocks, case.locals, ranks):
            change = _wrapped(_vector(local.mu_e) - _vector(local.mu_p), c.circular_state)
            recovered = _moore_penrose(_matrix(local.C_xy), rank) * change
            first = _wrapped(_vector(local.mu_y) - _vector(c.mu_y[block]), local.circular)
            parts.extend(first + _matrix(local.C_y) * recovered)
        dmf = _wrapped(mu_p + gain * mpmath.matrix(parts), c.circular_state)
        return _floats(dmf), _floats(cmf)
