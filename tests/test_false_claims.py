"""The false-claim corpus: false (or vacuous) statements pushed through every route the public API
offers, each of which must be refused — the kernel's verdict is not "proved" (or, for a claimed
refutation, not "refuted"), or the construction raises. Each entry also carries exact evidence
that the claim is false, so no entry is a true statement the kernel merely fails to prove.

:data:`PORTED` are the 30 claims refused by the previous engine, rewritten against the formal
statements and the kernel (their routes named as before where the route still exists);
:data:`ADVERSARY` are claims built against the new API, by different routes.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass

import pytest
import sympy as sp

from gpfverify.errors import InputError
from gpfverify.kernel.instances import Instance, Undefined
from gpfverify.kernel.terms import frozen, read_statement
from gpfverify.symbolic import fusion_claims as fc
from gpfverify.symbolic.certificate import Certificate, ListedCheck, Part
from gpfverify.symbolic.formal import (Declare, I, Sum, Term, as_term, eq, every, exp, fcr, forall, invertible,
                                       le, num, spd, tr, zero)
from tests.kernel_helpers import instance, is_refuted, matrix, outcome, problems

#: rank one, 2 × 2, and a 2 × 2 SPD matrix that does not map its kernel into itself
RANK_ONE = matrix([[1, 1], [1, 1]])
CY = matrix([[3, 1], [1, 1]])


@dataclass(frozen=True)
class FalseClaim:
    name: str
    route: str
    #: the outcome: a kernel verdict, a record's problems ([] = accepted), or raises where refused
    attempt: Callable[[], object]
    #: exact evidence that the claim is false (or its hypotheses unsatisfiable)
    false: Callable[[], bool]


def refused(result) -> bool:
    """A verdict other than proved/refuted, or a record the kernel finds problems with."""
    if isinstance(result, list):
        return bool(result)
    return result not in ("proved", "refuted")


# ---- shared statements ------------------------------------------------------------------------------------

def one_matrix(conclusion, hypotheses=(), rows="n", cols="l", extra: Callable | None = None):
    """A statement about A (rows × cols) and G (n × l)."""
    d = Declare()
    d.sizes("n", "l")
    a, g = d.matrix("A", rows, cols), d.matrix("G", "n", "l")
    if extra:
        extra(d)
    d.assume(*hypotheses(a, g)) if callable(hypotheses) else None
    d.conclude(conclusion(a, g))
    return d.json()


def at(sizes: dict, **values) -> dict:
    return instance(sizes, {k: matrix(v) for k, v in values.items()})


def prop1_proof(statement: dict, entries_edit: Callable | None = None) -> dict:
    proof = fc.attempt(fc.prop1_statement(), fc._templates(full_rank_hyp=1))
    proof = copy.deepcopy(proof)
    if entries_edit:
        entries_edit(proof["steps"][0]["by"])
    return proof


def deficient_fusion(seed: int = 0, **kwargs) -> dict:
    return fc.refuting(fc.prop1_statement(full_rank=False),
                       lambda s: fc.instance(500 + s, deficient=True, **kwargs))


def one_sensor(g, measurement=True, free=None) -> dict:
    return fc._one_sensor(g, measurement, free)


def penrose_proof(claim) -> dict:
    a = ("var", "A")
    return {"steps": [{"id": "s", "claim": claim, "by": [{"gen": {"penrose": 1, "of": a}}]}]}


A_PLUS_A = eq(Term(("var", "A")).pinv * Term(("var", "A")), I("l"))


def a_plus_a_statement():
    return one_matrix(lambda a, g: eq(a.pinv * a, I("l")))


def a_plus_a_false() -> bool:
    return is_refuted(a_plus_a_statement(), at({"n": 2, "l": 2}, A=RANK_ONE, G=[[0, 0], [0, 0]]))


def a_plus_a_record(status: str, formal: list | None = None) -> dict:
    record = {"claim": "a-plus-a", "statement": "A⁺A = I for every A", "status": status, "method": "asserted",
              "detail": "", "scope": "any dimension"}
    if formal is not None:
        record["formal"] = formal
    return record


# ---- the 30 ported claims -----------------------------------------------------------------------------------

def _planted_generator():
    return outcome(fc.prop1_statement(MUTANTS_T), prop1_proof(None, lambda by: by.append(
        {"gen": {"axiom": "G_m C_y^m (C_xy^m)ᵀ = G_m C_y^m (C_xy^m)⁺"}})), fc.instance(1))


MUTANTS_T = fc.MUTANTS[0]


def _any_rank_axiom():
    """The full-column-rank generator cited in a statement without that hypothesis."""
    statement = fc.prop1_statement(full_rank=False)
    return outcome(statement, prop1_proof(statement), fc.instance(1, full_rank=False))


def _p_is_i_hypothesis():
    """With P_m = I as a hypothesis the statement carries it; without it the same proof is refused."""
    f = fc.declare()
    f.d.assume(every("m", fc.SENSOR, spd(f.Cy["m"])),
               every("m", fc.SENSOR, eq(f.P["m"], I("l[m]"))))
    f.d.conclude(eq(f.dmf(f.y), f.cmf(f.y)))
    honest = f.d.json()
    proof = fc.attempt(honest, fc._templates(equation_hyp=1))
    certificate = Certificate("p-is-i", "", [Part(honest, proof, fc.instance(9))])
    assert certificate.status == "proved" and "P_m = I for every m" in certificate.statement
    return outcome(fc.prop1_statement(full_rank=False), proof, fc.instance(9, full_rank=False))


def _gap_zero_statement():
    f = fc.declare()
    f.d.assume(every("m", fc.SENSOR, spd(f.Cy["m"])))
    f.d.conclude(eq(f.dmf(f.y), f.cmf(f.y)))
    return f.d.json()


def _gap_zero_by_full_rank_lemma():
    statement = _gap_zero_statement()
    return outcome(statement, prop1_proof(statement), fc.instance(1))


def _forged_lemma():
    """A lemma step claiming G S C (C_xy)ᵀ = G S C (C_xy)⁺ whose entries prove something else."""
    statement = fc.prop1_statement(MUTANTS_T)
    proof = fc.attempt(fc.prop1_statement(), fc._templates(full_rank_hyp=1))
    lemma = {"id": "lemma", "index": {"i": fc.SENSOR},
             "claim": ("=", ("*", ("var", "C_xy", "i"), ("T", ("var", "C_xy", "i"))),
                       ("*", ("var", "C_xy", "i"), ("pinv", ("var", "C_xy", "i")))),
             "by": [{"gen": {"penrose": 3, "of": ("var", "C_xy", "i")}}]}
    return outcome(statement, {"steps": [lemma, *proof["steps"]]}, fc.instance(1))


def _no_rule_step():
    return outcome(a_plus_a_statement(), {"steps": [{"id": "s", "claim": A_PLUS_A, "by": []}]},
                   at({"n": 2, "l": 2}, A=[[1, 0], [0, 1]], G=[[0, 0], [0, 0]]))


def _edited_real_proof():
    """The proof of AA⁺A = A (Penrose 1) with its claim edited to A⁺A = I."""
    proof = penrose_proof(A_PLUS_A)
    return outcome(a_plus_a_statement(), proof, at({"n": 2, "l": 2}, A=[[1, 0], [0, 1]], G=[[0, 0], [0, 0]]))


def _wg_statement():
    d = Declare()
    d.sizes("n", "l")
    w, g = d.matrix("W", "n", "n"), d.matrix("G", "n", "l")
    d.conclude(eq(w * g, g))
    return d.json()


def _other_statements_hypothesis():
    """W G = G citing 'hypothesis 0' of another statement (W = I there); here there is none."""
    statement = _wg_statement()
    proof = {"steps": [{"id": "s", "claim": statement["conclusion"][0],
                        "by": [{"gen": {"hyp": 0}, "right": ("var", "G")}]}]}
    return outcome(statement, proof, at({"n": 1, "l": 1}, W=[[2]], G=[[1]]))


def _vacuous_rank_statement():
    def hyps(a, g):
        return [eq(a, zero("n", "l")), fcr(a), le(1, "l")]
    return one_matrix(lambda a, g: eq(g, zero("n", "l")), hyps)


def _vacuous_zero_rank():
    a, x = ("var", "A"), ("pinv", ("var", "A"))
    g = ("var", "G")
    statement = _vacuous_rank_statement()
    proof = {"steps": [{"id": "s", "claim": statement["conclusion"][0],
                        "by": [{"left": ("*", ("num", -1), g), "gen": {"fcr": a, "hyp": 1}},
                               {"left": ("*", g, x), "gen": {"hyp": 0}}]}]}
    return outcome(statement, proof, at({"n": 1, "l": 1}, A=[[0]], G=[[1]]))


def _weaker_hypothesis():
    statement = fc.sufficiency_statement(weaker=True)
    return outcome(statement, fc.attempt(statement, fc._templates(equation_hyp=1)),
                   fc.instance(5, kernel_inclusion=True))


def _three_squares(relation):
    d = Declare()
    d.sizes("n")
    w, v, u = (d.matrix(x, "n", "n") for x in "WVU")
    d.conclude(relation(w, v, u))
    return d.json()


def _trace_statement():
    return _three_squares(lambda w, v, u: eq(tr(w * v * u), tr(v * w * u)))


def _wvu() -> dict:
    return at({"n": 2}, W=[[0, 1], [0, 0]], V=[[0, 0], [1, 0]], U=[[1, 0], [0, 0]])


def _trace_rules():
    statement = _trace_statement()
    return outcome(statement, {"steps": [{"id": "s", "claim": statement["conclusion"][0], "by": []}]}, _wvu())


def _trace_fact():
    statement = _trace_statement()
    return outcome(statement, {"steps": [{"id": "s", "claim": statement["conclusion"][0],
                                          "by": [{"gen": {"fact": "tr(WVU) = tr(VWU)"}}]}]}, _wvu())


def _commute_fact():
    statement = _three_squares(lambda w, v, u: eq(w * v * u, v * w * u))
    return outcome(statement, {"steps": [{"id": "s", "claim": statement["conclusion"][0],
                                          "by": [{"gen": {"hyp": 0}, "right": ("var", "U")}]}]}, _wvu())


def _bound(smaller, larger, full_rank=True):
    statement = fc.rank_bound_statement(larger, full_rank, smaller)
    return outcome(statement, fc.rank_bound_proof(statement), at({"D": 3, "l": 2}, A=[[1, 0], [0, 1], [0, 0]]))


def _vandermonde_six() -> bool:
    six = sp.Matrix(6, 6, lambda i, j: (i + 1) ** j)  # full column rank, l = 6 > 5
    return is_refuted(fc.rank_bound_statement("5"), instance({"D": 6, "l": 6}, {"A": six}))


def _product_statement(hypotheses=()):
    d = Declare()
    d.sizes("n", "r")
    b, f = d.matrix("B", "n", "r"), d.matrix("F", "n", "r")
    d.assume(*hypotheses)
    d.conclude(eq(b * f.T * (b * f.T).inv, I("n")))
    return d.json()


def _product_inverse():
    statement = _product_statement()
    e = ("*", ("var", "B"), ("T", ("var", "F")))
    proof = {"steps": [{"id": "s", "claim": statement["conclusion"][0],
                        "by": [{"gen": {"inverse": "right", "of": e}}]}]}
    return outcome(statement, proof, at({"n": 2, "r": 1}, B=[[1], [2]], F=[[3], [4]]))


def _singular_product() -> bool:
    return (matrix([[1], [2]]) * matrix([[3], [4]]).T).det() == 0


def _sympy_inverse():
    b = sp.MatrixSymbol("B", 2, 1)
    as_term(b * b.T * (b * b.T).I)  # a sympy expression is not a term
    return "proved"


def _wide_inverse():
    return outcome(one_matrix(lambda a, g: eq(a * a.inv, I("n"))), None, at({"n": 1, "l": 2}, A=[[1, 2]], G=[[1, 1]]))


def _r_symmetric_statement():
    d = Declare()
    d.sizes("n")
    sig, xi = d.matrix("Σ", "n", "n"), d.matrix("Ξ", "n", "n")
    z, u = d.matrix("z", "n", 1), d.matrix("u", "n", 1)
    d.assume(spd(sig), spd(xi))
    r = d.define("R", sig * xi + I("n"))
    d.conclude(eq(z.T * r.inv * u, u.T * r.inv * z))
    return d.json()


def _r_symmetric_instance():
    return at({"n": 2}, Σ=[[2, 1], [1, 1]], Ξ=[[1, 0], [0, 3]], z=[[1], [0]], u=[[0], [1]])


def _r_declared_symmetric():
    statement = _r_symmetric_statement()
    return outcome(statement, {"steps": [{"id": "s", "claim": statement["conclusion"][0],
                                          "by": [{"gen": {"sym": ("var", "R")}}]}]}, _r_symmetric_instance())


def _define_again():
    data = fc.prop1_statement()
    data["definitions"]["C_y"] = {"body": ("I", "l[#]"), "over": fc.SENSOR}
    read_statement(frozen(data))
    return "proved"


def _pinned_measurement_statement():
    f = fc.declare()
    f.d.assume(every("m", fc.SENSOR, spd(f.Cy["m"])), eq(f.dmf(f.y), f.cmf(f.y)))
    j = f.d.free_index("j", fc.SENSOR)
    f.d.conclude(eq(f.G * f.S[j] * f.Cy[j] * (I(f"l[{j}]") - f.P[j]), zero("D", f"l[{j}]")))
    return f.d.json()


def _one_measurement():
    """'for every y' replaced by the one y of the statement: the instantiation is refused."""
    statement = _pinned_measurement_statement()
    proof = fc.necessity_proof(fc.necessity_statement())
    return outcome(statement, proof, one_sensor(RANK_ONE * CY.inv(), free={"j": 1}))


def _gap_vanishes_at_the_prediction() -> bool:
    """One rank-one sensor measured exactly at its prediction (y = S μ_y,loc): DMF = CMF there, yet X ≠ 0."""
    inst = one_sensor(sp.eye(2), free={"j": 1})
    inst["values"]["y"] = [[1], [0]]  # = μ_y,loc of the one sensor
    return is_refuted(_pinned_measurement_statement(), inst)


def _induction_without_rank():
    statement = fc.prop1_statement(full_rank=False)
    return outcome(statement, fc.attempt(statement, fc._templates()), fc.instance(1, full_rank=False))


def _listed(what, sizes, holds=True):
    return Certificate("listed", "", checks=[ListedCheck(what, sizes, (), holds)]).to_json()


def _c_squared():
    record = _listed("C·C = I for a generic 2 × 2 C", ("n = 2",))
    record["status"] = "proved"
    return problems(record)


def _commute_from_one():
    record = _listed("XY = YX", ("n = 1",))
    record.update(status="proved", scope="any dimension")
    return problems(record)


def _commute_with_title():
    record = _listed("XY = YX", ("n = 1",))
    record["title"] = "XY = YX, and the same holds for every D"
    assert record["status"] == "checked" and record["scope"] == "checked at n = 1 (not proved)"
    record["scope"] = "any dimension"
    return problems(record)


def _inverse_statement():
    d = Declare()
    d.sizes("n")
    c = d.matrix("C", "n", "n")
    d.assume(invertible(c))
    d.conclude(eq(c * c.inv, I("n")))
    return d.json()


def _not_a_counterexample():
    """The claim is the refutation itself: "refuted" would be its "proved"."""
    return judge_refutation(_inverse_statement(), at({"n": 2}, C=[[2, 1], [1, 1]]))


def judge_refutation(statement, inst):
    from gpfverify.kernel.verdict import judge

    return judge({"statement": statement, "refutation": inst}).outcome


def _declared_proved():
    return problems(a_plus_a_record("proved"))


def _borrowed_verdict():
    """The formal part of a true claim (AA⁺A = A) under the statement text of A⁺A = I."""
    statement = one_matrix(lambda a, g: eq(a * a.pinv * a, a))
    formal = [{"statement": statement, "proof": penrose_proof(statement["conclusion"][0]),
               "witness": at({"n": 1, "l": 1}, A=[[1]], G=[[1]])}]
    record = Certificate("a-plus-a", "", [Part(statement, formal[0]["proof"], formal[0]["witness"])]).to_json()
    record["statement"] = "A⁺A = I for every A"
    return problems(record)


def _forged_lemma_false():
    return is_refuted(fc.prop1_statement(MUTANTS_T), fc.refuting(fc.prop1_statement(MUTANTS_T),
                                                                lambda s: fc.instance(600 + s)))


def _fusion_false(statement_fn, **kwargs):
    statement = statement_fn()
    return is_refuted(statement, fc.refuting(statement, lambda s: fc.instance(700 + s, **kwargs)))


PORTED = [
    FalseClaim("DMF with (C_xy^m)ᵀ for (C_xy^m)⁺ equals CMF, by a generator no statement issues", "normal form",
               _planted_generator, _forged_lemma_false),
    FalseClaim("Proposition 1 for any rank, by A⁺A = I cited without the hypothesis", "normal form",
               _any_rank_axiom, lambda: _fusion_false(lambda: fc.prop1_statement(full_rank=False), deficient=True)),
    FalseClaim("Proposition 1 'for any rank', with A⁺A = I as a hypothesis (printed) then dropped", "statement words",
               _p_is_i_hypothesis, lambda: _fusion_false(lambda: fc.prop1_statement(full_rank=False), deficient=True)),
    FalseClaim("the gap is 0 for any rank, by the full-column-rank generator", "statement words",
               _gap_zero_by_full_rank_lemma, lambda: _fusion_false(_gap_zero_statement, deficient=True)),
    FalseClaim("DMF with Aᵀ equals CMF, by a lemma whose entries prove something else", "lemma",
               _forged_lemma, _forged_lemma_false),
    FalseClaim("A⁺A = I for every A, by a step that applies no rule", "chain", _no_rule_step, a_plus_a_false),
    FalseClaim("A⁺A = I for every A, by a record declared proved", "proof record", _declared_proved, a_plus_a_false),
    FalseClaim("A⁺A = I for every A, by a real proof's claim edited", "proof record", _edited_real_proof,
               a_plus_a_false),
    FalseClaim("W G = G, by a hypothesis of another statement (W = I)", "theories", _other_statements_hypothesis,
               lambda: is_refuted(_wg_statement(), at({"n": 1, "l": 1}, W=[[2]], G=[[1]]))),
    FalseClaim("G = 0, from hypotheses no instance satisfies (A = 0 of full column rank, l ≥ 1)", "instances",
               _vacuous_zero_rank, lambda: sp.zeros(2, 1).rank() < 1),
    FalseClaim("DMF = CMF for every measurement under the weaker G_m(I − P_m) = 0", "hypothesis",
               _weaker_hypothesis,
               lambda: is_refuted(fc.sufficiency_statement(weaker=True), fc._weaker_counterexample())),
    FalseClaim("tr(WVU) = tr(VWU), by the trace rules", "trace", _trace_rules,
               lambda: is_refuted(_trace_statement(), _wvu())),
    FalseClaim("tr(WVU) = tr(VWU), as a stated fact", "stated fact", _trace_fact,
               lambda: is_refuted(_trace_statement(), _wvu())),
    FalseClaim("WVU = VWU, by a commutation 'fact' cited as hypothesis 0", "stated fact", _commute_fact,
               lambda: is_refuted(_three_squares(lambda w, v, u: eq(w * v * u, v * w * u)), _wvu())),
    FalseClaim("l_m ≤ 5 for any D under full column rank", "size bound", lambda: _bound("l", "5"), _vandermonde_six),
    FalseClaim("l_m + 1 ≤ D under full column rank", "size bound", lambda: _bound("l + 1", "D"),
               lambda: is_refuted(fc.rank_bound_statement(smaller="l + 1"), instance({"D": 2, "l": 2},
                                                                                      {"A": sp.eye(2)}))),
    FalseClaim("l_m ≤ D without the full-column-rank hypothesis", "size bound", lambda: _bound("l", "D", False),
               lambda: is_refuted(fc.rank_bound_statement(full_rank=False), instance({"D": 1, "l": 2},
                                                                                     {"A": matrix([[1, 2]])}))),
    FalseClaim("(BFᵀ)(BFᵀ)⁻¹ = I for any rank r", "inverse", _product_inverse, _singular_product),
    FalseClaim("(BFᵀ)(BFᵀ)⁻¹ = I written with sympy's inverse (it cancels when formed)", "inverse", _sympy_inverse,
               _singular_product),
    FalseClaim("the inverse of an n × l matrix", "inverse", _wide_inverse,
               lambda: (matrix([[1, 2]]).T * matrix([[1, 2]])).det() == 0),
    FalseClaim("zᵀR⁻¹u = uᵀR⁻¹z, R = ΣΞ + I declared symmetric by hand", "symmetry", _r_declared_symmetric,
               lambda: is_refuted(_r_symmetric_statement(), _r_symmetric_instance())),
    FalseClaim("C_y^m = I, by defining the letter again", "definition", _define_again,
               lambda: CY.is_positive_definite and CY != sp.eye(2)),  # an SPD C_y^m that is not I
    FalseClaim("X_j = 0 when DMF = CMF at one measurement only", "instantiation", _one_measurement,
               _gap_vanishes_at_the_prediction),
    FalseClaim("DMF = CMF for every N whatever the rank, by a proof without the rank step", "induction",
               _induction_without_rank,
               lambda: _fusion_false(lambda: fc.prop1_statement(full_rank=False), deficient=True)),
    FalseClaim("C·C = I for a generic 2 × 2 C, recorded proved from a listed size", "listed sizes", _c_squared,
               lambda: matrix([[1, 2], [3, 4]]) ** 2 != sp.eye(2)),
    FalseClaim("XY = YX in any dimension, from n = 1", "scope words", _commute_from_one,
               lambda: matrix([[0, 1], [0, 0]]) * matrix([[0, 0], [1, 0]]) != matrix([[0, 0], [1, 0]]) * matrix(
                   [[0, 1], [0, 0]])),
    FalseClaim("XY = YX, with a title that says every D", "scope words", _commute_with_title,
               lambda: matrix([[0, 1], [0, 0]]) * matrix([[0, 0], [1, 0]]) != matrix([[0, 0], [1, 0]]) * matrix(
                   [[0, 1], [0, 0]])),
    FalseClaim("C C⁻¹ = I is refuted, by a 'counterexample' that is not one", "counterexample", _not_a_counterexample,
               lambda: (matrix([[2, 1], [1, 1]]) * matrix([[2, 1], [1, 1]]).inv()) == sp.eye(2)),
    FalseClaim("A⁺A = I, a record proved with no proof in it", "certificate record",
               lambda: problems(a_plus_a_record("proved", [{"statement": a_plus_a_statement()}])), a_plus_a_false),
    FalseClaim("A⁺A = I, proved with another claim's formal part", "certificate record", _borrowed_verdict,
               a_plus_a_false),
]


# ---- built against the new API ------------------------------------------------------------------------------

def _param_statement(conclusion, hypotheses=()):
    d = Declare()
    d.sizes("n")
    s = d.param("s")
    x = d.matrix("X", "n", "n")
    d.assume(*hypotheses(s, x)) if callable(hypotheses) else None
    d.conclude(conclusion(s, x))
    return d.json()


def _root_of_square():
    """√(a²) = a 'because a is a positive sympy symbol': the kernel takes no assumption from sympy."""
    statement = _param_statement(lambda s, x: eq((s ** 2) ** Term(("num", "1/2")), s))
    return outcome(statement, {"steps": [{"id": "s", "claim": statement["conclusion"][0], "by": []}]},
                   instance({"n": 1}, {"X": matrix([[1]])}, params={"s": -1}))


def _sympy_symbol_as_name():
    data = _param_statement(lambda s, x: eq(s * x, x * s))
    data["params"] = [sp.Symbol("s", positive=True)]
    read_statement(frozen(data))
    return "proved"


def _negative_size():
    d = Declare()
    d.sizes("n", "l")
    d.matrix("A", "n - l", 1)
    d.conclude(le("l", "n"))
    read_statement(frozen(d.json()))
    return "proved"


def _spd_equals_minus_identity():
    statement = one_matrix(lambda a, g: eq(a, -I("n")), lambda a, g: [spd(a), eq(a + I("n"), zero("n", "n")),
                                                                        le(1, "n")], rows="n", cols="n")
    proof = {"steps": [{"id": "s", "claim": statement["conclusion"][0], "by": [{"gen": {"hyp": 1}}]}]}
    return outcome(statement, proof, at({"n": 1, "l": 1}, A=[[1]], G=[[0]]))


def _ill_typed_cancelling():
    statement = one_matrix(lambda a, g: eq(a * a - a * a, zero("n", "l")))
    return outcome(statement, {"steps": [{"id": "s", "claim": statement["conclusion"][0], "by": []}]},
                   at({"n": 1, "l": 1}, A=[[1]], G=[[0]]))


def _refutation_outside_the_hypotheses():
    """'Proposition 1 is refuted', by an instance where C_xy^m is not of full column rank."""
    return judge_refutation(fc.prop1_statement(), deficient_fusion())


def _prop1_record():
    return fc.prove_prop1("small").to_json()


def _prop1_true() -> bool:
    """Evidence that a refutation of Proposition 1 is false: the kernel proves it."""
    return fc.prove_prop1("small").status == "proved"


def _text_says_any_rank():
    record = _prop1_record()
    record["statement"] = record["statement"].replace(" — assuming:", ", for any rank of C_xy^m — assuming:")
    return problems(record)


def _status_refuted():
    record = _prop1_record()
    record["status"] = "refuted"
    return problems(record)


def _same_name_other_content():
    """Two certificates named alike: the second (false) one is judged on its own content."""
    true = one_matrix(lambda a, g: eq(a * a.pinv * a, a))
    first = Certificate("same", "", [Part(true, penrose_proof(true["conclusion"][0]),
                                          at({"n": 2, "l": 2}, A=[[1, 0], [0, 1]], G=[[1, 0], [0, 1]]))])
    assert first.status == "proved"
    second = Certificate("same", "", [Part(a_plus_a_statement(), penrose_proof(true["conclusion"][0]),
                                           at({"n": 1, "l": 1}, A=[[1]], G=[[1]]))])
    return second.status


def _bad_witness():
    """The gap formula (true) with a 'witness' whose C_y^1 is not symmetric: not shown non-vacuous."""
    statement = fc.gap_statement()
    witness = fc.instance(3, full_rank=False)
    witness["values"]["C_y"][1] = [[2, 1], [0, 2]]
    return outcome(statement, fc.attempt(statement, fc._templates()), witness)


def _division_unguarded():
    statement = _param_statement(lambda s, x: eq(s * x * s ** -1, x))
    return outcome(statement, {"steps": [{"id": "s", "claim": statement["conclusion"][0], "by": []}]},
                   instance({"n": 1}, {"X": matrix([[1]])}, params={"s": 1}))


def _undefined_at_zero() -> bool:
    statement = _param_statement(lambda s, x: eq(s * x * s ** -1, x))
    st = read_statement(frozen(statement))
    inst = Instance(st, frozen(instance({"n": 1}, {"X": matrix([[1]])}, params={"s": 0})))
    try:
        inst.holds(st.conclusion[0])
    except Undefined:
        return True
    return False


def _s_minus_three():
    statement = _param_statement(lambda s, x: eq(x, zero("n", "n")),
                                 lambda s, x: [eq((s - 3) * x, zero("n", "n"))])
    left = as_term((Term(("param", "s")) - 3) ** -1)
    proof = {"steps": [{"id": "s", "claim": statement["conclusion"][0], "by": [{"left": left, "gen": {"hyp": 0}}]}]}
    return outcome(statement, proof, instance({"n": 1}, {"X": matrix([[0]])}, params={"s": 1}))


def _s_three_refutes() -> bool:
    statement = _param_statement(lambda s, x: eq(x, zero("n", "n")),
                                 lambda s, x: [eq((s - 3) * x, zero("n", "n"))])
    return is_refuted(statement, instance({"n": 1}, {"X": matrix([[1]])}, params={"s": 3}))


def _a_a_plus():
    return one_matrix(lambda a, g: eq(a * a.pinv, I("n")))


def _inverse_of_a_wide_matrix():
    statement = _a_a_plus()
    proof = {"steps": [{"id": "s", "claim": statement["conclusion"][0],
                        "by": [{"gen": {"inverse": "right", "of": ("var", "A")}}]}]}
    return outcome(statement, proof, at({"n": 2, "l": 1}, A=[[1], [0]], G=[[0], [0]]))


def _fcr_of_another_letter_statement():
    d = Declare()
    d.sizes("n", "l")
    a, b = d.matrix("A", "n", "l"), d.matrix("B", "n", "l")
    d.assume(fcr(a))
    d.conclude(eq(b.pinv * b, I("l")))
    return d.json()


def _fcr_of_another_letter():
    statement = _fcr_of_another_letter_statement()
    proof = {"steps": [{"id": "s", "claim": statement["conclusion"][0],
                        "by": [{"gen": {"fcr": ("var", "B"), "hyp": 0}}]}]}
    return outcome(statement, proof, at({"n": 2, "l": 2}, A=[[1, 0], [0, 1]], B=RANK_ONE))


def _family_statement(conclusion_index="k"):
    d = Declare()
    d.sizes("n", "N")
    d.index_set("J", "N")
    x = d.matrix("X", "n", "n", over="J")
    j, k = d.free_index("j", "J"), d.free_index("k", "J")
    d.assume(eq(x[j], zero("n", "n")))
    d.conclude(eq(x[k], zero("n", "n")))
    return d.json()


def _rename_a_pinned_index():
    statement = _family_statement()
    proof = {"steps": [{"id": "s1", "claim": ("=", ("var", "X", "j"), ("0", "n", "n")), "by": [{"gen": {"hyp": 0}}]},
                       {"id": "s2", "claim": statement["conclusion"][0],
                        "by": [{"gen": {"lemma": "s1", "index": {"j": "k"}}}]}]}
    inst = instance({"n": 1, "N": 2}, {"X": [matrix([[0]]), matrix([[0]])]}, free_indices={"j": 1, "k": 2})
    return outcome(statement, proof, inst)


def _self_citation():
    statement = a_plus_a_statement()
    proof = {"steps": [{"id": "s", "claim": statement["conclusion"][0], "by": [{"gen": {"lemma": "s"}}]}]}
    return outcome(statement, proof, at({"n": 1, "l": 1}, A=[[1]], G=[[1]]))


def _sigma_statement(conclusion):
    d = Declare()
    d.sizes("n")
    sig = d.matrix("Σ", "n", "n")
    d.assume(spd(sig))
    d.conclude(conclusion(sig))
    return d.json()


def _root_of_negative_det():
    """det(−Σ)^{1/2}·det(−Σ)^{1/2} = det(−Σ), with 'det(−Σ) > 0' from the factors −I and Σ."""
    def conclusion(sig):
        root = Term(("^", ("det", as_term(-sig)), "1/2"))
        return eq(root * root, Term(("det", as_term(-sig))))
    statement = _sigma_statement(conclusion)
    sig = ("var", "Σ")
    proof = {"steps": [{"id": "f", "claim": ("=", as_term(-Term(sig)), ("*", as_term(-I("n")), sig)), "by": []},
                       {"id": "p", "claim": ("positive", as_term(-Term(sig))), "factors": [as_term(-I("n")), sig],
                        "by": "f"},
                       {"id": "s", "claim": statement["conclusion"][0], "by": []}]}
    return outcome(statement, proof, instance({"n": 1}, {"Σ": matrix([[1]])}))


def _negative_root_undefined() -> bool:
    st = read_statement(frozen(_sigma_statement(lambda sig: eq(Term(("^", ("det", as_term(-sig)), "1/2")), num(1)))))
    try:
        Instance(st, frozen(instance({"n": 1}, {"Σ": matrix([[1]])}))).holds(st.conclusion[0])
    except Undefined:
        return True
    return False


def _divergent_integral_statement():
    d = Declare()
    d.sizes("n")
    x = Term(("var", "x"))
    d.conclude(eq(Term(("int", "x", "n", as_term(exp(num("1/2") * x.T * x)))),
                  Term(("^", ("2pi",), ("*", ("num", "1/2"), ("size", "n"))))))
    return d.json()


def _divergent_integral():
    """∫ exp(+½xᵀx) dx 'by the Gaussian rule' with A = −I (not SPD)."""
    statement = _divergent_integral_statement()
    gen = {"gauss": statement["conclusion"][0][1], "A": as_term(-I("n")), "b": ("0", "n", 1), "c": ("num", 0)}
    proof = {"steps": [{"id": "s", "claim": statement["conclusion"][0], "by": [{"gen": gen}]}]}
    return outcome(statement, proof, {"sizes": {"n": 1}})


def _square_roots_statement():
    d = Declare()
    d.sizes("n")
    a, b = d.matrix("A", "n", "n"), d.matrix("B", "n", "n")
    d.assume(eq(a * a, b * b))
    d.conclude(eq(a, b))
    return d.json()


def _congruence_by_square_root():
    statement = _square_roots_statement()
    proof = {"steps": [{"id": "s1", "claim": statement["hypotheses"][0], "by": [{"gen": {"hyp": 0}}]},
                       {"id": "s2", "claim": statement["conclusion"][0],
                        "by": [{"gen": {"congruence": "sqrt", "by": "s1"}}]}]}
    return outcome(statement, proof, instance({"n": 1}, {"A": matrix([[1]]), "B": matrix([[1]])}))


def _exp_by_nothing():
    d = Declare()
    d.sizes("n")
    x = d.matrix("x", "n", 1)
    d.conclude(eq(exp(x.T * x), num(1)))
    statement = d.json()
    proof = {"steps": [{"id": "s", "claim": statement["conclusion"][0], "by": [],
                        "subst": [{"exp": as_term(x.T * x), "by": "nowhere"}]}]}
    return outcome(statement, proof, instance({"n": 1}, {"x": matrix([[1]])}))


def _partition_that_does_not_add_up():
    inst = fc.instance(1)
    inst["sizes"]["L"] = 4  # the parts are 1 + 2
    return judge_refutation(fc.prop1_statement(), inst)


def _captured_index_statement():
    d = Declare()
    d.sizes("n", "N")
    d.index_set("J", "N")
    x = d.matrix("X", "n", "n", over="J")
    z = d.define("Z", lambda h: Sum("m", "J", x["m"]) * x[h], over="J")
    d.conclude(eq(Sum("m", "J", z["m"]), Sum("m", "J", x["m"] * x["m"])))
    return d.json()


def _capture():
    statement = _captured_index_statement()
    inst = instance({"n": 1, "N": 2}, {"X": [matrix([[1]]), matrix([[1]])]})
    return outcome(statement, {"steps": [{"id": "s", "claim": statement["conclusion"][0], "by": []}]}, inst)


def _symmetric_wide():
    statement = one_matrix(lambda a, g: eq(a * a.T, a.T * a), lambda a, g: [("sym", as_term(a))])
    return outcome(statement, {"steps": [{"id": "s", "claim": statement["conclusion"][0], "by": []}]},
                   at({"n": 1, "l": 1}, A=[[1]], G=[[1]]))


def _empty_family_statement():
    d = Declare()
    d.sizes("n", "N")
    d.index_set("J", "N")
    x = d.matrix("X", "n", "n")
    d.assume(every("m", "J", ("sym", as_term(x))))
    d.conclude(eq(x.T, x))
    return d.json()


def _symmetric_for_every_member_of_nothing():
    statement = _empty_family_statement()
    return outcome(statement, {"steps": [{"id": "s", "claim": statement["conclusion"][0], "by": []}]},
                   instance({"n": 1, "N": 1}, {"X": matrix([[1]])}))


def _self_referring_definition():
    d = Declare()
    d.sizes("n")
    d.data["definitions"]["Y"] = {"body": ("+", ("var", "Y"), ("I", "n"))}
    d.conclude(("=", ("var", "Y"), ("+", ("var", "Y"), ("I", "n"))))
    statement = d.json()
    return outcome(statement, {"steps": [{"id": "s", "claim": statement["conclusion"][0], "by": []}]},
                   {"sizes": {"n": 1}})



def _member_size_statement():
    """For every m: yᵀy c_m = 0 for every y ∈ ℝ^{l_m} (that is, l_m = 0 or c_m = 0); then z_kᵀz_k c_j = 0."""
    d = Declare()
    d.sizes("N")
    d.index_set("J", "N")
    d.family_size("l", "J")
    c, z = d.matrix("c", 1, 1, over="J"), d.matrix("z", "l[#]", 1, over="J")
    j, k = d.free_index("j", "J"), d.free_index("k", "J")
    y = Term(("var", "y"))
    d.assume(every("m", "J", forall([("y", "l[m]", 1)], eq(y.T * y * c["m"], zero(1, 1)))))
    d.conclude(eq(z[k].T * z[k] * c[j], zero(1, 1)))
    return d.json()


def _forall_size_of_another_member():
    """The hypothesis at member j, its "for every y ∈ ℝ^{l_m}" read with the step's own generic m (y := z_m)."""
    statement = _member_size_statement()
    z_m = ("var", "z", "m")
    lemma = ("=", ("*", ("T", z_m), z_m, ("var", "c", "j")), ("0", "1", "1"))
    proof = {"steps": [{"id": "s1", "index": {"m": "J"}, "claim": lemma,
                        "by": [{"gen": {"hyp": 0, "index": "j", "at": {"y": z_m}}}]},
                       {"id": "s2", "claim": statement["conclusion"][0],
                        "by": [{"gen": {"lemma": "s1", "index": {"m": "k"}}}]}]}
    witness = instance({"N": 1}, {"c": [matrix([[0]])], "z": [matrix([[1]])]}, indexed_sizes={"l": [1]},
                       free_indices={"j": 1, "k": 1})
    return outcome(statement, proof, witness)


