"""The 1-D two-sensor fusion experiment (tiny runs): the results contract, the σ² sweep written
once, DMF = CMF on full-rank steps, the squared Mahalanobis metric, the model equations, the
claims, and the page rendered from stored results (no experiment run)."""

import json
from pathlib import Path

import numpy as np
import pytest

from gpfverify.cli import main
from gpfverify.contract import ClaimRecord, RunEntry, SectionRuns
from gpfverify.papers.fusion import ungm1d_experiment as ungm1d
from gpfverify.papers.fusion.run import FAMILIES, METHOD_KEYS, one_step_equivalence, squared_mahalanobis
from gpfverify.filters.records import Gaussian
from gpfverify.papers.fusion.scenario import sine_sensor, ungm_transition
from gpfverify.tolerances import algebra_rtol

FIXTURE = Path(__file__).parent / "fixtures" / "ungm1d" / "results.json"


@pytest.fixture(scope="module")
def cli_results(tmp_path_factory):
    out = tmp_path_factory.mktemp("ungm1d")
    code = main(["reproduce", "ungm1d", "--train-points", "15", "--test-steps", "3", "--sweep", "2",
                 "--runs", "2", "--seed", "1", "--out", str(out)])
    assert code == 0
    return json.loads((out / "results.json").read_text())


def test_results_follow_the_contract_and_hold_the_sweep_once(cli_results):
    r = cli_results
    assert (r["experiment"], r["runs_ok"]) == ("ungm1d", 2)
    assert set(r["mahalanobis"]) == set(METHOD_KEYS) and len(METHOD_KEYS) == 12
    assert all(len(v) == 3 and all(x >= 0 for x in v) for v in r["mahalanobis"].values())
    assert r["params"]["sweep"] == [2.0] and r["noise_vars"] == [1.0, 2.0] and r["main_noise"] == "1.0"
    # the main σ² at top level only; the others under per_noise and sweep
    assert set(r["sweep"]) == set(r["per_noise"]) == {"2.0"}
    assert r["sweep"]["2.0"]["mahalanobis"] == r["per_noise"]["2.0"]["average_mahalanobis"]
    assert r["mahalanobis"] == r["average_mahalanobis"]
    assert set(r["average_mahalanobis_by_noise"]) == {"1.0", "2.0"}
    for key in ("measurement_noise_var", "prior_var", "prior_mean", "mahalanobis", "trajectory_start_var"):
        assert key in r["params"]
    assert all(not isinstance(v, str) or " " not in v for v in r["params"].values())  # no prose
    assert set(r["max_equivalence_gap"]) == set(FAMILIES)
    assert set(r["time_per_run"]) == set(METHOD_KEYS)


def test_claims_per_noise_and_across_the_sweep(cli_results):
    claims = [ClaimRecord.from_json(c) for c in cli_results["claims"]]
    ids = {c.id for c in claims}
    for noise in ("1.0", "2.0"):
        for family in FAMILIES:
            for name in ("dmf-equals-cmf", "fusion-beats-sensors", "fusion-beats-baselines", "sensor2-beats-sensor1"):
                assert f"ungm1d/s{noise}/{name}/{family}" in ids
    assert {"ungm1d/s1.0/fusion-gp-adf-beats-gp-ukf", "ungm1d/s2.0/fusion-gp-ukf-beats-gp-adf",
            "ungm1d/fusion-beats-sensors-every-noise"} <= ids
    assert all(c.n == 2 for c in claims)
    assert {c.paper_n for c in claims if c.setting} == {1000}  # Figs. 2, 3


def test_dmf_equals_cmf_on_every_full_rank_step():
    params = ungm1d.Params(train=20, test_steps=4, sweep=())
    record = ungm1d.run_one(params, np.random.SeedSequence(3)).settings["1.0"]
    for family in FAMILIES:
        holds, reproduced, resolved = one_step_equivalence(record.families[family])
        assert holds.any() and reproduced[holds].all() and resolved[holds].all()


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


def test_page_renders_from_stored_results(tmp_path):
    from gpfverify.report.inputs import SectionInput
    from gpfverify.report.render import to_markdown
    from gpfverify.papers.fusion import ungm1d_section as fusion_ungm1d

    results = json.loads(FIXTURE.read_text())
    runs = SectionRuns("ungm1d", "quick", 1, (RunEntry("ungm1d", "σ² = 1", "sweep", "results.json"),))
    page = to_markdown(fusion_ungm1d.render_section(SectionInput("ungm1d", tmp_path, runs, (results,))), tmp_path)
    assert "Claims of Liao et al. 2019 checked — σ² = 1" in page and "σ² = 2" in page
    assert "Claim of Liao et al. 2019 across σ²" in page
    # the verdicts under the interpretation tried, the filters' health and the rank rule
    assert "Verdicts under each interpretation tried — σ² = 1" in page and "numpy-rank" in page
    assert "Health of the filters compared" in page and "Rank rule of eq. 35 in the runs shown" in page
    assert "x_{k+1}" not in page and "xₖ₊₁" in page
    for name in ("mahalanobis-s1.0.png", "mahalanobis-s2.0.png", "sweep.png"):
        assert (tmp_path / name).stat().st_size > 5_000


def test_same_seed_object_twice_gives_the_same_numbers():
    params = ungm1d.Params(train=15, test_steps=3, sweep=(2.0,))
    seed = np.random.SeedSequence(1).spawn(2)[1]
    first, again = ungm1d.run_one(params, seed), ungm1d.run_one(params, seed)
    for noise in ("1.0", "2.0"):
        for family in FAMILIES:
            assert first.settings[noise].families[family].maha == again.settings[noise].families[family].maha


