"""Covariances are judged without units: rescaling components (a state in kilometres instead of
millimetres, a measurement in micro-units, a whole case in units 1e25 times larger) never changes
whether a matrix is accepted, and fusion results follow the rescaling. Genuinely indefinite
matrices, and a centre whose joint covariance of (x, y) is impossible, are still refused, naming
the matrix; a fused covariance that is not positive semidefinite is never printed; an RCC-CI size
too small to be a normal float is refused."""

import json

import numpy as np
import pytest

from gpfverify.cli import main
from gpfverify.errors import CaseFileError, InputError, NumericalError
from gpfverify.fusion.case import case_to_dict
from gpfverify.fusion.caseblock import case_from_dict
from gpfverify.fusion.methods import fuse_case
from gpfverify.fusion.synthetic import random_case, random_spd
from gpfverify.models.system import Sensor
from gpfverify.tolerances import SOLVER_TOL, algebra_rtol
from gpfverify.validate import as_covariance, computed_covariance, covariance_defects

#: Component scales of the brief's awkward units: one state component x1e-4 and one measurement
#: component x1e6 (others unchanged), and a whole case x1e-25 (covariances x1e-50).
MIXED_UNITS = "mixed"
TINY_UNITS = "tiny"


def _scales(kind: str, state_dim: int, meas_dim: int) -> tuple[np.ndarray, np.ndarray]:
    if kind == TINY_UNITS:
        return np.full(state_dim, 1e-25), np.full(meas_dim, 1e-25)
    sx, sy = np.ones(state_dim), np.ones(meas_dim)
    sx[0], sy[0] = 1e-4, 1e6
    return sx, sy


def _rescaled(case_dict: dict, sx: np.ndarray, sy: np.ndarray) -> dict:
    """The same case in other units: x -> Sx x, y -> Sy y (means scale once, covariances twice)."""
    out = json.loads(json.dumps(case_dict))
    c = out["central"]
    a = np.asarray

    def mat(m, left, right):
        return (left[:, None] * a(m) * right[None, :]).tolist()

    c["mu_p"] = (sx * a(c["mu_p"])).tolist()
    c["C_p"] = mat(c["C_p"], sx, sx)
    c["mu_y"] = (sy * a(c["mu_y"])).tolist()
    c["C_y"] = mat(c["C_y"], sy, sy)
    c["C_xy"] = mat(c["C_xy"], sx, sy)
    start = 0
    for r in out["locals"]:
        size = len(r["mu_y"])
        s = sy[start:start + size]
        start += size
        r["mu_p"] = (sx * a(r["mu_p"])).tolist()
        r["mu_y"] = (s * a(r["mu_y"])).tolist()
        r["C_y"] = mat(r["C_y"], s, s)
        r["C_xy"] = mat(r["C_xy"], sx, s)
        r["mu_e"] = (sx * a(r["mu_e"])).tolist()
        if "C_e" in r:
            r["C_e"] = mat(r["C_e"], sx, sx)
    out["y"] = (sy * a(out["y"])).tolist()
    return out


@pytest.mark.parametrize("kind", [MIXED_UNITS, TINY_UNITS])
def test_verdicts_do_not_depend_on_units(kind):
    rng = np.random.default_rng(3)
    n = 4
    definite = random_spd(rng, n)
    b = rng.normal(size=(n, n - 1))
    singular = b @ b.T                                   # PSD of rank n - 1
    q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    indefinite = (q * np.array([2.0, 1.0, 0.5, -0.05])) @ q.T
    # oracle: the verdicts of numpy's eigenvalues in the original, well-scaled units
    assert np.linalg.eigvalsh(definite)[0] > 0.05
    assert np.linalg.eigvalsh(indefinite)[0] < -0.04
    s = _scales(kind, n, 0)[0] if kind == TINY_UNITS else np.array([1e-4, 1e6, 1.0, 3.0])
    scaled = [s[:, None] * m * s[None, :] for m in (definite, singular, indefinite)]
    _, bad_psd, _ = covariance_defects(np.stack(scaled))
    _, bad_pd, _ = covariance_defects(np.stack(scaled), definite=True)
    assert bad_psd.tolist() == [False, False, True]
    assert bad_pd.tolist() == [False, True, True]


