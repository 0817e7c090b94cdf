"""How the proof engine decides, beyond the false-claim suite (tests/test_false_claims.py): rules
compare by identity, a hypothesis is carried into the statement, the engine draws general
instances and counts every check, a stated fact is at most "checked", no inverse can be formed
outside a declaration, and instantiation and induction refuse what they cannot justify."""

from __future__ import annotations

import pytest
import sympy as sp

from gpfverify.errors import InputError
from gpfverify.symbolic import dimension_free as fusion
from gpfverify.symbolic import word_algebra as wa
from gpfverify.symbolic.argument import Argument, is_identically_zero
from gpfverify.symbolic.certificate import Certificate
from gpfverify.symbolic.theory import Theory
from gpfverify.symbolic.word_algebra import identity, zero
from tests.test_false_claims import A_ZERO, AT_ONE

T = fusion.T
A, Ap, C, Ci, G, L = fusion.A, fusion.Ap, fusion.C, fusion.Ci, fusion.G, fusion.Lf
I_l = fusion.I_l


def verdict(statement: str, *results, theory=T, also=(), sizes=()):
    """The engine's verdict on ``results`` offered as the proof of ``statement``."""
    argument = Argument("false-claim", statement, "test", theory, also)
    if results:
        argument.conclude(*results)
    for label, residual in sizes:
        argument.at_sizes(statement, label, residual)
    return argument.verdict()


def refused(statement: str, *results, **kwargs) -> bool:
    return verdict(statement, *results, **kwargs).status != "proved"


def false_on_an_instance(lhs, rhs, in_force=frozenset(), theory=T) -> bool:
    return theory.counterexample(lhs, rhs, frozenset(in_force))


# ---- the rules a proof applies ---------------------------------------------------------------------

def test_a_look_alike_of_an_issued_rule_is_not_that_rule():
    """Rules compare by identity: a copy of the true Penrose equation built by hand is not issued."""
    copy = wa.Rule(fusion.PENROSE[0].name, fusion.PENROSE[0].lhs, fusion.PENROSE[0].rhs, "axiom")
    proof = wa.prove_by_normal_form(A * Ap * A * Ap, A * Ap, [copy])
    assert proof.proved and refused("AA⁺AA⁺ = AA⁺", proof)
    assert not refused("AA⁺AA⁺ = AA⁺", wa.prove_by_normal_form(A * Ap * A * Ap, A * Ap, [fusion.PENROSE[0]]))


def test_the_same_equation_as_a_hypothesis_is_carried_into_the_statement():
    """Issued as a hypothesis, A⁺A = I is honest: the statement must carry it, and may not then
    say "for any rank"."""
    proof = wa.prove_by_normal_form(fusion.dmf_term(), fusion.cmf_term(), fusion.ONE_SENSOR + [fusion.P_IS_I])
    v = verdict("DMF equals CMF for every measurement, for any rank of C_xy^m", proof)
    assert v.status != "proved" and any("any rank" in r for r in v.reasons)
    honest = Argument("a", "DMF equals CMF for every measurement", "test", T)
    honest.conclude(proof)
    certificate = honest.certificate()
    assert certificate.status == "proved" and "(C_xy^m)⁺C_xy^m = I" in certificate.statement


def test_a_lemma_whose_rule_is_not_its_proofs_conclusion_is_refused():
    proof = wa.prove_by_chain([(Ap * A, None), (L * A * Ap * A, fusion.FULL_RANK), (L * A, fusion.PENROSE[0]),
                               (I_l, fusion.FULL_RANK)])
    forged = wa.Rule("A⁺ = L", Ap, L, "lemma", proof.premises, proof)  # claims more than the proof shows
    used = wa.prove_by_normal_form(Ap * A, I_l, [forged, fusion.FULL_RANK])
    assert used.proved and refused("A⁺A = I when C_xy^m has full column rank", used)
    with pytest.raises(InputError):
        wa.lemma("unproved", wa.prove_by_normal_form(Ap * A, I_l, list(fusion.PENROSE)))


# ---- instances: what an assumption is checked on -------------------------------------------------

def test_hypotheses_no_instance_satisfies_prove_nothing():
    """C_xy^m = 0 together with L_m C_xy^m = I: every statement follows (here G_m = 0), and no
    instance satisfies both; a check that ran on no instance fails."""
    proof = wa.prove_by_chain([(G, None), (G * L * A, fusion.FULL_RANK), (zero(fusion.n, fusion.l), A_ZERO)])
    assert proof.proved
    v = verdict("G_m = 0 when C_xy^m = 0 has full column rank", proof)
    assert v.status != "proved"
    assert any(c.instances == 0 and not c.passed for c in v.checks)
    assert T.instances(frozenset({A_ZERO, fusion.FULL_RANK})) == []
    assert false_on_an_instance(G, zero(fusion.n, fusion.l))


