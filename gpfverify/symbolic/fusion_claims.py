"""The fusion claims of seed 000 (Proposition 1 and what SPEC §3 adds to it) as formal statements,
with the proofs the search writes for the kernel, witnesses, counterexamples and negative controls.

Sizes: D states, N sensors, L stacked outputs, l_m outputs of sensor m. The stacked measurement is
partitioned by selectors S_m (L × l_m, Σ_m S_m S_mᵀ = I, S_mᵀS_k = δ_mk I), so sensor m's share of a
stacked quantity is S_mᵀ(·) and G_m = G S_m is its block of the central gain G = C_xy C_y⁻¹ (any
D × L matrix arises so). With μ_e^m(y) = μ_p,loc^m + C_xy^m (C_y^m)⁻¹(S_mᵀy − μ_y,loc^m) (eq. 32):

    μ_CMF(y) = μ_p + G(y − μ_y)                                                         (eq. 15)
    μ_DMF(y) = μ_p + Σ_m G S_m(μ_y,loc^m − S_mᵀμ_y) + Σ_m G S_m C_y^m (C_xy^m)⁺(μ_e^m(y) − μ_p,loc^m)  (eq. 35)

"For every N" is in the statement itself (Σ over m = 1..N with N a size symbol): no induction.
Next to each kernel proof, an independent route at listed sizes (exact polynomial arithmetic over
ℚ[entries], :mod:`gpfverify.symbolic.polynomial`) is recorded as "also checked".
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Any

import sympy as sp

from gpfverify.kernel.rules import Checker
from gpfverify.kernel.terms import frozen, read_statement
from gpfverify.symbolic.certificate import Certificate, Control, ListedCheck, Part
from gpfverify.symbolic.formal import Declare, I, Sum, Term, eq, every, fcr, forall, le, spd, zero
from gpfverify.symbolic.fusion_forms import (SensorSymbols, cmf_term, dmf_term, kernel_condition, lift_sensor,
                                             predicted_gap_term)
from gpfverify.symbolic.polynomial import (Fraction as PolyFraction, factored_pinv, full_column_rank_pinv,
                                           generic_matrix, lift, penrose_residuals, polynomial_ring)
from gpfverify.symbolic.search import Template, prove_equation
from gpfverify.symbolic.witness import Builder, refuting

SENSOR = "sensor"
MUTANTS = ("A⁺ replaced by Aᵀ in eq. 35", "sign of G_m(μ_y,loc^m − S_mᵀμ_y) flipped",
           "G_m(μ_y,loc^m − S_mᵀμ_y) dropped", "C_y^m replaced by (C_y^m)⁻¹ in eq. 35",
           "local update with C_y^m in place of (C_y^m)⁻¹")


@dataclass
class Fusion:
    """The declarations shared by the fusion statements, and handles to their terms."""

    d: Declare
    S: Any
    G: Any
    Cy: Any
    Cxy: Any
    P: Any
    y: Any
    dmf: Any
    cmf: Any


def declare(mutation: str = "", measurement: bool = True) -> Fusion:
    """The fusion quantities; ``measurement``: y is a declared variable (else only bound)."""
    d = Declare()
    d.sizes("D", "L", "N")
    d.index_set(SENSOR, "N")
    d.family_size("l", SENSOR)
    S = d.partition("S", SENSOR, "L", "l[#]")
    mu_p, G = d.matrix("μ_p", "D", 1), d.matrix("G", "D", "L")
    y = d.matrix("y", "L", 1) if measurement else None
    mu_y = d.matrix("μ_y", "L", 1)
    Cy = d.matrix("C_y", "l[#]", "l[#]", over=SENSOR)
    Cxy = d.matrix("C_xy", "D", "l[#]", over=SENSOR)
    my, mp = d.matrix("μ_y,loc", "l[#]", 1, over=SENSOR), d.matrix("μ_p,loc", "D", 1, over=SENSOR)
    local = (lambda m, v: mp[m] + Cxy[m] * Cy[m] * (S[m].T * v - my[m])) if mutation.startswith("local") else (
        lambda m, v: mp[m] + Cxy[m] * Cy[m].inv * (S[m].T * v - my[m]))
    mu_e = d.define("μ_e", local, over=SENSOR, args=(("y", "L", 1),))
    P = d.define("P", lambda m: Cxy[m].pinv * Cxy[m], over=SENSOR)
    cmf = d.define("μ_CMF", lambda v: mu_p + G * (v - mu_y), args=(("y", "L", 1),))
    pinv = (lambda m: Cxy[m].T) if mutation == MUTANTS[0] else (lambda m: Cxy[m].pinv)
    cov = (lambda m: Cy[m].inv) if mutation == MUTANTS[3] else (lambda m: Cy[m])
    sign = -1 if mutation == MUTANTS[1] else 0 if mutation == MUTANTS[2] else 1

    def dmf_body(v):
        share = Sum("m", SENSOR, G * S["m"] * cov("m") * pinv("m") * (mu_e(v, index="m") - mp["m"]))
        if sign == 0:
            return mu_p + share
        prediction = Sum("m", SENSOR, G * S["m"] * (my["m"] - S["m"].T * mu_y))
        return mu_p + (prediction if sign == 1 else -prediction) + share

    dmf = d.define("μ_DMF", dmf_body, args=(("y", "L", 1),))
    return Fusion(d, S, G, Cy, Cxy, P, y, dmf, cmf)


def _templates(full_rank_hyp: int | None = None, equation_hyp: int | None = None) -> list[Template]:
    out = [Template(lambda i: {"inverse": "right", "of": ("var", "C_y", i)}, SENSOR),
           Template(lambda i: {"inverse": "left", "of": ("var", "C_y", i)}, SENSOR)]
    if full_rank_hyp is not None:
        out.append(Template(lambda i: {"fcr": ("var", "C_xy", i), "hyp": full_rank_hyp, "index": i}, SENSOR))
    if equation_hyp is not None:
        out.append(Template(lambda i: {"hyp": equation_hyp, "index": i}, SENSOR))
    return out


def attempt(statement: dict, templates: list[Template], bases: dict | None = None) -> dict:
    """The search's proof of every conclusion of ``statement`` (the kernel judges it)."""
    st = read_statement(frozen(statement))
    checker = Checker(st, {"bases": bases or {}, "steps": []})
    steps = [prove_equation(checker, f"s{k + 1}", c[1], c[2], templates)[0]
             for k, c in enumerate(st.conclusion) if c[0] == "="]
    return {"bases": bases or {}, "steps": steps}


