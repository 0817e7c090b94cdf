"""The proof engine cannot prove a false claim built the way its own proofs are built: a symmetry
declaration is a rule checked on instances, the sympy route inverts only what a hypothesis makes
invertible, and a stated fact outside the algebra is checked on every shape its hypothesis allows."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from gpfverify.errors import InputError
from gpfverify.symbolic import dimension_free, gp_claims, rewrites, word_algebra as wa
from gpfverify.symbolic.certificate import verdict


def test_a_symmetry_declaration_is_an_assumption_checked_like_a_rule():
    """zᵀR⁻¹u = uᵀR⁻¹z for R⁻¹ = (ΣΞ + I)⁻¹, which is not symmetric."""
    g = gp_claims
    lhs, rhs = g._quad(g.zv, g.Ri, g.uv), g._quad(g.uv, g.Ri, g.zv)
    assert not wa.prove_by_normal_form(lhs, rhs, []).proved  # no letter is its own transpose
    declared = wa.symmetry(g.Ri)
    assert wa.prove_by_normal_form(lhs, rhs, [declared]).proved  # the declaration would prove it ...
    inst = g._gp_instances()
    assert not dimension_free.check_rules([declared], {declared.name: inst}).holds  # ... and fails its check
    values, sizes = inst[-1]
    r_inv = np.array(values["R⁻¹"].evalf(), dtype=float)
    z, u = (np.array(values[k].evalf(), dtype=float).ravel() for k in ("z", "u"))
    assert not np.isclose(z @ r_inv @ u, u @ r_inv @ z)  # numpy: the claim is false there
    assert all(wa.holds_on(rule, inst) for rule in g.SYMMETRIES)  # the declared symmetries are true


def _penrose(a, x, **hypotheses):
    return [rewrites.Rewrite(a * x * a, a, "AXA = A", **hypotheses),
            rewrites.Rewrite(x * a * x, x, "XAX = X", **hypotheses),
            rewrites.Rewrite((a * x).T, a * x, "(AX)ᵀ = AX", **hypotheses),
            rewrites.Rewrite((x * a).T, x * a, "(XA)ᵀ = XA", **hypotheses)]


def test_the_sympy_route_refuses_the_inverse_of_a_rank_r_product():
    n, l = rewrites.n_states, rewrites.n_outputs
    r = sp.Symbol("r", integer=True, positive=True)
    b, f = sp.MatrixSymbol("B", n, r), sp.MatrixSymbol("F", l, r)
    with pytest.raises(InputError):
        rewrites.inverse(b * f.T)  # n × l: not square for every size
    f_square = sp.MatrixSymbol("F", n, r)
    a = b * f_square.T  # n × n of rank r
    x = rewrites.inverse(a)
    unstated = rewrites.check_independent(_penrose(a, x))
    assert not any(unstated.verdicts)  # its invertibility is not a hypothesis
    stated = rewrites.check_independent(_penrose(a, x, invertible=(a,), full_column_rank=(b, f_square)))
    assert not any(stated.verdicts)  # a stated hypothesis false on instances with r < n
    assert rewrites.check_independent(rewrites.factored_pinv_penrose()).holds  # F(FᵀF)⁻¹(BᵀB)⁻¹Bᵀ is A⁺


def test_the_true_pseudo_inverse_fails_when_its_hypothesis_is_dropped():
    steps = [dataclasses.replace(s, full_column_rank=()) for s in rewrites.factored_pinv_penrose()]
    assert not rewrites.check_independent(steps).holds  # BᵀB singular on some instance


def test_no_symbolic_route_inverts_with_dot_i():
    """``X.I`` in code (quoted in a docstring between double backquotes is fine)."""
    sources = Path(rewrites.__file__).parent.glob("*.py")
    assert not [p.name for p in sources if re.search(r"[\w)]\.I\b(?!``)", p.read_text())]


def test_a_false_rank_bound_built_like_l_le_d_is_rejected():
    false = dimension_free.rank_bound(lambda d: 3, "3")
    assert not false.holds and verdict(false.holds) == "refuted"
    true = dimension_free.l_le_d()
    assert true.holds and true.scope == f"checked on D ≤ {dimension_free.FACT_MAX_D}"
    shapes = {vals["C_xy^m"].shape for vals, _ in dimension_free.every_full_rank_shape()}
    top = dimension_free.FACT_MAX_D
    assert shapes == {(d, k) for d in range(1, top + 1) for k in range(1, d + 1)}


def test_the_induction_over_sensors_needs_the_one_sensor_rules():
    d = dimension_free
    proof, rules, inst = d.induction_step(d.C_RULES + [d.LOCAL_UPDATE], with_gap=False)  # no P = I
    assert not proof.proved
    assert all(wa.holds_on(rule, inst) for rule in rules)  # the block and hypothesis rules are true
    assert d.induction_step(d.C_RULES + [d.LOCAL_UPDATE], with_gap=True)[0].proved


@pytest.mark.parametrize("result", ["prop1", "gap_formula", "kernel_inclusion", "l_le_d"])
def test_every_control_has_instance_evidence_and_a_planted_rule(result):
    controls = getattr(dimension_free, result)().controls
    assert all(c.rejected and c.false_on_instance for c in controls)
    assert any(c.mutant.startswith("planted unsound rule") for c in controls)


def test_a_planted_rule_that_holds_is_not_counted_as_rejected():
    d = dimension_free
    control = d.planted_control("a true Penrose equation", d.PENROSE[0], d.instances())
    assert not control.rejected and not control.false_on_instance


def test_a_lemma_used_outside_its_hypotheses_is_refused():
    """P = A⁺A = I rests on full column rank; a DMF = CMF 'for any rank' built with it is refused."""
    d = dimension_free
    p_is_i, _ = d.lemma_projector_is_identity()
    assert p_is_i.premises == {d.LEFT_INVERSE.name}
    rules = d.C_RULES + [d.LOCAL_UPDATE]
    proof = wa.prove_by_normal_form(d.dmf_term(), d.cmf_term(), rules + [p_is_i], "DMF_m = CMF_m for any rank")
    assert proof.proved and d.LEFT_INVERSE.name in proof.premises
    result = d.DimensionFreeResult([proof], d.check_rules(rules, {}), [], "any dimension")
    assert result.checked.holds and result.outside_hypotheses == [proof.statement] and not result.holds
    stated = d.DimensionFreeResult([proof], d.check_rules(rules + [d.LEFT_INVERSE],
                                                          {d.LEFT_INVERSE.name: d.instances(full_rank=True)}),
                                   [], "any dimension")
    assert stated.holds  # with the hypothesis stated (and checked on its instances) it is the real claim


def test_stated_facts_are_in_the_record_and_on_the_page():
    from gpfverify.report.document import Table
    from gpfverify.report.sections.proofs import render
    from gpfverify.symbolic.certificate import Certificate

    record = Certificate("a", "s", "m", "proved", "d", scope="any dimension", stated_facts=("|XY| = |X||Y|",)).to_json()
    assert record["stated_facts"] == ["|XY| = |X||Y|"]
    assert "stated_facts" not in Certificate("b", "s", "m", "proved", "d").to_json()
    table = next(b for b in render([record]).blocks if isinstance(b, Table))
    assert table.rows[0][4] == "|XY| = |X||Y|"
