"""The constant-turn fusion experiment (tiny runs): the results contract, Proposition 1 on every
full-rank step (DMF = CMF from the same central prediction, to rounding scaled by conditioning),
the audit's closed-form gap on forced rank failures, determinism, the params record and claims,
and the page rendered from stored results (no experiment run)."""

import json
from pathlib import Path

import numpy as np
import pytest

from gpfverify.cli import main
from gpfverify.contract import ClaimRecord, Method, RunEntry, SectionRuns
from gpfverify.papers.fusion import ct2d_experiment as ct2d
from gpfverify.papers.fusion.run import FAMILIES, LOCAL_KEYS, METHOD_KEYS, one_step_equivalence
from gpfverify.papers.fusion.scenario import (CT_SENSOR_POSITIONS, ct_scenario, polar_to_cartesian,
                                               range_bearing, sensor_side, simulate_data, turn_matrix)
from gpfverify.tolerances import algebra_rtol

TINY = {"kappa": 12, "test_steps": 3, "fit_points": 12}
CONTRACT_METHODS = {f"{r}-{f}" for f in ("GP-ADF", "GP-UKF")
                    for r in ("Sensor1", "Sensor2", "CMF", "DMF", "RCC-CI", "CW")}
FIXTURES = Path(__file__).parent / "fixtures" / "ct2d"


@pytest.fixture(scope="module")
def cli_results(tmp_path_factory):
    out = tmp_path_factory.mktemp("ct2d")
    code = main(["reproduce", "ct2d", "--kappa", "12", "--omega", "0.0698", "--test-steps", "3",
                 "--fit-points", "12", "--runs", "2", "--seed", "1", "--out", str(out)])
    assert code == 0
    return json.loads((out / "results.json").read_text())


def test_results_follow_the_contract(cli_results):
    r = cli_results
    assert (r["experiment"], r["runs"], r["seed"], r["runs_ok"]) == ("ct2d", 2, 1, 2)
    assert set(r["rmse"]) == CONTRACT_METHODS == set(METHOD_KEYS)
    assert all(len(v) == 3 and all(np.isfinite(v)) for v in r["rmse"].values())
    assert set(r["full_rank_ratio"]) == {"Sensor1-GP-ADF", "Sensor2-GP-ADF", "Sensor1-GP-UKF", "Sensor2-GP-UKF"}
    assert all(len(v) == 3 and all(0.0 <= x <= 1.0 for x in v) for v in r["full_rank_ratio"].values())
    assert set(r["max_equivalence_gap"]) == set(FAMILIES)
    assert all(isinstance(v, float) for v in r["max_equivalence_gap"].values())
    assert set(r["time_per_step"]) == set(r["time_per_run"]) == CONTRACT_METHODS
    assert all(v > 0 for v in r["time_per_run"].values())
    assert "canonical correlations" in r["rank_tolerance"]  # the default rule


def test_params_record_every_interpretation_as_numbers(cli_results):
    p = cli_results["params"]
    assert p["sensor_positions"] == [[-200.0, 200.0], [200.0, 200.0]]
    assert p["kappa"] == 12 and p["omega"] == 0.0698
    assert (p["process_noise_var"], p["range_noise_var"]) == (5.0, 5.0)
    assert p["bearing_noise_var"] == (0.1 * np.pi / 180) ** 2
    assert (p["local_start"], p["fused_start"], p["rcc_on_empty"]) == \
        ("first-observation", "mean-of-sensor-starts", "enlarge")
    for key in ("training_start_var", "rank_tol", "fit_points", "restarts", "rcc_size", "alpha", "beta",
                "sigma_kappa", "perturbation_std"):
        assert key in p
    # no prose: every recorded value is a number, a choice word, a list of numbers or None
    assert all(not isinstance(v, str) or " " not in v for v in p.values())
    # κ < 300: the paper's N(20, 1) start perturbation; initial covariance its second moment
    assert cli_results["start_perturbation"] == {"mean": 20.0, "std": 1.0, "initial_cov_scale": 401.0}
    assert ct2d.Params().start_mean == 10.0 and ct2d.Params().start_cov_scale == 101.0  # κ = 300


