"""The check page's trajectory figure: its covariance ellipses against the ellipse's defining
equation and area, and the trajectory record against the RMSE and the repair verdicts the same
results.json holds, computed elsewhere."""

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2

from gpfverify.cli import main
from gpfverify.report.check_trajectory import ELLIPSE_LEVEL, ellipse_points, ellipse_steps
from gpfverify.tolerances import algebra_rtol

ROOT = Path(__file__).resolve().parents[1]
REDUNDANT = f"{ROOT / 'examples' / 'redundant_sensor_system.py'}:system"


@pytest.mark.parametrize("seed", range(5))
def test_ellipse_points_lie_on_the_quantile_contour_and_enclose_its_area(seed):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(2, 2)) * 10.0 ** rng.uniform(-3, 3)
    cov = a @ a.T + 1e-3 * np.abs(a).max() ** 2 * np.eye(2)
    mean = rng.normal(size=2) * 100
    n = 4000
    points = ellipse_points(mean, cov, n=n)
    offsets = points - mean
    radius2 = chi2.ppf(ELLIPSE_LEVEL, 2)
    mahalanobis = np.einsum("ij,ij->i", offsets, np.linalg.solve(cov, offsets.T).T)
    np.testing.assert_allclose(mahalanobis, radius2, rtol=algebra_rtol(np.linalg.cond(cov)))
    x, y = offsets[:, 0], offsets[:, 1]  # about the centre: no cancellation against a far mean
    area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))  # shoelace
    exact = np.pi * radius2 * np.sqrt(np.linalg.det(cov))
    inscribed = 2 * (2 * np.pi / (n - 1)) ** 2 / 6  # an inscribed polygon's relative shortfall, twice
    assert abs(area - exact) <= inscribed * exact


def test_ellipses_every_step_up_to_the_limit_then_evenly_including_the_last():
    assert ellipse_steps(7) == list(range(7))
    steps = ellipse_steps(1000)
    assert steps[0] == 0 and steps[-1] == 999 and len(steps) <= 26
    assert len(set(np.diff(steps[:-1]))) == 1


@pytest.fixture(scope="module")
def redundant_check(tmp_path_factory):
    out = tmp_path_factory.mktemp("check") / "out"
    assert main(["check", REDUNDANT, "--steps", "6", "--out", str(out)]) == 0
    return out, json.loads((out / "results.json").read_text())


@pytest.mark.slow
def test_the_trajectory_is_the_first_runs_truth_and_estimates(redundant_check):
    _, results = redundant_check
    trajectory = results["trajectory"]
    truth = np.asarray(trajectory["truth"])
    assert trajectory["k"] == results["k"] and truth.shape == (6, results["state_dim"])
    for method, rmse in results["rmse"].items():  # one run: the RMSE is each step's error
        means = np.asarray(trajectory["means"][method])
        np.testing.assert_allclose(np.linalg.norm(truth - means, axis=1), rmse, rtol=algebra_rtol())
        covs = np.asarray(trajectory["covs"][method])
        assert covs.shape == (6, truth.shape[1], truth.shape[1])
        assert np.all(np.linalg.eigvalsh(0.5 * (covs + covs.transpose(0, 2, 1))) > 0)
    # a repaired mean exactly at the steps where some sensor's repair message is not empty
    repairs = np.asarray(results["repair_dim"])[0]  # (T, N) of the first run
    assert [r["k"] for r in trajectory["repaired"]] == [k for k, row in zip(results["k"], repairs) if row.any()]
    assert trajectory["repaired"], "the redundant sensor loses rank: some step needs a repair"


@pytest.mark.slow
def test_the_check_page_shows_the_trajectory_with_the_repaired_estimate(redundant_check):
    out, results = redundant_check
    html = (out / "report.html").read_text(encoding="utf-8")
    assert (out / "figures" / "trajectory.png").stat().st_size > 0
    assert "each method&#x27;s estimate with its 95 % covariance ellipse" in html
    assert f"the repaired DMF mean at the {len(results['trajectory']['repaired'])} step(s)" in html
