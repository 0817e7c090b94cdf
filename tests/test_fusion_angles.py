"""Angle outputs in fusion (case key ``circular``): CMF, eq. 35 and the exactness terms wrap them.

Routes: (a) the reference three-sensor tracker, whose bearing crosses ±π, run through
:func:`run_fusion` — DMF against CMF computed by the filter family's own update from the same
belief, and the whole run against the same run in a frame rotated by π (where the bearing never
meets the cut), so the wrapping is right and not merely self-consistent; dropping ``circular``
gives an answer off by far more than rounding. (b) case files with ``circular``: round trip,
validation, and the ``audit``/``fuse`` commands. (c) a constructed case with a branch offset:
the audit's predicted gap (with its 2π term) equals the observed DMF − CMF gap, which is checked
against 2π G e_j with G from an independent solve.
"""

import dataclasses
import json

import numpy as np
import pytest

from gpfverify.angles import difference, wrap
from gpfverify.audit.case import audit_case, audit_to_dict
from gpfverify.cli import main
from gpfverify.errors import CaseFileError, InputError
from gpfverify.filters.records import Gaussian
from gpfverify.fusion.case import FusionCase, case_to_dict
from gpfverify.fusion.caseblock import case_from_dict, load_case
from gpfverify.fusion.centralized import cmf_update
from gpfverify.fusion.distributed import dmf_update
from gpfverify.fusion.exactness import branch_offsets, equivalence_tolerance
from gpfverify.model_fusion import cmf_step, run_fusion
from gpfverify.fusion.synthetic import random_case
from gpfverify.models import Sensor
from gpfverify.scenarios.three_sensor import SENSOR_RANGE_BEARING, range_bearing, three_sensor_model
from gpfverify.tolerances import algebra_rtol

STEPS = 20
BEARING = 3  # stacked index of sensor 1's bearing


def _state_tolerance(case: FusionCase) -> float:
    """The step's rounding bound (prior standard deviations) in state units: ‖L_p⁻¹δ‖ ≤ b gives
    ‖δ‖ ≤ ‖L_p‖ b."""
    dmf = dmf_update(case)
    return equivalence_tolerance(case, dmf.gain, dmf.sensors) * float(np.sqrt(np.linalg.eigvalsh(case.central.C_p)[-1]))


def _tolerance(dmf_step) -> float:
    return _state_tolerance(dmf_step.case)


def _recursion_tolerance(dmf_step) -> float:
    """Two recursions (or two frames) that each round on their own drift apart step by step, and the
    EKF's Jacobians follow the rounded means: exact-algebra agreement at the central C_y's
    condition, relative to the means' size."""
    c = dmf_step.case.central
    return algebra_rtol(np.linalg.cond(c.C_y)) * (np.linalg.norm(c.mu_p) + np.linalg.norm(dmf_step.record.mu_e))


def _rotated(model, phi):
    """The same system with the bearing measured from a frame rotated by ``phi``: atan2 + φ (not
    wrapped by the sensor function; the filters handle the angle)."""
    base = range_bearing(SENSOR_RANGE_BEARING)

    def measure(x):
        out = base(x)
        out[:, 1] += phi
        return out

    old = model.sensors[1]
    sensor = Sensor(measure, old.noise_cov, circular=old.circular, name="range-bearing rotated")
    return dataclasses.replace(model, sensors=(model.sensors[0], sensor, model.sensors[2]))


@pytest.fixture(scope="module")
def tracker():
    model = three_sensor_model()
    _, ys = model.simulate(STEPS, np.random.default_rng(0))
    return model, ys


def test_the_reference_run_crosses_the_cut(tracker):
    model, ys = tracker
    assert model.circular == (BEARING,)
    jumps = np.flatnonzero(np.abs(np.diff(ys[:, BEARING])) > np.pi)
    assert jumps.size == 1 and 8 <= jumps[0] + 1 <= 12