def _member_size_false() -> bool:
    """l = (0, 1), c = (1, 0): ℝ⁰ holds only y = 0 and c_2 = 0, so every hypothesis holds; z_2ᵀz_2 c_1 = 1."""
    counterexample = instance({"N": 2}, {"c": [matrix([[1]]), matrix([[0]])], "z": [sp.zeros(0, 1), matrix([[1]])]},
                              indexed_sizes={"l": [0, 1]}, free_indices={"j": 1, "k": 2})
    return is_refuted(_member_size_statement(), counterexample)


def _nested_integral_statement():
    """∫ e^{−½xᵀx} h(x) dx = ∫ e^{−½xᵀx} k dx, h(y) := ∫ e^{−½zᵀz} zᵀy dz (= 0), k := ∫ e^{−½zᵀz} zᵀz dz (= n(2π)^{n/2})."""
    d = Declare()
    d.sizes("n")
    x, z = Term(("var", "x")), Term(("var", "z"))
    gauss = lambda v: exp(num("-1/2") * v.T * v)  # noqa: E731
    h = d.define("h", lambda y: Term(("int", "z", "n", as_term(gauss(z) * (z.T * y)))), args=(("y", "n", 1),))
    k = d.define("k", Term(("int", "z", "n", as_term(gauss(z) * (z.T * z)))))
    d.conclude(eq(Term(("int", "x", "n", as_term(gauss(x) * h(x)))), Term(("int", "x", "n", as_term(gauss(x) * k)))))
    return d.json()