# ---- instances ----------------------------------------------------------------------------------------

PARTS = (2, 2)  # l_m of the two sensors of the witnesses (n = 2: both ≤ n; a witness's sizes are ≥ 2)


def instance(seed: int, full_rank: bool = True, kernel_inclusion: bool = False, measurement: bool = True,
             deficient: bool = False, parts=PARTS, n: int = 2, free: dict | None = None) -> dict:
    """A random fusion instance: every C_y^m SPD; C_xy^m of full column rank (or of rank l_m − 1
    when ``deficient``); with ``kernel_inclusion`` G's blocks are G_m = W C_xy^m (C_y^m)⁻¹."""
    b = Builder(seed, {"D": n, "L": sum(parts), "N": len(parts)}, {"l": list(parts)}, free_indices=free)
    b.draw("μ_p", n, 1)
    if measurement:
        b.draw("y", sum(parts), 1)
    b.draw("μ_y", sum(parts), 1)
    cy = b.draw_family("C_y", [(p, p) for p in parts], "spd")
    kinds = [f"rank-{p - 1}" if deficient else "fcr" if full_rank else "general" for p in parts]
    b.set("C_xy", [b.draw("tmp", n, p, kind) for p, kind in zip(parts, kinds)])
    del b.values["tmp"]
    b.draw_family("μ_y,loc", [(p, 1) for p in parts])
    b.draw_family("μ_p,loc", [(n, 1) for _ in parts])
    if kernel_inclusion:
        w = b.draw("W", n, n)
        del b.values["W"]
        b.set("G", sp.Matrix.hstack(*[w * a * c.inv() for a, c in zip(b.values["C_xy"], cy)]))
    else:
        b.draw("G", n, sum(parts))
    return b.json()


