"""``gpfverify check`` on users' systems, against independent routes:

* a linear-Gaussian system: CMF and DMF equal a hand-written Kalman filter on the stacked
  measurement (the exact answer) at every step;
* a sensor with more outputs than states: the rank condition fails at every step, the inexact steps
  are found, and the repaired DMF equals CMF;
* logged measurements (``--measurements``), the ``--json`` keys of the contract, and bad systems
  (exit 2, one line, nothing written).
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gpfverify.experiments import check
from gpfverify.tolerances import algebra_rtol

ROOT = Path(__file__).resolve().parents[1]
TRACKER = f"{ROOT / 'examples' / 'three_sensor_system.py'}:tracker"
REDUNDANT = f"{ROOT / 'examples' / 'redundant_sensor_system.py'}:system"

LINEAR_SYSTEM = '''
import numpy as np
from gpfverify.models import linear_model
F = np.array([[1.0, 1.0], [0.0, 0.95]])
H = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
Q = np.array([[0.2, 0.05], [0.05, 0.1]])
R = np.diag([0.5, 0.3, 0.4])
system = linear_model(F, H, Q, R, prior_mean=[1.0, 0.5], prior_cov=np.eye(2), sizes=(2, 1))
'''


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "gpfverify", "check", *map(str, args)],
                          capture_output=True, text=True, cwd=cwd)


def _hand_kalman(system, ys):
    """The textbook KF on the stacked measurement (explicit inverses: an independent route)."""
    F, H = system.linear_matrices()
    mean, cov, means = system.prior_mean, system.prior_cov, []
    for y in ys:
        mean, cov = F @ mean, F @ cov @ F.T + system.Q
        S = H @ cov @ H.T + system.R
        K = cov @ H.T @ np.linalg.inv(S)
        mean, cov = mean + K @ (y - H @ mean), cov - K @ S @ K.T
        means.append(mean)
    return np.array(means)


@pytest.mark.parametrize("family", ["ekf", "ukf"])
def test_cmf_and_dmf_equal_the_kalman_filter_on_a_linear_system(tmp_path, family):
    path = tmp_path / "linear.py"
    path.write_text(LINEAR_SYSTEM)
    params = check.params_for(f"{path}:system", filter=family, steps=25, methods=("cmf", "dmf"))
    record = check.run_one(params, np.random.SeedSequence(4))
    system = check.load_system(params.system)
    data_stream = np.random.SeedSequence(4).spawn(2)[0]  # the run draws its measurements from this child
    _, ys = system.simulate(25, np.random.default_rng(data_stream))
    exact = _hand_kalman(system, ys)
    rtol = algebra_rtol(1e4)
    for name in ("cmf", "dmf"):
        means = np.array([e["means"][name] for e in record.steps])
        np.testing.assert_allclose(means, exact, rtol=0, atol=rtol * np.abs(exact).max())
    assert all(e["condition_holds"] and e["exact"] for e in record.steps)


def test_a_sensor_with_more_outputs_than_states_is_found_and_repaired():
    params = check.params_for(REDUNDANT, steps=20, methods=("cmf", "dmf"))
    records = [check.run_one(params, s) for s in np.random.SeedSequence(2).spawn(2)]
    results = check.summarize(params, records)
    assert results["sensors"][1]["more_outputs_than_states"] and not results["sensors"][0]["more_outputs_than_states"]
    assert results["condition_held_steps"] == 0                      # l = 3 > D = 2: never full column rank
    inexact = [e for r in records for e in r.steps if not e["exact"]]
    assert inexact and results["exact_steps"] == results["total_steps"] - len(inexact)
    for e in inexact:
        assert e["gap_size"] > e["gap_bound"]                       # a real gap, not rounding (prior sd both)
        assert e["sensors"][1]["repair_dim"] == 1 and e["sensors"][0]["repair_dim"] == 0
        assert e["repaired_gap_size"] <= e["gap_bound"]             # the repair message restores CMF


def test_logged_measurements_with_and_without_truth(tmp_path):
    system = check.load_system(TRACKER)
    truth, ys = system.simulate(12, np.random.default_rng(5))
    np.savez(tmp_path / "run.npz", y=ys, x=truth)
    np.savez(tmp_path / "y_only.npz", y=ys)
    with_truth = json.loads(_cli(TRACKER, "--measurements", tmp_path / "run.npz", "--json").stdout)
    without = json.loads(_cli(TRACKER, "--measurements", tmp_path / "y_only.npz", "--json").stdout)
    assert with_truth["steps"] == without["steps"] == 12 and with_truth["runs"] == 1
    assert with_truth["params"]["steps"] == without["params"]["steps"] == 12  # the file's count, recorded once
    assert with_truth["truth_known"] and "rmse" in with_truth
    assert not without["truth_known"] and "rmse" not in without
    # the same measurements give the same fusion whether the truth is known or not
    assert with_truth["per_step"] == without["per_step"]


def test_json_has_the_contract_keys():
    out = _cli(TRACKER, "--steps", 6, "--runs", 2, "--json")
    assert out.returncode == 0, out.stderr
    results = json.loads(out.stdout)
    for key in ("steps", "runs", "filter", "per_step", "max_gap", "condition_held_steps", "exact_steps"):
        assert key in results
    assert results["steps"] == 6 and results["runs"] == 2 and results["filter"] == "ukf"
    assert len(results["per_step"]) == 6
    step = results["per_step"][0]
    assert {"k", "cmf_mean", "dmf_mean", "gap", "sensors"} <= set(step)
    np.testing.assert_array_equal(np.subtract(step["dmf_mean"], step["cmf_mean"]), step["gap"])
    assert {"index", "rank", "full_column_rank", "exact"} <= set(step["sensors"][0])
    assert results["exact_steps"] == results["condition_held_steps"] == 12  # every step of both runs


@pytest.mark.parametrize("source, spec, message", [
    (None, "missing.py:system", "no such file"),
    ("x = 1\n", "{path}:system", "defines no 'system'"),
    ("system = 42\n", "{path}:system", "is a int, not a gpfverify.models.StateSpaceModel"),
    ("raise RuntimeError('boom')\n", "{path}:system", "raised RuntimeError while loading: boom"),
    ("import numpy as np\nfrom gpfverify.models import Sensor, StateSpaceModel\n"
     "system = StateSpaceModel(np.eye(2), np.eye(2), [Sensor(lambda x: x[:, :1], np.eye(2))], [0, 0], np.eye(2))\n",
     "{path}:system", "sensor 0 measure returned shape"),
    ("import numpy as np\nfrom gpfverify.models import Sensor, StateSpaceModel\n"
     "def h(x):\n    raise ZeroDivisionError('no')\n"
     "system = StateSpaceModel(np.eye(2), np.eye(2), [Sensor(h, np.eye(1))], [0, 0], np.eye(2))\n",
     "{path}:system", "sensor 0 measure raised ZeroDivisionError"),
    (None, "{path}", "SYSTEM.py:NAME"),
])
def test_a_bad_system_exits_2_with_one_line_and_writes_nothing(tmp_path, source, spec, message):
    path = tmp_path / "system.py"
    if source is not None:
        path.write_text(source)
    out_dir = tmp_path / "out"
    result = _cli(spec.format(path=path), "--out", out_dir, cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and message in result.stderr, result.stderr
    assert "Traceback" not in result.stderr and not out_dir.exists()


def test_bad_measurement_files_exit_2(tmp_path):
    np.savez(tmp_path / "wrong.npz", y=np.zeros((5, 3)))
    (tmp_path / "junk.npz").write_text("not an npz")
    for name, message in (("wrong.npz", "y must have shape"), ("junk.npz", "is not an npz archive")):
        result = _cli(TRACKER, "--measurements", tmp_path / name, "--json")
        assert result.returncode == 2 and message in result.stderr and result.stderr.count("\n") == 1
    assert "--measurements expects a measurements file" in _cli(TRACKER, "--measurements", tmp_path / "wrong.npz",
                                                                "--json").stderr
    result = _cli(TRACKER, "--measurements", tmp_path / "wrong.npz", "--steps", "5", "--json")
    assert result.returncode == 2 and "leave out --steps" in result.stderr


def test_measurements_and_audit_run_files_are_told_apart(tmp_path):
    """An audit run file given to check --measurements, and a measurements file given to audit,
    are refused naming the format each command expected."""
    from gpfverify.audit.runfile import write_run
    from gpfverify.fusion.synthetic import random_case

    system = check.load_system(TRACKER)
    truth, ys = system.simulate(4, np.random.default_rng(5))
    np.savez(tmp_path / "measurements.npz", y=ys, x=truth)
    cases = [random_case(np.random.default_rng(k), 4, system.sizes) for k in range(3)]
    run = write_run(tmp_path / "run.npz", cases, list(range(3)))
    result = _cli(TRACKER, "--measurements", run, "--json")
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert "audit run file" in result.stderr and "--measurements expects a measurements file" in result.stderr
    audit = subprocess.run([sys.executable, "-m", "gpfverify", "audit", str(tmp_path / "measurements.npz")],
                           capture_output=True, text=True)
    assert audit.returncode == 2 and audit.stderr.count("\n") == 1
    assert "check --measurements" in audit.stderr and "run file of fusion cases" in audit.stderr


def test_the_rank_rule_is_unit_free_by_default_and_recorded():
    records = {}
    for rule in ("canonical", "numpy"):
        params = check.params_for(REDUNDANT, steps=6, methods=("cmf", "dmf"), rank_rule=rule)
        records[rule] = check.summarize(params, [check.run_one(params, np.random.SeedSequence(3))])
    assert records["canonical"]["rank_rule"]["name"] == "canonical"
    assert records["numpy"]["rank_rule"]["name"] == "numpy"
    correlations = np.array(records["canonical"]["min_canonical_correlation"], dtype=float)  # (R, T, N)
    assert np.all((correlations >= 0) & (correlations <= 1))
    with pytest.raises(check.InputError, match="unknown rank rule"):
        check.params_for(REDUNDANT, rank_rule="sigma-max")


def test_the_ci_criterion_is_chosen_recorded_and_applied(tmp_path):
    """--ci-criterion det reaches CI: recorded in results.json, CI's estimate at every step is the
    determinant-optimal CI of that step's local posteriors (as saved in the run), not the
    trace-optimal one, and the page names the criterion."""
    from gpfverify.filters.records import Gaussian
    from gpfverify.fusion.ci import covariance_intersection

    proc = _cli(TRACKER, "--steps", 3, "--methods", "cmf,dmf,ci", "--ci-criterion", "det", "--out", tmp_path / "o")
    assert proc.returncode == 0, proc.stderr
    results = json.loads((tmp_path / "o" / "results.json").read_text(encoding="utf-8"))
    assert results["params"]["ci_criterion"] == "det"
    run = json.loads(next((tmp_path / "o" / "runs").glob("run-*.json")).read_text(encoding="utf-8"))
    for step in run["result"]["steps"]:
        local = [Gaussian(np.array(mu), np.array(report["C_e"]))
                 for mu, report in zip(step["local_means"], step["case"]["locals"])]
        det, trace = (covariance_intersection(local, c).mean for c in ("det", "trace"))
        np.testing.assert_allclose(step["means"]["ci"], det, rtol=0, atol=algebra_rtol() * np.abs(det).max())
        assert np.abs(det - trace).max() > 1e3 * algebra_rtol() * np.abs(det).max()
    assert "determinant criterion" in (tmp_path / "o" / "README.md").read_text(encoding="utf-8")