def test_claims_are_records_of_every_paper_claim(cli_results):
    claims = [ClaimRecord.from_json(c) for c in cli_results["claims"] + cli_results["timing_claims"]]
    ids = {c.id for c in claims}
    # the wall-clock claims apart, among the timing fields (not compared across executions)
    assert "timing_claims" in cli_results["timing_keys"]
    assert all(c["timing"] for c in cli_results["timing_claims"])
    assert not any(c["timing"] for c in cli_results["claims"])
    for family in FAMILIES:
        for name in ("dmf-equals-cmf", "fusion-beats-sensors", "fusion-beats-baselines", "dmf-cheaper-than-cmf",
                     "rcc-ci-costs-most"):
            assert f"ct2d/{name}/{family}" in ids
    assert "ct2d/gp-ukf-loses-full-rank" in ids  # κ = 12 < 300
    assert all(c.n == 2 and c.paper_n == 1000 and c.setting == "κ = 12, Ω = 2π/90" for c in claims)
    assert {c.id.split("/")[1] for c in claims if c.timing} == {"dmf-cheaper-than-cmf", "dmf-update-cheaper-than-cmf",
                                                                "rcc-ci-costs-most", "cw-fastest",
                                                                "gp-ukf-fusion-time-vs-gp-adf"}
    assert not any(c.needs for c in claims)  # a run's summary keeps every per-run time the claims need
    equivalence = [c for c in claims if c.id.startswith("ct2d/dmf-equals-cmf/")]
    for c in equivalence:
        family = c.id.rsplit("/", 1)[1]
        gap = cli_results["one_step_gap"][family]
        assert c.statistic == gap["full_rank_steps_outside"] and c.group == "Proposition 1"
        assert gap["full_rank_steps_reproduced"] + gap["full_rank_steps_unresolved"] + c.statistic == \
            gap["steps_full_rank"]
        assert c.verdict == ("NOT held" if c.statistic else "held" if gap["full_rank_steps_reproduced"] else
                             "not decidable")


def test_rank_claim_only_for_small_training_sets():
    params = ct2d.Params(test_steps=3, fit_points=12)
    record = ct2d.run_one(params.replace(kappa=12), np.random.SeedSequence(4))
    big = ct2d.summarize(params.replace(kappa=300), [record])
    small = ct2d.summarize(params.replace(kappa=30), [record])
    assert not any(c.id == "ct2d/gp-ukf-loses-full-rank" for c in big["claims"])
    assert any(c.id == "ct2d/gp-ukf-loses-full-rank" for c in small["claims"])


def _one_run(seed=1, **overrides):
    return ct2d.run_one(ct2d.Params(**{**TINY, **overrides}), np.random.SeedSequence(seed))


def test_dmf_equals_cmf_on_every_full_rank_step():
    record = _one_run(seed=4)
    for family in FAMILIES:
        holds, reproduced, resolved = one_step_equivalence(record.families[family])
        assert holds.any() and reproduced[holds].all() and resolved[holds].all()


def test_forced_rank_failures_are_audited_and_match_the_closed_form_gap():
    # an absolute tolerance above every singular value: each C_xy^m counts as rank 0
    record = _one_run(seed=2, rank_tol=1e6)
    for family in FAMILIES:
        f = record.families[family]
        assert not any(f.condition_holds) and not any(f.full_rank[Method.sensor_filter(1, family).key])
        assert len(f.audit) == TINY["test_steps"]
        for entry in f.audit:
            assert entry.gap_norm > 0 and not entry.exact
            assert [s.rank for s in entry.sensors] == [0, 0]
            scale = entry.correction_norm + entry.gap_norm
            assert entry.gap_error <= algebra_rtol(1.0) * scale


def test_same_seed_same_numbers_other_seed_other_numbers():
    first, again, other = _one_run(seed=7), _one_run(seed=7), _one_run(seed=8)
    for family in FAMILIES:
        assert first.families[family].sq_err == again.families[family].sq_err
        assert first.families[family].singular_values == again.families[family].singular_values
    assert first.families["GP-ADF"].sq_err != other.families["GP-ADF"].sq_err


def test_full_rank_ratio_by_tolerance_is_monotone(cli_results):
    by_tol = cli_results["full_rank_ratio_by_relative_tolerance"]
    tols = sorted(by_tol, key=float)
    for name in LOCAL_KEYS:
        ratios = np.array([by_tol[t][name] for t in tols])
        assert np.all(np.diff(ratios, axis=0) <= 0)  # a larger tolerance never raises the ratio