def _controls(mutants, instance_for) -> list[Control]:
    """Each mutant with the search's attempt and an instance that refutes it (``instance_for(title, seed)``)."""
    return [Control(title, statement, attempt(statement, templates),
                    refuting(statement, lambda seed, title=title: instance_for(title, seed)))
            for title, statement, templates in mutants]


# ---- the claims ---------------------------------------------------------------------------------------

def prop1_statement(mutation: str = "", full_rank: bool = True) -> dict:
    f = declare(mutation)
    f.d.assume(every("m", SENSOR, spd(f.Cy["m"])))
    if full_rank:
        f.d.assume(every("m", SENSOR, fcr(f.Cxy["m"])))
    f.d.conclude(eq(f.dmf(f.y), f.cmf(f.y)))
    return f.d.json()


def prove_prop1(size: str = "small") -> Certificate:
    start = time.perf_counter()
    statement = prop1_statement()
    part = Part(statement, attempt(statement, _templates(full_rank_hyp=1)), instance(1))
    mutants = [(m, prop1_statement(m), _templates(full_rank_hyp=1)) for m in MUTANTS]
    mutants.append(("full-column-rank hypothesis dropped", prop1_statement(full_rank=False), _templates(1)))
    controls = _controls(mutants, lambda title, seed: instance(
        100 + seed, deficient=title.startswith("full-column-rank")))
    checks = [_per_sensor_check(size)]
    return Certificate("prop1-full-column-rank",
                       "Proposition 1 (seed 000): DMF (eq. 35) equals CMF (eq. 15) when every C_xy^m has full column "
                       "rank", [part], controls, checks, time.perf_counter() - start)


def gap_statement(mutation: str = "") -> dict:
    f = declare()
    f.d.assume(every("m", SENSOR, spd(f.Cy["m"])))

    def share(m):
        cy, proj = f.Cy[m], f.P[m]
        inner = proj - I(f"l[{m}]") if mutation != "(I − P) in place of (P − I)" else I(f"l[{m}]") - proj
        cinv = cy.inv if mutation != "(C_y^m)⁻¹ replaced by C_y^m" else cy
        lead = f.G * f.S[m] * cy if mutation != "C_y^m factor dropped" else f.G * f.S[m]
        meas = Term(("var", "μ_y,loc", m)) if mutation != "innovation against S_mᵀμ_y" else f.S[m].T * Term(
            ("var", "μ_y"))
        return lead * inner * cinv * (f.S[m].T * f.y - meas)

    gap = Sum("m", SENSOR, share("m"))
    f.d.conclude(eq(f.dmf(f.y) - f.cmf(f.y), -gap if mutation == "sign of the gap flipped" else gap))
    return f.d.json()


GAP_MUTANTS = ("(I − P) in place of (P − I)", "(C_y^m)⁻¹ replaced by C_y^m", "C_y^m factor dropped",
               "innovation against S_mᵀμ_y", "sign of the gap flipped")


def prove_gap_formula(size: str = "small") -> Certificate:
    start = time.perf_counter()
    statement = gap_statement()
    part = Part(statement, attempt(statement, _templates()), instance(3, full_rank=False))
    mutants = [(m, gap_statement(m), _templates()) for m in GAP_MUTANTS]
    controls = _controls(mutants, lambda title, seed: instance(200 + seed, deficient=True))
    return Certificate("dmf-gap-formula",
                       "The gap: μ_DMF − μ_CMF = Σ_m G_m C_y^m (P_m − I)(C_y^m)⁻¹(y^m − μ_y^m), whatever the rank of "
                       "each C_xy^m", [part], controls, [_gap_check(size)], time.perf_counter() - start)


