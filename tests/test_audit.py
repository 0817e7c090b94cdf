"""The rank-condition audit (Python API and ``gpfverify audit``/``fuse``): fields against the
fusion routines they report on, the CONTRACT.md JSON shape, and the one-line exit-2 contract for
bad case files."""

import dataclasses
import json

import numpy as np
import pytest

from gpfverify.audit.case import audit_case, audit_run, audit_to_dict, format_audit
from gpfverify.cli import main
from gpfverify.fusion.case import case_to_dict
from gpfverify.fusion.centralized import cmf_update
from gpfverify.fusion.distributed import dmf_update
from gpfverify.fusion.synthetic import random_case, random_spd
from gpfverify.tolerances import CANONICAL_RANK_TOL, algebra_rtol

SENSOR_KEYS = {"index", "rows", "cols", "rank", "full_column_rank", "singular_values", "tol", "exact",
               "repair_dim"}


def _write(tmp_path, case, name="case.json"):
    path = tmp_path / name
    path.write_text(json.dumps(case_to_dict(case) if not isinstance(case, dict) else case))
    return str(path)


def _run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_audit_reports_what_the_fusion_routines_compute():
    case = random_case(np.random.default_rng(1), 2, (3, 2))
    audit = audit_case(case)
    dmf, cmf = dmf_update(case), cmf_update(case.central, case.y)
    np.testing.assert_array_equal(audit.dmf_mean, dmf.mean)
    np.testing.assert_array_equal(audit.cmf_mean, cmf.mean)
    np.testing.assert_array_equal(audit.gap, dmf.mean - cmf.mean)
    assert [s.rank for s in audit.sensors] == [2, 2] and [s.repair_dim for s in audit.sensors] == [1, 0]
    assert not audit.condition_holds and not audit.exact
    scale = np.linalg.norm(cmf.mean) + np.linalg.norm(audit.gap)
    tol = algebra_rtol(np.linalg.cond(case.central.C_y)) * scale
    np.testing.assert_allclose(audit.gap, audit.predicted_gap, atol=tol)
    np.testing.assert_allclose(audit.repaired_dmf_mean, cmf.mean, atol=tol)
    assert all(s.local_consistency_residual <= s.consistency_tol for s in audit.sensors)
    # sensor 0 lost rank: the note gives the unit-free variant's distance, in prior standard deviations
    [note] = audit.notes
    assert note.startswith("sensor(s) [0] lost rank") and "depends on the units" in note
    variant = dmf_update(case, unit_free=True).mean
    np.testing.assert_array_equal(audit.unit_free_dmf_mean, variant)
    whitened = np.linalg.solve(np.linalg.cholesky(case.central.C_p), audit.dmf_mean - variant)
    assert audit.unit_dependence == pytest.approx(np.linalg.norm(whitened), rel=algebra_rtol(
        np.linalg.cond(case.central.C_p)))
    assert audit.unit_dependence > 1e3 * audit.gap_bound  # a real effect, not rounding


def test_exact_despite_rank_failure_is_explained():
    audit = audit_case(random_case(np.random.default_rng(2), 2, (3, 2), decoupled=(2,)))
    assert not audit.condition_holds and audit.exact
    assert any("rank condition of Proposition 1 fails but DMF is exact" in n for n in audit.notes)


def test_without_y_the_audit_explains_what_cannot_be_recovered():
    case = dataclasses.replace(random_case(np.random.default_rng(3), 2, (3, 2)), y=None)
    out = audit_to_dict(audit_case(case))
    assert not {"cmf_mean", "gap", "predicted_gap"} & set(out)
    assert any("range(P_m)" in n for n in out["notes"])


def test_inconsistent_log_is_flagged():
    case = random_case(np.random.default_rng(4), 2, (2, 2))
    local = dataclasses.replace(case.locals[0], mu_e=case.locals[0].mu_e + 1.0)
    audit = audit_case(dataclasses.replace(case, locals=(local, case.locals[1])))
    assert audit.sensors[0].local_consistency_residual > audit.sensors[0].consistency_tol
    assert any("not the local update" in n for n in audit.notes)