def test_range_bearing_inverts_and_simulation_is_consistent():
    rng = np.random.default_rng(0)
    x = rng.normal(0.0, 50.0, size=(20, 2))
    for z in CT_SENSOR_POSITIONS:
        y = range_bearing(np.array(z))(x)
        back = np.array([polar_to_cartesian(row, z, sensor_side(z)) for row in y])
        np.testing.assert_allclose(back, x, rtol=0, atol=algebra_rtol(1.0) * 300)
    data = simulate_data(ct_scenario(0.5, 15, 4), rng)
    np.testing.assert_array_equal(data.transition_targets[:-1], data.transition_inputs[1:])
    assert data.transition_inputs.shape == (14, 2) and data.measurement_inputs.shape == (15, 2)
    assert data.test_states.shape == (4, 2) and data.stacked_test_measurements().shape == (4, 4)
    F = turn_matrix(0.5)
    np.testing.assert_allclose(F @ F.T, np.eye(2), atol=algebra_rtol(1.0))


def test_scenario_from_params_is_the_papers_model():
    """The experiment builds its model from Params; with the defaults it equals the scenario module's."""
    params = ct2d.Params(kappa=15, test_steps=4)
    ours, reference = ct2d.scenario(params).model, ct_scenario(params.omega, 15, 4).model
    np.testing.assert_array_equal(ours.Q, reference.Q)
    np.testing.assert_array_equal(ours.prior_cov, reference.prior_cov)
    for a, b in zip(ours.sensors, reference.sensors):
        np.testing.assert_array_equal(a.noise_cov, b.noise_cov)


def _section_input(tmp_path, names):
    entries, results = [], []
    for name in names:
        r = json.loads((FIXTURES / f"{name}.json").read_text())
        label = ct2d.Params.from_json(r["params"]).label + ("" if name.startswith("k12") else f" ({name})")
        entries.append(RunEntry("ct2d", label, name, f"{name}.json"))
        results.append(r)
    from gpfverify.report.inputs import SectionInput

    return SectionInput("ct2d", tmp_path, SectionRuns("ct2d", "quick", 1, tuple(entries)), tuple(results))


def test_page_renders_from_stored_results(tmp_path):
    from gpfverify.report.render import to_markdown
    from gpfverify.papers.fusion import ct2d_section as fusion_ct2d

    section = fusion_ct2d.render_section(_section_input(tmp_path, ["k12-w0.0698", "forced-rank-failure"]))
    page = to_markdown(section, tmp_path)
    assert "Claims of Liao et al. 2019 checked — κ = 12, Ω = 2π/90" in page and "Rank-failure audit" in page
    assert "Multisensor Estimation Fusion with Gaussian Process" in page  # cited in full
    for kind in ("rmse", "full-rank", "time"):
        assert (tmp_path / f"{kind}-k12-w0.0698.png").stat().st_size > 5_000
    # every forced rank failure is listed, the closed-form gap beside the actual one
    audit_rows = [line for line in page.splitlines() if "(forced-rank-failure) |" in line and "rank 0/2" in line]
    forced = json.loads((FIXTURES / "forced-rank-failure.json").read_text())
    assert len(audit_rows) == forced["runs_ok"] * len(FAMILIES) * forced["params"]["test_steps"]
    assert "GP-ADF: DMF = CMF when the rank condition holds" in page
    # the verdicts under each interpretation tried, with the robustness sentence; health; both timings
    assert "Verdicts under each interpretation tried — κ = 12, Ω = 2π/90" in page
    table = page.split("Verdicts under each interpretation tried")[1]
    assert all(f"| {name} |" in table for name in ("numpy-rank", "initial-cov-wide", "sensors-z1-below"))
    assert "interpretations tried" in page  # robustness(): "... under all 4 interpretations tried" or "depends"
    assert "Health of the filters compared" in page and "CMF-GP-UKF" in page
    assert "(the update alone)" in page and "(whole fusion step)" in page
    assert "rests on 2 runs; the paper used 1000" in page or "⚠" in page
    # Unicode maths, no pseudo-LaTeX
    assert "x_{k+1}" not in page and "xₖ₊₁" in page


def test_method_styles_separate_the_families():
    from gpfverify.papers.fusion.contract import METHODS
    from gpfverify.papers.fusion.section import method_style

    styles = {m: method_style(m) for m in METHODS}
    assert len({s["color"] for s in styles.values()}) == len(METHODS)
    for family, other in (("GP-ADF", "GP-UKF"), ("GP-UKF", "GP-ADF")):
        mine = {s["color"] for m, s in styles.items() if m.family == family}
        theirs = {s["color"] for m, s in styles.items() if m.family == other}
        assert not mine & theirs
        assert len({s["linestyle"] for m, s in styles.items() if m.family == family}) == 1
    assert styles[Method("CMF", "GP-ADF")]["linestyle"] != styles[Method("CMF", "GP-UKF")]["linestyle"]
