"""The compiled rank-one loop of :func:`gpfverify.filters.sr_ukf.cholupdate` (numba, the optional
``fast`` extra; imported on first use). Every step is the IEEE operation of the numpy loop there,
in the same order (no fused multiply–add, no reassociation requested), so both agree to rounding
and flag the same failed downdates (tested); a compiler or processor may still round differently,
so the two routes are never held to the same bits."""

from __future__ import annotations

import numba
import numpy as np

from gpfverify import numba_target

numba_target.configure()


@numba.njit(cache=True, nogil=True, error_model="numpy")
def cholupdate_in_place(lower: np.ndarray, x: np.ndarray, sign: float) -> None:
    """L ← L' with L'L'ᵀ = L Lᵀ + sign · x xᵀ for lower (B, D, D) and x (B, D), both overwritten
    (x with the rotated remainder), column by column as in :func:`gpfverify.filters.sr_ukf.cholupdate`."""
    batch, dim = x.shape
    for b in range(batch):
        for k in range(dim):
            diag = lower[b, k, k]
            xk = x[b, k]
            r = np.sqrt(diag * diag + sign * xk * xk)
            c = r / diag
            s = xk / diag
            lower[b, k, k] = r
            for i in range(k + 1, dim):
                column = (lower[b, i, k] + sign * s * x[b, i]) / c
                lower[b, i, k] = column
                x[b, i] = c * x[b, i] - s * column