def _integral_through_a_definition():
    """The outer variable passed into a definition's integral took the inner variable's place."""
    statement = _nested_integral_statement()
    return outcome(statement, {"steps": [{"id": "s", "claim": statement["conclusion"][0], "by": []}]},
                   {"sizes": {"n": 1}})


def _nested_integral_false() -> bool:
    """At n = 1 the left side is ∫ e^{−x²/2}·0 dx = 0 and the right side 2π."""
    x, z = sp.symbols("x z", real=True)
    inner = lambda f: sp.integrate(sp.exp(-z ** 2 / 2) * f, (z, -sp.oo, sp.oo))  # noqa: E731
    outer = lambda f: sp.integrate(sp.exp(-x ** 2 / 2) * f, (x, -sp.oo, sp.oo))  # noqa: E731
    return outer(inner(z * x)) == 0 and outer(inner(z * z)) == 2 * sp.pi


def _scaled_inverse_statement():
    d = Declare()
    d.sizes("n")
    r, x = d.param("ρ"), d.matrix("X", "n", "n")
    d.assume(invertible(x))
    d.conclude(eq(r * x.inv * (r * x.inv).pinv, I("n")))
    return d.json()


def _scaled_inverse_invertible():
    """ρX⁻¹ 'invertible' because X is, whatever ρ: the inverse generator's E E⁺ = I for E = ρX⁻¹."""
    statement = _scaled_inverse_statement()
    e = ("*", ("param", "ρ"), ("inv", ("var", "X")))
    proof = {"steps": [{"id": "s", "claim": statement["conclusion"][0],
                        "by": [{"gen": {"inverse": "right", "of": e}}]}]}
    return outcome(statement, proof, instance({"n": 1}, {"X": matrix([[1]])}, params={"ρ": 1}))


