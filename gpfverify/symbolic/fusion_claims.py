"""Symbolic proofs of the fusion claims (seed 000 Proposition 1 and what SPEC §3 adds to it).

Every explicit-size check is exact polynomial arithmetic over Q[entries] (see
:mod:`gpfverify.symbolic.polynomial`); every dimension-free argument is a proof in the word
algebra of :mod:`gpfverify.symbolic.word_algebra` from stated, instance-checked rules, with negative
controls (see :mod:`gpfverify.symbolic.dimension_free`). μ_DMF − μ_CMF = Σ_m (DMF_m − CMF_m)
is a sum of per-sensor rational functions (module docstring of
:mod:`gpfverify.symbolic.fusion_forms`), so an identity checked for every sensor of a
configuration holds for the configuration.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
import sympy as sp

from gpfverify.symbolic import dimension_free, rewrites
from gpfverify.symbolic.certificate import Certificate, verdict
from gpfverify.symbolic.fusion_forms import (LiftedSensor, SensorSymbols, cmf_term, dmf_term,
                                             kernel_condition, lift_sensor, predicted_gap_term,
                                             whole_difference)
from gpfverify.symbolic.polynomial import (Fraction, factored_pinv, full_column_rank_pinv,
                                           generic_matrix, identity, lift, penrose_residuals,
                                           polynomial_ring)

#: (D, l_m, rank) families of rank-deficient cross terms C_xy^m = B Fᵀ, B (D×r), F (l×r).
RANK_DEFICIENT = {
    "small": ((1, 2, 1), (2, 2, 1), (2, 3, 1), (3, 2, 1), (3, 3, 1)),
    "large": ((1, 2, 1), (1, 3, 1), (2, 2, 1), (2, 3, 1), (2, 3, 2), (3, 2, 1), (3, 3, 1), (3, 3, 2)),
}
#: (D, (l_1, …, l_N)) configurations whose whole μ_DMF − μ_CMF is reduced in Q(entries)
#: (seconds on one core: D=3 with (3, 1) ≈ 30, (3, 3) ≈ 90 — left out, the per-sensor route covers
#: it; the small set ≈ 3 in total).
WHOLE_EXPRESSION = {
    "small": ((1, (1, 1)), (1, (1, 1, 1)), (2, (1, 1)), (2, (2, 1)), (2, (2, 2)), (2, (1, 1, 1)),
              (3, (1, 1)), (3, (2, 1))),
    "large": ((1, (1, 1)), (1, (1, 1, 1)), (2, (1, 1)), (2, (2, 1)), (2, (2, 2)), (2, (1, 1, 1)),
              (2, (2, 1, 1)), (2, (2, 2, 1)), (2, (2, 2, 2)), (3, (1, 1)), (3, (2, 1)), (3, (2, 2)),
              (3, (3, 1)), (3, (3, 2)), (3, (1, 1, 1)), (3, (2, 1, 1))),
}
#: Families for the kernel-inclusion claim (the sufficiency family G_m = W C_xy^m (C_y^m)⁻¹ grows
#: fast: (2, 3, 1) ≈ 6 s, (3, 3, 1) ≈ 14 s, (2, 3, 2) ≈ 4 min on one core).
KERNEL_FAMILIES = {
    "small": ((1, 2, 1), (1, 3, 1), (2, 2, 1), (3, 2, 1)),
    "large": ((1, 2, 1), (1, 3, 1), (2, 2, 1), (2, 3, 1), (3, 2, 1), (3, 3, 1)),
}
#: Seed of the evaluation points that show a formula is not identically zero.
POINT_SEED = 20191126


@dataclass(frozen=True)
class SymbolicSensor:
    """One sensor's quantities over its own polynomial ring, with the symbols they are generic in."""

    lifted: LiftedSensor
    symbols: tuple[sp.Matrix, ...]
    ring: object

    def lift(self, matrix: sp.Matrix) -> Fraction:
        return Fraction.of(lift(matrix, self.ring))


