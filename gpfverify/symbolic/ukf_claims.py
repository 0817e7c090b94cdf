"""At the listed sizes, the unscented transform is exact for affine maps, so the UKF equals the KF
on linear models (seed 000 eq. 21–31 with symbolic sigma-point parameters).

Sigma points χ_0 = μ, χ_{±i} = μ ± √s L_i with C = LLᵀ (L lower triangular), s = D + λ,
λ = α²(D + κ) − D; weights w_m0 = λ/s, w_c0 = w_m0 + 1 − α² + β, w_i = 1/(2s). For y = Hx + b:
Σ w_m Hχ + b = Hμ + b, Σ w_c (y_i − ȳ)(y_i − ȳ)ᵀ = HCHᵀ, Σ w_c (χ_i − μ)(y_i − ȳ)ᵀ = CHᵀ —
the KF's predicted mean, covariance and cross covariance, so the update μ + C_xy C_y⁻¹(y − ȳ),
C − C_xy C_y⁻¹ C_xyᵀ (C_y = HCHᵀ + R) and the prediction (H = F, b = u, + Q) coincide with the KF.
"""

from __future__ import annotations

import time

import sympy as sp

from gpfverify.symbolic.argument import Argument
from gpfverify.symbolic.certificate import Certificate
from gpfverify.symbolic.polynomial import generic_matrix

SIZES = {"small": ((1, 1), (2, 1), (2, 2), (3, 2)), "large": ((1, 1), (2, 1), (2, 2), (3, 1), (3, 2), (3, 3), (4, 2))}


def unscented_moments(mean: sp.Matrix, factor: sp.Matrix, transform, s, gamma):
    """(ȳ, C_y, C_xy) of the scaled unscented transform of ``transform`` at N(mean, factor factorᵀ).
    The parameters enter only through s = D + λ = α²(D + κ) and γ = 1 − α² + β."""
    d = mean.shape[0]
    lam = s - d
    root = sp.sqrt(s)
    points = [mean] + [mean + root * factor[:, i] for i in range(d)] + [mean - root * factor[:, i] for i in range(d)]
    w_mean = [lam / s] + [1 / (2 * s)] * (2 * d)
    w_cov = [lam / s + gamma] + [1 / (2 * s)] * (2 * d)
    images = [transform(p) for p in points]
    y_bar = sum((w * y for w, y in zip(w_mean, images)), sp.zeros(*images[0].shape))
    c_y = sum((w * (y - y_bar) * (y - y_bar).T for w, y in zip(w_cov, images)), sp.zeros(y_bar.shape[0]))
    c_xy = sum((w * (p - mean) * (y - y_bar).T for w, p, y in zip(w_cov, points, images)),
               sp.zeros(d, y_bar.shape[0]))
    return y_bar, c_y, c_xy


def prove_ukf_equals_kf(size: str = "small") -> Certificate:
    start = time.perf_counter()
    s = sp.Symbol("s", positive=True)  # D + λ = α²(D + κ)
    gamma = sp.Symbol("gamma", real=True)  # 1 − α² + β
    argument = Argument("ukf-equals-kf-linear",
                        "at the listed sizes, the unscented transform is exact for affine maps, so the UKF equals the "
                        "KF on linear models", "sympy: symbolic sigma points")
    shown = []
    for d, l in SIZES[size]:
        mean = generic_matrix("mu", d, 1)
        factor = sp.Matrix(d, d, lambda i, j: sp.Symbol(f"L_{i}_{j}") if j <= i else 0)
        h, b = generic_matrix("H", l, d), generic_matrix("b", l, 1)
        y_bar, c_y, c_xy = unscented_moments(mean, factor, lambda x, h=h, b=b: h * x + b, s, gamma)
        cov = factor * factor.T
        label = f"(D, l) = ({d}, {l})"
        argument.at_sizes("unscented mean = Hμ + b", label, y_bar - (h * mean + b))
        argument.at_sizes("unscented covariance = HCHᵀ", label, c_y - h * cov * h.T)
        argument.at_sizes("unscented cross covariance = CHᵀ", label, c_xy - cov * h.T)
        shown.append(f"({d}, {l})")
    _negative_controls(argument, s, gamma)
    argument.note(f"For (D, l) ∈ {{{', '.join(shown)}}}: every entry of μ, of the lower Cholesky factor L of C, of H "
                  "and b free, and the sigma-point parameters symbolic through s = D + λ = α²(D + κ) > 0 and "
                  "γ = 1 − α² + β, the only ways α, β, κ enter (√s kept symbolic). The UKF prediction (H = F) and "
                  "update then apply the KF's formulas to identical moments: at these sizes UKF = KF on "
                  "linear-Gaussian models for every choice of sigma-point parameters with s > 0.")
    return argument.certificate(time.perf_counter() - start)


def _negative_controls(argument: Argument, s, gamma) -> None:
    """The same exactness test on statements that must fail, at D = 2, l = 1."""
    mean = generic_matrix("mu", 2, 1)
    factor = sp.Matrix(2, 2, lambda i, j: sp.Symbol(f"L_{i}_{j}") if j <= i else 0)
    h, b = generic_matrix("H", 1, 2), generic_matrix("b", 1, 1)
    cov = factor * factor.T
    y_bar, c_y, c_xy = unscented_moments(mean, factor, lambda x: h * x + b, s, gamma)
    sq_bar, _, _ = unscented_moments(mean, factor, lambda x: (h * x).applyfunc(lambda e: e**4), s, gamma)
    hm, hch = (h * mean)[0], (h * cov * h.T)[0]
    for mutant, residual in (
            ("ȳ = Hμ (offset b dropped)", y_bar - h * mean),
            ("C_xy = −CHᵀ (sign)", c_xy + cov * h.T),
            ("C_y = HCHᵀ + HHᵀ (extra term)", c_y - h * cov * h.T - h * h.T),
            ("mean exact for the quartic map x ↦ (Hx)⁴ (true only at s = 3)",
             sq_bar - sp.Matrix([hm**4 + 6 * hm**2 * hch + 3 * hch**2]))):
        argument.control_residual(mutant, residual)