def _scaled_inverse_false() -> bool:
    """At ρ = 0, ρX⁻¹(ρX⁻¹)⁺ = 0 ≠ I."""
    return is_refuted(_scaled_inverse_statement(), instance({"n": 1}, {"X": matrix([[1]])}, params={"ρ": 0}))


def _vacuous_every_statement(kind):
    """C_j C_j⁺ = I from "for every m = 1..K: C_j is SPD (invertible)", a hypothesis free of m."""
    d = Declare()
    d.sizes("n", "N", "K")
    d.index_set("J", "N")
    d.index_set("M", "K")
    c, j = d.matrix("C", "n", "n", over="J"), d.free_index("j", "J")
    d.assume(every("m", "M", kind(c[j])))
    d.conclude(eq(c[j] * c[j].pinv, I("n")))
    return d.json()


def _every_member_of_nothing(kind):
    statement = _vacuous_every_statement(kind)
    proof = {"steps": [{"id": "s", "claim": statement["conclusion"][0],
                        "by": [{"gen": {"inverse": "right", "of": ("var", "C", "j")}}]}]}
    return outcome(statement, proof, instance({"n": 1, "N": 1, "K": 1}, {"C": [matrix([[1]])]}, free_indices={"j": 1}))


def _vacuous_every_false(kind) -> bool:
    """K = 0 (no m): the hypothesis holds for C_1 = 0, and 0·0⁺ = 0 ≠ I."""
    return is_refuted(_vacuous_every_statement(kind), instance({"n": 1, "N": 1, "K": 0}, {"C": [matrix([[0]])]},
                                                               free_indices={"j": 1}))


