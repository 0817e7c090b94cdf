"""expm1 by the algorithm of the fused moment-matching kernel (:mod:`gpfverify.gp.fused`, whose
docstring derives it): Cody–Waite reduction by ln 2 and a degree-9 Chebyshev polynomial by Estrin's
scheme. :func:`expm1_reference` evaluates it in numpy, one IEEE operation per step; the compiled
kernel (:mod:`gpfverify.gp.fused_kernels`) uses the same constants and :func:`_expm1_reduced`.
"""

from __future__ import annotations

import numpy as np

#: ln 2 split so that k·LN2_HI is exact for |k| < 2²⁰ (fdlibm's constants)
LN2_HI = 6.93147180369123816490e-01
LN2_LO = 1.90821492927058770002e-10
INV_LN2 = 1.44269504088896338700e+00
#: 1.5·2⁵²: adding it rounds x/ln 2 to an integer held in the low bits of the sum
SHIFTER = 6755399441055744.0
_SHIFTER_BITS = int(np.float64(SHIFTER).view(np.int64))
#: expm1(x) rounds to −1 for x ≤ LOWEST
LOWEST = -60.0
#: P's coefficients, constant term first: mpmath's Chebyshev fit (``chebyfit``, 50 digits) of
#: (expm1(r) − r)/r² on |r| ≤ ½ ln 2 · (1 + 2⁻³⁰), degree 9, rounded to doubles
#: (tests/test_gp_fused.py fits them again). Two terms fewer than the Taylor series to r¹³ needs
#: for the same accuracy, and the polynomial is most of the exponential's work.
_P = (0.5000000000000001, 0.16666666666666669, 0.041666666666624164, 0.008333333333330065,
      0.0013888888917196719, 0.00019841269863040545, 2.4801521322368448e-05, 2.7557268480309837e-06,
      2.7620075880100385e-07, 2.510037583265122e-08)
(_P0, _P1, _P2, _P3, _P4, _P5, _P6, _P7, _P8, _P9) = _P


def _expm1_reduced(r):
    """expm1(r) ≈ r + r²·P(r) for |r| ≤ ½ ln 2 (:data:`_P`), P by Estrin's scheme (pairs, then
    powers r², r⁴, r⁸): a dependency chain a third as long as Horner's, so the compiled loop is
    not bound by the latency of one long chain. Works on floats and on arrays alike."""
    r2 = r * r
    r4 = r2 * r2
    low = (_P0 + _P1 * r) + (_P2 + _P3 * r) * r2
    middle = (_P4 + _P5 * r) + (_P6 + _P7 * r) * r2
    return r2 * ((low + middle * r4) + (_P8 + _P9 * r) * (r4 * r4)) + r


def expm1_reference(x: np.ndarray) -> np.ndarray:
    """expm1 by the kernel's algorithm in numpy, one IEEE operation per step (module docstring);
    for x ≤ 700."""
    x = np.maximum(np.asarray(x, dtype=float), LOWEST)
    t = x * INV_LN2 + SHIFTER
    k = t - SHIFTER
    r = (x - k * LN2_HI) - k * LN2_LO
    p = _expm1_reduced(r)
    scale = ((t.view(np.int64) - _SHIFTER_BITS + 1023) << 52).view(np.float64)  # 2ᵏ
    return scale * p + (scale - 1.0)
