"""Angle states in fusion (docs/fusion-definitions.md): a heading in the state, seen by two compasses
and a turn-rate sensor, across the ±π cut. Oracles written here with numpy: CMF by hand (G from a
plain solve, innovations and the mean wrapped by hand), and the same scene rotated by π and by an
angle that moves the cut — every rule equivariant to rounding. Case and run files carry the
top-level ``circular_state``."""

import json

import numpy as np
import pytest

from gpfverify.angles import wrap
from gpfverify.audit.case import audit_case
from gpfverify.cli import main
from gpfverify.errors import CaseFileError
from gpfverify.fusion.case import CentralPrediction, FusionCase, LocalReport, case_to_dict
from gpfverify.fusion.caseblock import load_case
from gpfverify.fusion.centralized import cmf_update
from gpfverify.fusion.distributed import dmf_update
from gpfverify.audit.runfile import iter_steps, write_run
from gpfverify.tolerances import algebra_rtol

HEADING = 0
#: state (heading θ, turn rate ω); sensors: compass (θ), compass (θ), gyro (ω)
H = [np.array([[1.0, 0.0]]), np.array([[1.0, 0.0]]), np.array([[0.0, 1.0]])]
R = [np.array([[0.04]]), np.array([[0.09]]), np.array([[0.01]])]
C_P = np.array([[0.3, 0.05], [0.05, 0.1]])


def _local(mu_p: np.ndarray, y_m: np.ndarray, h: np.ndarray, r: np.ndarray, circular_out: bool) -> LocalReport:
    """The sensor's own update from the common prior (innovation and posterior heading wrapped)."""
    mu_y = h @ mu_p
    c_y, c_xy = h @ C_P @ h.T + r, C_P @ h.T
    gain = np.linalg.solve(c_y, c_xy.T).T
    innovation = y_m - mu_y
    if circular_out:
        innovation = wrap(innovation)
        mu_y = wrap(mu_y)
    mu_e = mu_p + gain @ innovation
    mu_e[HEADING] = wrap(mu_e[HEADING])
    return LocalReport(mu_p, mu_y, c_y, c_xy, mu_e, C_P - gain @ c_xy.T, (0,) if circular_out else ())


def scene(heading: float, measured: tuple[float, float], rotation: float = 0.0) -> FusionCase:
    """Prior heading ``heading`` + rotation, compasses reading ``measured`` + rotation."""
    mu_p = np.array([wrap(heading + rotation), 0.2])
    y = np.array([wrap(measured[0] + rotation), wrap(measured[1] + rotation), 0.25])
    locals_ = tuple(_local(mu_p, y[m:m + 1], H[m], R[m], m < 2) for m in range(3))
    h, r = np.vstack(H), np.diag([r[0, 0] for r in R])
    mu_y = h @ mu_p
    mu_y[:2] = wrap(mu_y[:2])
    central = CentralPrediction(mu_p, C_P, mu_y, h @ C_P @ h.T + r, C_P @ h.T, (1, 1, 1), (0, 1), (HEADING,))
    return FusionCase(central, locals_, y)


def _cmf_by_hand(case: FusionCase) -> np.ndarray:
    c = case.central
    gain = np.linalg.solve(c.C_y, c.C_xy.T).T
    innovation = case.y - c.mu_y
    innovation[:2] = wrap(innovation[:2])
    mean = c.mu_p + gain @ innovation
    mean[HEADING] = wrap(mean[HEADING])
    return mean


def _close_on_circle(a, b, tol):
    d = np.asarray(a, float) - np.asarray(b, float)
    d[HEADING] = wrap(d[HEADING])
    assert np.all(np.abs(d) <= tol), d


TOL = algebra_rtol(np.linalg.cond(C_P)) * 10  # means of size ≤ π, conditioning of C_p and C_y ≈ 10


#: headings straddling the cut: the sensors' posteriors land on the other side from the prior
STRADDLING = [(3.10, (-3.12, -3.07)), (-3.12, (3.10, 3.05)), (3.05, (3.13, -3.13)), (0.4, (0.5, 0.3))]


@pytest.mark.parametrize("heading, measured", STRADDLING)
def test_dmf_equals_cmf_across_the_cut_and_the_audit_says_so(heading, measured):
    case = scene(heading, measured)
    cmf = _cmf_by_hand(case)
    _close_on_circle(cmf_update(case.central, case.y).mean, cmf, TOL)
    dmf = dmf_update(case)
    assert dmf.exact and dmf.condition_holds
    _close_on_circle(dmf.mean, cmf, TOL)
    assert -np.pi < dmf.mean[HEADING] <= np.pi
    audit = audit_case(case)
    assert audit.reproduced and np.all(np.abs(audit.gap) <= TOL), audit.gap
    assert not audit.notes


@pytest.mark.parametrize("rotation", [np.pi, 0.5, -2.0, 3.0])
@pytest.mark.parametrize("heading, measured", STRADDLING)
def test_every_rule_is_equivariant_under_a_rotation_of_the_heading(heading, measured, rotation):
    """The same scene in a frame rotated by ``rotation`` (π, and angles that move the cut through
    it): CMF and DMF rotate with it."""
    base, turned = scene(heading, measured), scene(heading, measured, rotation)
    for fuse in (lambda c: cmf_update(c.central, c.y).mean, lambda c: dmf_update(c).mean,
                 lambda c: audit_case(c).dmf_mean):
        expected = fuse(base).copy()
        expected[HEADING] = wrap(expected[HEADING] + rotation)
        _close_on_circle(fuse(turned), expected, TOL)


def test_without_circular_state_dmf_is_off_by_a_turn_fraction():
    """The control: the same case with the heading treated as a plain number (the old behaviour)
    is far from CMF — the comparison above can fail."""
    import dataclasses

    case = scene(3.10, (-3.12, -3.07))
    plain = dataclasses.replace(case, central=dataclasses.replace(case.central, circular_state=()))
    gap = dmf_update(plain).mean - _cmf_by_hand(case)
    gap[HEADING] = wrap(gap[HEADING])
    assert np.abs(gap).max() > 0.1


def test_case_and_run_files_carry_circular_state(tmp_path, capsys):
    case = scene(3.10, (-3.12, -3.07))
    data = case_to_dict(case)
    assert data["circular_state"] == [HEADING]
    path = tmp_path / "case.json"
    path.write_text(json.dumps(data))
    assert load_case(path).circular_state == (HEADING,)
    assert main(["audit", str(path), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["reproduced"] and report["exact"]
    _close_on_circle(report["dmf_mean"], _cmf_by_hand(case), TOL)
    assert main(["fuse", str(path), "--method", "dmf", "--json"]) == 0
    _close_on_circle(json.loads(capsys.readouterr().out)["mean"], _cmf_by_hand(case), TOL)
    cases = [scene(h, m) for h, m in STRADDLING]
    for suffix in ("jsonl", "npz"):
        run = tmp_path / f"run.{suffix}"
        write_run(run, cases)
        back = [c for _, c in iter_steps(run)]
        assert [c.circular_state for c in back] == [(HEADING,)] * len(cases)


@pytest.mark.parametrize("bad, message", [([2], "circular_state index 2 is out of range for 2 state component"),
                                          ([0, 0], "circular_state lists an index twice")])
def test_a_bad_circular_state_is_refused(tmp_path, capsys, bad, message):
    data = case_to_dict(scene(3.10, (-3.12, -3.07)))
    data["circular_state"] = bad
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(CaseFileError, match=message):
        load_case(path)
    assert main(["audit", str(path)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and message in err