def test_an_empty_check_is_a_failure_and_every_check_counts_its_instances():
    empty = T.check(fusion.PENROSE[0], frozenset({A_ZERO, fusion.FULL_RANK}))
    assert empty.instances == 0 and not empty.passed and "NO instance" in str(empty)
    full = T.check(fusion.FULL_RANK, frozenset({fusion.FULL_RANK}))
    assert full.passed and full.instances > 0 and f"on {full.instances} instances" in str(full)


def test_instances_are_general_unless_a_hypothesis_says_otherwise():
    """The engine's own generator: without hypotheses C_y^m is neither symmetric nor diagonal and
    C_xy^m takes deficient ranks; with the SPD hypothesis C_y^m is symmetric but not diagonal."""
    free = T.instances(frozenset())
    assert any(i.values["C_y^m"] != i.values["C_y^m"].T for i in free)
    assert any(i.values["G_m"].shape[0] > 1 and not i.values["G_m"].is_diagonal() for i in free)
    assert any(i.values["C_xy^m"].rank() < min(i.values["C_xy^m"].shape) for i in free)
    spd = T.instances(frozenset({fusion.C_SPD}))
    assert all(i.values["C_y^m"] == i.values["C_y^m"].T for i in spd)
    assert any(not i.values["C_y^m"].is_diagonal() for i in spd)
    full = T.instances(frozenset({fusion.FULL_RANK}))
    assert full and all(i.values["C_xy^m"].rank() == i.values["C_xy^m"].shape[1] for i in full)


# ---- stated facts and traces ------------------------------------------------------------------------

def test_a_claim_resting_on_a_stated_fact_is_at_most_checked():
    """A stated fact is checked on general instances, never proved: even the true AA⁺A = A, stated
    as a fact instead of taken from the pseudo-inverse's declaration, leaves its claim "checked";
    the false WV = VW stated as a fact fails its check and its claim is refuted on an instance."""
    facts = Theory("facts")
    n = sp.Symbol("n", integer=True, positive=True)
    a = facts.general("A", n, n)
    ap, _ = facts.pinv("A⁺", a)
    penrose = facts.fact("AA⁺A = A", a * ap * a, a)
    proof = wa.prove_by_normal_form(a * ap * a * ap, a * ap, [penrose])
    v = verdict("AA⁺AA⁺ = AA⁺", proof, theory=facts)
    assert v.status == "checked" and v.facts and v.facts[0].passed and v.facts[0].instances > 0
    w, u = facts.general("W", n, n), facts.general("V", n, n)
    commute = facts.fact("WV = VW", w * u, u * w)
    wrong = wa.prove_by_normal_form(w * u * a, u * w * a, [commute])
    v_wrong = verdict("WVA = VWA", wrong, theory=facts)
    assert wrong.proved and v_wrong.status == "refuted" and not v_wrong.facts[0].passed


def test_full_column_rank_does_not_give_a_bound_smaller_than_d():
    """l_m ≤ 5 'for any D' (a rank-6 6×6 matrix refutes it) and l_m ≤ D − 1 are refused; the true
    bound l_m ≤ D is proved from D − l_m = tr((I − AA⁺)ᵀ(I − AA⁺)) ≥ 0."""
    p_is_i = fusion.projector_is_identity()
    rules = [*fusion.PENROSE, p_is_i]
    square = [(1, identity(fusion.n) - A * Ap)]
    assert not wa.prove_size_bound(fusion.l, 5, square, rules).proved
    assert not wa.prove_size_bound(fusion.l, fusion.n - 1, square, rules).proved
    assert not wa.prove_size_bound(fusion.l, fusion.n, [(-1, A * Ap)], rules).proved  # a negative "square"
    assert not wa.prove_size_bound(fusion.l, fusion.n, square, list(fusion.PENROSE)).proved  # rank dropped
    assert verdict("l_m ≤ D when C_xy^m has full column rank", wa.prove_size_bound(fusion.l, fusion.n, square, rules)
                   ).status == "proved"
    six = sp.Matrix(6, 6, lambda i, j: (i + 1) ** j)  # Vandermonde: rank 6 = l_m > 5
    assert six.rank() == 6 and (six.inv() * six) == sp.eye(6)  # a left inverse exists: full column rank


# ---- inverses ---------------------------------------------------------------------------------------