def build_sensor(state_dim: int, outputs: int, rank: int | None = None, kernel_inclusion: bool = False,
                 extra: tuple[sp.Matrix, ...] = (), point: dict | None = None) -> SymbolicSensor:
    """A symbolic sensor (index 0) whose every entry is a free symbol.

    ``rank`` None: C_xy^m = A generic D×l with (C_xy^m)⁺ = (AᵀA)⁻¹Aᵀ (full column rank).
    ``rank`` r: C_xy^m = B Fᵀ with B (D×r), F (l×r) generic, (C_xy^m)⁺ = F(FᵀF)⁻¹(BᵀB)⁻¹Bᵀ.
    ``kernel_inclusion``: G_m = W C_xy^m (C_y^m)⁻¹ with W generic D×D — the general solution of
    G_m C_y^m (I − P_m) = 0 (rows of G_m C_y^m in the row space of C_xy^m). ``extra`` symbol
    matrices join the ring (e.g. a direction v). With ``point`` (symbol -> number) the same
    sensor is built at that point, over Q (fast evaluation of the same formulas).
    """
    generic = SensorSymbols.generic(0, state_dim, outputs)
    sensor = generic if not kernel_inclusion else SensorSymbols(
        0, sp.zeros(state_dim, outputs), *generic.matrices()[1:])
    factors: tuple[sp.Matrix, ...]
    if rank is None:
        factors = (generic_matrix("A0", state_dim, outputs),)
    else:
        factors = (generic_matrix("B0", state_dim, rank), generic_matrix("F0", outputs, rank))
    w_sym: tuple[sp.Matrix, ...] = (generic_matrix("W0", state_dim, state_dim),) if kernel_inclusion else ()
    symbols = tuple(m for m in sensor.matrices() if m.free_symbols) + factors + w_sym + tuple(extra)
    if point is not None:
        sensor = SensorSymbols(0, *(m.subs(point) for m in sensor.matrices()))
        factors = tuple(m.subs(point) for m in factors)
        w_sym = tuple(m.subs(point) for m in w_sym)
        ring = polynomial_ring(*sensor.matrices(), *factors, *w_sym)  # Q if nothing is left symbolic
    else:
        ring = polynomial_ring(*symbols)
    lifted_factors = [Fraction.of(lift(m, ring)) for m in factors]
    if rank is None:
        a = lifted_factors[0]
        a_pinv = full_column_rank_pinv(a)
    else:
        b, f = lifted_factors
        a, a_pinv = b @ f.T, factored_pinv(b, f)
    lifted = lift_sensor(sensor, ring, a, a_pinv)
    if kernel_inclusion:
        lifted = replace(lifted, G=Fraction.of(lift(w_sym[0], ring)) @ a @ lifted.C_y_inv)
    return SymbolicSensor(lifted, symbols, ring)


def _free(symbols) -> set:
    return set().union(*(m.free_symbols for m in symbols))


def random_point(symbols, rng: np.random.Generator) -> dict:
    """Small random integers for every free symbol (deterministic given ``rng``)."""
    return {s: int(rng.integers(-4, 5)) for s in sorted(_free(symbols), key=str)}


def nonzero_somewhere(formula, symbols, build, rng: np.random.Generator, tries: int = 20):
    """An integer point where ``formula(build(point), point)`` (a :class:`Fraction` over Q) is
    defined and nonzero, with its value; None if ``tries`` points fail. Evidence that a formula
    is not identically zero."""
    for _ in range(tries):
        point = random_point(symbols, rng)
        try:
            value = formula(build(point), point)
            matrix = value.num.to_Matrix() / value.num.domain.to_sympy(value.den)
        except ZeroDivisionError:
            continue
        if any(matrix):
            return point, matrix
    return None


