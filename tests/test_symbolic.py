"""Unit tests of the symbolic machinery: each checker must accept true identities and reject
false ones (negative controls), and the symbolic fusion formulas must agree with an independent
numpy evaluation of eq. 15/32/35 at a point."""

import json

import numpy as np
import pytest
import sympy as sp

from gpfverify.cli import main
from gpfverify.errors import InputError
from gpfverify.symbolic.certificate import Certificate
from gpfverify.symbolic.claims import CLAIMS, run_claim
from gpfverify.symbolic.fusion_claims import build_sensor, random_point
from gpfverify.symbolic.fusion_forms import cmf_term, dmf_term, predicted_gap_term
from gpfverify.symbolic import dimension_free, gp_claims, word_algebra as wa
from gpfverify.symbolic.argument import Argument
from gpfverify.symbolic.polynomial import Fraction, generic_symmetric, identity, inverse, lift, polynomial_ring
from gpfverify.symbolic.ukf_claims import unscented_moments
from gpfverify.tolerances import algebra_rtol


def _value(fraction: Fraction) -> np.ndarray:
    matrix = fraction.num.to_Matrix() / fraction.num.domain.to_sympy(fraction.den)
    return np.array(matrix.tolist(), dtype=float)


def test_inverse_times_matrix_is_identity_and_a_wrong_identity_is_not_zero():
    c_sym = generic_symmetric("c", 3)
    ring = polynomial_ring(c_sym)
    c = Fraction.of(lift(c_sym, ring))
    assert (inverse(c) @ c - identity(3, ring)).is_zero()
    assert not (c @ c - identity(3, ring)).is_zero()


@pytest.mark.parametrize("rank", [None, 1])
def test_symbolic_fusion_terms_match_numpy_formulas_at_a_point(rank):
    """Eq. 32/35/15 evaluated by numpy (np.linalg.pinv, solves) at the same integer point."""
    rng = np.random.default_rng(3)
    d, l = 3, 2
    sensor = build_sensor(d, l, rank)
    for _ in range(20):
        point = random_point(sensor.symbols, rng)
        at = {k: sp.Matrix(m.subs(point)) for k, m in zip(("G", "Cy", "y", "my", "mc", "mp"), sensor.symbols[:6])}
        a = (np.array(sensor.symbols[6].subs(point).tolist(), float) if rank is None else
             np.array((sensor.symbols[6] * sensor.symbols[7].T).subs(point).tolist(), float))
        num = {k: np.array(v.tolist(), dtype=float) for k, v in at.items()}
        if abs(np.linalg.det(num["Cy"])) > 0.5 and (rank is not None or np.linalg.matrix_rank(a) == l):
            break
    built = build_sensor(d, l, rank, point=point).lifted
    g, c_y, y, mu_y, mu_c, mu_p = (num[k] for k in ("G", "Cy", "y", "my", "mc", "mp"))
    mu_e = mu_p + a @ np.linalg.solve(c_y, y - mu_y)
    dmf = g @ (mu_y - mu_c) + g @ c_y @ np.linalg.pinv(a) @ (mu_e - mu_p)
    cmf = g @ (y - mu_c)
    projector = np.linalg.pinv(a) @ a
    gap = g @ c_y @ (projector - np.eye(l)) @ np.linalg.solve(c_y, y - mu_y)
    scale = np.linalg.cond(c_y) * np.linalg.cond(a)
    magnitude = max(np.abs(dmf).max(), np.abs(cmf).max())  # the gap is a difference of these
    for symbolic, numeric in ((dmf_term(built), dmf), (cmf_term(built), cmf), (predicted_gap_term(built), gap)):
        np.testing.assert_allclose(_value(symbolic), numeric, rtol=algebra_rtol(scale),
                                   atol=algebra_rtol(scale) * magnitude)
    if rank is not None:
        assert np.abs(gap).max() > 0  # the point really is a rank-deficient case with a gap


