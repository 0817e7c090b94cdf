"""The example files the docs use (examples/make_example_files.py wrote them) are what they say:
a measurements file check reads, an audit run file of five steps and its first step as a case."""

import json
from pathlib import Path

import numpy as np

from gpfverify.audit.case import audit_case
from gpfverify.experiments import check
from gpfverify.fusion.caseblock import load_case
from gpfverify.fusion.centralized import cmf_update
from gpfverify.audit.runfile import load_run
from gpfverify.tolerances import algebra_rtol

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
TRACKER = f"{EXAMPLES / 'three_sensor_system.py'}:tracker"


def test_the_measurements_file_is_read_by_check_with_its_truth():
    system = check.load_system(TRACKER)
    truth, ys = check.logged_measurements(str(EXAMPLES / "tracker-measurements.npz"), system)
    assert ys.shape == (20, system.measurement_dim) and truth is not None and truth.shape == (20, system.state_dim)


def test_the_case_file_is_the_run_files_first_step():
    run = load_run(EXAMPLES / "tracker-run.jsonl")
    assert len(run) == 5 and run.ks == [1, 2, 3, 4, 5]
    first_line = json.loads((EXAMPLES / "tracker-run.jsonl").read_text().splitlines()[0])
    case_json = json.loads((EXAMPLES / "tracker-case.json").read_text())
    assert {k: v for k, v in first_line.items() if k != "k"} == case_json
    case = load_case(EXAMPLES / "tracker-case.json")
    # the tracker's sensors keep full column rank, so DMF reproduces CMF (independent route: cmf_update)
    audit = audit_case(case)
    assert audit.condition_holds and audit.exact
    cmf = cmf_update(case.central, case.y)
    scale = np.sqrt(np.diag(case.central.C_p))
    np.testing.assert_allclose(audit.dmf_mean / scale, np.asarray(cmf.mean) / scale, rtol=0,
                               atol=algebra_rtol(np.linalg.cond(case.central.C_y)) * np.abs(cmf.mean / scale).max())