def _dimension_free_detail(result: dimension_free.DimensionFreeResult) -> str:
    return (f"Any dimension (word-algebra rewriting from stated rules, "
            f"{'every proof accepted' if result.holds else 'a proof or rule check FAILED'}): {result.describe()}")


def _controls(result: dimension_free.DimensionFreeResult) -> tuple:
    return tuple(c.to_json() for c in result.controls)


# ---- prop1-full-column-rank ------------------------------------------------------------------

def prove_prop1(size: str = "small") -> Certificate:
    start = time.perf_counter()
    per_sensor_ok, penrose_ok, largest = True, True, 0
    pairs = [(d, l) for d in (1, 2, 3) for l in range(1, d + 1)]
    for d, l in pairs:
        s = build_sensor(d, l).lifted
        penrose_ok &= all(r.is_zero() for r in penrose_residuals(s.C_xy, s.C_xy_pinv).values())
        per_sensor_ok &= (dmf_term(s) - cmf_term(s)).is_zero()
        largest = max(largest, dmf_term(s).term_count())
    whole = WHOLE_EXPRESSION[size]
    whole_ok = all(whole_difference(d, sizes).is_zero_matrix for d, sizes in whole)
    general = dimension_free.prop1()
    holds = per_sensor_ok and penrose_ok and whole_ok and general.holds
    detail = (
        "(a) Per sensor, for every (D, l_m) with l_m ≤ D ≤ 3: DMF_m − CMF_m = N_m/(det(C_xyᵀC_xy)·det(C_y^m)) "
        "with every entry of G_m, C_y^m (symmetric), C_xy^m, y^m, μ_y^m, μ_y(m), μ_p^m a free symbol and "
        "(C_xy^m)⁺ = (C_xyᵀC_xy)⁻¹C_xyᵀ written as adj/det; every numerator N_m expands to the zero "
        f"polynomial ({'yes' if per_sensor_ok else 'NO'}; largest DMF numerator {largest} monomials). As "
        "μ_DMF − μ_CMF = Σ_m (DMF_m − CMF_m), this covers every configuration of N sensors with l_m ≤ D ≤ 3. "
        "(b) Without that decomposition: the whole μ_DMF − μ_CMF, central μ_p included, formed in the rational "
        f"function field Q(entries) reduces to 0 for {len(whole)} configurations "
        f"({', '.join(f'D={d}:' + '/'.join(map(str, c)) for d, c in whole)}) ({'yes' if whole_ok else 'NO'}). "
        "(c) (C_xyᵀC_xy)⁻¹C_xyᵀ satisfies the four Penrose conditions identically "
        f"({'yes' if penrose_ok else 'NO'}); the denominators are nonzero exactly under the hypotheses "
        "(full column rank, C_y^m SPD). (d) " + _dimension_free_detail(general))
    return Certificate("prop1-full-column-rank",
                       "DMF (eq. 35) equals CMF (eq. 15) for every measurement when every C_xy^m has full column rank",
                       "word-algebra rewriting from the Penrose equations and a left inverse (any dimension) + "
                       "sympy polynomial identity over Q[entries] and rational-function field reduction (l_m ≤ D ≤ 3)",
                       verdict(holds), detail, time.perf_counter() - start,
                       scope="any dimension",
                       negative_controls=_controls(general))


# ---- dmf-gap-formula -------------------------------------------------------------------------