def sufficiency_statement(weaker: bool = False) -> dict:
    f = declare()
    f.d.assume(every("m", SENSOR, spd(f.Cy["m"])))
    if weaker:  # G_m (I − P_m) = 0 in place of G_m C_y^m (I − P_m) = 0
        f.d.assume(every("m", SENSOR, eq(f.G * f.S["m"] * f.P["m"], f.G * f.S["m"])))
    else:
        f.d.assume(every("m", SENSOR, eq(f.G * f.S["m"] * f.Cy["m"] * (I("l[m]") - f.P["m"]),
                                         zero("D", "l[m]"))))
    f.d.conclude(eq(f.dmf(f.y), f.cmf(f.y)))
    return f.d.json()


def necessity_statement(mutation: str = "") -> dict:
    f = declare(measurement=False)
    v = Term(("var", "y"))
    f.d.assume(every("m", SENSOR, spd(f.Cy["m"])),
               forall([("y", "L", 1)], eq(f.dmf(v), f.cmf(v))))
    j = f.d.free_index("j", SENSOR)
    if mutation == "G_j (I − P_j) = 0":
        f.d.conclude(eq(f.G * f.S[j] * (I(f"l[{j}]") - f.P[j]), zero("D", f"l[{j}]")))
    else:
        f.d.conclude(eq(f.G * f.S[j] * f.Cy[j] * (I(f"l[{j}]") - f.P[j]), zero("D", f"l[{j}]")))
    return f.d.json()


def necessity_proof(statement: dict) -> dict:
    """Instantiate "for every y" at y = Σ_k S_k μ_y,loc^k + S_j C_y^j e_i (e_i the standard basis of
    ℝ^{l_j}): the gap formula leaves G_j C_y^j (P_j − I) e_i = 0 for every i; then X_j = X_j Σ_i e_i e_iᵀ."""
    st = read_statement(frozen(statement))
    bases = {"e": "l[j]"}
    checker = Checker(st, {"bases": bases, "steps": []})
    e_i = ("sel", "e", "i")
    at = ("+", ("sum", "k", SENSOR, ("*", ("sel", "S", "k"), ("var", "μ_y,loc", "k"))),
          ("*", ("sel", "S", "j"), ("var", "C_y", "j"), e_i))
    x_j = ("*", ("var", "G"), ("sel", "S", "j"), ("var", "C_y", "j"),
           ("+", ("var", "P", "j"), ("*", ("num", -1), ("I", "l[j]"))))
    claim_lhs = ("*", x_j, e_i)
    claim_rhs = ("*", ("var", "G"), ("sel", "S", "j"), ("var", "C_y", "j"), ("num", 0), e_i)
    first, left = prove_equation(checker, "s1", claim_lhs, claim_rhs, _templates(), generic={"i": "e"},
                                 extra=[{"gen": {"hyp": 1, "at": {"y": at}}}])
    checker.step(frozen(first))
    target = st.conclusion[0]
    second, _ = prove_equation(checker, "s2", target[1], target[2],
                               [Template(lambda i: {"lemma": "s1", "index": {"i": i}}, "e")],
                               extra=[{"left": ("*", ("num", -1), target[1]), "gen": {"complete": "e"}}])
    return {"bases": bases, "steps": [first, second]}


def prove_kernel_inclusion(size: str = "small") -> Certificate:
    start = time.perf_counter()
    sufficiency = sufficiency_statement()
    necessity = necessity_statement()
    parts = [Part(sufficiency, attempt(sufficiency, _templates(equation_hyp=1)), instance(5, kernel_inclusion=True)),
             Part(necessity, necessity_proof(necessity),
                  instance(6, kernel_inclusion=True, measurement=False, free={"j": 2}))]
    weaker = sufficiency_statement(weaker=True)
    controls = [Control("⇐ from the weaker G_m(I − P_m) = 0", weaker, attempt(weaker, _templates(equation_hyp=1)),
                        _weaker_counterexample()),
                Control("⇐ with the hypothesis dropped", prop1_statement(full_rank=False),
                        attempt(prop1_statement(full_rank=False), _templates()), instance(7, deficient=True))]
    wrong = necessity_statement("G_j (I − P_j) = 0")
    controls.append(Control("⇒ concluding G_j (I − P_j) = 0", wrong, _safe(necessity_proof, wrong),
                            _inclusion_without_g_condition()))
    return Certificate("dmf-exact-iff-kernel-inclusion",
                       "DMF = CMF for every measurement iff G_m C_y^m (I − P_m) = 0 for every m "
                       "(ker C_xy^m ⊆ ker G_m C_y^m)", parts, controls, [_kernel_check(size)],
                       time.perf_counter() - start)


