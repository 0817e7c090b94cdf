"""The pff1d and bearing experiments end to end on tiny settings: the results.json keys the
CONTRACT names, curves of length T, deterministic per seed."""

import json

import numpy as np

from gpfverify.experiments import EXPERIMENTS, bearing, pff1d
from gpfverify.experiments.runner import run_experiment
from gpfverify.scenarios.bearing import INITIAL_STATE, SENSOR


def _params(module, argv):
    import argparse

    parser = argparse.ArgumentParser()
    module.add_arguments(parser)
    return module.params_from_args(parser.parse_args(argv))


def test_pff1d_writes_the_contract_keys(tmp_path):
    params = _params(pff1d, ["--steps", "6", "--particles", "20", "--table-q", "1", "--table-r", "1",
                             "--dlambda", "0.1", "--gamma-r", "0.1", "--gamma-dlambda", "0.1"])
    first = run_experiment(pff1d, params, 2, 3, tmp_path / "a", show_progress=False)
    again = run_experiment(pff1d, params, 2, 3, tmp_path / "b", show_progress=False)
    assert EXPERIMENTS["pff1d"] == pff1d.__name__
    assert set(first["rmse"]) == {"PF", "UPF", "EDH", "IE-PFF"}
    assert set(first["time_per_run"]) == {"PF", "UPF", "EDH", "IE-PFF"}
    assert all(len(curve) == 6 for curve in first["rmse"].values())
    assert first["rmse"] == again["rmse"] and first["table1"][0]["method"] == "PF"
    assert json.loads((tmp_path / "a" / "results.json").read_text())["experiment"] == "pff1d"


def test_bearing_writes_the_contract_keys_and_wraps_bearings(tmp_path):
    params = _params(bearing, ["--duration", "30"])
    res = run_experiment(bearing, params, 2, 1, tmp_path, show_progress=False)
    assert set(res["rmse"]) == {"PF-N50", "PF-N200", "IE-PFF-N50"} == set(res["time_per_run"])
    # the target crosses the ±π bearing cut near t = 15 s; without wrapped residuals the flow
    # loses it by far more than the initial target–sensor distance
    scene = np.linalg.norm(INITIAL_STATE[[0, 2]] - SENSOR)
    assert all(np.all(np.isfinite(c)) and max(c) < scene for c in res["rmse"].values())