def prove_gap_formula(size: str = "small") -> Certificate:
    start = time.perf_counter()
    rng = np.random.default_rng(POINT_SEED)
    ok, nonvacuous, rows = True, True, []
    for d, l, r in RANK_DEFICIENT[size]:
        s = build_sensor(d, l, r)
        ok &= (dmf_term(s.lifted) - cmf_term(s.lifted) - predicted_gap_term(s.lifted)).is_zero()
        witness = nonzero_somewhere(lambda built, _: predicted_gap_term(built.lifted), s.symbols,
                                    lambda point, d=d, l=l, r=r: build_sensor(d, l, r, point=point), rng)
        nonvacuous &= witness is not None
        rows.append(f"(D={d}, l={l}, rank {r})")
    for d, l in ((2, 2), (3, 2)):  # full rank: the same residual, through the other pseudo-inverse
        full = build_sensor(d, l).lifted
        ok &= (dmf_term(full) - cmf_term(full) - predicted_gap_term(full)).is_zero()
        rows.append(f"(D={d}, l={l}, full rank)")
    penrose = rewrites.check_independent(rewrites.factored_pinv_penrose())
    general = dimension_free.gap_formula()
    holds = ok and penrose.holds and nonvacuous and general.holds
    detail = (f"(a) Families {', '.join(rows)}: C_xy^m = B Fᵀ with B (D×r), F (l×r) generic and "
              "(C_xy^m)⁺ = F(FᵀF)⁻¹(BᵀB)⁻¹Bᵀ; every entry of B, F, G_m, C_y^m (symmetric), y^m, μ_y^m, μ_y(m), "
              "μ_p^m a free symbol. (DMF_m − CMF_m) − G_m C_y^m (P_m − I)(C_y^m)⁻¹(y^m − μ_y^m) expands to the "
              f"zero polynomial ({'yes' if ok else 'NO'}). (b) For each rank-deficient family the gap is nonzero "
              f"at an integer point ({'yes' if nonvacuous else 'NO'}): the formula is not vacuous. "
              "(c) F(FᵀF)⁻¹(BᵀB)⁻¹Bᵀ is the Moore–Penrose inverse of BFᵀ for every size (four Penrose "
              f"conditions checked on matrix symbols: {'yes' if penrose.holds else 'NO'}). Since μ_DMF − μ_CMF "
              "is the sum of the sensor terms, (a) holds for any N. (d) " + _dimension_free_detail(general))
    return Certificate("dmf-gap-formula",
                       "μ_DMF − μ_CMF = Σ_m G_m C_y^m (P_m − I)(C_y^m)⁻¹(y^m − μ_y^m), P_m = (C_xy^m)⁺C_xy^m",
                       "word-algebra rewriting (any dimension) + sympy polynomial identity for rank-deficient "
                       "families", verdict(holds), detail, time.perf_counter() - start,
                       scope="any dimension",
                       negative_controls=_controls(general))


# ---- dmf-exact-iff-kernel-inclusion and the two refuted statements ----------------------------


def _with_measurement(s: LiftedSensor, innovation: Fraction) -> LiftedSensor:
    """The sensor with y^m := μ_y^m + ``innovation``."""
    return replace(s, innovation=innovation, y=s.mu_y + innovation)


def _breaking_direction(sensor: SymbolicSensor, v: Fraction) -> Fraction:
    """C_y^m (I − P_m) v: C_y^m times a vector of ker C_xy^m."""
    s = sensor.lifted
    return s.C_y @ (v - s.C_xy_pinv @ (s.C_xy @ v))


def _necessity(d: int, l: int, r: int, rng: np.random.Generator) -> tuple[bool, bool]:
    """Generic G_m, C_xy^m = BFᵀ of rank r: with y^m = μ_y^m + C_y^m (I − P_m) v the DMF − CMF
    difference equals −X_m v identically, and X_m v is nonzero at some integer point."""
    v_sym = generic_matrix("v", l, 1)
    sensor = build_sensor(d, l, r, extra=(v_sym,))
    v = sensor.lift(v_sym)
    chosen = _with_measurement(sensor.lifted, _breaking_direction(sensor, v))
    identity_holds = (dmf_term(chosen) - cmf_term(chosen) + kernel_condition(sensor.lifted) @ v).is_zero()
    witness = nonzero_somewhere(
        lambda built, point: kernel_condition(built.lifted) @ built.lift(v_sym.subs(point)),
        sensor.symbols, lambda point: build_sensor(d, l, r, extra=(v_sym,), point=point), rng)
    return identity_holds, witness is not None