def _safe(make, statement):
    try:
        return make(statement)
    except Exception:  # noqa: BLE001 - the search failing on a false statement is expected
        return None


# ---- the two refuted statements ------------------------------------------------------------------------

#: D = 2, one sensor with l = 2: C_xy = [[1, 1], [1, 1]] (rank 1), C_y = [[3, 1], [1, 1]] (SPD; it does not
#: map ker C_xy into itself)
_RANK_ONE = sp.Matrix([[1, 1], [1, 1]])
_CY = sp.Matrix([[3, 1], [1, 1]])


def _one_sensor(g: sp.Matrix, measurement: bool, free: dict | None = None) -> dict:
    b = Builder(8, {"D": 2, "L": 2, "N": 1}, {"l": [2]}, free_indices=free)
    b.draw("μ_p", 2, 1)
    if measurement:
        b.set("y", sp.Matrix([[3], [-1]]))
    b.draw("μ_y", 2, 1)
    b.set("C_y", [_CY])
    b.set("C_xy", [_RANK_ONE])
    b.set("μ_y,loc", [sp.Matrix([[1], [0]])])
    b.draw_family("μ_p,loc", [(2, 1)])
    b.set("G", g)
    return b.json()


def necessity_of_full_rank_statement() -> dict:
    f = declare(measurement=False)
    v = Term(("var", "y"))
    f.d.assume(every("m", SENSOR, spd(f.Cy["m"])), forall([("y", "L", 1)], eq(f.dmf(v), f.cmf(v))))
    j = f.d.free_index("j", SENSOR)
    f.d.conclude(fcr(f.Cxy[j]))
    return f.d.json()


def refute_full_rank_necessary(size: str = "small") -> Certificate:
    """A rank-deficient C_xy^m for which DMF is exact for every measurement (G = C_xy C_y⁻¹)."""
    start = time.perf_counter()
    counterexample = _one_sensor(_RANK_ONE * _CY.inv(), measurement=False, free={"j": 1})
    return Certificate("full-column-rank-necessary",
                       "Full column rank of every C_xy^m is necessary for DMF = CMF (the kernel-inclusion condition "
                       "is weaker)",
                       [Part(necessity_of_full_rank_statement(), refutation=counterexample)],
                       seconds=time.perf_counter() - start, expected="refuted")


def without_condition_statement() -> dict:
    f = declare()
    f.d.assume(every("m", SENSOR, spd(f.Cy["m"])))
    f.d.conclude(eq(f.dmf(f.y), f.cmf(f.y)))
    return f.d.json()


def refute_exact_without_condition(size: str = "small") -> Certificate:
    """eq. 35 applied with G = I when kernel inclusion fails: a measurement with a nonzero gap."""
    start = time.perf_counter()
    return Certificate("dmf-exact-without-condition",
                       "DMF (eq. 35) equals CMF for every measurement without any rank or kernel condition",
                       [Part(without_condition_statement(), refutation=_one_sensor(sp.eye(2), True))],
                       seconds=time.perf_counter() - start, expected="refuted")


def _weaker_counterexample() -> dict:
    """G(I − P) = 0 but G C_y (I − P) ≠ 0: G = P-rows, one sensor, rank-one C_xy."""
    return _one_sensor(sp.Matrix([[1, 1], [0, 0]]) * _RANK_ONE.pinv() * _RANK_ONE, measurement=True)


def _inclusion_without_g_condition() -> dict:
    """Kernel inclusion holds (DMF exact for every y) but G(I − P) ≠ 0."""
    return _one_sensor(_RANK_ONE * _CY.inv(), measurement=False, free={"j": 1})


