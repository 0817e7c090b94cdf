"""Missing and asynchronous measurements: a sensor that drops out, joins late or reports at a lower
rate has NaN in its whole block of y at those steps (or False in run_fusion's ``reported`` mask).

Oracles: the Gaussian update with missing outputs equals the update on the outputs that reported
(the Kalman filter on the sub-model, to rounding); CMF over a run with drop-outs equals a Kalman
filter written here that stacks, step by step, only the sensors that reported; DMF equals CMF
where every reporting sensor keeps full column rank (Proposition 1 over the sensors present); the
baselines fuse the reporting sensors' posteriors alone; the batched route equals the one-run route;
a fusion case with a sensor that did not report keeps its form through JSON Lines and npz run files
and the audit judges the rank condition over the sensors present. From the command line: a
measurements file with drop-outs and a late-joining sensor is checked and its run file audited;
a NaN where none is allowed (part of a block, the truth) is one line naming the row, the sensor and
the output."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from gpfverify.audit.runfile import load_run, write_run
from gpfverify.cli import main
from gpfverify.errors import InputError
from gpfverify.filters.families import gaussian_family
from gpfverify.filters.records import Gaussian
from gpfverify.fusion.convex import convex_combination
from gpfverify.model_fusion import run_fusion, run_fusion_batch
from gpfverify.models import Sensor, StateSpaceModel, linear_model
from gpfverify.scenarios.three_sensor import three_sensor_model
from gpfverify.tolerances import PER_RUN_RTOL, algebra_rtol

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "fixtures" / "robot"))
from unicycle import NAMES, unicycle  # noqa: E402

TRACKER = f"{ROOT / 'examples' / 'three_sensor_system.py'}:tracker"


def _linear_system() -> StateSpaceModel:
    """A constant-velocity target in the plane with a position fix, a velocity sensor and a sensor of
    the sum of the positions: every sensor's C_xy of full column rank."""
    F = np.kron(np.eye(2), [[1.0, 1.0], [0.0, 1.0]])
    Q = np.kron(np.eye(2), 0.05 * np.array([[1 / 3, 1 / 2], [1 / 2, 1.0]]))
    H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0], [1.0, 0, 1.0, 0]])
    R = np.diag([4.0, 4.0, 0.5, 0.5, 2.0])
    return linear_model(F, H, Q, R, np.array([0.0, 1.0, 0.0, 1.0]), np.diag([25.0, 1.0, 25.0, 1.0]), sizes=(2, 2, 1))


def _with_gaps(ys: np.ndarray, model) -> np.ndarray:
    """Sensor 1 joins at step 5, sensor 0 drops out at steps 8–9, sensor 2 reports every other step."""
    ys = ys.copy()
    blocks = model.blocks
    ys[:4, blocks[1]] = np.nan
    ys[7:9, blocks[0]] = np.nan
    ys[1::2, blocks[2]] = np.nan
    return ys