#: the quantifier steps of the kernel-inclusion iff, which the word algebra does not express
KERNEL_LOGIC_STEPS = ("X_m v = 0 for every v ⇒ X_m = 0; ⇐ of the kernel form: A(I − P_m) = 0 (proved) puts "
                      "(I − P_m)w in ker C_xy^m ⊆ ker G_m C_y^m, so X_m w = 0 for every w")


def prove_kernel_inclusion(size: str = "small") -> Certificate:
    start = time.perf_counter()
    rng = np.random.default_rng(POINT_SEED)
    families = KERNEL_FAMILIES[size]
    sufficient, necessary, nonzero = True, True, True
    for d, l, r in families:
        s = build_sensor(d, l, r, kernel_inclusion=True).lifted
        sufficient &= kernel_condition(s).is_zero() and (dmf_term(s) - cmf_term(s)).is_zero()
        identity_holds, witnessed = _necessity(d, l, r, rng)
        necessary &= identity_holds
        nonzero &= witnessed
    general = dimension_free.kernel_inclusion()
    holds = sufficient and necessary and nonzero and general.holds
    fams = ", ".join(f"(D={d}, l={l}, rank {r})" for d, l, r in families)
    detail = (
        f"Families {fams}, C_xy^m = BFᵀ generic of rank r. Sufficiency: with G_m = W C_xy^m (C_y^m)⁻¹, W generic "
        "D×D (the general solution of G_m C_y^m (I − P_m) = 0), both G_m C_y^m (I − P_m) and DMF_m − CMF_m "
        f"expand to the zero polynomial in the entries of W, B, F, C_y^m, y^m, μ_y^m, μ_y(m), μ_p^m "
        f"({'yes' if sufficient else 'NO'}). Necessity: for generic G_m and the measurement direction "
        "y^m = μ_y^m + C_y^m (I − P_m) v (C_y^m times a vector of ker C_xy^m), DMF_m − CMF_m = −G_m C_y^m (I − P_m) v "
        f"identically ({'yes' if necessary else 'NO'}), and that vector is nonzero at an integer point "
        f"({'yes' if nonzero else 'NO'}): whenever X_m = G_m C_y^m (I − P_m) ≠ 0, some v (other sensors at "
        "y^k = μ_y^k) gives a nonzero gap. " + _dimension_free_detail(general)
        + " Stated (logic steps not rewritten): " + KERNEL_LOGIC_STEPS + ".")
    return Certificate("dmf-exact-iff-kernel-inclusion",
                       "DMF = CMF for every measurement iff G_m C_y^m (I − P_m) = 0 for every m "
                       "(ker C_xy^m ⊆ ker G_m C_y^m)",
                       "sympy: polynomial identities for rank-deficient families (sufficiency), explicit "
                       "breaking measurement direction (necessity), word-algebra rewriting (any dimension)",
                       verdict(holds), detail, time.perf_counter() - start,
                       scope="any dimension",
                       negative_controls=_controls(general),
                       stated_facts=(KERNEL_LOGIC_STEPS,))


# ---- concrete counterexamples (the two refuted statements) ------------------------------------

#: D = 2, l = 2: C_xy^m = [1 1; 1 1] (rank 1, kernel spanned by (1, −1)), C_y^m = [2 1; 1 2] (SPD).
_EXAMPLE = {"B0": [[1], [1]], "F0": [[1], [1]], "Cy0": [[2, 1], [1, 2]]}


def _example_point(extra: dict) -> dict:
    values = dict(_EXAMPLE, **extra)
    point = {}
    for name, rows in values.items():
        for i, row in enumerate(rows):
            for j, value in enumerate(row):
                point[sp.Symbol(f"{name}_{min(i, j)}_{max(i, j)}" if name == "Cy0" else f"{name}_{i}_{j}")] = value
    return point