def test_moment_integral_equality_rejects_a_sign_flipped_cross_moment():
    """The old log-based test accepted exp(2·diff) = 1 for diff = ±iπ, i.e. a flipped sign."""
    setting = gp_claims.Setting.of(1)
    got = gp_claims.integrals(setting, product=False)
    closed = gp_claims.closed_forms(setting, product=False)
    flipped = gp_claims.closed_forms(setting, product=False, mutate="cross moment sign flipped")
    key = "Cov[x, k_a]_0 (eq. 20)"
    assert gp_claims.exactly_equal(got[key], closed[key])
    assert not gp_claims.exactly_equal(got[key], flipped[key])
    assert not gp_claims.exactly_equal(got["q_i (eq. 8-9)"],
                                       gp_claims.closed_forms(setting, False, "determinant dropped")["q_i (eq. 8-9)"])


def test_word_algebra_needs_the_stated_rules():
    """C C⁻¹ = I is not built in: without the rule the local update does not cancel; Penrose alone
    does not give A⁺A = I; a chain step that applies no rule is refused."""
    d = dimension_free
    lhs, rhs = d.dmf_term() - d.cmf_term(), d.gap_term()
    assert wa.prove_by_normal_form(lhs, rhs, d.ONE_SENSOR).proved
    assert not wa.prove_by_normal_form(lhs, rhs, [d.LOCAL_UPDATE]).proved
    assert not wa.prove_by_normal_form(d.Ap * d.A, d.I_l, list(d.PENROSE)).proved
    assert not wa.prove_by_chain([(d.Ap * d.A, None), (d.I_l, d.PENROSE[0])]).proved
    with pytest.raises(wa.ShapeError):
        _ = d.A * d.A  # n×l times n×l


def test_the_theory_checks_its_rules_on_exact_instances():
    """Every issued rule holds on the engine's instances of its own hypotheses; a wrong equation
    fails on the general instances, and the instances that satisfy it (as a hypothesis) are those
    with C_xy^m = 0, where A⁺ = A⁺AA⁺AA⁺ + A⁺ does hold."""
    d = dimension_free
    for rule in [*d.PENROSE, *d.C_INVERSE, d.LOCAL_UPDATE, d.PHI, *d.SELECTORS]:
        check = d.T.check(rule, rule.premises)
        assert check.passed, str(check)
    wrong = d.T.hypothesis("a wrong Penrose equation (test)", d.Ap * d.A * d.Ap, d.Ap * d.A * d.Ap * d.A * d.Ap + d.Ap,
                           "a wrong Penrose equation")
    assert not d.T.check(wrong, frozenset()).holds
    satisfying = d.T.instances(frozenset({wrong}))
    assert satisfying and all(i.values["C_xy^m"].is_zero_matrix for i in satisfying)


def test_a_proof_whose_negative_control_is_accepted_is_not_a_proof(tmp_path, monkeypatch, capsys):
    d = dimension_free
    argument = Argument("x", "A⁺A = I when C_xy^m has full column rank", "m", d.T)
    argument.conclude(d.projector_is_identity().derivation)
    evidence = argument.verdict()
    c = Certificate("x", "s", "m", "proved", "d", negative_controls=({"mutant": "sign", "rejected": False},),
                    evidence=evidence)
    with pytest.raises(ValueError):  # a verdict on another claim is not evidence
        Certificate("y", "s", "m", "proved", "d", evidence=evidence)
    assert evidence.status == "proved" and c.status == "checked" and c.detail.startswith("NOT A PROOF")
    assert c.to_json()["negative_controls"] == [{"mutant": "sign", "rejected": False}]
    import gpfverify.symbolic.claims as claims_module

    monkeypatch.setattr(claims_module, "run_claims", lambda size, only, progress=None: [c])
    assert main(["prove", "--out", str(tmp_path), "--size", "small", "--only", "full-rank-needs-l-le-D"]) == 1
    assert "NOT A PROOF" in capsys.readouterr().err