def test_audit_json_contract(tmp_path, capsys):
    case = random_case(np.random.default_rng(5), 3, (2, 4))
    code, out, err = _run(["audit", _write(tmp_path, case), "--json"], capsys)
    assert code == 0 and err == ""
    data = json.loads(out)
    assert {"sensors", "condition_holds", "exact", "dmf_mean", "cmf_mean", "gap", "predicted_gap"} <= set(data)
    for m, s in enumerate(data["sensors"]):
        assert SENSOR_KEYS <= set(s) and s["index"] == m and s["rows"] == 3
    assert [s["cols"] for s in data["sensors"]] == [2, 4]
    assert [s["full_column_rank"] for s in data["sensors"]] == [True, False]
    assert data["sensors"][1]["repair_dim"] == 1 and data["condition_holds"] is False
    assert len(data["dmf_mean"]) == len(data["gap"]) == len(data["predicted_gap"]) == 3
    # default rule (changed from numpy's): canonical correlations against tau, tol in the rule's units
    assert data["rank_rule"]["name"] == "canonical" and data["rank_rule"]["tol"] == CANONICAL_RANK_TOL
    assert data["rank_rule"]["covariance"] == "local C_p from C_e"
    for s in data["sensors"]:
        assert s["tol"] == CANONICAL_RANK_TOL and s["rank_rule"]["name"] == "canonical"
        assert s["rank"] == sum(rho > CANONICAL_RANK_TOL for rho in s["canonical_correlations"])


def test_rank_tolerance_from_file_and_flag(tmp_path, capsys):
    case = random_case(np.random.default_rng(6), 2, (2, 2))
    s_min = np.linalg.svd(case.locals[0].C_xy, compute_uv=False)[-1]
    data = case_to_dict(case)
    data["rank_tol"] = 1.5 * s_min
    path = _write(tmp_path, data)
    out = json.loads(_run(["audit", path, "--json"], capsys)[1])
    assert out["sensors"][0]["tol"] == 1.5 * s_min and out["sensors"][0]["rank"] == 1
    assert out["rank_rule"]["name"] == "absolute" and out["rank_rule"]["tol"] == 1.5 * s_min
    assert "explicit" in out["rank_rule"]["description"]
    out = json.loads(_run(["audit", path, "--json", "--rank-tol", "0"], capsys)[1])
    assert out["sensors"][0]["tol"] == 0.0 and out["sensors"][0]["rank"] == 2


def test_audit_text_by_default(tmp_path, capsys):
    code, out, _ = _run(["audit", _write(tmp_path, random_case(np.random.default_rng(7), 2, (1, 3)))], capsys)
    assert code == 0 and "Proposition 1 condition" in out and "predicted gap" in out
    assert out.strip() == format_audit(audit_case(random_case(np.random.default_rng(7), 2, (1, 3))))


def _intersecting_case(seed):
    """A case whose local posteriors are close, so that RCC-CI's ellipsoids meet."""
    rng = np.random.default_rng(seed)
    case = random_case(rng, 2, (2, 1))
    locals_ = tuple(dataclasses.replace(r, mu_e=0.1 * rng.normal(size=2), C_e=random_spd(rng, 2))
                    for r in case.locals)
    return dataclasses.replace(case, locals=locals_)


@pytest.mark.parametrize("method", ["cmf", "dmf", "cc", "ci", "rcc-ci", "ici", "ei"])
def test_fuse_json_contract(tmp_path, capsys, method):
    code, out, err = _run(["fuse", _write(tmp_path, _intersecting_case(8)), "--method", method, "--json"], capsys)
    assert code == 0 and err == ""
    data = json.loads(out)
    assert data["method"] == method and len(data["mean"]) == 2 and np.shape(data["cov"]) == (2, 2)
    assert ("weights" in data) == (method in ("ci", "rcc-ci", "ici"))
    assert ("c" in data) == (method == "rcc-ci")
    if method in ("ci", "rcc-ci"):
        assert sum(data["weights"]) == pytest.approx(1.0)


def test_fuse_criterion_and_size_flags(tmp_path, capsys):
    path = _write(tmp_path, _intersecting_case(9))
    det = json.loads(_run(["fuse", path, "--method", "ci", "--criterion", "det", "--json"], capsys)[1])
    assert det["criterion"] == "det"
    rcc = json.loads(_run(["fuse", path, "--method", "rcc-ci", "--c", "50", "--json"], capsys)[1])
    assert rcc["c"] == 50.0


def _bad_cases(tmp_path):
    good = case_to_dict(random_case(np.random.default_rng(10), 2, (1, 2)))
    no_y = dict(good)
    del no_y["y"]
    no_ce = json.loads(json.dumps(good))
    del no_ce["locals"][1]["C_e"]
    non_psd = json.loads(json.dumps(good))
    non_psd["locals"][0]["C_y"] = [[-1.0]]
    mismatch = json.loads(json.dumps(good))
    mismatch["central"]["sizes"] = [2, 2]
    files = {"not json": "{", "not psd": non_psd, "sizes mismatch": mismatch, "list": [1]}
    out = {name: (["fuse", "--method", "dmf"], content) for name, content in files.items()}
    out.update({name: (["audit"], content) for name, content in files.items() if name != "list"})
    out["cmf without y"] = (["fuse", "--method", "cmf"], no_y)
    out["ci without C_e"] = (["fuse", "--method", "ci"], no_ce)
    return out