def refute_full_rank_necessary(size: str = "small") -> Certificate:
    """A rank-deficient C_xy^m for which DMF is exact anyway (kernel inclusion holds)."""
    start = time.perf_counter()
    point = _example_point({"W0": [[1, 0], [0, 1]]})
    sensor = build_sensor(2, 2, 1, kernel_inclusion=True, point=point)
    s = sensor.lifted
    rank_deficient = not (identity(2, sensor.ring) - s.C_xy_pinv @ s.C_xy).is_zero()
    exact = (dmf_term(s) - cmf_term(s)).is_zero()
    g = (s.G.num.to_Matrix() / s.G.num.domain.to_sympy(s.G.den)).applyfunc(sp.nsimplify)
    refuted = rank_deficient and exact
    detail = (f"Counterexample (exact rationals): D = 2, one sensor with C_xy^m = [[1, 1], [1, 1]] (rank 1 < l_m = 2, "
              f"so P_m ≠ I: {'yes' if rank_deficient else 'NO'}), C_y^m = [[2, 1], [1, 2]], G_m = C_xy^m (C_y^m)⁻¹ = "
              f"{sp.sstr(g.tolist())}; DMF_m − CMF_m is the zero polynomial in the symbols y^m, μ_y^m, μ_y(m), μ_p^m "
              f"({'yes' if exact else 'NO'}): DMF is exact for every measurement although the rank condition fails "
              "(kernel inclusion holds). Full column rank is sufficient, not necessary.")
    return Certificate("full-column-rank-necessary",
                       "DMF equals CMF for every measurement only if every C_xy^m has full column rank",
                       "sympy: exact counterexample", "refuted" if refuted else "checked", detail,
                       time.perf_counter() - start)


def refute_exact_without_condition(size: str = "small") -> Certificate:
    """The DMF of eq. 35 applied when kernel inclusion fails: a measurement with a nonzero gap."""
    start = time.perf_counter()
    v_sym = generic_matrix("v", 2, 1)
    point = _example_point({"G0": [[1, 0], [0, 1]], "v": [[1], [0]]})
    sensor = build_sensor(2, 2, 1, extra=(v_sym,), point=point)
    v = sensor.lift(v_sym.subs(point))
    direction = _breaking_direction(sensor, v)
    chosen = _with_measurement(sensor.lifted, direction)
    gap = dmf_term(chosen) - cmf_term(chosen)
    gap_value = gap.num.to_Matrix() / gap.num.domain.to_sympy(gap.den)
    mu = {s: 0 for s in gap_value.free_symbols}  # the gap does not depend on the means
    gap_at = gap_value.subs(mu)
    dir_value = (direction.num.to_Matrix() / direction.num.domain.to_sympy(direction.den))
    refuted = bool(any(gap_at)) and not gap_value.free_symbols
    detail = (f"Counterexample (exact rationals): D = 2, C_xy^m = [[1, 1], [1, 1]] (rank 1), "
              f"C_y^m = [[2, 1], [1, 2]], "
              f"G_m = I, every other sensor at y^k = μ_y^k. Measurement y^m = μ_y^m + C_y^m (I − P_m) v "
              f"with v = (1, 0): "
              f"y^m − μ_y^m = {sp.sstr(dir_value.T.tolist()[0])} (C_y^m times a kernel vector of C_xy^m). "
              f"μ_DMF − μ_CMF = {sp.sstr(gap_at.T.tolist()[0])} ≠ 0 for every value of the means "
              f"({'yes' if refuted else 'NO'}); here G_m C_y^m (I − P_m) ≠ 0, "
              f"so eq. 35 is not exact without the condition.")
    return Certificate("dmf-exact-without-condition",
                       "DMF (eq. 35) equals CMF for every measurement without any rank or kernel condition",
                       "sympy: exact counterexample (the measurement direction that breaks it)",
                       "refuted" if refuted else "checked", detail, time.perf_counter() - start)


