"""One vocabulary across subcommands: the fusion rules' names (``cc``, also spelled ``cw``) in
``fuse``, ``check`` and ``run_fusion``; one ``--rank-rule`` syntax in ``check``, ``audit`` and
``reproduce``; RCC-CI's options spelled and defaulted alike in ``fuse`` and ``reproduce``."""

import json
from pathlib import Path

import numpy as np
import pytest

from gpfverify.cli import main
from gpfverify.contract.ungm1d import Params as Ungm1dParams
from gpfverify.errors import InputError
from gpfverify.experiments import check
from gpfverify.fusion.case import case_to_dict
from gpfverify.fusion.model_fusion import run_fusion
from gpfverify.fusion.names import ALIASES, FUSION_RULES
from gpfverify.fusion.synthetic import random_case, random_spd
from gpfverify.tolerances import algebra_rtol

ROOT = Path(__file__).resolve().parents[1]
REDUNDANT = f"{ROOT / 'examples' / 'redundant_sensor_system.py'}:system"


def _run(argv, capsys):
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's usage errors
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def _case_file(tmp_path, seed=8, far=False):
    """A two-sensor case with its local posteriors (far apart when ``far``: RCC-CI's ellipsoids
    then do not meet)."""
    import dataclasses

    rng = np.random.default_rng(seed)
    case = random_case(rng, 2, (2, 1))
    shift = (50.0, 0.0) if far else (0.0, 0.0)
    locals_ = tuple(dataclasses.replace(r, mu_e=0.1 * rng.normal(size=2) + m * np.asarray(shift),
                                        C_e=random_spd(rng, 2)) for m, r in enumerate(case.locals))
    case = dataclasses.replace(case, locals=locals_)
    path = tmp_path / "case.json"
    path.write_text(json.dumps(case_to_dict(case)))
    return str(path), case


@pytest.mark.parametrize("spelling", ["cc", "cw", "CW"])
def test_fuse_takes_either_name_of_the_convex_combination_and_reports_the_canonical_one(tmp_path, capsys,
                                                                                         spelling):
    path, case = _case_file(tmp_path)
    code, out, err = _run(["fuse", path, "--method", spelling, "--json"], capsys)
    assert code == 0 and err == ""
    data = json.loads(out)
    assert data["method"] == "cc"
    # independent route: information-weighted sum with explicit inverses
    infos = [np.linalg.inv(r.C_e) for r in case.locals]
    cov = np.linalg.inv(sum(infos))
    mean = cov @ sum(i @ r.mu_e for i, r in zip(infos, case.locals))
    np.testing.assert_allclose(data["cov"], cov, rtol=algebra_rtol(np.linalg.cond(cov)))
    np.testing.assert_allclose(data["mean"], mean, rtol=algebra_rtol(np.linalg.cond(cov)),
                               atol=algebra_rtol(np.linalg.cond(cov)) * np.abs(mean).max())


def test_an_unknown_rule_exits_2_naming_every_choice(tmp_path, capsys):
    path, _ = _case_file(tmp_path)
    for argv in (["fuse", path, "--method", "avg"], ["check", REDUNDANT, "--methods", "cmf,dmf,avg", "--json"]):
        code, out, err = _run(argv, capsys)
        assert code == 2 and out == ""
        assert len(err.strip().splitlines()) == 1
        assert all(rule in err for rule in FUSION_RULES) and "cw = cc" in err


def test_check_runs_every_rule_fuse_knows_under_the_same_names():
    params = check.params_for(REDUNDANT, steps=4, methods=("cmf", "dmf", "cw", "ici", "ei", "rcc-ci", "ci"))
    assert params.methods == ("cmf", "dmf", "cc", "ici", "ei", "rcc-ci", "ci")
    results = check.summarize(params, [check.run_one(params, np.random.SeedSequence(5))])
    assert set(results["time_per_step"]) >= set(FUSION_RULES)


def test_run_fusion_records_canonical_names_and_reads_either():
    from gpfverify.systems import load_system

    model = load_system(REDUNDANT)
    _, ys = model.simulate(3, np.random.default_rng(2))
    fused = run_fusion(model, ys, methods=("cmf", "dmf", "cw"))
    assert fused.methods == ("cmf", "dmf", "cc")
    np.testing.assert_array_equal(fused.means("cw"), fused.means("cc"))  # one record, two spellings
    with pytest.raises(InputError, match="unknown fusion rule"):
        run_fusion(model, ys, methods=("cmf", "dmf", "average"))
    assert set(ALIASES.values()) <= set(FUSION_RULES)


@pytest.mark.parametrize("rule", ["numpy", "canonical", "canonical:1e-6", "absolute:1e-9"])
def test_reproduce_takes_the_rank_rule_syntax_of_check_and_audit(rule):
    params = Ungm1dParams(rank_rule=rule)
    assert params.rank_rule_spec == rule
    check.params_for(REDUNDANT, rank_rule=rule)  # the same strings are valid in check


def test_rank_rule_misuse_is_refused_by_every_command(tmp_path, capsys):
    with pytest.raises(InputError, match="unknown rank rule"):
        Ungm1dParams(rank_rule="sigma-max")
    with pytest.raises(InputError, match="--rank-tol"):
        Ungm1dParams(rank_rule="numpy", rank_tol=1e-9)
    path, _ = _case_file(tmp_path)
    for argv in (["audit", path, "--rank-rule", "sigma-max"],
                 ["check", REDUNDANT, "--rank-rule", "sigma-max", "--json"],
                 ["reproduce", "ungm1d", "--rank-rule", "sigma-max", "--out", str(tmp_path / "r")]):
        code, out, err = _run(argv, capsys)
        assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and "rank rule" in err, argv
    assert not (tmp_path / "r").exists()


def test_fuse_rcc_options_have_reproduces_names_and_default(tmp_path, capsys):
    path, _ = _case_file(tmp_path, seed=3, far=True)
    code, out, _ = _run(["fuse", path, "--method", "rcc-ci", "--json"], capsys)
    assert code == 0 and json.loads(out)["enlarged"] is True  # default enlarge, as in reproduce
    assert Ungm1dParams().rcc_on_empty == "enlarge"
    code, out, err = _run(["fuse", path, "--method", "rcc-ci", "--rcc-on-empty", "error"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1
    near, _ = _case_file(tmp_path, seed=8)
    for flag in ("--rcc-size", "--c"):  # the old spelling stays
        code, out, _ = _run(["fuse", near, "--method", "rcc-ci", flag, "40", "--json"], capsys)
        assert code == 0 and json.loads(out)["c"] == 40.0