@pytest.mark.parametrize("name", ["not json", "not psd", "sizes mismatch", "list", "cmf without y",
                                  "ci without C_e"])
def test_bad_case_files_exit_2_with_one_line(tmp_path, capsys, name):
    argv, content = _bad_cases(tmp_path)[name]
    path = tmp_path / "bad.json"
    path.write_text(content if isinstance(content, str) else json.dumps(content))
    code, out, err = _run([argv[0], str(path), *argv[1:]], capsys)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith(f"gpfverify {argv[0]}: error: ") and "Traceback" not in err


def test_audit_run_arrays():
    rng = np.random.default_rng(11)
    cases = [random_case(rng, 2, (2, 3)) for _ in range(4)] + [random_case(rng, 2, (2, 3), with_y=False)]
    run = audit_run(cases)
    assert run.rank.shape == run.full_column_rank.shape == run.exact.shape == (5, 2)
    assert np.all(run.full_column_rank[:, 0]) and not np.any(run.full_column_rank[:, 1])
    np.testing.assert_array_equal(run.repair_dim, np.tile([0, 1], (5, 1)))
    assert np.all(np.isfinite(run.gap_norm[:4])) and np.isnan(run.gap_norm[4])
    cond = max(np.linalg.cond(c.central.C_y) * max(np.linalg.cond(r.C_y) for r in c.locals) for c in cases)
    np.testing.assert_allclose(run.gap_norm[:4], run.predicted_gap_norm[:4], rtol=algebra_rtol(cond))


def test_sensor_gap_shares_add_up_to_the_gap_and_name_the_driving_sensor():
    case = random_case(np.random.default_rng(11), 2, (3, 2))
    audit = audit_case(case)
    shares = [s.gap_contribution for s in audit.sensors]
    tol = algebra_rtol(np.linalg.cond(case.central.C_y)) * (np.linalg.norm(audit.gap) + 1.0)
    np.testing.assert_allclose(sum(shares), audit.predicted_gap, atol=tol)
    # sensor 1 has full column rank (2 outputs, 2 states): it contributes nothing
    assert audit.sensors[1].repair_dim == 0 and np.linalg.norm(shares[1]) == 0.0
    assert np.linalg.norm(shares[0]) > 0
    assert "gap_contribution" in audit_to_dict(audit)["sensors"][0]


@pytest.mark.parametrize("condition", [1e1, 1e4, 1e7])
def test_sensitivity_equals_the_closed_form_and_respects_the_sigma_bound(condition):
    case = random_case(np.random.default_rng(12), 3, (2, 3), cross_condition=condition)
    audit = audit_case(case, sensitivity=True)
    gain = np.linalg.solve(case.central.C_y, case.central.C_xy.T).T
    for s, block, local in zip(audit.sensors, case.central.blocks, case.locals):
        assert s.full_column_rank
        closed = np.linalg.norm(gain[:, block] @ local.C_y @ np.linalg.pinv(local.C_xy), 2)
        norm = s.sensitivity.jacobian_norms["mu_e"]
        assert norm == pytest.approx(closed, rel=algebra_rtol(condition))
        assert norm <= s.sensitivity.mu_e_bound * (1 + algebra_rtol(condition))
        assert s.sensitivity.sigma_r == pytest.approx(s.singular_values[-1], rel=1e-12)


def test_audit_sensitivity_flag(tmp_path, capsys):
    path = _write(tmp_path, random_case(np.random.default_rng(13), 2, (2, 2)))
    code, out, _ = _run(["audit", path, "--json", "--sensitivity"], capsys)
    sensors = json.loads(out)["sensors"]
    assert code == 0 and all({"jacobian_norms", "sigma_r", "mu_e_bound"} <= set(s["sensitivity"]) for s in sensors)
    code, out, _ = _run(["audit", path, "--sensitivity"], capsys)
    assert code == 0 and "sensitivity |d mu_DMF / d report|" in out
    code, out, _ = _run(["audit", path, "--json"], capsys)
    assert "sensitivity" not in json.loads(out)["sensors"][0]
