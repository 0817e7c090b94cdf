"""Dimension-free proofs of the fusion claims (seed 000 Proposition 1 and SPEC §3) in the word
algebra, from the fusion :class:`~gpfverify.symbolic.theory.Theory` below.

Sizes are symbols: n states (D), l outputs of sensor m (l_m), K outputs of the first N sensors
together, and k measurements processed at once (every quantity below is linear or affine in each
column, so k = 1 is the paper's case and k free loses nothing). One generic sensor m:

* G_m (n × l), C_xy^m (n × l) and the measurement quantities y^m, μ_y^m, μ_y(m) (l × k), μ_p^m
  (n × k): general letters;
* C_y^m: symmetric positive definite (a hypothesis), (C_y^m)⁻¹ its inverse, (C_xy^m)⁺ the
  Moore–Penrose inverse (the four Penrose equations), L_m a left inverse (the hypothesis "full
  column rank");
* μ_e^m := μ_p^m + C_xy^m (C_y^m)⁻¹ (y^m − μ_y^m) (eq. 32), Φ_m := G_m C_y^m (P_m − I)(C_y^m)⁻¹
  with P_m = (C_xy^m)⁺C_xy^m: definitions.

The first N sensors are letters of their own (the block row G_(N), the stacked y_(N), μ_y(N),
local μ_y,loc(N), the block row Φ_(N) of their gap maps, and the sum Σ_{m≤N} DMF_m of their shares
of μ_DMF − μ_p); adding sensor m stacks them with the selectors S1, S2 of the partition K + l
(G_(N+1) := G_(N)S1ᵀ + G_m S2ᵀ, y_(N+1) := S1 y_(N) + S2 y^m, …). A statement about the first N
sensors is proved for every N by :meth:`Theory.induction`: the one-sensor proof is the base and the
step N → N + 1 uses the statement for N as its (discharged) hypothesis.

DMF_m = G_m(μ_y^m − μ_y(m)) + G_m C_y^m (C_xy^m)⁺(μ_e^m − μ_p^m) (eq. 35) and CMF_m = G_m(y^m − μ_y(m))
(eq. 15) are sensor m's shares of μ_DMF − μ_p and μ_CMF − μ_p.
"""

from __future__ import annotations

import sympy as sp

from gpfverify.symbolic import word_algebra as wa
from gpfverify.symbolic.argument import Argument
from gpfverify.symbolic.theory import Theory
from gpfverify.symbolic.word_algebra import Rule, identity, zero

n, l, K, k = sp.symbols("n l K k", integer=True, positive=True)
SEED = 20191126

T = Theory("fusion (one generic sensor m, the first N sensors)", SEED)
G = T.general("G_m", n, l)
C, C_SPD = T.spd("C_y^m", l, "every C_y^m symmetric positive definite")
Ci, C_INVERSE = T.inverse("(C_y^m)⁻¹", C)
A = T.general("C_xy^m", n, l)
Ap, PENROSE = T.pinv("(C_xy^m)⁺", A)
Lf, FULL_RANK = T.left_inverse("L_m", A, "every C_xy^m has full column rank (a left inverse L_m: L_m C_xy^m = I)")
y = T.general("y^m", l, k)
my = T.general("μ_y^m", l, k)
mc = T.general("μ_y(m)", l, k)
mp = T.general("μ_p^m", n, k)
me, LOCAL_UPDATE = T.define("μ_e^m", mp + A * Ci * (y - my))
I_l, I_n = identity(l), identity(n)
P = Ap * A
Phi, PHI = T.define("Φ_m", G * C * (P - I_l) * Ci)
W = T.general("W", n, n)
X_ZERO = T.hypothesis("G_m C_y^m (I − P_m) = 0", G * C * Ap * A, G * C,
                      "every G_m C_y^m (I − P_m) = 0, i.e. ker C_xy^m ⊆ ker G_m C_y^m", realise={"G_m": W * A * Ci})