def _denesting_statement():
    """For every x: √(3 + 2√2)·x = (1 + √2)·x — true (3 + 2√2 = (1 + √2)²), as a claim to refute."""
    root2 = ("^", ("num", 2), "1/2")
    lhs = ("*", ("^", ("+", ("num", 3), ("*", ("num", 2), root2)), "1/2"), ("var", "x"))
    return {"conclusion": [("forall", (("x", "1", "1"),), ("=", lhs, ("*", ("+", ("num", 1), root2), ("var", "x"))))]}


def _refuted_by_an_unseen_zero():
    """'Refuted' with no instance at all: the difference (√(3 + 2√2) − 1 − √2)·x does not cancel in sympy."""
    return judge_refutation(_denesting_statement(), {})


def _empty_world_statement():
    """C = −I for C SPD with C + I = 0: both hypotheses hold only at n = 0."""
    d = Declare()
    d.sizes("n")
    c = d.matrix("C", "n", "n")
    d.assume(spd(c), eq(c + I("n"), zero("n", "n")))
    d.conclude(eq(c, -I("n")))
    return d.json()


def _witnessed_by_empty_matrices():
    statement = _empty_world_statement()
    proof = {"steps": [{"id": "s", "claim": statement["conclusion"][0], "by": [{"gen": {"hyp": 1}}]}]}
    return outcome(statement, proof, instance({"n": 0}, {"C": sp.zeros(0, 0)}))


