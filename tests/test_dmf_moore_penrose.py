"""DMF is eq. 35 as the paper writes it: with the Moore–Penrose inverse (C_xy^m)⁺ truncated at the
decided rank in C_xy^m's own SVD — checked against an oracle written here from
``numpy.linalg.pinv`` on rank-deficient cases of several shapes, through the API (dmf_update,
audit_case) and the command line (audit --json, fuse --method dmf --json). The rank each case's
sensors have is known by construction (fusion.synthetic), not read from the code under test."""

import json

import numpy as np
import pytest

from gpfverify.audit.case import audit_case
from gpfverify.cli import main
from gpfverify.fusion.case import FusionCase, case_to_dict
from gpfverify.fusion.distributed import dmf_update
from gpfverify.fusion.synthetic import random_case
from gpfverify.tolerances import algebra_rtol

#: (D, l_m per sensor, rank of each C_xy^m)
SHAPES = [(3, (5,), (3,)), (4, (3, 2), (2, 2)), (2, (3, 2), (1, 1)), (5, (4, 4, 2), (2, 4, 1)), (6, (8,), (3,)),
          (3, (2, 4), (2, 2))]


def _truncated_pinv(c_xy: np.ndarray, rank: int) -> np.ndarray:
    """numpy's pinv with its cut-off between the rank-th and the next singular value."""
    s = np.linalg.svd(c_xy, compute_uv=False)
    below = s[rank] if rank < s.size else 0.0
    cut = np.sqrt(s[rank - 1] * max(below, s[rank - 1] * 1e-30))
    return np.linalg.pinv(c_xy, rcond=cut / s[0])


def _oracle(case: FusionCase, ranks) -> dict:
    """Eq. 35 and 36 and the closed-form gap, from plain numpy."""
    c = case.central
    gain = np.linalg.solve(c.C_y, c.C_xy.T).T
    dmf_parts, predicted, scale = [], np.zeros(case.state_dim), 0.0
    start = 0
    for local, rank in zip(case.locals, ranks):
        block = slice(start, start + local.mu_y.size)
        start = block.stop
        pinv = _truncated_pinv(local.C_xy, rank)
        change = local.mu_e - local.mu_p
        dmf_parts.append(local.mu_y - c.mu_y[block] + local.C_y @ pinv @ change)
        w = np.linalg.solve(local.C_y, case.y[block] - local.mu_y)
        predicted -= gain[:, block] @ local.C_y @ (np.eye(local.mu_y.size) - pinv @ local.C_xy) @ w
        s = np.linalg.svd(local.C_xy, compute_uv=False)
        scale += np.linalg.norm(local.C_y, 2) * np.linalg.norm(pinv, 2) * np.linalg.norm(change) * s[0] / s[rank - 1]
    dmf = c.mu_p + gain @ np.concatenate(dmf_parts)
    cmf = c.mu_p + gain @ (case.y - c.mu_y)
    tol = algebra_rtol(np.linalg.cond(c.C_y)) * (np.linalg.norm(c.mu_p) + np.linalg.norm(dmf)
                                                  + np.linalg.norm(gain, 2) * (scale + np.linalg.norm(case.y)))
    return {"dmf": dmf, "cmf": cmf, "gap": dmf - cmf, "predicted": predicted, "tol": tol}


def _cases():
    for seed, (dim, sizes, ranks) in enumerate(SHAPES):
        yield random_case(np.random.default_rng(100 + seed), dim, sizes, ranks), ranks


@pytest.mark.parametrize("index", range(len(SHAPES)))
def test_dmf_and_its_audit_are_eq_35_with_the_moore_penrose_inverse(index):
    case, ranks = list(_cases())[index]
    oracle = _oracle(case, ranks)
    tol = oracle["tol"]
    dmf = dmf_update(case)
    assert [s.split.rank.rank for s in dmf.sensors] == list(ranks)
    np.testing.assert_allclose(dmf.mean, oracle["dmf"], rtol=0, atol=tol)
    audit = audit_case(case)
    for got, key in ((audit.dmf_mean, "dmf"), (audit.cmf_mean, "cmf"), (audit.gap, "gap"),
                     (audit.predicted_gap, "predicted")):
        np.testing.assert_allclose(got, oracle[key], rtol=0, atol=tol, err_msg=key)