# the first N sensors, and sensor m added to them
G_N = T.general("G_(N)", n, K)
y_N = T.general("y_(N)", K, k)
mu_N = T.general("μ_y(N)", K, k)
my_N = T.general("μ_y,loc(N)", K, k)
Phi_N = T.general("Φ_(N)", n, K, opaque=True, depends_on=(G_N,))  # and the sensors' C_y, C_xy
D = T.general("Σ_{m≤N} DMF_m", n, k, opaque=True, depends_on=(G_N, y_N, mu_N, my_N, "Φ_(N)"))
(S1, S2), SELECTORS = T.partition("S", (K, l))
G_next, G_NEXT = T.define("G_(N+1)", G_N * S1.T + G * S2.T)
y_next, Y_NEXT = T.define("y_(N+1)", S1 * y_N + S2 * y)
mu_next, MU_NEXT = T.define("μ_y(N+1)", S1 * mu_N + S2 * mc)
my_next, MY_NEXT = T.define("μ_y,loc(N+1)", S1 * my_N + S2 * my)
Phi_next, PHI_NEXT = T.define("Φ_(N+1)", Phi_N * S1.T + Phi * S2.T)
STACKING = [*SELECTORS, G_NEXT, Y_NEXT, MU_NEXT, MY_NEXT, PHI_NEXT]

CMF_N = G_N * (y_N - mu_N)
GAP_N = Phi_N * (y_N - my_N)
IH_EXACT = T.hypothesis("the first N sensors: Σ DMF_m = G_(N)(y_(N) − μ_y(N))", D, CMF_N,
                        "induction hypothesis (DMF = CMF for the first N sensors)", realise={"Σ_{m≤N} DMF_m": CMF_N},
                        induction=True)
IH_GAP = T.hypothesis("the first N sensors: Σ DMF_m = G_(N)(y_(N) − μ_y(N)) + Φ_(N)(y_(N) − μ_y,loc(N))", D,
                      CMF_N + GAP_N, "induction hypothesis (the gap of the first N sensors)",
                      realise={"Σ_{m≤N} DMF_m": CMF_N + GAP_N}, induction=True)
EVERY_MEASUREMENT = T.hypothesis("μ_DMF = μ_CMF for every measurement", D, CMF_N,
                                 "μ_DMF = μ_CMF for every measurement", for_all=(y_N,),
                                 realise={"Σ_{m≤N} DMF_m": CMF_N, "Φ_(N)": zero(n, K)})
#: an unsound shortcut, for the negative controls: P = I assumed as a hypothesis, and the same
#: equation as an axiom no declaration issues
P_IS_I = T.hypothesis("(C_xy^m)⁺C_xy^m = I", P, I_l, "(C_xy^m)⁺C_xy^m = I", restricts=("rank",))
PLANTED_P_IS_I = Rule("(C_xy^m)⁺C_xy^m = I", P, I_l, "axiom")
PLANTED_TRANSPOSE = Rule("G_m C_y^m (C_xy^m)ᵀ = G_m C_y^m (C_xy^m)⁺", G * C * A.T, G * C * Ap, "axiom")
Z = T.general("Z", n, l)
G_P = T.hypothesis("G_m P_m = G_m", G * Ap * A, G, "G_m (I − P_m) = 0", realise={"G_m": Z * Ap * A})

ONE_SENSOR = [*C_INVERSE, LOCAL_UPDATE]


def dmf_term(gain=G, cov=C, pinv=Ap, posterior=me, local_mean=my, central=mc, prior=mp):
    """Sensor m's share of μ_DMF − μ_p (eq. 35)."""
    return gain * (local_mean - central) + gain * cov * pinv * (posterior - prior)


def cmf_term(gain=G, meas=y, central=mc):
    """Sensor m's share of μ_CMF − μ_p (eq. 15 with G split into column blocks)."""
    return gain * (meas - central)


def gap_term(gain=G, cov=C, proj=P, inv=Ci, meas=y, local_mean=my):
    return gain * cov * (proj - I_l) * inv * (meas - local_mean)


# ---- lemmas ---------------------------------------------------------------------------------------