def _rank_one_world_statement():
    """u vᵀ = v uᵀ for every u, v ∈ ℝⁿ, assuming x yᵀ = y xᵀ for every x, y ∈ ℝⁿ (true only at n ≤ 1)."""
    d = Declare()
    d.sizes("n")
    u, v = d.matrix("u", "n", 1), d.matrix("v", "n", 1)
    x, y = Term(("var", "x")), Term(("var", "y"))
    d.assume(forall([("x", "n", 1), ("y", "n", 1)], eq(x * y.T, y * x.T)))
    d.conclude(eq(u * v.T, v * u.T))
    return d.json()


def _witnessed_in_dimension_one():
    statement = _rank_one_world_statement()
    proof = {"steps": [{"id": "s", "claim": statement["conclusion"][0],
                        "by": [{"gen": {"hyp": 0, "at": {"x": ("var", "u"), "y": ("var", "v")}}}]}]}
    return outcome(statement, proof, instance({"n": 1}, {"u": matrix([[1]]), "v": matrix([[2]])}))


def _empty_world_only() -> bool:
    """No SPD C with C + I = 0 in any dimension n ≥ 1, and e₁e₂ᵀ ≠ e₂e₁ᵀ for n ≥ 2."""
    e1, e2 = sp.Matrix([1, 0]), sp.Matrix([0, 1])
    return (-sp.eye(1)).is_positive_definite is False and e1 * e2.T != e2 * e1.T


