"""The gpadf-scalar experiment: scores against scipy, the typed contract (parameters, run record,
claims), the results.json contract, the command line, the report page rendered from a stored
results.json, and the paper's consistency claim on a small seeded run."""

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.stats

from gpfverify.cli import main
from gpfverify.contract.claims import read_claims
from gpfverify.contract.experiment import RunEntry, SectionRuns
from gpfverify.papers.gpadf_scalar.contract import PROFILES, Params, RunRecord
from gpfverify.contract.serial import from_json, to_json
from gpfverify.errors import InputError
from gpfverify.papers.gpadf_scalar import experiment as gpadf_scalar
from gpfverify.experiments.runner import run_experiment
from gpfverify.models import Sensor, StateSpaceModel
from gpfverify.models.functions import FD_STEP
from gpfverify.report.inputs import SectionInput
from gpfverify.papers.gpadf_scalar import section
from gpfverify.papers.gpadf_scalar.scenario import (ScalarSetting, measurement, measurement_derivative,
                                                  transition, transition_derivative)
from gpfverify.tolerances import ALGEBRA_SAFETY, EPS, algebra_rtol

FIXTURE = Path(__file__).parent / "fixtures" / "gpadf_scalar" / "results.json"
TABLE_KEYS = {"nll", "nll_se", "maha", "maha_se", "rmse", "rmse_se"}


def test_scores_match_scipy():
    rng = np.random.default_rng(0)
    mean, var, truth = rng.normal(size=20), rng.uniform(0.01, 3.0, size=20), rng.normal(size=20)
    scores = gpadf_scalar.gaussian_scores(mean, var, truth)
    rtol = algebra_rtol()
    np.testing.assert_allclose(scores["nll"], -scipy.stats.norm.logpdf(truth, mean, np.sqrt(var)), rtol=rtol)
    np.testing.assert_allclose(scores["maha"], np.abs(truth - mean) / np.sqrt(var), rtol=rtol)


def test_model_derivatives_match_central_differences():
    """The experiment's model carries the analytic derivatives (what the EKF uses); the same model
    without them differentiates by central differences (gpfverify.models.functions), step
    h = FD_STEP·max(1, |x|). Their error is at most the truncation h²/6·max|f⁽³⁾| plus the rounding
    eps·(|f| + |x| |f′|)/h (values and perturbed arguments rounded; ALGEBRA_SAFETY on it). On
    [−10, 10]: |f| ≤ 17.5, |f′| ≤ 25.5, |f⁽³⁾| ≤ 150 (25·6, from x/(1 + x²) at 0); |g| ≤ 5,
    |g′| ≤ 10, |g⁽³⁾| ≤ 40."""
    setting = ScalarSetting()
    exact = setting.model()
    by_differences = StateSpaceModel(transition, exact.Q, [Sensor(measurement, exact.R)],
                                     exact.prior_mean, exact.prior_cov)
    x = np.linspace(-setting.domain, setting.domain, 41)[:, None]
    h = FD_STEP * np.maximum(1.0, np.abs(x[:, 0]))
    for name, deriv, value, slope, third in (("f", transition_derivative, 17.5, 25.5, 150.0),
                                             ("h", measurement_derivative, 5.0, 10.0, 40.0)):
        analytic = getattr(exact, f"{name}_jacobian")(x)[:, 0, 0]
        np.testing.assert_array_equal(analytic, deriv(x[:, 0]))
        numeric = getattr(by_differences, f"{name}_jacobian")(x)[:, 0, 0]
        bound = h**2 / 6.0 * third + ALGEBRA_SAFETY * EPS * (value + np.abs(x[:, 0]) * slope) / h
        assert np.all(np.abs(numeric - analytic) <= bound), name


@pytest.fixture(scope="module")
def small_results(tmp_path_factory):
    return run_experiment(gpadf_scalar, Params(restarts=1), runs=3, seed=1, out_dir=tmp_path_factory.mktemp("run"),
                          show_progress=False)


def test_params_validate_every_option():
    assert Params() == Params.from_json(json.loads(json.dumps(Params().to_json())))
    for field, bad, option in (("prior_std", -1.0, "--prior-std"), ("domain", 0.0, "--domain"),
                               ("train_points", 1, "--train-points"), ("restarts", 0, "--restarts"),
                               ("alpha", 0.0, "--alpha"), ("kappa", -1.0, "--sigma-kappa")):
        with pytest.raises(InputError, match=option):
            Params(**{field: bad})
    with pytest.raises(InputError, match="--restarts"):
        Params().replace(restarts=0)  # overrides are validated too


def test_profiles_use_the_paper_setting():
    assert PROFILES["full"].runs == gpadf_scalar.DEFAULT_RUNS > PROFILES["quick"].runs
    assert all(s.params == Params() for p in PROFILES.values() for s in p.settings)


def test_run_record_round_trips():
    record = gpadf_scalar.run_one(Params(train_points=20, test_points=5, restarts=1), np.random.SeedSequence(3))
    assert isinstance(record, RunRecord)
    assert from_json(RunRecord, json.loads(json.dumps(to_json(record)))) == record
    assert set(record.scores) == {m.key for m in gpadf_scalar.METHODS} == {"UKF", "EKF", "GP-UKF", "GP-ADF"}
    assert len(record.scores["GP-ADF"].nll) == 5