def projector_is_identity() -> Rule:
    """Full column rank (L A = I) ⇒ P = A⁺A = I: A⁺A = (LA)A⁺A = L(AA⁺A) = LA = I."""
    proof = wa.prove_by_chain([(Ap * A, None), (Lf * A * Ap * A, FULL_RANK), (Lf * A, PENROSE[0]),
                               (I_l, FULL_RANK)], "P_m = (C_xy^m)⁺C_xy^m = I when C_xy^m has a left inverse")
    return wa.lemma("P_m = I (full column rank)", proof)


def over_sensors(name: str, hypothesis: Rule, base: wa.Proof, one_sensor: list[Rule], gap: bool) -> Rule:
    """Σ_{m≤N} DMF_m = G_(N)(y_(N) − μ_y(N)) [+ Φ_(N)(y_(N) − μ_y,loc(N))] for every N, from the
    one-sensor proof ``base`` and the step that adds sensor m with the rules ``one_sensor``."""
    rhs = G_next * (y_next - mu_next) + (Phi_next * (y_next - my_next) if gap else zero(n, k))
    step = wa.prove_by_normal_form(D + dmf_term(), rhs, one_sensor + STACKING + [hypothesis],
                                   f"{name}: step N → N + 1 (sensor m added)")
    base_map = {"Σ_{m≤N} DMF_m": dmf_term(), "G_(N)": G, "y_(N)": y, "μ_y(N)": mc}
    step_map = {"Σ_{m≤N} DMF_m": D + dmf_term(), "G_(N)": G_next, "y_(N)": y_next, "μ_y(N)": mu_next}
    if gap:
        base_map |= {"Φ_(N)": Phi, "μ_y,loc(N)": my}
        step_map |= {"Φ_(N)": Phi_next, "μ_y,loc(N)": my_next}
    return T.induction(name, hypothesis, base, step, base_map, step_map, {K: l}, {K: K + l})


def prop1(argument: Argument) -> None:
    """Proposition 1: DMF_m = CMF_m for one sensor under full column rank, and for N sensors by
    induction; negative controls."""
    p_is_i = projector_is_identity()
    rules = ONE_SENSOR + [p_is_i]
    one = wa.prove_by_normal_form(dmf_term(), cmf_term(), rules, "one sensor: DMF_m = CMF_m")
    every_n = over_sensors("every N: μ_DMF = μ_CMF", IH_EXACT, one, rules, gap=False)
    argument.conclude(one, every_n)
    full = frozenset({C_SPD, FULL_RANK})
    for mutant, lhs in (("A⁺ replaced by Aᵀ in eq. 35", dmf_term(pinv=A.T)),
                        ("sign of G_m(μ_y^m − μ_y(m)) flipped", dmf_term() - 2 * (G * (my - mc))),
                        ("G_m(μ_y^m − μ_y(m)) dropped", dmf_term() - G * (my - mc)),
                        ("C_y^m replaced by (C_y^m)⁻¹ in eq. 35", dmf_term(cov=Ci)),
                        ("local update with C_y^m in place of (C_y^m)⁻¹", dmf_term(posterior=mp + A * C * (y - my)))):
        argument.control(mutant, wa.prove_by_normal_form(lhs, cmf_term(), rules), false_under=full)
    argument.control("full-column-rank hypothesis dropped",
                     wa.prove_by_normal_form(dmf_term(), cmf_term(), ONE_SENSOR + list(PENROSE)),
                     false_under=frozenset({C_SPD}))
    argument.control("planted rule G_m C_y^m Aᵀ = G_m C_y^m A⁺ (an axiom no declaration issued)",
                     wa.prove_by_normal_form(dmf_term(pinv=A.T), cmf_term(), rules + [PLANTED_TRANSPOSE]),
                     false_under=full)
    argument.control("planted rule A⁺A = I as an axiom (no declaration issued it)",
                     wa.prove_by_normal_form(dmf_term(), cmf_term(), ONE_SENSOR + [PLANTED_P_IS_I]),
                     statement="DMF equals CMF for every measurement", false_under=frozenset({C_SPD}))
    argument.control("A⁺A = I as a hypothesis, stated for any rank",
                     wa.prove_by_normal_form(dmf_term(), cmf_term(), ONE_SENSOR + [P_IS_I]),
                     statement="DMF equals CMF for every measurement, for any rank of C_xy^m",
                     false_under=frozenset({C_SPD}))


