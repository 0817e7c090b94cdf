"""One vocabulary across subcommands: the fusion rules' names (``cc``, also spelled ``cw``) in
``fuse``, ``check`` and ``run_fusion``; one ``--rank-rule`` syntax in ``check``, ``audit`` and
``reproduce``; RCC-CI's options spelled and defaulted alike in ``fuse`` and ``reproduce``."""

import argparse
import json
import re
from pathlib import Path

import numpy as np
import pytest

from gpfverify.cli import main
from gpfverify.papers.fusion.ungm1d_contract import Params as Ungm1dParams
from gpfverify.errors import InputError
from gpfverify.experiments import check
from gpfverify.fusion.case import case_to_dict
from gpfverify.model_fusion import run_fusion
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


# ---- options by their full names only, one name per meaning ------------------------------------

from gpfverify.cli import COMMANDS, command_parser  # noqa: E402
from gpfverify.commands.reproduce import experiment_parser  # noqa: E402
from gpfverify.papers import EXPERIMENTS  # noqa: E402

#: what each parser needs besides the option under test, so that only that option can be refused
REQUIRED = {"check": ["sys.py:m"], "audit": ["case.json"], "fuse": ["case.json", "--method", "cc"],
            "prove": ["--out", "o"], "props": ["--out", "o"], "report": []}


def _parsers():
    """(name, parser, required arguments) for every subcommand and every experiment of reproduce."""
    for command in COMMANDS:
        if command != "reproduce":
            yield command, command_parser(command), REQUIRED[command]
    for name in EXPERIMENTS:
        yield f"reproduce {name}", experiment_parser(name), ["--out", "o"]


def _long_options(parser):
    return [(s, action) for action in parser._actions for s in action.option_strings
            if s.startswith("--") and s not in ("--help",)]


@pytest.mark.parametrize("name,parser,required", list(_parsers()), ids=lambda v: v if isinstance(v, str) else "")
def test_no_option_is_taken_by_a_prefix_of_its_name(name, parser, required, capsys):
    """argparse's prefix matching would take ``--train 60`` as ``--training-start-var 60``: every
    long option of every parser, cut by one letter, is refused as unrecognized."""
    options = _long_options(parser)
    assert options, name
    for option, action in options:
        prefix = option[:-1]
        if any(s == prefix for s, _ in options):
            continue  # the prefix is another option's full name
        value = [] if action.nargs == 0 else ["1"]
        with pytest.raises(SystemExit) as exc:
            parser.parse_args([*required, prefix, *value])
        err = capsys.readouterr().err
        assert exc.value.code == 2 and f"unrecognized arguments: {prefix}" in err, (name, option, err)


#: (parser, Params field) -> the one option name of its meaning
ONE_NAME = {
    **{(p, f): "--train-points" for p, f in [("check", "train"), ("reproduce ungm1d", "train"),
                                              ("reproduce ct2d", "kappa"), ("reproduce gpadf-scalar", "train_points"),
                                              ("reproduce moments", "train_points"),
                                              ("reproduce sins-gps", "train_points")]},
    **{(p, f): "--sigma-kappa" for p, f in [("reproduce ct2d", "sigma_kappa"), ("reproduce ungm1d", "sigma_kappa"),
                                             ("reproduce gpadf-scalar", "kappa")]},
}


#: how the help of a training-sample count begins (not "at most this many training samples ... for the fit")
COUNT_OF_TRAINING_SAMPLES = r"(gp families: )?(gp )?(training (samples|points)|samples drawn from the system)"


def test_the_training_sample_count_and_the_sigma_point_kappa_have_one_name_everywhere():
    parsers = {name: parser for name, parser, _ in _parsers()}
    for (name, dest), option in ONE_NAME.items():
        actions = [a for a in parsers[name]._actions if a.dest == dest and a.help != argparse.SUPPRESS]
        assert len(actions) == 1 and actions[0].option_strings[0] == option, (name, dest)
    # no other option of any parser is a training count or a sigma-point κ under another name
    for name, parser in parsers.items():
        for action in parser._actions:
            text = (action.help or "").lower()
            if action.help != argparse.SUPPRESS and re.match(COUNT_OF_TRAINING_SAMPLES, text):
                assert action.option_strings[0] == "--train-points", (name, action.option_strings)
            if action.help != argparse.SUPPRESS and text.startswith("sigma-point κ"):
                assert action.option_strings[0] == "--sigma-kappa", (name, action.option_strings)


@pytest.mark.parametrize("name,old,new,dest,value", [
    ("check", "--train", "--train-points", "train", "40"),
    ("reproduce ungm1d", "--train", "--train-points", "train", "40"),
    ("reproduce gpadf-scalar", "--kappa", "--sigma-kappa", "kappa", "0.5"),
])
def test_an_older_name_still_works_with_one_note_on_stderr(name, old, new, dest, value, capsys):
    parser = {n: p for n, p, _ in _parsers()}[name]
    required = REQUIRED.get(name, ["--out", "o"])
    before = getattr(parser.parse_args([*required, new, value]), dest)
    assert capsys.readouterr().err == ""
    after = getattr(parser.parse_args([*required, old, value]), dest)
    err = capsys.readouterr().err
    assert after == before == type(before)(value)
    assert err.count("\n") == 1 and f"{old} is deprecated" in err and new in err


def test_the_contract_command_of_ct2d_keeps_kappa_without_a_note(capsys):
    """CONTRACT.md's ``reproduce ct2d --kappa 300 --omega 0.0698 ...``: κ training samples, as before."""
    from gpfverify.papers.fusion import ct2d_contract as ct2d
    from gpfverify.contract.params import from_arguments

    opts = experiment_parser("ct2d").parse_args(["--kappa", "300", "--omega", "0.0698", "--runs", "20", "--seed", "1",
                                                 "--out", "o"])
    assert capsys.readouterr().err == ""
    assert from_arguments(ct2d.Params, opts) == ct2d.Params(kappa=300, omega=0.0698)
    opts = experiment_parser("ct2d").parse_args(["--train-points", "60", "--out", "o"])
    assert from_arguments(ct2d.Params, opts).kappa == 60


def test_a_value_out_of_bounds_is_named_by_the_option_the_user_typed():
    with pytest.raises(InputError, match="--train-points must be at least 3"):
        Ungm1dParams(train=2)


@pytest.mark.parametrize("argv", [["reproduce"], []], ids=["reproduce", "no command"])
def test_a_missing_name_is_one_line_listing_the_choices(argv, capsys):
    code, out, err = _run(argv, capsys)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    names = sorted(EXPERIMENTS) if argv else list(COMMANDS)
    assert all(n in err for n in names), err


@pytest.mark.parametrize("suffix", [".jsonl", ".npz"])
def test_check_names_the_measurement_format_when_given_another_file(tmp_path, capsys, suffix):
    path = tmp_path / f"run{suffix}"
    path.write_text('{"central": {}}\n')
    code, out, err = _run(["check", REDUNDANT, "--measurements", str(path), "--json"], capsys)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert "MEASUREMENTS.npz: y (T, " in err and "optional truth x" in err and "zip" not in err.split(";")[-1]
    if suffix == ".jsonl":
        assert "gpfverify audit" in err and "File is not a zip file" not in err