@pytest.mark.parametrize("family", ["ukf", "ekf"])
def test_dmf_equals_cmf_across_the_cut(tracker, family):
    model, ys = tracker
    run = run_fusion(model, ys, family=family, methods=("cmf", "dmf"))
    belief = Gaussian(model.prior_mean, model.prior_cov)
    for step in run.steps:
        assert step.dmf.result.condition_holds and step.dmf.result.exact
        tol = _tolerance(step.dmf)
        # CMF by the family's own update from the belief DMF started from
        same_start = cmf_step(belief, model, ys[step.k - 1], k=step.k, family=family)
        np.testing.assert_allclose(step.dmf.record.mu_e, same_start.mu_e, rtol=0, atol=tol)
        np.testing.assert_allclose(step.dmf.record.C_e, same_start.C_e, rtol=0,
                                   atol=tol * np.abs(same_start.C_e).max())
        # the two recursions stay together, and the audit sees no gap
        np.testing.assert_allclose(step.dmf.record.mu_e, step.cmf.mu_e, rtol=0, atol=_recursion_tolerance(step.dmf))
        assert np.linalg.norm(step.audit.gap) <= tol and not any(s.branch_offsets.any() for s in step.audit.sensors)
        belief = step.dmf.record.posterior


@pytest.mark.parametrize("family", ["ukf", "ekf"])
def test_a_rotated_bearing_frame_gives_the_same_posteriors(tracker, family):
    model, ys = tracker
    rotated_ys = ys.copy()
    rotated_ys[:, BEARING] = wrap(ys[:, BEARING] + np.pi)
    assert np.all(np.abs(rotated_ys[:, BEARING]) < np.pi / 2)  # never near the cut in that frame
    run = run_fusion(model, ys, family=family, methods=("cmf", "dmf"), audit=False)
    rotated = run_fusion(_rotated(model, np.pi), rotated_ys, family=family, methods=("cmf", "dmf"), audit=False)
    for a, b in zip(run.steps, rotated.steps):
        tol = _recursion_tolerance(a.dmf)
        for method in ("cmf", "dmf"):
            np.testing.assert_allclose(a.estimate(method).mean, b.estimate(method).mean, rtol=0, atol=tol)
        for local_a, local_b in zip(a.local, b.local):
            np.testing.assert_allclose(local_a.mu_e, local_b.mu_e, rtol=0, atol=tol)


def _without_angles(case: FusionCase) -> FusionCase:
    central = dataclasses.replace(case.central, circular=())
    return FusionCase(central, tuple(dataclasses.replace(r, circular=()) for r in case.locals), case.y)


def test_dropping_circular_is_wrong_where_y_and_its_prediction_straddle_the_cut(tracker):
    model, ys = tracker
    run = run_fusion(model, ys, family="ukf", methods=("dmf",), audit=False)
    straddling = [s for s in run.steps if abs(ys[s.k - 1, BEARING] - s.dmf.case.central.mu_y[BEARING]) > np.pi]
    assert straddling
    for step in straddling:
        tol = _tolerance(step.dmf)
        plain = _without_angles(step.dmf.case)
        jump = cmf_update(plain.central, plain.y).mean - cmf_update(step.dmf.case.central, step.dmf.case.y).mean
        assert np.linalg.norm(jump) > 1e3 * tol
        gap = dmf_update(plain).mean - cmf_update(plain.central, plain.y).mean
        assert np.linalg.norm(gap) > 1e3 * tol


# -- (b) case files ------------------------------------------------------------------------------

