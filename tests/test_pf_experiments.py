"""The pff1d and bearing experiments (Zhou et al. 2020): typed parameters and records, the
results.json keys the CONTRACT names, curves of length T, deterministic per seed, the paired
decision rule of their claims."""

import json
from typing import Any

import numpy as np
import pytest

from gpfverify.cli import main
from gpfverify.papers.particle_flow import pff1d_contract as pff_contract
from gpfverify.contract.claims import read_claims
from gpfverify.papers.particle_flow.contract import EDH, IE_PFF, PF, Variant
from gpfverify.contract.serial import from_json, to_json
from gpfverify.errors import InputError
from gpfverify.papers import EXPERIMENTS
from gpfverify.papers.particle_flow import bearing_experiment as bearing
from gpfverify.papers.particle_flow import pff1d_experiment as pff1d
from gpfverify.papers.particle_flow.methods import paired_comparison
from gpfverify.experiments.runner import run_experiment
from gpfverify.papers.particle_flow.bearing_scenario import INITIAL_STATE, SENSOR
from gpfverify.papers.particle_flow.pff1d_scenario import GAMMA_PRIOR, UNGM_PRIOR

#: a spacing that does not exist (typed Any: the point is that validation rejects it)
LINEAR: Any = "linear"

TINY_PFF = pff1d.Params(steps=6, particles=20, table_q=(1.0,), table_r=(1.0,), dlambda=(0.1,), gamma_r=(0.1,),
                        gamma_dlambda=0.1)


def _round_trip(tp, value):
    return from_json(tp, json.loads(json.dumps(to_json(value))))


def test_pff1d_writes_the_contract_keys(tmp_path):
    first = run_experiment(pff1d, TINY_PFF, 2, 3, tmp_path / "a", show_progress=False)
    again = run_experiment(pff1d, TINY_PFF, 2, 3, tmp_path / "b", show_progress=False)
    assert EXPERIMENTS["pff1d"] == pff1d.__name__
    assert set(first["rmse"]) == {"PF", "UPF", "EDH", "IE-PFF"}
    assert set(first["time_per_run"]) == {"PF", "UPF", "EDH", "IE-PFF"}
    assert all(len(curve) == 6 for curve in first["rmse"].values())
    assert first["rmse"] == again["rmse"] and first["table1"][0]["method"] == "PF"
    assert first["claims"] == again["claims"]
    assert json.loads((tmp_path / "a" / "results.json").read_text())["experiment"] == "pff1d"
    # the typed summary records read the file back; the main gamma case is a cell of the grid
    rows = pff_contract.table1_rows(first)
    assert [r.variant for r in rows] == [Variant(PF), Variant(EDH, 0.1, "uniform"), Variant(EDH, 0.1, "exponential"),
                                         Variant(IE_PFF, 0.1, "uniform"), Variant(IE_PFF, 0.1, "exponential")]
    gamma = pff_contract.gamma_entries(first)["0.1"]
    assert gamma[Variant(IE_PFF, 0.1, "uniform").label].rmse == tuple(first["rmse"]["IE-PFF"])
    # one gamma R: the two claims that compare small and large R cannot be decided
    verdicts = {c.id: c.verdict for c in read_claims(first)}
    assert verdicts["pff1d/gamma-small-r-upf-and-ie-pff-best"] == "not decidable"
    assert all(c.paper_n == 30 and c.n == 2 and c.paper == "seed003" for c in read_claims(first))


def test_bearing_writes_the_contract_keys_and_wraps_bearings(tmp_path):
    res = run_experiment(bearing, bearing.Params(duration=30), 2, 1, tmp_path, show_progress=False)
    assert set(res["rmse"]) == {"PF-N50", "PF-N200", "IE-PFF-N50", "IE-PFF-N200"} == set(res["time_per_run"])
    assert set(res["large_noise"]["rmse"]) == {"PF-N50", "PF-N200", "IE-PFF-N50"}
    # the target crosses the ±π bearing cut near t = 15 s; without wrapped residuals the flow
    # loses it by far more than the initial target–sensor distance
    scene = np.linalg.norm(INITIAL_STATE[[0, 2]] - SENSOR)
    assert all(np.all(np.isfinite(c)) and max(c) < scene for c in res["rmse"].values())
    claims = {c.id.removeprefix("bearing/"): c for c in read_claims(res)}
    assert {k for k, c in claims.items() if c.timing} == {"ie-pff-faster-same-n", "ie-pff-faster-than-larger-pf"}
    assert len(claims) == 7 and all(c.paper_n == 200 and c.n == 2 and c.quote and not c.needs
                                    for c in claims.values())
    # the time claim: the geometric mean of the paired per-run CPU-time ratios, against 1
    seconds = [json.loads(path.read_text())["result"]["filters"] for path in sorted((tmp_path / "runs").glob("*.json"))]
    log_ratio = np.log([s["IE-PFF-N50"]["seconds"] / s["PF-N200"]["seconds"] for s in seconds])
    atol = 5.0 * log_ratio.std(ddof=1) / np.sqrt(log_ratio.size)
    faster = claims["ie-pff-faster-than-larger-pf"]
    assert faster.statistic == pytest.approx(np.exp(log_ratio.mean())) and faster.threshold == 1.0
    assert faster.verdict == ("held" if log_ratio.mean() < -atol else "NOT held" if log_ratio.mean() > atol
                              else "undecided")