# ---- full-rank-needs-l-le-D ------------------------------------------------------------------

#: (D, l) with l > D: a kernel vector for each; det(AᵀA) ≡ 0 expanded for the smaller ones.
WIDE = {"small": ((1, 2), (1, 3), (2, 3), (2, 4), (3, 4)),
        "large": ((1, 2), (1, 3), (2, 3), (2, 4), (2, 5), (3, 4), (3, 5), (3, 6))}
GRAM_DET_MAX_ENTRIES = 12  # expand det(AᵀA) only for D·l ≤ this (the 3×5 case is already slow)


def cofactor_kernel_vector(a: sp.Matrix) -> sp.Matrix:
    """For A (D×l), l > D: v_j = (−1)^j det(A without column j) over the first D + 1 columns, 0
    beyond. Av = 0 by Laplace expansion (each row of Av is the determinant of a (D+1)×(D+1)
    matrix with a repeated row)."""
    d, l = a.shape
    first = a[:, : d + 1]
    v = sp.zeros(l, 1)
    for j in range(d + 1):
        minor = first[:, [k for k in range(d + 1) if k != j]]
        v[j] = (-1) ** j * minor.det(method="berkowitz")
    return v


def prove_full_rank_needs_l_le_d(size: str = "small") -> Certificate:
    start = time.perf_counter()
    kernel_ok, gram_ok, gram_sizes = True, True, []
    for d, l in WIDE[size]:
        a_sym = generic_matrix("A", d, l)
        ring = polynomial_ring(a_sym)
        a = lift(a_sym, ring)
        v = lift(cofactor_kernel_vector(a_sym), ring)
        kernel_ok &= (a * v).is_zero_matrix and not v.is_zero_matrix
        if d * l <= GRAM_DET_MAX_ENTRIES:
            gram_ok &= not (a.transpose() * a).det()
            gram_sizes.append(f"{d}×{l}")
    general = dimension_free.l_le_d()
    holds = kernel_ok and gram_ok and general.holds
    wide = ", ".join(f"({d},{l})" for d, l in WIDE[size])
    detail = (f"For generic D×l_m matrices C_xy^m with l_m > D, (D, l_m) ∈ {{{wide}}}: "
              "the cofactor vector v (signed maximal minors of the first D + 1 columns) is a nonzero polynomial "
              f"vector with C_xy^m v ≡ 0 ({'yes' if kernel_ok else 'NO'}), so rank C_xy^m ≤ l_m − 1 for every value "
              f"of the entries; det(C_xyᵀC_xy) expands to the zero polynomial for {', '.join(gram_sizes)} "
              f"({'yes' if gram_ok else 'NO'}), so (C_xyᵀC_xy)⁻¹ never exists and P_m = (C_xy^m)⁺C_xy^m ≠ I. "
              "Every size: full column rank ⇔ a left inverse L (LA = I); then E = AL is idempotent (proved) "
              "and l_m = tr(I) = tr(LA) = tr(AL) = rank(AL) ≤ D (a stated fact, checked on every full-column-rank "
              f"shape with D ≤ {dimension_free.FACT_MAX_D}, not proved). " + _dimension_free_detail(general))
    return Certificate("full-rank-needs-l-le-D",
                       "a sensor with l_m > D outputs never has a full-column-rank C_xy^m (Proposition 1 cannot apply)",
                       "sympy explicit polynomial kernel vector and vanishing Gram determinant (listed sizes) + "
                       "word-algebra rewriting with a stated trace/rank fact checked on instances",
                       verdict(holds), detail, time.perf_counter() - start,
                       scope=f"(D, l_m) ∈ {{{wide}}}; checked on D ≤ {dimension_free.FACT_MAX_D}",
                       negative_controls=_controls(general),
                       stated_facts=tuple(general.checked.facts))