def _angle_case(local_wrap: float = 2.0, innovation: float = 2.0, seed: int = 3) -> FusionCase:
    """A consistent random case (D = 2, sizes (1, 2)) whose sensor 1 output 1 (stacked index 2) is
    an angle with wrap(μ_y^1 − μ_y(1)) = ``local_wrap`` and wrap(y^1 − μ_y^1) = ``innovation``;
    sensor 1's μ_e is its local update with the wrapped innovation."""
    base = random_case(np.random.default_rng(seed), 2, (1, 2))
    central_mu_y = base.central.mu_y.copy()
    central_mu_y[2] = 3.0
    local = base.locals[1]
    local_mu_y = local.mu_y.copy()
    local_mu_y[1] = wrap(3.0 + local_wrap)
    y = base.y.copy()
    y[2] = wrap(local_mu_y[1] + innovation)
    w = np.linalg.solve(local.C_y, difference(y[1:], local_mu_y, (1,)))
    local = dataclasses.replace(local, mu_y=local_mu_y, mu_e=local.mu_p + local.C_xy @ w, circular=(1,))
    central = dataclasses.replace(base.central, mu_y=central_mu_y, circular=(2,))
    return FusionCase(central, (base.locals[0], local), y)


def test_case_with_circular_round_trips(tmp_path):
    data = case_to_dict(_angle_case())
    assert data["central"]["circular"] == [2] and data["locals"][1]["circular"] == [1]
    assert "circular" not in data["locals"][0]
    path = tmp_path / "case.json"
    path.write_text(json.dumps(data))
    case = load_case(path)
    assert case.central.circular == (2,) and [r.circular for r in case.locals] == [(), (1,)]
    assert case_to_dict(case) == data


def test_either_side_of_circular_is_enough():
    data = case_to_dict(_angle_case())
    only_locals = json.loads(json.dumps(data))
    del only_locals["central"]["circular"]
    only_central = json.loads(json.dumps(data))
    del only_central["locals"][1]["circular"]
    for variant in (only_locals, only_central):
        assert case_to_dict(case_from_dict(variant)) == data


def _set(path, value):
    def apply(d):
        target = d
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value
    return apply


BAD_CIRCULAR = {
    "not a list": (_set(["locals", 1, "circular"], 1), "locals[1].circular"),
    "float index": (_set(["locals", 1, "circular"], [1.0]), "locals[1].circular"),
    "bool index": (_set(["central", "circular"], [True]), "central.circular"),
    "out of range": (_set(["locals", 1, "circular"], [2]), "locals[1].circular index 2"),
    "negative": (_set(["locals", 0, "circular"], [-1]), "locals[0].circular[0] must be an integer >= 0"),
    "central out of range": (_set(["central", "circular"], [3]), "central.circular index 3"),
    "duplicate": (_set(["locals", 1, "circular"], [1, 1]), "locals[1].circular lists an index twice"),
    "disagree": (_set(["central", "circular"], [1]), "locals[1].circular"),
}


@pytest.mark.parametrize("name", list(BAD_CIRCULAR))
def test_invalid_circular_names_the_entry(name):
    mutate, needle = BAD_CIRCULAR[name]
    data = case_to_dict(_angle_case())
    mutate(data)
    with pytest.raises(CaseFileError, match=needle.replace("[", r"\[").replace("]", r"\]")):
        case_from_dict(data)


def test_a_typed_case_must_agree_on_its_angles():
    case = _angle_case()
    with pytest.raises(InputError, match="central.circular"):
        FusionCase(dataclasses.replace(case.central, circular=()), case.locals, case.y)