@pytest.mark.parametrize("claim", ["prop1-full-column-rank", "dmf-gap-formula", "dmf-exact-iff-kernel-inclusion",
                                   "full-rank-needs-l-le-D"])
def test_contract_claims_have_scope_and_rejected_controls(claim):
    record = run_claim(claim, "small").to_json()
    assert record["status"] == "proved" and record["scope"] == "any dimension"
    controls = record["negative_controls"]
    assert len(controls) >= 3 and all(c["rejected"] for c in controls)
    # every mutant is shown false on an exact instance (it is a real error)
    assert all(c["false_on_instance"] for c in controls)
    # every check the engine ran counts its instances, and none ran on none
    assert record["checks"] and all(c["instances"] > 0 and c["holds"] for c in record["checks"])


def test_unscented_transform_is_not_exact_for_a_quadratic_map():
    mean, factor = sp.Matrix([sp.Symbol("m")]), sp.Matrix([[sp.Symbol("L", positive=True)]])
    s = sp.Symbol("s", positive=True)
    y_bar, _, _ = unscented_moments(mean, factor, lambda x: x.applyfunc(lambda e: e**2), s, sp.Symbol("g"))
    exact_mean = mean[0] ** 2 + factor[0] ** 2
    assert sp.simplify(y_bar[0] - exact_mean) == 0  # second moments are matched ...
    y_bar4, _, _ = unscented_moments(mean, factor, lambda x: x.applyfunc(lambda e: e**4), s, sp.Symbol("g"))
    exact_fourth = mean[0] ** 4 + 6 * mean[0] ** 2 * factor[0] ** 2 + 3 * factor[0] ** 4
    assert sp.simplify(y_bar4[0] - exact_fourth) != 0  # ... fourth moments are not (unless s = 3)


def test_certificate_rejects_unknown_status_and_registry_rejects_unknown_claims():
    with pytest.raises(ValueError):
        Certificate("x", "s", "m", "maybe", "d")
    with pytest.raises(InputError):
        run_claim("no-such-claim")
    with pytest.raises(InputError):
        run_claim("full-rank-needs-l-le-D", "huge")


def test_prove_command_writes_contract_certificates(tmp_path, capsys):
    assert main(["prove", "--out", str(tmp_path), "--size", "small", "--only", "full-rank-needs-l-le-D"]) == 0
    records = json.loads((tmp_path / "certificates.json").read_text())
    assert [r["claim"] for r in records] == ["full-rank-needs-l-le-D"]
    assert set(records[0]) >= {"claim", "method", "status", "detail"} and records[0]["status"] == "proved"
    assert "full-rank-needs-l-le-D" in (tmp_path / "README.md").read_text()


def test_contract_claims_are_registered():
    assert {"prop1-full-column-rank", "dmf-gap-formula", "dmf-exact-iff-kernel-inclusion",
            "full-rank-needs-l-le-D", "gp-moment-integrals", "ukf-equals-kf-linear"} <= set(CLAIMS)


def test_prove_command_rejects_a_file_as_output_folder(tmp_path, capsys):
    target = tmp_path / "file.txt"
    target.write_text("x")
    assert main(["prove", "--out", str(target), "--size", "small", "--only", "full-rank-needs-l-le-D"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a folder" in err[0]


def test_proofs_page_lists_every_certificate_with_its_status():
    from gpfverify.report.document import Table
    from gpfverify.report.proofs import render

    records = [{"claim": "a", "statement": "s", "method": "m", "status": "proved", "detail": "d"},
               {"claim": "b", "statement": "s", "method": "m", "status": "refuted", "detail": "d"}]
    section = render(records)
    table = next(b for b in section.blocks if isinstance(b, Table))
    assert [row[:2] for row in table.rows] == [["a", "proved"], ["b", "refuted"]]
    assert "1 proved, 1 refuted, 0 checked" in section.blocks[0].text