def _read_as_any_dimension():
    """Xᵀ = X with no hypothesis, true for the 1 × 1 X it declares: proved, but its words must say 1 × 1
    (the claim refused is "every matrix is symmetric, in any dimension")."""
    d = Declare()
    x = d.matrix("X", 1, 1)
    d.conclude(eq(x.T, x))
    statement = d.json()
    certificate = Certificate("symmetric", "", [Part(statement, {"steps": [{"id": "s", "claim": statement["conclusion"][0],
                                                                            "by": []}]}, {"values": {"X": [[1]]}})])
    honest = certificate.scope != "any dimension" and "X ∈ ℝ^{1 × 1}" in certificate.statement
    return "proved at the sizes it prints" if honest else certificate.status


def _sift_statement():
    """exp(ρ)(Σ_i (S_iᵀS_j + I)⁺)ᵀ = exp(ρ) Σ_i (I + I)⁺, S_i the columns of I_N (exp(ρ) keeps the witness's
    check inexact)."""
    body = ("pinv", ("+", ("*", ("T", ("sel", "S", "i")), ("sel", "S", "j")), ("I", "1")))
    e = ("exp", ("param", "ρ"))
    return {"sizes": ["N"], "params": ["ρ"], "index_sets": {"J": "N"},
            "partitions": {"S": {"over": "J", "total": "N", "part": "1"}}, "free_indices": {"j": "J"},
            "conclusion": [("=", ("*", e, ("T", ("sum", "i", "J", body))),
                            ("*", e, ("sum", "i", "J", ("pinv", ("+", ("I", "1"), ("I", "1"))))))]}


def _sift_inside_a_pinv():
    """Transposing the sum re-normalised the pinv's body with the sum's index as its own: S_iᵀS_j sifted to I."""
    statement = _sift_statement()
    return outcome(statement, {"steps": [{"id": "s", "claim": statement["conclusion"][0], "by": []}]},
                   {"sizes": {"N": 2}, "params": {"ρ": 1}, "free_indices": {"j": 1}})


def _sift_false() -> bool:
    """N = 2, j = 1, ρ = 0: the left side is (1 + 1)⁻¹ + (0 + 1)⁻¹ = 3/2, the right side 2·(1/2) = 1."""
    return is_refuted(_sift_statement(), {"sizes": {"N": 2}, "params": {"ρ": 0}, "free_indices": {"j": 1}})