def gap_formula(argument: Argument) -> None:
    """μ_DMF − μ_CMF = Σ_m Φ_m (y^m − μ_y^m) for any rank: one sensor and every N; controls."""
    rules = ONE_SENSOR + [PHI]
    one = wa.prove_by_normal_form(dmf_term() - cmf_term(), Phi * (y - my), rules,
                                  "one sensor: DMF_m − CMF_m = Φ_m (y^m − μ_y^m), any C_xy^m")
    every_n = over_sensors("every N: μ_DMF − μ_CMF = Φ_(N)(y_(N) − μ_y,loc(N))", IH_GAP,
                         wa.prove_by_normal_form(dmf_term(), cmf_term() + Phi * (y - my), rules, "base: one sensor"),
                         rules, gap=True)
    argument.conclude(one, every_n)
    lhs = dmf_term() - cmf_term()
    for mutant, rhs in (("(I − P) in place of (P − I)", gap_term(proj=2 * I_l - P)),
                        ("(C_y^m)⁻¹ replaced by C_y^m", gap_term(inv=C)),
                        ("A⁺ replaced by Aᵀ in P", gap_term(proj=A.T * A)),
                        ("C_y^m factor dropped", G * (P - I_l) * Ci * (y - my)),
                        ("innovation against μ_y(m) instead of μ_y^m", gap_term(local_mean=mc)),
                        ("sign of the gap flipped", -gap_term())):
        argument.control(mutant, wa.prove_by_normal_form(lhs, rhs, ONE_SENSOR))
    p_is_i = projector_is_identity()
    argument.control("the gap is 0 for any rank, by the full-column-rank lemma P = I",
                     wa.prove_by_normal_form(gap_term(), zero(n, k), ONE_SENSOR + [p_is_i]),
                     statement="gap_m = 0 for any rank of C_xy^m", false_under=frozenset({C_SPD}))


def kernel_inclusion(argument: Argument) -> None:
    """DMF = CMF for every measurement iff every X_m = G_m C_y^m (I − P_m) = 0:
    ⇐ one sensor and every N from the hypothesis X_m = 0; ⇒ from "μ_DMF = μ_CMF for every
    measurement" and the gap formula (every N), instantiated at y_(N) = μ_y,loc(N) + I (k = K), the
    block row Φ_(N) = [Φ_1, …, Φ_N] of the sensors' gap maps is 0; and X_m = −Φ_m C_y^m."""
    rules = ONE_SENSOR + [X_ZERO]
    one = wa.prove_by_normal_form(dmf_term(), cmf_term(), rules, "⇐, one sensor: X_m = 0 ⇒ DMF_m = CMF_m")
    sufficiency = over_sensors("⇐, every N: every X_m = 0 ⇒ μ_DMF = μ_CMF", IH_EXACT, one, rules, gap=False)
    gap_rules = ONE_SENSOR + [PHI]
    gap_every_n = over_sensors("every N: μ_DMF − μ_CMF = Φ_(N)(y_(N) − μ_y,loc(N))", IH_GAP,
                             wa.prove_by_normal_form(dmf_term(), cmf_term() + Phi * (y - my), gap_rules, "base"),
                             gap_rules, gap=True)
    pointwise = wa.prove_by_chain([(GAP_N, None), (D - CMF_N, gap_every_n), (zero(n, k), EVERY_MEASUREMENT)],
                                  "⇒: Φ_(N)(y_(N) − μ_y,loc(N)) = 0 for every y_(N)")
    necessity = T.instantiate(wa.lemma("Φ_(N)(y_(N) − μ_y,loc(N)) = 0", pointwise),
                              {"y_(N)": my_N.substitute({}, {k: K}) + identity(K)}, {k: K},
                              "⇒, every N: Φ_(N) = [Φ_1, …, Φ_N] = 0")
    blocks = wa.prove_by_normal_form(G * C * (I_l - P), -(Phi * C), [*C_INVERSE, PHI],
                                     "X_m = G_m C_y^m (I − P_m) = −Φ_m C_y^m (so Φ_m = 0 ⇔ X_m = 0)")
    argument.conclude(sufficiency, necessity, blocks)
    argument.control("⇐ from the weaker G_m(I − P_m) = 0",
                     wa.prove_by_normal_form(dmf_term(), cmf_term(), ONE_SENSOR + [G_P]),
                     statement="DMF = CMF for every measurement if G_m(I − P_m) = 0",
                     false_under=frozenset({C_SPD, G_P}))
    argument.control("⇐ with the hypothesis dropped",
                     wa.prove_by_normal_form(dmf_term(), cmf_term(), ONE_SENSOR + list(PENROSE)),
                     statement="DMF = CMF for every measurement", false_under=frozenset({C_SPD}))
    argument.control("X_m = +Φ_m C_y^m (sign)",
                     wa.prove_by_normal_form(G * C * (I_l - P), Phi * C, [*C_INVERSE, PHI]),
                     statement="X_m = Φ_m C_y^m", false_under=frozenset({C_SPD}))
    argument.control("X_m = −Φ_m (C_y^m dropped)",
                     wa.prove_by_normal_form(G * C * (I_l - P), -Phi, [*C_INVERSE, PHI]), statement="X_m = −Φ_m",
                     false_under=frozenset({C_SPD}))