def test_the_oracle_tells_the_moore_penrose_inverse_from_the_unit_free_variant():
    """The comparison above can fail: on these cases the whitened truncation (the unit-free variant)
    is far from eq. 35 wherever a sensor lost rank, and equal to it where none did."""
    far = 0
    for case, ranks in _cases():
        oracle = _oracle(case, ranks)
        variant = dmf_update(case, unit_free=True).mean
        lost = any(r < local.mu_y.size for r, local in zip(ranks, case.locals))
        if lost and np.linalg.norm(variant - oracle["dmf"]) > 1e3 * oracle["tol"]:
            far += 1
    assert far >= len(SHAPES) - 1


def _cli(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("index", [0, 3, 4])
def test_the_command_line_reports_eq_35(index, tmp_path, capsys):
    case, ranks = list(_cases())[index]
    oracle = _oracle(case, ranks)
    path = tmp_path / "case.json"
    path.write_text(json.dumps(case_to_dict(case)))
    code, out, err = _cli(["audit", str(path), "--json"], capsys)
    assert code == 0 and err == ""
    report = json.loads(out)
    for field, key in (("dmf_mean", "dmf"), ("gap", "gap"), ("predicted_gap", "predicted")):
        np.testing.assert_allclose(report[field], oracle[key], rtol=0, atol=oracle["tol"], err_msg=field)
    assert [s["rank"] for s in report["sensors"]] == list(ranks)
    assert report["unit_dependence"] > 0 and len(report["unit_free_dmf_mean"]) == case.state_dim
    code, out, err = _cli(["fuse", str(path), "--method", "dmf", "--json"], capsys)
    assert code == 0 and err == ""
    np.testing.assert_allclose(json.loads(out)["mean"], oracle["dmf"], rtol=0, atol=oracle["tol"])


@pytest.mark.parametrize("rule, zero_rank", [("canonical", False), ("numpy", False), ("absolute:1e300", True)])
def test_fuse_takes_the_rank_rule_and_names_it(rule, zero_rank, tmp_path, capsys):
    """fuse --method dmf --rank-rule RULE: eq. 35 at the rank RULE decides — the known ranks for
    canonical and numpy here, none for an absolute tolerance above every singular value — and the
    rule named in the output, in text and JSON."""
    case, ranks = list(_cases())[3]
    oracle = _oracle(case, [0] * len(ranks) if zero_rank else ranks)
    path = tmp_path / "case.json"
    path.write_text(json.dumps(case_to_dict(case)))
    code, out, err = _cli(["fuse", str(path), "--method", "dmf", "--rank-rule", rule, "--json"], capsys)
    assert code == 0 and err == ""
    result = json.loads(out)
    np.testing.assert_allclose(result["mean"], oracle["dmf"], rtol=0, atol=oracle["tol"])
    assert result["rank_rule"]["name"] == rule.split(":")[0]
    code, out, err = _cli(["fuse", str(path), "--method", "dmf", "--rank-rule", rule], capsys)
    named = {"canonical": "rank rule: canonical correlations", "numpy": "rank rule: numpy matrix_rank rule",
             "absolute:1e300": "rank rule: explicit absolute tolerance 1e+300"}[rule]
    assert code == 0 and named in out, out


def test_fuse_names_the_ci_criterion_once_and_keeps_its_old_spelling(tmp_path, capsys):
    case, _ = list(_cases())[1]
    path = tmp_path / "case.json"
    path.write_text(json.dumps(case_to_dict(case)))
    outputs = []
    for option in ("--ci-criterion", "--criterion"):
        code, out, err = _cli(["fuse", str(path), "--method", "ci", option, "det", "--json"], capsys)
        assert code == 0 and err == ""
        outputs.append(json.loads(out))
    assert outputs[0] == outputs[1] and outputs[0]["criterion"] == "det"
    code, out, err = _cli(["fuse", str(path), "--method", "cc", "--rank-rule", "numpy"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--method dmf" in err