ADVERSARY = [
    FalseClaim("√(a²) = a, the parameter being 'positive' in sympy", "sympy assumptions", _root_of_square,
               lambda: sp.sqrt((-1) ** 2) != -1),
    FalseClaim("a sympy Symbol(positive=True) given as a parameter name", "sympy assumptions", _sympy_symbol_as_name,
               lambda: sp.Symbol("s") * 1 != sp.Symbol("s", positive=True)),
    FalseClaim("l ≤ n from a letter of size n − l", "negative sizes", _negative_size,
               lambda: is_refuted(fc.rank_bound_statement(full_rank=False), instance({"D": 1, "l": 2},
                                                                                     {"A": matrix([[1, 2]])}))),
    FalseClaim("an SPD matrix equal to −I (hypotheses no instance satisfies, n ≥ 1)", "vacuous hypotheses",
               _spd_equals_minus_identity, lambda: not matrix([[-1]]).is_positive_definite),
    FalseClaim("AA − AA = 0 for A n × l (ill-typed, cancels in the normal form)", "ill-typed terms",
               _ill_typed_cancelling, lambda: matrix([[1, 2]]).shape[1] != matrix([[1, 2]]).shape[0]),
    FalseClaim("Proposition 1 refuted by an instance where C_xy^m is rank-deficient", "instance off the hypotheses",
               _refutation_outside_the_hypotheses, _prop1_true),
    FalseClaim("Proposition 1 'for any rank' in the record's text", "rendering", _text_says_any_rank,
               lambda: _fusion_false(lambda: fc.prop1_statement(full_rank=False), deficient=True)),
    FalseClaim("Proposition 1 recorded as refuted", "status edited", _status_refuted, _prop1_true),
    FalseClaim("A⁺A = I under the name of a proved claim (content keys, not names)", "cache collision",
               _same_name_other_content, a_plus_a_false),
    FalseClaim("the gap formula witnessed by a C_y^1 that is not symmetric", "plausible witness", _bad_witness,
               lambda: matrix([[2, 1], [0, 2]]) != matrix([[2, 1], [0, 2]]).T),
    FalseClaim("(sX)s⁻¹ = X with no hypothesis s ≠ 0", "division", _division_unguarded, _undefined_at_zero),
    FalseClaim("X = 0 from (s − 3)X = 0, dividing by s − 3", "division", _s_minus_three, _s_three_refutes),
    FalseClaim("AA⁺ = I for A n × l, by the inverse generator", "generator outside its theory",
               _inverse_of_a_wide_matrix, lambda: is_refuted(_a_a_plus(), at({"n": 2, "l": 1}, A=[[1], [0]],
                                                                               G=[[0], [0]]))),
    FalseClaim("B⁺B = I, by the full-column-rank hypothesis of A", "generator outside its theory",
               _fcr_of_another_letter, lambda: is_refuted(_fcr_of_another_letter_statement(),
                                                          at({"n": 2, "l": 2}, A=[[1, 0], [0, 1]], B=RANK_ONE))),
    FalseClaim("X_k = 0 from X_j = 0, renaming the statement's own index", "index instantiation",
               _rename_a_pinned_index,
               lambda: is_refuted(_family_statement(), instance({"n": 1, "N": 2}, {"X": [matrix([[0]]), matrix([[1]])]},
                                                                free_indices={"j": 1, "k": 2}))),
    FalseClaim("A⁺A = I, by a step that cites itself", "circular step", _self_citation, a_plus_a_false),
    FalseClaim("det(−Σ)^{1/2} squared is det(−Σ), 'det(−Σ) > 0' from the factors −I, Σ", "determinant powers",
               _root_of_negative_det, _negative_root_undefined),
    FalseClaim("∫ exp(+½xᵀx) dx = (2π)^{n/2}, the Gaussian rule with A = −I", "integrals", _divergent_integral,
               lambda: sp.integrate(sp.exp(sp.Symbol("x") ** 2 / 2), (sp.Symbol("x"), -sp.oo, sp.oo)) == sp.oo),
    FalseClaim("A = B from A² = B², by a 'congruence' under the square root", "congruence",
               _congruence_by_square_root,
               lambda: is_refuted(_square_roots_statement(), instance({"n": 1}, {"A": matrix([[1]]),
                                                                                  "B": matrix([[-1]])}))),
    FalseClaim("exp(xᵀx) = 1, by an exponent substitution citing no step", "substitution", _exp_by_nothing,
               lambda: sp.exp(1) != 1),
    FalseClaim("Proposition 1 refuted by an instance whose blocks do not add up to L", "instance off the partition",
               _partition_that_does_not_add_up, _prop1_true),
    FalseClaim("Σ_m Z_m = Σ_m X_m X_m, Z_h := (Σ_m X_m) X_h (as if the inner m captured the outer)",
               "capture", _capture,
               lambda: is_refuted(_captured_index_statement(),
                                  instance({"n": 1, "N": 2}, {"X": [matrix([[1]]), matrix([[1]])]}))),
    FalseClaim("AAᵀ = AᵀA for A n × l 'symmetric'", "ill-typed hypothesis", _symmetric_wide,
               lambda: (matrix([[1, 2]]) * matrix([[1, 2]]).T).shape != (matrix([[1, 2]]).T * matrix([[1, 2]])).shape),
    FalseClaim("Xᵀ = X from 'X symmetric for every m' when there is no m", "empty family",
               _symmetric_for_every_member_of_nothing,
               lambda: is_refuted(_empty_family_statement(), instance({"n": 2, "N": 0},
                                                                      {"X": matrix([[0, 1], [0, 0]])}))),
    FalseClaim("Y = Y + I, with Y defined as Y + I", "definition", _self_referring_definition,
               lambda: sp.eye(1) != sp.zeros(1)),
    FalseClaim("z_kᵀz_k c_j = 0 from 'yᵀy c_m = 0 for y ∈ ℝ^{l_m}', y's size left at another member's",
               "bound sizes", _forall_size_of_another_member, _member_size_false),
    FalseClaim("∫ e^{−½xᵀx} h(x) dx = ∫ e^{−½xᵀx} k dx, the outer x captured by h's inner integral", "nested integrals",
               _integral_through_a_definition, _nested_integral_false),
    FalseClaim("ρX⁻¹(ρX⁻¹)⁺ = I for X invertible, the coefficient ρ taken for nonzero", "coefficients",
               _scaled_inverse_invertible, _scaled_inverse_false),
    FalseClaim("C_j C_j⁺ = I from 'C_j SPD for every m = 1..K', K possibly 0", "empty family",
               lambda: _every_member_of_nothing(spd), lambda: _vacuous_every_false(spd)),
    FalseClaim("C_j C_j⁺ = I from 'C_j invertible for every m = 1..K', K possibly 0", "empty family",
               lambda: _every_member_of_nothing(invertible), lambda: _vacuous_every_false(invertible)),
    FalseClaim("√(3 + 2√2) x = (1 + √2) x is refuted (a true statement)", "true statement refuted",
               _refuted_by_an_unseen_zero, lambda: sp.sqrtdenest(sp.sqrt(3 + 2 * sp.sqrt(2))) == 1 + sp.sqrt(2)),
    FalseClaim("C = −I for an SPD C with C + I = 0, witnessed at n = 0", "degenerate witness",
               _witnessed_by_empty_matrices, _empty_world_only),
    FalseClaim("u vᵀ = v uᵀ from 'x yᵀ = y xᵀ for every x, y ∈ ℝⁿ', witnessed at n = 1", "degenerate witness",
               _witnessed_in_dimension_one, _empty_world_only),
    FalseClaim("Xᵀ = X for every X in any dimension, printed from a statement about a 1 × 1 X", "statement words",
               _read_as_any_dimension, lambda: matrix([[0, 1], [0, 0]]).T != matrix([[0, 1], [0, 0]])),
    FalseClaim("(Σ_i (S_iᵀS_j + I)⁺)ᵀ = Σ_i (I + I)⁺, the selectors sifted inside a pseudo-inverse", "sums",
               _sift_inside_a_pinv, _sift_false),
]

FALSE_CLAIMS = PORTED + ADVERSARY


def test_the_corpus_keeps_the_thirty_ported_claims_and_twenty_new_ones():
    assert len(PORTED) == 30 and len(ADVERSARY) >= 20
    assert len({c.name for c in FALSE_CLAIMS}) == len(FALSE_CLAIMS)
    assert not {c.route for c in ADVERSARY} <= {c.route for c in PORTED}  # new routes, not variations


@pytest.mark.parametrize("claim", FALSE_CLAIMS, ids=[c.name for c in FALSE_CLAIMS])
def test_a_false_claim_is_false_and_refused(claim):
    assert claim.false(), "the evidence must show the claim false"
    try:
        result = claim.attempt()
    except (InputError, TypeError):
        return  # refused when built
    assert refused(result), result