def test_no_inverse_or_power_can_be_formed_outside_a_theory_declaration():
    b, f = wa.symbol("B", fusion.n, sp.Symbol("r")), wa.symbol("F", fusion.n, sp.Symbol("r"))
    product = b * f.T
    for build in (lambda: product.I, lambda: product ** -1, lambda: product ** 2, lambda: product.inverse()):
        with pytest.raises(InputError):
            build()
    with pytest.raises(InputError):
        Argument("x", "s", "m", T).conclude(sp.MatrixSymbol("B", 2, 2) * sp.MatrixSymbol("B", 2, 2).I)
    wide = Theory("wide")
    with pytest.raises(InputError):
        wide.inverse("(BFᵀ)⁻¹", wide.general("B", fusion.n, sp.Symbol("r")) * wide.general("F", fusion.l,
                                                                                            sp.Symbol("r")).T)


def test_the_inverse_of_a_rank_r_product_rests_on_its_invertibility():
    """(BFᵀ)(BFᵀ)⁻¹ = I for n×n BFᵀ of rank r: the declaration's hypothesis "BFᵀ invertible" is
    carried into the statement (and restricts the rank); "for any rank r" is refused, and the
    instances of the hypothesis are those with r ≥ n."""
    r = sp.Symbol("r", integer=True, positive=True)
    theory = Theory("rank-r product")
    b, f = theory.general("B", fusion.n, r), theory.general("F", fusion.n, r)
    x, (right, _left) = theory.inverse("(BFᵀ)⁻¹", b * f.T)
    proof = wa.prove_by_normal_form(b * f.T * x, identity(fusion.n), [right])
    assert proof.proved
    assert refused("(BFᵀ)(BFᵀ)⁻¹ = I for any rank r", proof, theory=theory)
    honest = Argument("h", "(BFᵀ)(BFᵀ)⁻¹ = I", "test", theory)
    honest.conclude(proof)
    assert honest.certificate().statement.endswith("assuming: B·Fᵀ invertible")
    assert all(i.sizes[r] >= i.sizes[fusion.n] for i in theory.instances(proof.premises))


# ---- definitions, instantiation, induction -----------------------------------------------------------

def test_a_hypothesis_about_one_measurement_cannot_be_instantiated_at_another():
    """Φ_(N) = 0 from "μ_DMF = μ_CMF at one measurement": refused (the hypothesis pins y_(N))."""
    gap = fusion.over_sensors(
        "gap", fusion.IH_GAP,
        wa.prove_by_normal_form(fusion.dmf_term(), fusion.cmf_term() + fusion.Phi * (fusion.y - fusion.my),
                                fusion.ONE_SENSOR + [fusion.PHI]),
        fusion.ONE_SENSOR + [fusion.PHI], gap=True)
    assert T.depends_on("Φ_(N)") == {"G_(N)"}  # verified by the induction that built it
    pointwise = wa.lemma("pointwise", wa.prove_by_chain([(fusion.GAP_N, None), (fusion.D - fusion.CMF_N, gap),
                                                        (zero(fusion.n, fusion.k), AT_ONE)]))
    with pytest.raises(InputError, match="holds at one value"):
        T.instantiate(pointwise, {"y_(N)": fusion.my_N.substitute({}, {fusion.k: fusion.K}) + identity(fusion.K)},
                      {fusion.k: fusion.K})
    with pytest.raises(InputError):  # a quantity that stands for a function of others
        T.instantiate(pointwise, {"Φ_(N)": zero(fusion.n, fusion.K)})
    with pytest.raises(InputError, match="holds at one value"):  # nor the hypothesis itself
        T.instantiate(AT_ONE, {"y_(N)": fusion.mu_N})
    with pytest.raises(InputError, match="no definition to expand"):  # it speaks of Σ DMF_m, a function of y_(N)
        T.instantiate(fusion.EVERY_MEASUREMENT, {"y_(N)": fusion.mu_N})
    every = wa.lemma("every", wa.prove_by_chain([(fusion.GAP_N, None), (fusion.D - fusion.CMF_N, gap),
                                                 (zero(fusion.n, fusion.k), fusion.EVERY_MEASUREMENT)]))
    instance = T.instantiate(every, {"y_(N)": fusion.mu_N})
    assert fusion.EVERY_MEASUREMENT in instance.premises  # an instance still rests on its hypothesis


def test_an_induction_whose_base_or_step_proves_something_else_is_refused():
    rules = [*fusion.ONE_SENSOR, fusion.projector_is_identity()]
    wrong_base = wa.prove_by_normal_form(fusion.dmf_term(), fusion.dmf_term(), rules)  # proves DMF = DMF
    base_map = {"Σ_{m≤N} DMF_m": fusion.dmf_term(), "G_(N)": G, "y_(N)": fusion.y, "μ_y(N)": fusion.mc}
    with pytest.raises(InputError, match="the base proves"):
        T.induction("x", fusion.IH_EXACT, wrong_base, wrong_base, base_map, base_map, {fusion.K: fusion.l})
    with pytest.raises(InputError, match="not an induction hypothesis"):
        T.induction("x", fusion.FULL_RANK, wrong_base, wrong_base, base_map, base_map)


