"""The CMF and DMF means of seed 000 (eq. 15, 32, 35) written over generic symbolic matrices.

For sensor m with l_m outputs the symbols are: the column block G_m (D×l_m) of G = C_xy C_y⁻¹
(any D×l_m matrix arises as such a block, since C_xy = G C_y is free), the local C_y^m (l_m×l_m,
symmetric), the local cross term C_xy^m (D×l_m), the measurement y^m, the local predicted
measurement μ_y^m, the central predicted measurement block μ_y(m) and the local prediction μ_p^m.
The local posterior is μ_e^m = μ_p^m + C_xy^m (C_y^m)⁻¹ (y^m − μ_y^m) (eq. 32), and

    μ_DMF = μ_p + Σ_m G_m (μ_y^m − μ_y(m)) + Σ_m G_m C_y^m (C_xy^m)⁺ (μ_e^m − μ_p^m)   (eq. 35)
    μ_CMF = μ_p + Σ_m G_m (y^m − μ_y(m))                                               (eq. 15)

The central μ_p appears identically in both, so μ_DMF − μ_CMF = Σ_m [DMF_m − CMF_m] with the
per-sensor terms below, each a rational function of sensor m's symbols only.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp
from sympy import QQ

from gpfverify.symbolic.polynomial import (Fraction, generic_matrix, generic_symmetric, identity,
                                           inverse, lift)


@dataclass(frozen=True)
class SensorSymbols:
    """Generic symbolic quantities of sensor ``index`` (see the module docstring)."""

    index: int
    G: sp.Matrix
    C_y: sp.Matrix
    y: sp.Matrix
    mu_y: sp.Matrix
    mu_y_central: sp.Matrix
    mu_p: sp.Matrix

    @classmethod
    def generic(cls, index: int, state_dim: int, outputs: int, G: sp.Matrix | None = None,
                C_y: sp.Matrix | None = None) -> SensorSymbols:
        """Every entry an independent symbol unless ``G`` or ``C_y`` is given."""
        m = index
        return cls(m,
                   generic_matrix(f"G{m}", state_dim, outputs) if G is None else G,
                   generic_symmetric(f"Cy{m}", outputs) if C_y is None else C_y,
                   generic_matrix(f"y{m}", outputs, 1), generic_matrix(f"my{m}", outputs, 1),
                   generic_matrix(f"mc{m}", outputs, 1), generic_matrix(f"mp{m}", state_dim, 1))

    def matrices(self) -> tuple[sp.Matrix, ...]:
        return (self.G, self.C_y, self.y, self.mu_y, self.mu_y_central, self.mu_p)


@dataclass(frozen=True)
class LiftedSensor:
    """A sensor's quantities as :class:`Fraction` over a common polynomial ring, with its cross
    term C_xy^m and the pseudo-inverse to use for it."""

    G: Fraction
    C_y: Fraction
    C_y_inv: Fraction
    C_xy: Fraction
    C_xy_pinv: Fraction
    innovation: Fraction  # y^m − μ_y^m
    mu_y: Fraction
    mu_y_central: Fraction
    y: Fraction
    mu_p: Fraction


def lift_sensor(sensor: SensorSymbols, ring, c_xy: Fraction, c_xy_pinv: Fraction) -> LiftedSensor:
    g, c_y, y, mu_y, mu_c, mu_p = (Fraction.of(lift(m, ring)) for m in sensor.matrices())
    return LiftedSensor(g, c_y, inverse(c_y), c_xy, c_xy_pinv, y - mu_y, mu_y, mu_c, y, mu_p)


def local_posterior_mean(s: LiftedSensor) -> Fraction:
    """μ_e^m = μ_p^m + C_xy^m (C_y^m)⁻¹ (y^m − μ_y^m) (eq. 32)."""
    return s.mu_p + s.C_xy @ s.C_y_inv @ s.innovation


def dmf_term(s: LiftedSensor) -> Fraction:
    """Sensor m's contribution to μ_DMF − μ_p: G_m(μ_y^m − μ_y(m)) + G_m C_y^m (C_xy^m)⁺(μ_e^m − μ_p^m)."""
    return s.G @ (s.mu_y - s.mu_y_central) + s.G @ s.C_y @ s.C_xy_pinv @ (local_posterior_mean(s) - s.mu_p)


def cmf_term(s: LiftedSensor) -> Fraction:
    """Sensor m's contribution to μ_CMF − μ_p: G_m (y^m − μ_y(m))."""
    return s.G @ (s.y - s.mu_y_central)


def projector(s: LiftedSensor) -> Fraction:
    """P_m = (C_xy^m)⁺ C_xy^m, the orthogonal projector onto the row space of C_xy^m."""
    return s.C_xy_pinv @ s.C_xy


def predicted_gap_term(s: LiftedSensor) -> Fraction:
    """Sensor m's term of the closed-form gap: G_m C_y^m (P_m − I)(C_y^m)⁻¹(y^m − μ_y^m)."""
    outputs = s.C_y.shape[0]
    return s.G @ s.C_y @ (projector(s) - identity(outputs, s.G.num.domain)) @ s.C_y_inv @ s.innovation


def kernel_condition(s: LiftedSensor) -> Fraction:
    """G_m C_y^m (I − P_m): zero iff ker C_xy^m ⊆ ker G_m C_y^m (the exactness condition)."""
    outputs = s.C_y.shape[0]
    return s.G @ s.C_y @ (identity(outputs, s.G.num.domain) - projector(s))


def whole_difference(state_dim: int, sizes: tuple[int, ...]):
    """μ_DMF − μ_CMF for N = len(sizes) sensors computed as one expression in the rational
    function field Q(all entries), full-column-rank (C_xy^m)⁺ = (AᵀA)⁻¹Aᵀ, no per-sensor
    decomposition: the central μ_p, both sums and the local updates are formed and subtracted
    with exact cancellation. Returns the D×1 DomainMatrix (zero iff the identity holds)."""
    sensors = [SensorSymbols.generic(m, state_dim, l) for m, l in enumerate(sizes)]
    cross = [generic_matrix(f"A{m}", state_dim, l) for m, l in enumerate(sizes)]
    mu_p_sym = generic_matrix("mp", state_dim, 1)
    matrices = [mu_p_sym, *cross] + [m for s in sensors for m in s.matrices()]
    symbols = sorted(set().union(*(m.free_symbols for m in matrices)), key=str)
    field = QQ.frac_field(*symbols)
    mu_p = lift(mu_p_sym, field)
    dmf, cmf = mu_p, mu_p
    for sensor, a_sym in zip(sensors, cross):
        g, c_y, y, mu_y, mu_c, mu_p_m = (lift(m, field) for m in sensor.matrices())
        a = lift(a_sym, field)
        mu_e = mu_p_m + a * c_y.inv() * (y - mu_y)
        a_pinv = (a.transpose() * a).inv() * a.transpose()
        dmf = dmf + g * (mu_y - mu_c) + g * c_y * a_pinv * (mu_e - mu_p_m)
        cmf = cmf + g * (y - mu_c)
    return dmf - cmf
