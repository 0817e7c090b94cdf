"""The 1-D two-sensor fusion experiment (tiny runs): the results contract, the σ² sweep, DMF = CMF
on full-rank steps, the squared Mahalanobis metric and the model equations."""

import json

import numpy as np
import pytest

from gpfverify.cli import main
from gpfverify.experiments import ungm1d
from gpfverify.experiments.fusion_run import FAMILIES, METHODS, one_step_equivalence, squared_mahalanobis
from gpfverify.filters.records import Gaussian
from gpfverify.scenarios.fusion_models import sine_sensor, ungm_transition
from gpfverify.tolerances import algebra_rtol


@pytest.fixture(scope="module")
def cli_results(tmp_path_factory):
    out = tmp_path_factory.mktemp("ungm1d")
    code = main(["reproduce", "ungm1d", "--train", "15", "--test-steps", "3", "--sweep", "2",
                 "--runs", "2", "--seed", "1", "--out", str(out)])
    assert code == 0
    return json.loads((out / "results.json").read_text())


def test_results_follow_the_contract_and_hold_the_sweep(cli_results):
    r = cli_results
    assert (r["experiment"], r["runs_ok"]) == ("ungm1d", 2)
    assert set(r["mahalanobis"]) == set(METHODS) and len(METHODS) == 12
    assert all(len(v) == 3 and all(x >= 0 for x in v) for v in r["mahalanobis"].values())
    assert r["params"]["noise_vars"] == [1.0, 2.0]
    assert set(r["sweep"]) == {"1.0", "2.0"}
    assert r["sweep"]["1.0"]["mahalanobis"] == r["mahalanobis"]
    for key in ("measurement_noise_var", "prior_var", "prior_mean", "mahalanobis", "trajectory_start"):
        assert key in r["params"]
    assert set(r["max_equivalence_gap"]) == set(FAMILIES)
    assert set(r["time_per_run"]) == set(METHODS)


def test_dmf_equals_cmf_on_every_full_rank_step():
    params = ungm1d.default_params(train=20, test_steps=4, sweep=[])
    record = ungm1d.run_one(params, np.random.SeedSequence(3))["settings"]["1.0"]
    for family in FAMILIES:
        holds, within = one_step_equivalence(record["families"][family])
        assert holds.any() and within[holds].all()


def test_squared_mahalanobis_against_the_explicit_quadratic_form():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(3, 3))
    cov = a @ a.T + 0.5 * np.eye(3)
    mean, truth = rng.normal(size=3), rng.normal(size=3)
    eigval, eigvec = np.linalg.eigh(cov)
    whitened = (eigvec.T @ (truth - mean)) / np.sqrt(eigval)
    expected = float(whitened @ whitened)
    assert abs(squared_mahalanobis(truth, Gaussian(mean, cov)) - expected) <= \
        algebra_rtol(eigval[-1] / eigval[0]) * expected


def test_model_equations():
    x = np.array([[0.0], [1.0], [-2.0]])
    np.testing.assert_allclose(ungm_transition(x)[:, 0], [0.0, 0.5 + 12.5, -1.0 - 10.0], rtol=algebra_rtol(1.0))
    np.testing.assert_allclose(sine_sensor(np.pi / 4)(x)[:, 0], 5 * np.sin(2 * x[:, 0] + np.pi / 4),
                               rtol=algebra_rtol(1.0))


def test_page_renders_both_noise_levels_and_the_sweep(cli_results, tmp_path):
    from gpfverify.report.render import to_markdown
    from gpfverify.report.sections import fusion_ungm1d

    page = to_markdown(fusion_ungm1d.render(cli_results, tmp_path), tmp_path)
    assert "Claims of the paper checked — σ² = 1.0" in page and "σ² = 2.0" in page
    assert "Claim across σ²" in page
    for name in ("mahalanobis-s1.0.png", "mahalanobis-s2.0.png", "sweep.png"):
        assert (tmp_path / name).stat().st_size > 5_000


def test_same_seed_object_twice_gives_the_same_numbers():
    params = ungm1d.default_params(train=15, test_steps=3, sweep=[2.0])
    seed = np.random.SeedSequence(1).spawn(2)[1]
    first, again = ungm1d.run_one(params, seed), ungm1d.run_one(params, seed)
    for noise in ("1.0", "2.0"):
        for family in FAMILIES:
            assert first["settings"][noise]["families"][family]["maha"] == \
                again["settings"][noise]["families"][family]["maha"]