# ---- identities at listed sizes, counterexamples, the record -----------------------------------------

def test_an_author_cannot_declare_a_certificate_proved():
    with pytest.raises(ValueError):
        Certificate("x", "s", "m", "proved", "d")
    with pytest.raises(ValueError):
        Certificate("x", "s", "m", "proved", "d", evidence=verdict("a false claim", sizes=[("n = 1", sp.Integer(1))]))


def test_every_residual_type_has_one_zero_test():
    x = sp.Symbol("x")
    assert is_identically_zero(sp.Matrix([[(x**2 - 1) / (x - 1) - x - 1]]))
    assert not is_identically_zero((x, sp.Integer(0)))
    assert not is_identically_zero(())  # an empty residual is not a proof
    with pytest.raises(InputError):
        is_identically_zero("0")


def test_an_opaque_letter_built_from_what_it_is_declared_not_to_depend_on_is_refused():
    """Q_(N) = Z_(N) y_(N) is declared a function of Z_(N) alone; the induction that builds it adds
    W y at each step, so the declaration is false and the induction refused (and Q_(N) keeps
    counting as a function of every letter)."""
    n, l, big, k = sp.symbols("n l K k", integer=True, positive=True)
    theory = Theory("stacked measurements")
    z, y_n = theory.general("Z", n, big), theory.general("y_(N)", big, k)
    q = theory.general("Q", n, k, opaque=True, depends_on=(z,))
    w, y = theory.general("W", n, l), theory.general("y", l, k)
    (s1, s2), selectors = theory.partition("S", (big, l))
    z_next, z_def = theory.define("Z_(N+1)", z * s1.T + w * s2.T)
    y_next, y_def = theory.define("y_(N+1)", s1 * y_n + s2 * y)
    hypothesis = theory.hypothesis("Q = Z y_(N)", q, z * y_n, "induction hypothesis", realise={"Q": z * y_n},
                                   induction=True)
    base = wa.prove_by_normal_form(w * y, w * y, [])
    step = wa.prove_by_normal_form(q + w * y, z_next * y_next, [*selectors, z_def, y_def, hypothesis])
    assert base.proved and step.proved
    with pytest.raises(InputError, match="declared not to depend on"):
        theory.induction("Q for every N", hypothesis, base, step, {"Q": w * y, "Z": w, "y_(N)": y},
                         {"Q": q + w * y, "Z": z_next, "y_(N)": y_next}, {big: l}, {big: big + l})
    assert theory.depends_on("Q") == frozenset(theory.declarations)


def test_no_symbolic_route_builds_sympy_matrix_expressions():
    """sympy's MatrixSymbol products cancel M·M⁻¹ when formed, whatever M is: no proof module uses
    them (matrices of symbolic size are word-algebra letters; explicit sizes are exact matrices)."""
    from pathlib import Path

    import gpfverify.symbolic

    folder = Path(gpfverify.symbolic.__file__).parent
    offenders = [p.name for p in folder.glob("*.py")
                 if any(token in p.read_text(encoding="utf-8") for token in ("MatrixSymbol", "MatMul", "Inverse("))]
    assert not offenders


def test_instantiation_expands_what_is_defined_from_the_letter_and_refuses_what_is_not():
    """μ_e^m := μ_p^m + C_xy^m (C_y^m)⁻¹(y^m − μ_y^m) follows y^m when y^m is instantiated; the
    pseudo-inverse cannot follow C_xy^m, so instantiating C_xy^m in a rule that mentions it is refused."""
    assert T.depends_on("μ_e^m") >= {"y^m", "C_xy^m", "(C_y^m)⁻¹", "C_y^m"}
    assert T.depends_on("(C_xy^m)⁺") == {"C_xy^m"}
    update = wa.lemma("μ_e^m − μ_p^m = C_xy^m(C_y^m)⁻¹(y^m − μ_y^m)", wa.prove_by_normal_form(
        fusion.me - fusion.mp, A * Ci * (fusion.y - fusion.my), [fusion.LOCAL_UPDATE]))
    at_prediction = T.instantiate(update, {"y^m": fusion.my})
    assert at_prediction.lhs == zero(fusion.n, fusion.k) and at_prediction.rhs == zero(fusion.n, fusion.k)
    projector = wa.lemma("AA⁺A = A", wa.prove_by_normal_form(A * Ap * A, A, [fusion.PENROSE[0]]))
    with pytest.raises(InputError, match="no definition to expand"):
        T.instantiate(projector, {"C_xy^m": G})