def test_fusion_across_sweep_is_made_of_the_decided_per_noise_claims(cli_results):
    """Fig. 4's claim goes through the paired rule and the health gate of its parts: NOT held when one
    part is, not decidable when a part is and none is NOT held, held when all are."""
    claims = [ClaimRecord.from_json(c) for c in cli_results["claims"]]
    parts = [c.verdict for c in claims if "/fusion-beats-sensors/" in c.id]
    sweep = next(c for c in claims if c.id == "ungm1d/fusion-beats-sensors-every-noise")
    assert len(parts) == 4
    expected = ("NOT held" if "NOT held" in parts else "not decidable" if "not decidable" in parts else
                "held" if set(parts) == {"held"} else "undecided")
    assert sweep.verdict == expected
    assert "point estimates" not in " ".join(sweep.caveats)


def test_metric_readings_are_summary_only_interpretations(tmp_path):
    """The square-root Mahalanobis form and the RMSE read the same runs: their claims compare the
    per-run means of |x − x̂|/σ and ‖x − x̂‖², recomputed here from the saved runs."""
    out = tmp_path / "run"
    assert main(["reproduce", "ungm1d", "--train-points", "15", "--test-steps", "3", "--sweep", "2", "--runs", "3",
                 "--seed", "1", "--out", str(out), "--interpretations", "mahalanobis-root,rmse"]) == 0
    assert not (out / "interpretations" / "rmse" / "runs").exists()
    saved = [json.loads(p.read_text())["result"]["settings"]["1.0"]["families"]["GP-ADF"]
             for p in sorted((out / "runs").glob("run-*.json"))]
    for name, per_step in (("mahalanobis-root", lambda f, m: np.sqrt(f["maha"][m])),
                           ("rmse", lambda f, m: np.asarray(f["sq_err"][m]))):
        results = json.loads((out / "interpretations" / name / "results.json").read_text())
        claim = next(c for c in results["claims"] if c["id"] == "ungm1d/s1.0/sensor2-beats-sensor1/GP-ADF")
        d = np.array([np.mean(per_step(f, "Sensor2-GP-ADF")) - np.mean(per_step(f, "Sensor1-GP-ADF")) for f in saved])
        assert claim["statistic"] == pytest.approx(d.mean(), rel=1e-12)
        assert claim["threshold"] == pytest.approx(5 * d.std(ddof=1) / np.sqrt(d.size), rel=1e-12)
    main_claim = next(c for c in json.loads((out / "results.json").read_text())["claims"]
                      if c["id"] == "ungm1d/s1.0/sensor2-beats-sensor1/GP-ADF")
    assert [i["name"] for i in main_claim["interpretations"]] == ["mahalanobis-root", "rmse"]


def test_cmf_gp_ukf_variance_falls_to_the_noise_scale_because_three_sigma_points_span_a_plane():
    """With one state GP-UKF has three sigma points; their images (x, y₁, y₂) lie in a plane, so on
    them x = a + bᵀy exactly, and the fused variance C_p − C_xy C_y⁻¹ C_xyᵀ = bᵀ(S⁻¹ + R⁻¹)⁻¹b is at
    most bᵀRb (S the sigma points' output covariance, R the GP noise): the noise scale, whatever the
    state's uncertainty. A single sensor's (x, y) is not degenerate."""
    from gpfverify.papers.fusion.run import train_models
    from gpfverify.filters.gp_ukf import gp_noise_covariance
    from gpfverify.filters.sigma_points import SigmaParams, sigma_points
    from gpfverify.model_fusion import cmf_step
    from gpfverify.rng import generator
    from gpfverify.papers.fusion.scenario import simulate_data, ungm_scenario

    rng = generator(np.random.SeedSequence(4))
    data = simulate_data(ungm_scenario(1.0, 0.01, 1.0, 60, 5), rng)
    models = train_models(data, 1, 60, rng)
    belief = Gaussian(np.zeros(1), np.eye(1))
    ys = data.stacked_test_measurements()
    for k in range(4):
        record = cmf_step(belief, models, ys[k], k=k + 1, family="GP-UKF", params=SigmaParams())
        points = sigma_points(record.mu_p, record.C_p, SigmaParams())  # drawn from N(μ_p, C_p), eq. 25
        y = models.measurement.predict_mean(points)  # (3, 2): both sensors' GP means
        assert points.shape == (3, 1)
        # three points: x = a + bᵀy holds exactly on them
        a, *b = np.linalg.solve(np.column_stack([np.ones(3), y]), points[:, 0])
        R = gp_noise_covariance(models.measurement, record.mu_p)
        b = np.array(b)
        S = record.C_y - R  # the sigma points' output covariance
        exact = float(b @ (S - S @ np.linalg.solve(record.C_y, S)) @ b)  # bᵀ(S⁻¹ + R⁻¹)⁻¹b
        # both sides subtract from C_p-sized terms: rounding scales with C_p and the conditioning
        atol = algebra_rtol(np.linalg.cond(record.C_y) * np.linalg.cond(np.column_stack([np.ones(3), y]))) \
            * record.C_p[0, 0]
        assert record.C_e[0, 0] == pytest.approx(exact, rel=0, abs=atol)
        assert record.C_e[0, 0] <= float(b @ R @ b) + atol
        belief = record.posterior