def test_results_follow_the_contract(small_results):
    r = small_results
    assert (r["experiment"], r["runs"], r["seed"], r["runs_ok"]) == ("gpadf-scalar", 3, 1, 3)
    assert set(r["table"]) == {m.key for m in gpadf_scalar.METHODS} == set(r["time_per_run"])
    for row in r["table"].values():
        assert TABLE_KEYS <= set(row)
        assert all(np.isfinite(row[k]) for k in TABLE_KEYS)
        assert row["cases"] == 3 * ScalarSetting().test_points
    assert r["params"] == Params(restarts=1).to_json()
    records = read_claims(r)
    assert [c.id for c in records] == ["gpadf-scalar/smallest-nll", "gpadf-scalar/gp-adf-consistent",
                                       "gpadf-scalar/over-confident/UKF", "gpadf-scalar/over-confident/EKF",
                                       "gpadf-scalar/over-confident/GP-UKF"]
    assert all(c.paper == "deisenroth2009" and c.n == 3 and c.paper_n == gpadf_scalar.DEFAULT_RUNS for c in records)
    assert all(c.cautions for c in records)  # 3 runs against the paper's 20


def test_gp_adf_is_consistent_and_the_known_model_filters_are_over_confident(small_results):
    """Deisenroth et al. (2009): GP-ADF's NEES is compatible with 1, UKF and EKF with the true
    model put the true state outside ±2σ far more often than 4.55 %. (GP-UKF's verdict is left to
    the report: on small runs its excess is of the order of the tolerance.)"""
    table = small_results["table"]
    assert table["GP-ADF"]["nll"] < min(table[m]["nll"] for m in ("UKF", "EKF", "GP-UKF"))
    verdicts = {c.id: c for c in read_claims(small_results)}
    consistent = verdicts["gpadf-scalar/gp-adf-consistent"]
    assert consistent.verdict == "held" and consistent.statistic <= consistent.threshold
    for method in ("UKF", "EKF"):
        claim = verdicts[f"gpadf-scalar/over-confident/{method}"]
        assert claim.verdict == "held" and claim.statistic > claim.threshold, method
        assert claim.statistic == table[method]["outside_2sigma"]
    # the NLL claim is a paired difference over runs: every per-run difference is negative here
    nll = small_results["per_run"]
    assert all(a < b for m in ("UKF", "EKF", "GP-UKF") for a, b in zip(nll["GP-ADF"]["nll"], nll[m]["nll"]))
    assert verdicts["gpadf-scalar/smallest-nll"].verdict in ("held", "undecided")


def _section_input(results: dict, folder: Path) -> SectionInput:
    runs = SectionRuns("gpadf-scalar", "quick", results["seed"],
                       (RunEntry("gpadf-scalar", "", "default", "gpadf-scalar-default/run/results.json"),))
    return SectionInput("gpadf-scalar", folder, runs, (results,))


def test_report_page_renders_from_a_stored_results_file(tmp_path):
    """The page from the committed fixture (2 runs of 20 test cases): no experiment runs."""
    results = json.loads(FIXTURE.read_text(encoding="utf-8"))
    page = section.render_section(_section_input(results, tmp_path))
    assert (tmp_path / "posteriors.png").stat().st_size > 0
    claims = [b for b in page.blocks if getattr(b, "caption", "").startswith("Claims")]
    assert len(claims) == 1 and len(claims[0].rows) == len(results["claims"]) == 5
    verdicts = [getattr(row[2], "verdict", row[2]) for row in claims[0].rows]
    assert verdicts == [c["verdict"] for c in results["claims"]]
    assert all("the paper used 20" in repr(row) for row in claims[0].rows)  # 2 runs: cautioned
    text = " ".join(b.text for b in page.blocks if hasattr(b, "text"))
    assert "Deisenroth" in text and "Liao et al. 2019" in text
    assert f"{results['table']['GP-ADF']['cases']} test cases pooled" in text


def test_report_section_imports_no_experiment():
    source = Path(section.__file__).read_text(encoding="utf-8")
    assert "gpfverify.experiments" not in source and "run_for_report" not in source
    assert not hasattr(section, "build")


def test_reproduce_help_lists_the_generated_options(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["reproduce", "gpadf-scalar", "--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    for option in ("--train-points", "--test-points", "--prior-std", "--system-noise-std",
                   "--measurement-noise-std", "--domain", "--restarts", "--alpha", "--beta", "--sigma-kappa"):
        assert option in out


def test_command_line_run_and_errors(tmp_path, capsys):
    out = tmp_path / "cli"
    assert main(["reproduce", "gpadf-scalar", "--runs", "1", "--test-points", "20", "--train-points", "30",
                 "--restarts", "1", "--seed", "4", "--out", str(out)]) == 0
    results = json.loads((out / "results.json").read_text())
    assert results["table"]["GP-ADF"]["cases"] == 20 and results["seed"] == 4
    capsys.readouterr()
    for bad in (["--prior-std", "-1"], ["--sigma-kappa", "-2"]):
        assert main(["reproduce", "gpadf-scalar", *bad, "--out", str(tmp_path / "bad")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and bad[0] in err[0]
    assert not (tmp_path / "bad").exists()