# ---- full-rank-needs-l-le-D -----------------------------------------------------------------------------

def rank_bound_statement(bound: str = "D", full_rank: bool = True, smaller: str = "l") -> dict:
    d = Declare()
    d.sizes("D", "l")
    a = d.matrix("A", "D", "l")
    if full_rank:
        d.assume(fcr(a))
    d.conclude(le(smaller, bound))
    return d.json()


def rank_bound_proof(statement: dict) -> dict:
    """D − l = tr((I − AA⁺)ᵀ(I − AA⁺)) + [Penrose 3 and 1, A⁺A = I] ≥ 0."""
    a, x = ("var", "A"), ("pinv", ("var", "A"))
    conclusion = statement["conclusion"][0]
    return {"steps": [{"id": "s1", "claim": conclusion, "squares": [[1, ("+", ("I", "D"), ("*", ("num", -1), a, x))]],
                       "by": [{"left": ("num", -1), "gen": {"penrose": 3, "of": a}, "right": ("*", a, x)},
                              {"left": ("num", -1), "gen": {"penrose": 1, "of": a}, "right": x},
                              {"gen": {"fcr": a, "hyp": 0}}]}]}


def prove_full_rank_needs_l_le_d(size: str = "small") -> Certificate:
    start = time.perf_counter()
    statement = rank_bound_statement()
    witness = Builder(9, {"D": 3, "l": 2})
    witness.draw("A", 3, 2, "fcr")
    controls = []
    for title, wrong, sizes, kind in (("l_m + 1 ≤ D", rank_bound_statement(smaller="l + 1"), (2, 2), "fcr"),
                                      ("l_m ≤ 2 whatever D", rank_bound_statement("2"), (3, 3), "fcr"),
                                      ("l_m ≤ D with the hypothesis dropped", rank_bound_statement(full_rank=False),
                                       (2, 3), "general")):
        b = Builder(10, {"D": sizes[0], "l": sizes[1]})
        b.draw("A", sizes[0], sizes[1], kind)
        controls.append(Control(title, wrong, rank_bound_proof(wrong), b.json()))
    return Certificate("full-rank-needs-l-le-D",
                       "A C_xy^m of full column rank has l_m ≤ D: a sensor with more outputs than states never has "
                       "one (Proposition 1 cannot apply to it)",
                       [Part(statement, rank_bound_proof(statement), witness.json())], controls,
                       [_gram_check(size)], time.perf_counter() - start)


# ---- the independent route at listed sizes (exact polynomial arithmetic over ℚ[entries]) -------------------

RANK_DEFICIENT = {"small": ((2, 2, 1), (2, 3, 1), (3, 2, 1)),
                  "large": ((1, 2, 1), (2, 2, 1), (2, 3, 1), (2, 3, 2), (3, 2, 1), (3, 3, 1), (3, 3, 2))}
FULL_RANK_SIZES = {"small": ((1, 1), (2, 1), (2, 2), (3, 2)),
                   "large": ((1, 1), (2, 1), (2, 2), (3, 1), (3, 2), (3, 3))}
KERNEL_FAMILIES = {"small": ((1, 2, 1), (2, 2, 1)), "large": ((1, 2, 1), (1, 3, 1), (2, 2, 1), (3, 2, 1))}
WIDE = {"small": ((1, 2), (2, 3)), "large": ((1, 2), (1, 3), (2, 3), (2, 4), (3, 4))}


