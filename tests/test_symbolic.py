"""The claims' certificates as ``gpfverify prove`` writes them, the second routes at listed sizes,
and the symbolic fusion formulas against an independent numpy evaluation of eq. 15/32/35."""

import json

import numpy as np
import pytest
import sympy as sp

from gpfverify.cli import main
from gpfverify.errors import InputError
from gpfverify.symbolic import gp_claims
from gpfverify.symbolic.certificate import Certificate, NumericalCheck
from gpfverify.symbolic.claims import CLAIMS, run_claim
from gpfverify.symbolic.fusion_claims import build_sensor
from gpfverify.symbolic.fusion_forms import cmf_term, dmf_term, predicted_gap_term
from gpfverify.symbolic.polynomial import Fraction, generic_symmetric, identity, inverse, lift, polynomial_ring
from gpfverify.symbolic.ukf_claims import unscented_moments
from gpfverify.tolerances import algebra_rtol

CONTRACT = ["prop1-full-column-rank", "dmf-gap-formula", "dmf-exact-iff-kernel-inclusion", "full-rank-needs-l-le-D"]


def _at(fraction: Fraction, point: dict) -> np.ndarray:
    matrix = fraction.num.to_Matrix().xreplace(point) / fraction.num.domain.to_sympy(fraction.den).xreplace(point)
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
    s = build_sensor(d, l, rank)
    symbols = sorted(set().union(*(m.num.to_Matrix().free_symbols for m in (s.G, s.C_y, s.C_xy, s.y, s.mu_y,
                                                                            s.mu_y_central, s.mu_p))), key=str)
    while True:
        point = {x: int(rng.integers(-4, 5)) for x in symbols}
        c_y, a = _at(s.C_y, point), _at(s.C_xy, point)
        if abs(np.linalg.det(c_y)) > 0.5 and np.linalg.matrix_rank(a) == (l if rank is None else rank):
            break
    g, y, mu_y, mu_c, mu_p = (_at(m, point) for m in (s.G, s.y, s.mu_y, s.mu_y_central, s.mu_p))
    mu_e = mu_p + a @ np.linalg.solve(c_y, y - mu_y)
    dmf = g @ (mu_y - mu_c) + g @ c_y @ np.linalg.pinv(a) @ (mu_e - mu_p)
    cmf = g @ (y - mu_c)
    gap = g @ c_y @ (np.linalg.pinv(a) @ a - np.eye(l)) @ np.linalg.solve(c_y, y - mu_y)
    scale = np.linalg.cond(c_y) * np.linalg.cond(a)
    magnitude = max(np.abs(dmf).max(), np.abs(cmf).max())  # the gap is a difference of these
    for symbolic, numeric in ((dmf_term(s), dmf), (cmf_term(s), cmf), (predicted_gap_term(s), gap)):
        np.testing.assert_allclose(_at(symbolic, point), numeric, rtol=algebra_rtol(scale),
                                   atol=algebra_rtol(scale) * magnitude)
    if rank is not None:
        assert np.abs(gap).max() > 0  # the point really is a rank-deficient case with a gap


def test_moment_integral_equality_rejects_a_sign_flipped_cross_moment():
    setting = gp_claims.Setting.of(1)
    got = gp_claims.integrals(setting, product=False)
    closed = gp_claims.closed_forms(setting, product=False)
    flipped = gp_claims.closed_forms(setting, product=False, mutate="cross moment sign flipped")
    key = "Cov[x, k_a]_0 (eq. 20)"
    assert gp_claims.exactly_equal(got[key], closed[key])
    assert not gp_claims.exactly_equal(got[key], flipped[key])


def test_unscented_transform_is_not_exact_for_a_quartic_map():
    mean, factor = sp.Matrix([sp.Symbol("m")]), sp.Matrix([[sp.Symbol("L", positive=True)]])
    s = sp.Symbol("s", positive=True)
    y_bar, _, _ = unscented_moments(mean, factor, lambda x: x.applyfunc(lambda e: e**2), s, sp.Symbol("g"))
    assert sp.simplify(y_bar[0] - mean[0] ** 2 - factor[0] ** 2) == 0  # second moments are matched ...
    y_bar4, _, _ = unscented_moments(mean, factor, lambda x: x.applyfunc(lambda e: e**4), s, sp.Symbol("g"))
    exact_fourth = mean[0] ** 4 + 6 * mean[0] ** 2 * factor[0] ** 2 + 3 * factor[0] ** 4
    assert sp.simplify(y_bar4[0] - exact_fourth) != 0  # ... fourth moments are not (unless s = 3)