def _kalman_over_reports(model, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The Kalman filter written here: at each step the stack of the rows that reported."""
    F, H = model.linear_matrices()
    R = model.R
    mean, cov = model.prior_mean.copy(), model.prior_cov.copy()
    means, covs = [], []
    for y in ys:
        mean, cov = F @ mean, F @ cov @ F.T + model.Q
        rows = ~np.isnan(y)
        Hr, Rr = H[rows], R[np.ix_(rows, rows)]
        S = Hr @ cov @ Hr.T + Rr
        K = np.linalg.solve(S, Hr @ cov).T
        mean = mean + K @ (y[rows] - Hr @ mean)
        cov = cov - K @ S @ K.T
        means.append(mean)
        covs.append(cov)
    return np.array(means), np.array(covs)


def _assert_close(a, b, scale, condition=1.0):
    np.testing.assert_allclose(a, b, rtol=0, atol=algebra_rtol(condition) * scale)


# -- the update and the filters ----------------------------------------------------------------------------

@pytest.mark.parametrize("family", ["kf", "ekf", "ukf"])
def test_an_update_with_missing_outputs_is_the_update_on_those_that_reported(family):
    model = three_sensor_model() if family != "kf" else _linear_system()
    _, ys = model.simulate(2, np.random.default_rng(1))
    step = gaussian_family(family).step
    belief = Gaussian(model.prior_mean, model.prior_cov)
    y = ys[0].copy()
    y[model.blocks[1]] = np.nan
    full = step(belief, model, y)
    alone = step(belief, model.with_sensors([0, 2]), y[~np.isnan(y)])
    scale = np.abs(alone.mu_e).max() + np.sqrt(np.abs(alone.C_e).max())
    _assert_close(full.mu_e, alone.mu_e, scale, np.linalg.cond(alone.C_e))
    _assert_close(full.C_e, alone.C_e, np.abs(alone.C_e).max(), np.linalg.cond(alone.C_e))
    np.testing.assert_array_equal(full.C_y, step(belief, model, ys[0]).C_y)  # the record keeps every output
    nothing = step(belief, model, np.full_like(y, np.nan))
    np.testing.assert_array_equal(nothing.mu_e, nothing.mu_p)
    np.testing.assert_array_equal(nothing.C_e, nothing.C_p)


def test_cmf_and_dmf_over_drop_outs_equal_the_kalman_filter_of_the_sensors_that_reported():
    model = _linear_system()
    _, ys = model.simulate(12, np.random.default_rng(2))
    ys = _with_gaps(ys, model)
    fused = run_fusion(model, ys, family="kf", methods=("cmf", "dmf", "cc"))
    means, covs = _kalman_over_reports(model, ys)
    scale = np.abs(means).max() + np.sqrt(np.abs(covs).max())
    cond = max(np.linalg.cond(c) for c in covs)
    for method in ("cmf", "dmf"):  # every sensor keeps full column rank: DMF is CMF (Proposition 1)
        _assert_close(fused.means(method), means, scale, cond)
    for t, step in enumerate(fused.steps):
        here = ~np.isnan(ys[t])
        reported = [bool(here[b].all()) for b in model.blocks]
        assert list(step.audit.missing) == [m for m, r in enumerate(reported) if not r]
        assert [s.index for s in step.audit.sensors] == [m for m, r in enumerate(reported) if r]
        assert step.audit.condition_holds and step.audit.exact and step.audit.reproduced
        alone = convex_combination([step.local[m].posterior for m in range(3) if reported[m]])
        np.testing.assert_array_equal(step.estimate("cc").mean, alone.mean)
        for m in range(3):  # a sensor that did not report only predicts
            if not reported[m]:
                np.testing.assert_array_equal(step.local[m].mu_e, step.local[m].mu_p)


def test_the_mask_is_the_nan_blocks_and_a_nan_elsewhere_is_refused_naming_row_sensor_and_output():
    model = _linear_system()
    _, ys = model.simulate(6, np.random.default_rng(3))
    gaps = _with_gaps(ys, model)
    mask = np.stack([~np.isnan(gaps[:, b]).all(axis=1) for b in model.blocks], axis=1)
    by_nan = run_fusion(model, gaps, family="kf", methods=("cmf", "dmf"))
    by_mask = run_fusion(model, ys, family="kf", methods=("cmf", "dmf"), reported=mask)
    np.testing.assert_array_equal(by_nan.means("dmf"), by_mask.means("dmf"))
    part = ys.copy()
    part[3, 3] = np.nan
    with pytest.raises(InputError, match=r"ys row 3, sensor 1 output 1 is NaN, but not the sensor's whole block"):
        run_fusion(model, part, family="kf")
    silent = ys.copy()
    silent[2] = np.nan
    with pytest.raises(InputError, match="ys row 2: no sensor reported"):
        run_fusion(model, silent, family="kf")


def test_the_batched_route_equals_each_run_alone():
    model = three_sensor_model()
    ys = np.stack([_with_gaps(model.simulate(10, np.random.default_rng(s))[1], model) for s in range(3)])
    ys[2] = model.simulate(10, np.random.default_rng(9))[1]  # a run where every sensor reports
    methods = ("cmf", "dmf", "cc", "ci", "rcc-ci")
    batched = run_fusion_batch(model, ys, methods=methods)
    for b in range(3):
        alone = run_fusion(model, ys[b], methods=methods)
        for method in methods:
            np.testing.assert_allclose(batched[b].means(method), alone.means(method), rtol=PER_RUN_RTOL,
                                       atol=PER_RUN_RTOL * np.abs(alone.means(method)).max())
        assert [s.audit.missing for s in batched[b].steps] == [s.audit.missing for s in alone.steps]


def test_the_rank_condition_is_judged_over_the_sensors_that_reported():
    """The robot's 8-output sensor never has full column rank; at the steps where it did not report
    the condition holds (every sensor that did keeps full rank), elsewhere it fails."""
    model = unicycle(sensors=("compass 1", "beacon", "gps", "eight"))
    _, ys = model.simulate(6, np.random.default_rng(4))
    ys[2:4, model.blocks[3]] = np.nan
    fused = run_fusion(model, ys, methods=("cmf", "dmf"))
    held = [s.audit.condition_holds for s in fused.steps]
    assert held == [False, False, True, True, False, False]


# -- run files and the audit ------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["run.jsonl", "run.npz"])
def test_a_step_with_a_sensor_that_did_not_report_keeps_its_form_in_a_run_file(tmp_path, name, capsys):
    model = three_sensor_model()
    _, ys = model.simulate(8, np.random.default_rng(5))
    ys = _with_gaps(ys, model)
    fused = run_fusion(model, ys, methods=("cmf", "dmf"))
    path = write_run(tmp_path / name, [s.dmf.case for s in fused.steps], [s.k for s in fused.steps])
    for (k, case), step in zip(load_run(path).steps, fused.steps):
        assert case.sensor_ids == step.dmf.case.sensor_ids and k == step.k
        np.testing.assert_array_equal(case.y, step.dmf.case.y)
    if name.endswith("jsonl"):
        first = json.loads(path.read_text().splitlines()[0])
        assert first["locals"][1] is None and first["y"][2:4] == [None, None]
    assert main(["audit", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["steps"][0]["missing_sensors"] == [1] and [s["index"] for s in out["steps"][0]["sensors"]] == [0, 2]
    summary = out["summary"]["sensors"]
    assert summary[1]["not_reported_steps"] == [1, 2, 3, 4] and summary[2]["not_reported_steps"] == [2, 4, 6, 8]


def test_a_run_file_whose_y_and_locals_disagree_is_refused(tmp_path, capsys):
    model = three_sensor_model()
    _, ys = model.simulate(2, np.random.default_rng(6))
    fused = run_fusion(model, _with_gaps(ys, model), methods=("cmf", "dmf"))
    path = write_run(tmp_path / "run.jsonl", [s.dmf.case for s in fused.steps])
    line = json.loads(path.read_text().splitlines()[0])
    line["y"][2] = 1.0  # a value in the block of sensor 1, whose report is null
    path.write_text(json.dumps(line) + "\n")
    assert main(["audit", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "y[2] (sensor 1's output 0) holds a value, but sensor 1 did not report" in err[0]


# -- the command line --------------------------------------------------------------------------------------

def _measurements(tmp_path, ys, truth=None) -> str:
    path = tmp_path / "m.npz"
    np.savez(path, y=ys, **({} if truth is None else {"x": truth}))
    return str(path)


def test_check_fuses_and_audits_drop_outs_and_a_late_joining_sensor_end_to_end(tmp_path, capsys):
    model = three_sensor_model()
    truth, ys = model.simulate(14, np.random.default_rng(7))
    ys = _with_gaps(ys, model)
    out = tmp_path / "out"
    assert main(["check", TRACKER, "--measurements", _measurements(tmp_path, ys, truth), "--methods",
                 "cmf,dmf,cc,ci", "--out", str(out)]) == 0
    line = capsys.readouterr().out
    assert "sensor 1 reported at 10 of 14, sensor 2 reported at 7 of 14" in line
    results = json.loads((out / "results.json").read_text())
    reported = np.array(results["reported"][0])
    np.testing.assert_array_equal(reported, np.stack([~np.isnan(ys[:, b]).all(axis=1) for b in model.blocks], 1))
    assert results["reproduced_steps"] == 14 and results["condition_held_steps"] == 14
    complete = int((~np.isnan(ys)).all(axis=1).sum())  # the NIS of CMF is tested where every output reported
    assert results["nis"]["local"][1]["steps"] == 10 and results["nis"]["cmf"]["steps"] == complete
    assert "Reports per step" in (out / "README.md").read_text(encoding="utf-8")
    assert main(["audit", str(out / "run.jsonl")]) == 0
    assert "sensor 1 did not report at k = 1-4" in capsys.readouterr().out


@pytest.mark.parametrize("where, message", [
    ("part", "m.npz: y row 5, sensor 1 output 1 is NaN, but not the sensor's whole block"),
    ("truth", "m.npz: x row 3, state component 2 is NaN"),
    ("silent", "m.npz: y row 6: no sensor reported"),
])
def test_a_nan_where_none_is_allowed_is_one_line_naming_row_sensor_and_output(tmp_path, capsys, where, message):
    model = three_sensor_model()
    truth, ys = model.simulate(8, np.random.default_rng(8))
    if where == "part":
        ys[5, 3] = np.nan
    elif where == "truth":
        truth[3, 2] = np.nan
    else:
        ys[6] = np.nan
    assert main(["check", TRACKER, "--measurements", _measurements(tmp_path, ys, truth), "--json"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1 and message in err


def test_a_model_that_returns_nan_is_not_read_as_a_missing_measurement():
    sensor = Sensor(lambda x: np.where(x[:, :1] > 3.0, np.nan, x[:, :1]), [[1.0]], name="clipped")
    model = StateSpaceModel(np.eye(1), [[0.1]], [sensor], [0.0], [[1.0]])
    with pytest.raises(InputError, match=r"sensor 0 \(clipped\) measure returned NaN at step k=1 \(output 0, for row"):
        gaussian_family("ukf").step(Gaussian(np.array([5.0]), np.eye(1)), model, np.array([1.0]))