def test_indefinite_sensor_noise_is_refused_naming_the_sensor():
    with pytest.raises(InputError, match="sensor 'radar' noise_cov is not positive semidefinite"):
        Sensor(lambda x: x[:, :2], [[1e6, 2e6], [2e6, 1e6]], name="radar")
    # the same correlation in any units is refused; a valid one in tiny units is accepted
    with pytest.raises(InputError, match="prior_cov is not positive semidefinite"):
        as_covariance([[1e-40, 3e-30], [3e-30, 1e-20]], "prior_cov")
    accepted = Sensor(lambda x: x[:, :2], [[1e-50, 5e-41], [5e-41, 1e-30]], name="tiny")
    assert accepted.noise_cov.shape == (2, 2)


def test_a_zero_variance_with_a_covariance_is_refused():
    """A component with zero variance cannot covary with another (|C_ij| <= sqrt(C_ii C_jj))."""
    with pytest.raises(InputError, match="is not positive semidefinite"):
        as_covariance([[1.0, 1e-3], [1e-3, 0.0]], "C")
    assert as_covariance([[1.0, 0.0], [0.0, 0.0]], "C")[1, 1] == 0.0


@pytest.mark.parametrize("kind", [MIXED_UNITS, TINY_UNITS])
@pytest.mark.parametrize("method, criterion", [("cmf", "trace"), ("dmf", "trace"), ("cc", "trace"),
                                               ("ci", "det"), ("ici", "det")])
def test_a_case_in_other_units_is_accepted_and_fused_equivariantly(kind, method, criterion):
    """CI's and ICI's determinant criterion has no units; their trace criterion adds variances of
    different components and so depends on the units by definition (not tested here)."""
    rng = np.random.default_rng(11)
    case = random_case(rng, 3, (2, 2))
    base = case_to_dict(case)
    sx, sy = _scales(kind, 3, 4)
    moved = case_from_dict(_rescaled(base, sx, sy))
    want = fuse_case(case, method, criterion)
    got = fuse_case(moved, method, criterion)
    std = np.sqrt(np.diag(case.central.C_p))
    # CI and ICI choose their weights with a solver: its accuracy, not rounding, bounds the change
    rtol = SOLVER_TOL if method in ("ci", "ici") else algebra_rtol(np.linalg.cond(case.central.C_y))
    mean_back = np.asarray(got["mean"]) / sx
    cov_back = np.asarray(got["cov"]) / np.outer(sx, sx)
    assert np.all(np.abs(mean_back - np.asarray(want["mean"])) <= rtol * std)
    assert np.all(np.abs(cov_back - np.asarray(want["cov"])) <= rtol * np.outer(std, std))


@pytest.mark.parametrize("command", [["fuse", "--method", "cmf"], ["audit", "--json"]], ids=lambda c: c[0])
def test_an_impossible_cross_covariance_is_refused(tmp_path, capsys, command):
    """Every C_xy x100 implies correlations above one between x and y: refused by every command
    that reads a case (docs/output-and-errors.md, "Covariances in the outputs")."""
    data = case_to_dict(random_case(np.random.default_rng(5), 2, (1, 2)))
    c = data["central"]
    c["C_xy"] = (100.0 * np.asarray(c["C_xy"])).tolist()
    joint = np.block([[np.asarray(c["C_p"]), np.asarray(c["C_xy"])],
                      [np.asarray(c["C_xy"]).T, np.asarray(c["C_y"])]])
    assert np.linalg.eigvalsh(joint)[0] < 0                      # oracle: impossible indeed
    with pytest.raises(CaseFileError, match=r"central joint covariance \[\[C_p, C_xy\], \[C_xyᵀ, C_y\]\] "
                                            "is not positive semidefinite"):
        case_from_dict(data)
    path = tmp_path / "case.json"
    path.write_text(json.dumps(data))
    assert main([command[0], str(path), *command[1:]]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "central joint covariance" in err


def test_a_computed_covariance_that_is_not_psd_is_never_shown():
    q, _ = np.linalg.qr(np.random.default_rng(2).normal(size=(3, 3)))
    with pytest.raises(NumericalError, match="the dmf fused covariance is not positive semidefinite"):
        computed_covariance((q * [3.0, 1.0, -4321.0]) @ q.T, "the dmf fused covariance")
    with pytest.raises(NumericalError, match="NaN"):
        computed_covariance([[np.nan]], "C")


def test_a_subnormal_rcc_size_is_refused_in_one_line(tmp_path, capsys):
    """c = 1e-320 has lost its precision (subnormal); it used to reach the solver as inf."""
    path = tmp_path / "case.json"
    path.write_text(json.dumps(case_to_dict(random_case(np.random.default_rng(0), 2, (1, 2)))))
    assert main(["fuse", str(path), "--method", "rcc-ci", "--c", "1e-320"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "c must be at least 2.23e-308" in err
