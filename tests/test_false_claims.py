"""The false-claim suite: false statements written in every route the proof engine's API offers,
each of which must be refused — its status is not "proved", or the construction it needs raises.
Each entry also carries exact evidence that the statement is false (an instance, a point or an
explicit matrix), so no entry is a true statement the engine merely fails to prove.

The routes are listed in :data:`ROUTES`; docs/proofs.md states why each is sound.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import pytest
import sympy as sp

from gpfverify.errors import InputError
from gpfverify.symbolic import dimension_free as fusion
from gpfverify.symbolic import gp_claims
from gpfverify.symbolic import word_algebra as wa
from gpfverify.symbolic.argument import Argument
from gpfverify.symbolic.certificate import Certificate
from gpfverify.symbolic.fusion_claims import build_sensor
from gpfverify.symbolic.fusion_forms import cmf_term, dmf_term, projector
from gpfverify.symbolic.polynomial import Fraction, generic_matrix, identity as poly_identity, inverse, lift
from gpfverify.symbolic.polynomial import polynomial_ring
from gpfverify.symbolic.theory import Theory, size_counterexample
from gpfverify.symbolic.word_algebra import identity, zero

T = fusion.T
A, Ap, C, G, L, W = fusion.A, fusion.Ap, fusion.C, fusion.G, fusion.Lf, fusion.W
n, l = fusion.n, fusion.l
SPD, FULL = frozenset({fusion.C_SPD}), frozenset({fusion.C_SPD, fusion.FULL_RANK})

ROUTES = ("normal form", "chain", "lemma", "proof record", "theories", "hypothesis", "definition", "inverse",
          "symmetry", "stated fact", "trace", "size bound", "instantiation", "induction", "instances",
          "listed sizes", "counterexample", "statement words", "scope words", "certificate record")

#: hypotheses only the false claims below use (issued once: a theory's rules are fixed objects)
A_ZERO = T.hypothesis("C_xy^m = 0 (a false claim)", A, zero(n, l), "C_xy^m = 0")
AT_ONE = T.hypothesis("μ_DMF = μ_CMF at one measurement (a false claim)", fusion.D, fusion.CMF_N,
                      "μ_DMF = μ_CMF at one measurement")
FOREIGN = Theory("another theory with a letter W")
FOREIGN_W = FOREIGN.general("W", n, n)
W_IS_I = FOREIGN.hypothesis("W = I", FOREIGN_W, identity(n), "W = I")
TRACES = Theory("traces")
_m = sp.Symbol("n", integer=True, positive=True)
TW, TV, TU = (TRACES.general(name, _m, _m) for name in "WVU")
WVU_FACT = TRACES.fact("tr(WVU) = tr(VWU)", wa.trace(TW * TV * TU), wa.trace(TV * TW * TU))
COMMUTE_FACT = TRACES.fact("WV = VW", TW * TV, TV * TW)
R = sp.Symbol("r", integer=True, positive=True)
PRODUCT = Theory("a rank-r product")
PB, PF = PRODUCT.general("B", n, R), PRODUCT.general("F", n, R)
PX, PRODUCT_INVERSE = PRODUCT.inverse("(BFᵀ)⁻¹", PB * PF.T)


@dataclass(frozen=True)
class FalseClaim:
    name: str
    route: str
    #: the engine's answer: a status, or raises InputError / ValueError where the construction is refused
    attempt: Callable[[], str]
    #: exact evidence that the statement is false
    false: Callable[[], bool]


def status(statement: str, *results, theory=T, sizes=(), notes=()) -> str:
    argument = Argument("false claim", statement, "test", theory)
    if results:
        argument.conclude(*results)
    for label, residual in sizes:
        argument.at_sizes(statement, label, residual)
    for note in notes:
        argument.note(note)
    return argument.verdict().status


def false_at(lhs, rhs, in_force=frozenset(), theory=T) -> bool:
    return theory.counterexample(lhs, rhs, frozenset(in_force))


def one_sensor(*rules):
    return [*fusion.ONE_SENSOR, *rules]


def _forged_lemma():
    real = fusion.projector_is_identity().derivation  # a real proof, of A⁺A = I
    return wa.Rule("G_m C_y^m Aᵀ = G_m C_y^m A⁺", G * C * A.T, G * C * Ap, "lemma", real.premises, real)


def _forged_proof():
    return wa.Proof("A⁺A = I", Ap * A, fusion.I_l, True, (), "trust me", method="normal form")


def _edited_proof():
    proof = wa.prove_by_normal_form(A * Ap * A * Ap, A * Ap, [fusion.PENROSE[0]])
    proof.lhs, proof.rhs = Ap * A, fusion.I_l
    return proof


def _gap_for_every_n():
    rules = one_sensor(fusion.PHI)
    base = wa.prove_by_normal_form(fusion.dmf_term(), fusion.cmf_term() + fusion.Phi * (fusion.y - fusion.my), rules)
    return fusion.over_sensors("gap", fusion.IH_GAP, base, rules, gap=True)


def _at_one_measurement():
    pointwise = wa.lemma("pointwise", wa.prove_by_chain([(fusion.GAP_N, None),
                                                        (fusion.D - fusion.CMF_N, _gap_for_every_n()),
                                                        (zero(n, fusion.k), AT_ONE)]))
    at = T.instantiate(pointwise, {"y_(N)": fusion.my_N.substitute({}, {fusion.k: fusion.K}) + identity(fusion.K)},
                       {fusion.k: fusion.K})
    return status("Φ_(N) = 0 if μ_DMF = μ_CMF at one measurement", at)


def _gap_zero_at_the_prediction_with_phi_nonzero() -> bool:
    """One rank-deficient sensor at y^m = μ_y^m: DMF_m = CMF_m exactly, yet Φ_m ≠ 0."""
    s = build_sensor(2, 2, 1).lifted
    at = replace(s, y=s.mu_y, innovation=s.mu_y - s.mu_y)
    at_prediction = dmf_term(at) - cmf_term(at)
    phi = s.G @ s.C_y @ (projector(s) - poly_identity(2, s.G.num.domain)) @ s.C_y_inv
    return at_prediction.is_zero() and not phi.is_zero()


def _step_without_p_is_i():
    step = wa.prove_by_normal_form(fusion.D + fusion.dmf_term(), fusion.G_next * (fusion.y_next - fusion.mu_next),
                                   one_sensor(*fusion.STACKING, fusion.IH_EXACT))
    one = wa.prove_by_normal_form(fusion.dmf_term(), fusion.cmf_term(), one_sensor())
    base_map = {"Σ_{m≤N} DMF_m": fusion.dmf_term(), "G_(N)": G, "y_(N)": fusion.y, "μ_y(N)": fusion.mc}
    step_map = {"Σ_{m≤N} DMF_m": fusion.D + fusion.dmf_term(), "G_(N)": fusion.G_next, "y_(N)": fusion.y_next,
                "μ_y(N)": fusion.mu_next}
    T.induction("μ_DMF = μ_CMF for every N, whatever the rank", fusion.IH_EXACT, one, step, base_map, step_map,
                {fusion.K: l}, {fusion.K: fusion.K + l})
    return "proved"


def _generic(name, size=2):
    c = generic_matrix(name, size, size)
    ring = polynomial_ring(c)
    return Fraction.of(lift(c, ring)), ring


def _square_residual():
    c, ring = _generic("c")
    return c @ c - Fraction.of(lift(sp.eye(2), ring))


def _commutator_residual(size):
    x = generic_matrix("x", size, size)
    y = generic_matrix("y", size, size)
    return sp.expand(x * y - y * x)


def _identity_residual():
    c, ring = _generic("c")
    return c @ inverse(c) - Fraction.of(lift(sp.eye(2), ring))


def _not_a_counterexample():
    """The claim here is the refutation itself: "refuted" would be its "proved"."""
    argument = Argument("false claim", "C C⁻¹ = I fails for a generic 2×2 C", "test")
    argument.refute("generic C", nonzero=(_identity_residual(),))
    return "proved" if argument.verdict().status == "refuted" else argument.verdict().status


def _certificate_by_hand():
    Certificate("a-plus-a", "A⁺A = I for every C_xy^m", "asserted", "proved", "")
    return "proved"


def _borrowed_evidence():
    argument = Argument("a true claim", "AA⁺A = A", "test", T)
    argument.conclude(wa.prove_by_normal_form(A * Ap * A, A, [fusion.PENROSE[0]]))
    Certificate("a-plus-a", "A⁺A = I for every C_xy^m", "borrowed", "proved", "", evidence=argument.verdict())
    return "proved"


def _six_by_six_rank_six() -> bool:
    six = sp.Matrix(6, 6, lambda i, j: (i + 1) ** j)  # Vandermonde: D = 6, l_m = 6 > 5, full column rank
    return six.rank() == 6


RULES_FULL = [*fusion.ONE_SENSOR, fusion.projector_is_identity()]

FALSE_CLAIMS = [
    FalseClaim("DMF with (C_xy^m)ᵀ for (C_xy^m)⁺ equals CMF, by a rule no declaration issued", "normal form",
               lambda: status("DMF with Aᵀ equals CMF when every C_xy^m has full column rank",
                              wa.prove_by_normal_form(fusion.dmf_term(pinv=A.T), fusion.cmf_term(),
                                                      RULES_FULL + [fusion.PLANTED_TRANSPOSE])),
               lambda: false_at(fusion.dmf_term(pinv=A.T), fusion.cmf_term(), FULL)),
    FalseClaim("Proposition 1 for any rank, by the axiom A⁺A = I (true only at full rank)", "normal form",
               lambda: status("DMF equals CMF for every measurement",
                              wa.prove_by_normal_form(fusion.dmf_term(), fusion.cmf_term(),
                                                      one_sensor(fusion.PLANTED_P_IS_I))),
               lambda: false_at(fusion.dmf_term(), fusion.cmf_term(), SPD)),
    FalseClaim("Proposition 1 'for any rank', with A⁺A = I as a hypothesis", "statement words",
               lambda: status("DMF equals CMF for every measurement, for any rank of C_xy^m",
                              wa.prove_by_normal_form(fusion.dmf_term(), fusion.cmf_term(), one_sensor(fusion.P_IS_I))),
               lambda: false_at(fusion.dmf_term(), fusion.cmf_term(), SPD)),
    FalseClaim("gap_m = 0 for any rank, by the full-column-rank lemma P = I", "statement words",
               lambda: status("gap_m = 0 for any rank of C_xy^m",
                              wa.prove_by_normal_form(fusion.gap_term(), zero(n, fusion.k), RULES_FULL)),
               lambda: false_at(fusion.gap_term(), zero(n, fusion.k), SPD)),
    FalseClaim("DMF with Aᵀ equals CMF, by a lemma whose proof shows something else", "lemma",
               lambda: status("DMF with Aᵀ equals CMF when every C_xy^m has full column rank",
                              wa.prove_by_normal_form(fusion.dmf_term(pinv=A.T), fusion.cmf_term(),
                                                      RULES_FULL + [_forged_lemma()])),
               lambda: false_at(fusion.dmf_term(pinv=A.T), fusion.cmf_term(), FULL)),
    FalseClaim("A⁺A = I for every C_xy^m, by a chain step that applies no rule", "chain",
               lambda: status("A⁺A = I", wa.prove_by_chain([(Ap * A, None), (fusion.I_l, fusion.PENROSE[0])])),
               lambda: false_at(Ap * A, fusion.I_l)),
    FalseClaim("A⁺A = I for every C_xy^m, by a Proof object made by hand", "proof record",
               lambda: status("A⁺A = I", _forged_proof()), lambda: false_at(Ap * A, fusion.I_l)),
    FalseClaim("A⁺A = I for every C_xy^m, by a real proof's record edited", "proof record",
               lambda: status("A⁺A = I", _edited_proof()), lambda: false_at(Ap * A, fusion.I_l)),
    FalseClaim("W G_m = G_m, by another theory's hypothesis W = I", "theories",
               lambda: status("W G_m = G_m", wa.prove_by_normal_form(W * G, G, [W_IS_I])),
               lambda: false_at(W * G, G)),
    FalseClaim("G_m = 0, from hypotheses no instance satisfies (C_xy^m = 0 of full column rank)", "instances",
               lambda: status("G_m = 0", wa.prove_by_chain([(G, None), (G * L * A, fusion.FULL_RANK),
                                                            (zero(n, l), A_ZERO)])),
               lambda: false_at(G, zero(n, l))),
    FalseClaim("DMF = CMF for every measurement under the weaker hypothesis G_m(I − P_m) = 0", "hypothesis",
               lambda: status("DMF = CMF for every measurement if G_m(I − P_m) = 0",
                              wa.prove_by_normal_form(fusion.dmf_term(), fusion.cmf_term(), one_sensor(fusion.G_P))),
               lambda: false_at(fusion.dmf_term(), fusion.cmf_term(), {fusion.C_SPD, fusion.G_P})),
    FalseClaim("tr(WVU) = tr(VWU), by the trace rules", "trace",
               lambda: status("tr(WVU) = tr(VWU)",
                              wa.prove_trace_identity(wa.trace(TW * TV * TU), wa.trace(TV * TW * TU), []),
                              theory=TRACES),
               lambda: false_at(wa.trace(TW * TV * TU), wa.trace(TV * TW * TU), theory=TRACES)),
    FalseClaim("tr(WVU) = tr(VWU), as a stated fact (true on diagonal matrices)", "stated fact",
               lambda: status("tr(WVU) = tr(VWU)", wa.prove_trace_identity(WVU_FACT.lhs, WVU_FACT.rhs, [WVU_FACT]),
                              theory=TRACES),
               lambda: false_at(WVU_FACT.lhs, WVU_FACT.rhs, theory=TRACES)),
    FalseClaim("WVU = VWU, by the stated fact WV = VW", "stated fact",
               lambda: status("WVU = VWU", wa.prove_by_normal_form(TW * TV * TU, TV * TW * TU, [COMMUTE_FACT]),
                              theory=TRACES),
               lambda: false_at(TW * TV * TU, TV * TW * TU, theory=TRACES)),
    FalseClaim("l_m ≤ 5 for any D under full column rank", "size bound",
               lambda: status("l_m ≤ 5", wa.prove_size_bound(l, 5, [(1, identity(n) - A * Ap)],
                                                            [*fusion.PENROSE, fusion.projector_is_identity()])),
               _six_by_six_rank_six),
    FalseClaim("l_m ≤ D − 1 under full column rank", "size bound",
               lambda: status("l_m ≤ D − 1", wa.prove_size_bound(l, n - 1, [(1, identity(n) - A * Ap)],
                                                                [*fusion.PENROSE, fusion.projector_is_identity()])),
               lambda: size_counterexample(T, l, n - 1, frozenset({fusion.FULL_RANK}))),
    FalseClaim("l_m ≤ D without the full-column-rank hypothesis", "size bound",
               lambda: status("l_m ≤ D", wa.prove_size_bound(l, n, [(1, identity(n) - A * Ap)], list(fusion.PENROSE))),
               lambda: size_counterexample(T, l, n, frozenset())),
    FalseClaim("(BFᵀ)(BFᵀ)⁻¹ = I for any rank r", "inverse",
               lambda: status("(BFᵀ)(BFᵀ)⁻¹ = I for any rank r",
                              wa.prove_by_normal_form(PB * PF.T * PX, identity(n), [PRODUCT_INVERSE[0]]),
                              theory=PRODUCT),
               lambda: (sp.Matrix([[1], [2]]) * sp.Matrix([[3], [4]]).T).det() == 0),  # r = 1 < n = 2: singular
    FalseClaim("(BFᵀ)(BFᵀ)⁻¹ = I written with sympy's inverse (it cancels when formed)", "inverse",
               lambda: status("(BFᵀ)(BFᵀ)⁻¹ = I", (PB * PF.T) * (PB * PF.T).I, theory=PRODUCT),
               lambda: (sp.Matrix([[1], [2]]) * sp.Matrix([[3], [4]]).T).det() == 0),
    FalseClaim("the inverse of an n × l matrix", "inverse",
               lambda: status("(BFᵀ)(BFᵀ)⁻¹ = I", Theory("wide").inverse("(BFᵀ)⁻¹", fusion.A)[1][0]),
               lambda: (sp.Matrix([[1, 2]]).T * sp.Matrix([[1, 2]])).det() == 0),  # 2×1 times 1×2: never invertible
    FalseClaim("zᵀR⁻¹u = uᵀR⁻¹z, R⁻¹ = (ΣΞ + I)⁻¹ declared symmetric by hand", "symmetry",
               lambda: status("zᵀR⁻¹u = uᵀR⁻¹z", wa.prove_by_normal_form(
                   gp_claims._quad(gp_claims.zv, gp_claims.Ri, gp_claims.uv),
                   gp_claims._quad(gp_claims.uv, gp_claims.Ri, gp_claims.zv), [gp_claims.PLANTED_R_SYMMETRIC]),
                   theory=gp_claims.GP),
               lambda: false_at(gp_claims._quad(gp_claims.zv, gp_claims.Ri, gp_claims.uv),
                                gp_claims._quad(gp_claims.uv, gp_claims.Ri, gp_claims.zv),
                                {gp_claims.LAM, gp_claims.LAM_B, gp_claims.SIG}, gp_claims.GP)),
    FalseClaim("C_y^m = I, by defining the letter again", "definition",
               lambda: status("C_y^m = I", T.define("C_y^m", fusion.I_l)[1]),
               lambda: false_at(C, fusion.I_l, SPD)),
    FalseClaim("Φ_(N) = 0 when μ_DMF = μ_CMF at one measurement only", "instantiation",
               _at_one_measurement, _gap_zero_at_the_prediction_with_phi_nonzero),
    FalseClaim("μ_DMF = μ_CMF for every N whatever the rank, by an induction whose step is not proved", "induction",
               _step_without_p_is_i,
               lambda: false_at(fusion.D + fusion.dmf_term(), fusion.G_next * (fusion.y_next - fusion.mu_next),
                                {fusion.C_SPD, fusion.IH_EXACT})),
    FalseClaim("C·C = I for a generic 2 × 2 C", "listed sizes",
               lambda: status("C·C = I", sizes=[("n = 2", _square_residual())]),
               lambda: not _square_residual().is_zero()),
    FalseClaim("XY = YX in any dimension, from n = 1", "scope words",
               lambda: status("XY = YX in any dimension", sizes=[("n = 1", _commutator_residual(1))]),
               lambda: _commutator_residual(2) != sp.zeros(2, 2)),
    FalseClaim("XY = YX, with a note that says it holds for every D", "scope words",
               lambda: status("XY = YX", sizes=[("n = 1", _commutator_residual(1))],
                              notes=["The same holds for every D."]),
               lambda: _commutator_residual(2) != sp.zeros(2, 2)),
    FalseClaim("C C⁻¹ = I is refuted, by a 'counterexample' that is not one", "counterexample",
               _not_a_counterexample, lambda: _identity_residual().is_zero()),  # C C⁻¹ = I holds identically
    FalseClaim("A⁺A = I for every C_xy^m, declared proved in the record", "certificate record",
               _certificate_by_hand, lambda: false_at(Ap * A, fusion.I_l)),
    FalseClaim("A⁺A = I for every C_xy^m, proved with another claim's verdict", "certificate record",
               _borrowed_evidence, lambda: false_at(Ap * A, fusion.I_l)),
]


def test_the_suite_has_at_least_twenty_false_claims_in_every_route():
    assert len(FALSE_CLAIMS) >= 20
    assert {c.route for c in FALSE_CLAIMS} == set(ROUTES)
    assert len({c.name for c in FALSE_CLAIMS}) == len(FALSE_CLAIMS)


@pytest.mark.parametrize("claim", FALSE_CLAIMS, ids=[c.name for c in FALSE_CLAIMS])
def test_a_false_claim_is_false_and_refused(claim):
    assert claim.false(), "the evidence must show the statement false"
    try:
        outcome = claim.attempt()
    except (InputError, ValueError):
        return  # refused when built
    assert outcome != "proved"