def test_params_and_records_round_trip_through_json_text():
    for params in (TINY_PFF, pff1d.Params(), *(s.params for p in pff1d.PROFILES.values() for s in p.settings)):
        assert type(params).from_json(json.loads(json.dumps(params.to_json()))) == params
    for params in (bearing.Params(), bearing.Params(spacing="exponential", pf_small=10, omega_deg=-3.0)):
        assert bearing.Params.from_json(json.loads(json.dumps(params.to_json()))) == params
    seed = np.random.SeedSequence(5)
    record = pff1d.run_one(TINY_PFF, seed)
    assert _round_trip(pff1d.RunRecord, record) == record
    brg = bearing.run_one(bearing.Params(duration=4), seed)
    assert _round_trip(bearing.RunRecord, brg) == brg
    assert set(brg.filters) == {"PF-N50", "PF-N200", "IE-PFF-N50", "IE-PFF-N200"}
    assert set(brg.large_noise) == {"PF-N50", "PF-N200", "IE-PFF-N50"}


def test_defaults_are_the_papers_and_the_scenarios():
    p, b = pff1d.Params(), bearing.Params()
    assert (p.particles, p.steps, pff1d.DEFAULT_RUNS, bearing.DEFAULT_RUNS) == (50, 50, 30, 200)
    assert (p.ungm_prior.mean, p.ungm_prior.var) == UNGM_PRIOR
    assert (p.gamma_prior.mean, p.gamma_prior.var) == GAMMA_PRIOR
    assert b.initial_state == tuple(INITIAL_STATE)
    assert [f.key for f in b.filters] == ["PF-N50", "PF-N200", "IE-PFF-N50", "IE-PFF-N200"]
    assert pff1d.PROFILES["full"].runs == 30 and bearing.PROFILES["full"].runs == 200
    assert pff1d.PROFILES["full"].settings[0].params == pff1d.Params()


@pytest.mark.parametrize("make, message", [
    (lambda: pff1d.Params(particles=1), "--particles must be at least 2"),
    (lambda: pff1d.Params(gamma_main_r=0.5), "--gamma-main-r 0.5 must be one of --gamma-r"),
    (lambda: pff1d.Params(dlambda=(0.1, 0.0)), "--dlambda must be greater than 0"),
    (lambda: pff1d.Params(table_q=()), "--table-q needs at least one value"),
    (lambda: pff1d.Params(spacings=("uniform", LINEAR)), r"--spacings\[1\] must be one of"),
    (lambda: pff1d.Params().replace(steps=0), "--steps must be at least 1"),
    (lambda: bearing.Params(pf_small=200), "--pf-small and --pf-large must differ"),
    (lambda: bearing.Params(dlambda=2.0), "--dlambda must be at most 1"),
    (lambda: bearing.Params(bearing_std=0.0), "--bearing-std must be greater than 0"),
    (lambda: bearing.Params(spacing=LINEAR), "--spacing must be one of"),
])
def test_invalid_params_name_the_option(make, message):
    with pytest.raises(InputError, match=message):
        make()


@pytest.mark.parametrize("name, options", [
    ("pff1d", ("--particles", "--steps", "--gamma-main-r", "--gamma-dlambda", "--gamma-shape", "--exponential-ratio")),
    ("bearing", ("--q-pos", "--q-vel", "--bearing-std", "--omega-deg", "--switch-time", "--duration", "--dlambda",
                 "--spacing", "--pf-small", "--pf-large", "--flow-particles")),
])
def test_reproduce_help_lists_the_generated_options(capsys, name, options):
    with pytest.raises(SystemExit) as exit_info:
        main(["reproduce", name, "--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert all(option in out for option in options)


def test_command_line_errors_name_the_option(tmp_path, capsys):
    assert main(["reproduce", "bearing", "--pf-large", "50", "--out", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--pf-large" in err[0]
    assert not (tmp_path / "bad").exists()


def test_paired_comparison_decides_by_the_paired_t_test():
    rng = np.random.default_rng(0)
    worse = list(rng.normal(5.0, 1.0, 30))
    level = 0.05
    assert paired_comparison([w - 1.0 + 0.01 * rng.normal() for w in worse], worse, level).verdict == "held"
    assert paired_comparison([w + 1.0 + 0.01 * rng.normal() for w in worse], worse, level).verdict == "NOT held"
    assert paired_comparison([w + rng.normal() for w in worse], worse, level).verdict == "undecided"
    # a divergence where the competitor stayed finite loses the claim, whatever the other runs say
    lost = paired_comparison([None] + [w - 1.0 for w in worse[1:]], worse, level)
    assert lost.verdict == "NOT held" and lost.lost == 1 and lost.t is None
    assert paired_comparison([None, None], [None, 1.0], level).verdict == "NOT held"
    # the statistic is the t statistic, compared with the Student quantile of n − 1 degrees of freedom
    better = [w - 0.5 + rng.normal() for w in worse]
    c = paired_comparison(better, worse, level)
    d = np.subtract(better, worse)
    assert c.t == pytest.approx(d.mean() / (d.std(ddof=1) / np.sqrt(30)))
    assert c.critical == pytest.approx(2.0452, abs=1e-4)  # t₀.₉₇₅ with 29 degrees of freedom (tables)


def test_the_command_line_keeps_the_grid_options():
    import argparse

    from gpfverify.contract.params import add_arguments, from_arguments

    parser = argparse.ArgumentParser()
    add_arguments(parser, pff1d.Params)
    args = parser.parse_args(["--table-q", "0.1", "10", "--table-r", "1", "--dlambda", "0.1", "0.01",
                              "--spacings", "exponential", "--gamma-r", "0.1"])
    assert from_arguments(pff1d.Params, args) == pff1d.Params(table_q=(0.1, 10.0), table_r=(1.0,), dlambda=(0.1, 0.01),
                                                              spacings=("exponential",), gamma_r=(0.1,))