@pytest.mark.parametrize("claim", CONTRACT + ["gp-moment-integrals", "ukf-equals-kf-linear"])
def test_every_claim_is_proved_in_any_dimension_with_its_controls_refused_and_refuted(claim):
    record = run_claim(claim, "small").to_json()
    assert record["status"] == "proved" and record["scope"] == "any dimension", record["detail"]
    controls = record["negative_controls"]
    assert len(controls) >= 3 and all(c["rejected"] and c["false_on_instance"] for c in controls)
    assert all(c["holds"] for c in record["checks"])


@pytest.mark.parametrize("claim", ["full-column-rank-necessary", "dmf-exact-without-condition"])
def test_the_two_expected_false_statements_are_refuted_on_exact_instances(claim):
    record = run_claim(claim, "small").to_json()
    assert record["status"] == "refuted" and record["scope"].startswith("counterexample at")


def test_a_failing_control_or_check_makes_prove_exit_non_zero(tmp_path, monkeypatch, capsys):
    import gpfverify.symbolic.claims as claims_module

    failing = NumericalCheck("casadi-x", "two implementations agree", "m", False, "they do not")
    assert failing.to_json()["status"] == "checked" and failing.failures
    monkeypatch.setattr(claims_module, "run_claims", lambda size, only, progress=None: [failing])
    assert main(["prove", "--out", str(tmp_path), "--size", "small", "--only", "full-rank-needs-l-le-D"]) == 1
    assert "NOT A PROOF" in capsys.readouterr().err


def test_a_certificate_has_no_status_of_its_authors():
    with pytest.raises(TypeError):
        Certificate("x", "t", status="proved")  # type: ignore[call-arg]
    assert Certificate("x", "a title only").status == "checked"


def test_registry_rejects_unknown_claims_and_sizes():
    with pytest.raises(InputError):
        run_claim("no-such-claim")
    with pytest.raises(InputError):
        run_claim("full-rank-needs-l-le-D", "huge")


def test_prove_command_writes_contract_certificates_that_the_kernel_accepts(tmp_path, capsys):
    assert main(["prove", "--out", str(tmp_path), "--size", "small", "--only", "full-rank-needs-l-le-D"]) == 0
    records = json.loads((tmp_path / "certificates.json").read_text())
    assert [r["claim"] for r in records] == ["full-rank-needs-l-le-D"]
    assert set(records[0]) >= {"claim", "method", "status", "detail", "scope", "negative_controls", "formal"}
    assert records[0]["status"] == "proved"
    assert "full-rank-needs-l-le-D" in (tmp_path / "README.md").read_text()
    assert main(["prove", "--check", str(tmp_path / "certificates.json")]) == 0


def test_contract_claims_are_registered():
    assert set(CONTRACT) | {"gp-moment-integrals", "ukf-equals-kf-linear"} <= set(CLAIMS)


def test_prove_command_rejects_a_file_as_output_folder_and_a_missing_out(tmp_path, capsys):
    target = tmp_path / "file.txt"
    target.write_text("x")
    assert main(["prove", "--out", str(target), "--size", "small", "--only", "full-rank-needs-l-le-D"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a folder" in err[0]
    assert main(["prove", "--size", "small"]) == 2


def test_proofs_page_shows_each_status_the_kernel_confirms():
    from gpfverify.report.document import Table
    from gpfverify.report.proofs import render

    records = [run_claim(name, "small").to_json() for name in ("full-rank-needs-l-le-D", "dmf-exact-without-condition")]
    records.append({"claim": "by-hand", "statement": "s", "method": "m", "status": "proved", "detail": "d"})
    section = render(records)
    table = next(b for b in section.blocks if isinstance(b, Table))
    shown = [[row[0], getattr(row[1], "value", row[1])] for row in table.rows]
    assert shown == [["full-rank-needs-l-le-D", "proved"], ["dmf-exact-without-condition", "refuted, as intended"],
                     ["by-hand", "checked"]]
    assert "1 proved, 1 refuted, 1 checked" in section.blocks[0].text