def _cli(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_audit_and_fuse_commands_on_a_case_with_angles(tmp_path, capsys):
    case = _angle_case(local_wrap=0.1, innovation=0.2)  # y^1 = wrap(3.3) and μ_y(1) = 3 straddle the cut
    path = tmp_path / "case.json"
    path.write_text(json.dumps(case_to_dict(case)))
    code, out, err = _cli(["audit", str(path), "--json"], capsys)
    assert code == 0 and err == ""
    report = json.loads(out)
    assert report == json.loads(json.dumps(audit_to_dict(audit_case(case))))
    assert [s["branch_offsets"] for s in report["sensors"]] == [[0], [0, 0]]
    assert not report["notes"]  # consistent logs (wrapped residuals), no branch offset, exact
    for method in ("cmf", "dmf"):
        code, out, err = _cli(["fuse", str(path), "--method", method, "--json"], capsys)
        assert code == 0 and err == ""
        np.testing.assert_allclose(json.loads(out)["mean"], report[f"{method}_mean"], rtol=0, atol=0)
    # CMF by hand: G (y ⊖ μ_y) with G from a plain solve and the innovation wrapped by hand
    gain = np.linalg.solve(case.central.C_y, case.central.C_xy.T).T
    innovation = case.y - case.central.mu_y
    innovation[2] -= 2 * np.pi * np.round(innovation[2] / (2 * np.pi))
    tol = _state_tolerance(case)
    np.testing.assert_allclose(report["cmf_mean"], case.central.mu_p + gain @ innovation, rtol=0, atol=tol)
    np.testing.assert_allclose(report["dmf_mean"], report["cmf_mean"], rtol=0, atol=tol)


@pytest.mark.parametrize("command", [["audit"], ["fuse", "--method", "dmf"]])
def test_bad_circular_exits_2_with_one_line(tmp_path, capsys, command):
    data = case_to_dict(_angle_case())
    data["locals"][1]["circular"] = [5]
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    code, out, err = _cli([command[0], str(path), *command[1:]], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1
    assert err.startswith(f"gpfverify {command[0]}: error: ") and "locals[1].circular index 5" in err


# -- (c) branch offsets -------------------------------------------------------------------------

@pytest.mark.parametrize("sign", [1, -1])
def test_branch_offset_is_predicted_and_named(sign):
    case = _angle_case(local_wrap=sign * 2.0, innovation=sign * 2.0)  # a + b = ±4 leaves (−π, π]
    offsets = branch_offsets(case)
    assert [n.tolist() for n in offsets] == [[0], [0, sign]]
    dmf = dmf_update(case)
    tol = _state_tolerance(case)
    observed = dmf.mean - cmf_update(case.central, case.y).mean
    gain = np.linalg.solve(case.central.C_y, case.central.C_xy.T).T  # independent G
    np.testing.assert_allclose(observed, 2 * np.pi * sign * gain[:, 2], rtol=0, atol=tol)
    assert np.linalg.norm(observed) > 1e3 * tol
    audit = audit_case(case)
    assert audit.exact and audit.condition_holds
    np.testing.assert_allclose(audit.predicted_gap, observed, rtol=0, atol=tol)
    np.testing.assert_allclose(sum(s.gap_contribution for s in audit.sensors), audit.predicted_gap, rtol=0, atol=tol)
    assert audit.sensors[1].branch_offsets.tolist() == [0, sign]
    assert audit.sensors[1].local_consistency_residual <= audit.sensors[1].consistency_tol
    [note] = audit.notes
    assert f"sensor 1 output 1 (n = {sign:+d})" in note and "2 pi" in note
    assert audit_to_dict(audit)["sensors"][1]["branch_offsets"] == [0, sign]


def test_the_documented_example_is_a_valid_case(tmp_path, capsys):
    """docs/fusion-case-format.md: its example loads and audits as the text says."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "fusion-case-format.md").read_text()
    example = text.split("```json\n", 1)[1].split("```", 1)[0]
    path = tmp_path / "example.json"
    path.write_text(example)
    code, out, _ = _cli(["audit", str(path), "--json"], capsys)
    report = json.loads(out)
    assert code == 0 and report["condition_holds"] and report["exact"] and report["notes"] == []
    assert [s["branch_offsets"] for s in report["sensors"]] == [[0], [0, 0]]
    case = load_case(path)
    tol = _state_tolerance(case)
    np.testing.assert_allclose(report["dmf_mean"], report["cmf_mean"], rtol=0, atol=tol)
    assert np.round(report["cmf_mean"], 4).tolist() == [0.2312, -0.1022]  # the 4 digits the text prints
    plain = _without_angles(case)
    assert np.linalg.norm(cmf_update(plain.central, plain.y).mean - report["cmf_mean"]) > 1e3 * tol