def build_sensor(state_dim: int, outputs: int, rank: int | None = None, kernel_inclusion: bool = False):
    """One sensor with every entry a free symbol; C_xy^m = A (full column rank, (AᵀA)⁻¹Aᵀ) or
    B Fᵀ of rank r (F(FᵀF)⁻¹(BᵀB)⁻¹Bᵀ); with ``kernel_inclusion`` G_m = W C_xy^m (C_y^m)⁻¹."""
    sensor = SensorSymbols.generic(0, state_dim, outputs)
    factors = ((generic_matrix("A0", state_dim, outputs),) if rank is None else
               (generic_matrix("B0", state_dim, rank), generic_matrix("F0", outputs, rank)))
    w = (generic_matrix("W0", state_dim, state_dim),) if kernel_inclusion else ()
    ring = polynomial_ring(*sensor.matrices(), *factors, *w)
    lifted = [PolyFraction.of(lift(m, ring)) for m in factors]
    a, a_pinv = ((lifted[0], full_column_rank_pinv(lifted[0])) if rank is None else
                 (lifted[0] @ lifted[-1].T, factored_pinv(lifted[0], lifted[-1])))
    s = lift_sensor(sensor, ring, a, a_pinv)
    for extra in w:  # kernel inclusion
        s = replace(s, G=PolyFraction.of(lift(extra, ring)) @ a @ s.C_y_inv)
    return s


def _per_sensor_check(size: str) -> ListedCheck:
    holds = True
    for d, l in FULL_RANK_SIZES[size]:
        s = build_sensor(d, l)
        holds &= all(r.is_zero() for r in penrose_residuals(s.C_xy, s.C_xy_pinv).values())
        holds &= (dmf_term(s) - cmf_term(s)).is_zero()
    return ListedCheck("sensor m's share DMF_m − CMF_m is the zero rational function of every entry of G_m, C_y^m, "
                       "C_xy^m, y^m, μ_y,loc^m, μ_y(m), μ_p,loc^m, with (C_xy^m)⁺ = (C_xyᵀC_xy)⁻¹C_xyᵀ",
                       tuple(f"(D, l_m) = ({d}, {l})" for d, l in FULL_RANK_SIZES[size]),
                       ("det(C_y^m) ≠ 0", "det(C_xy^mᵀC_xy^m) ≠ 0"), holds)


def _families(families) -> tuple[tuple, tuple]:
    """The listed sizes of rank-r families C_xy^m = BFᵀ, and the domain of their identities."""
    return (tuple(f"(D, l_m, r) = ({d}, {l}, {r})" for d, l, r in families),
            ("det(C_y^m) ≠ 0", "det(FᵀF) ≠ 0", "det(BᵀB) ≠ 0"))


def _gap_check(size: str) -> ListedCheck:
    holds = all((dmf_term(s) - cmf_term(s) - predicted_gap_term(s)).is_zero()
                for s in (build_sensor(d, l, r) for d, l, r in RANK_DEFICIENT[size]))
    return ListedCheck("DMF_m − CMF_m − G_m C_y^m (P_m − I)(C_y^m)⁻¹(y^m − μ_y^m) is the zero rational function, "
                       "C_xy^m = BFᵀ of rank r with (C_xy^m)⁺ = F(FᵀF)⁻¹(BᵀB)⁻¹Bᵀ",
                       *_families(RANK_DEFICIENT[size]), holds)


def _kernel_check(size: str) -> ListedCheck:
    holds = True
    for d, l, r in KERNEL_FAMILIES[size]:
        s = build_sensor(d, l, r, kernel_inclusion=True)
        holds &= kernel_condition(s).is_zero() and (dmf_term(s) - cmf_term(s)).is_zero()
    return ListedCheck("with G_m = W C_xy^m (C_y^m)⁻¹ (W generic, the general solution of G_m C_y^m (I − P_m) = 0), "
                       "G_m C_y^m (I − P_m) and DMF_m − CMF_m are zero rational functions",
                       *_families(KERNEL_FAMILIES[size]), holds)


def _gram_check(size: str) -> ListedCheck:
    holds = True
    for d, l in WIDE[size]:
        a = lift(generic_matrix("A", d, l), polynomial_ring(generic_matrix("A", d, l)))
        gram = a.transpose() * a
        holds &= gram.det() == gram.domain.zero
    return ListedCheck("det(C_xyᵀC_xy) is the zero polynomial for a generic C_xy^m with l_m > D",
                       tuple(f"(D, l_m) = ({d}, {l})" for d, l in WIDE[size]), (), holds)