def rank_bound(argument: Argument) -> None:
    """Full column rank ⇒ l_m ≤ D in every dimension: with P = A⁺A = I (from L A = I),
    D − l_m = tr(I_D) − tr(A⁺A) = tr(I_D − AA⁺) = tr((I − AA⁺)ᵀ(I − AA⁺)) ≥ 0 (Penrose: I − AA⁺ is a
    symmetric idempotent)."""
    p_is_i = projector_is_identity()
    rules = list(PENROSE) + [p_is_i]
    square = [(1, I_n - A * Ap)]
    bound = wa.prove_size_bound(l, n, square, rules, "l_m ≤ D when C_xy^m has full column rank")
    argument.conclude(bound)
    argument.control("l_m ≤ D − 1", wa.prove_size_bound(l, n - 1, square, rules), statement="l_m ≤ D − 1")
    argument.control("l_m ≤ 2 whatever D", wa.prove_size_bound(l, 2, square, rules), statement="l_m ≤ 2")
    argument.control("l_m ≤ D with the hypothesis dropped", wa.prove_size_bound(l, n, square, list(PENROSE)),
                     statement="l_m ≤ D", false_under=frozenset())


# ---- the pseudo-inverse of a rank-r product, which the explicit rank-deficient families use ---------

r = sp.Symbol("r", integer=True, positive=True)
FACTORS = Theory("a rank-r product C_xy^m = B Fᵀ", SEED + 1)
B = FACTORS.general("B", n, r)
F = FACTORS.general("F", l, r)
FtF_inv, FTF_INVERSE = FACTORS.inverse("(FᵀF)⁻¹", F.T * F, "FᵀF invertible (F of full column rank)", F)
BtB_inv, BTB_INVERSE = FACTORS.inverse("(BᵀB)⁻¹", B.T * B, "BᵀB invertible (B of full column rank)", B)


def factored_pseudo_inverse() -> list[wa.Proof]:
    """X = F(FᵀF)⁻¹(BᵀB)⁻¹Bᵀ satisfies the four Penrose equations of A = BFᵀ, so it is A⁺ (the
    unique solution), in every dimension, when BᵀB and FᵀF are invertible (B, F of full column
    rank r — the full-rank factorisation the rank-deficient families are built from)."""
    a, x = B * F.T, F * FtF_inv * BtB_inv * B.T
    rules = [*FTF_INVERSE, *BTB_INVERSE]
    return [wa.prove_by_normal_form(lhs, rhs, rules, f"Penrose {name} for A = BFᵀ, X = F(FᵀF)⁻¹(BᵀB)⁻¹Bᵀ")
            for lhs, rhs, name in ((a * x * a, a, "AXA = A"), (x * a * x, x, "XAX = X"),
                                   ((a * x).T, a * x, "(AX)ᵀ = AX"), ((x * a).T, x * a, "(XA)ᵀ = XA"))]
