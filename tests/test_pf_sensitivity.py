"""Sensitivity parameters and health checks of the particle-flow experiments (pff1d, bearing):
each parameter changes what it says, the health checks flag a diverged flow and a collapsed PF in
the experiments' own settings, and the declared interpretations are valid parameter changes."""

import dataclasses

import numpy as np
import pytest

from gpfverify.contract.claims import read_claims
from gpfverify.papers.particle_flow.contract import IE_PFF, PF
from gpfverify.errors import InputError
from gpfverify.papers.particle_flow import bearing_experiment as bearing
from gpfverify.papers.particle_flow import pff1d_experiment as pff1d
from gpfverify.papers.particle_flow.methods import (ess_health, flow_steps, paired_comparison, run_method,
                                                    schedule_words)
from gpfverify.experiments.runner import run_experiment
from gpfverify.health import HealthCheck
from gpfverify.papers.particle_flow.pff1d_scenario import ungm_model

TINY = dict(steps=6, particles=20, table_q=(10.0,), table_r=(1.0,), gamma_r=(0.1,), gamma_dlambda=0.1)


@pytest.mark.parametrize("module", [pff1d, bearing])
def test_interpretations_are_valid_named_changes(module):
    names = [s.name for s in module.INTERPRETATIONS]
    assert len(names) == len(set(names)) >= 4
    for spec in module.INTERPRETATIONS:
        for profile in module.PROFILES.values():
            for setting in profile.settings:
                changed = setting.params.replace(**spec.changes)  # validates
                assert any(getattr(changed, k) != getattr(setting.params, k) for k in spec.changes), spec.name
        assert spec.why


def test_exponential_schedule_grows_and_sums_to_one():
    uniform = flow_steps(0.1, "uniform", 1.2)
    assert len(uniform) == 10 and np.allclose(uniform, 0.1)
    steps = flow_steps(0.1, "exponential", 1.2)
    assert len(steps) == 10 and steps.sum() == pytest.approx(1.0)
    assert np.allclose(steps[1:] / steps[:-1], 1.2) and steps[0] < 0.1 < steps[-1]
    # the number of steps: Li & Coates' 29 whatever Δλ; the uniform schedule ignores it
    for dlam in (0.1, 0.01):
        li = flow_steps(dlam, "exponential", 1.2, 29)
        assert len(li) == 29 and li.sum() == pytest.approx(1.0) and np.allclose(li[1:] / li[:-1], 1.2)
    assert len(flow_steps(0.1, "uniform", 1.2, 29)) == 10
    # the ratio: steeper first steps
    assert flow_steps(0.1, "exponential", 1.5)[0] < steps[0]
    assert "29 exponential λ-steps (ratio 1.2" in schedule_words(0.1, "exponential", 1.2, 29)


def test_noise_values_read_as_standard_deviations_square_the_variances():
    grid = dict(table_q=(10.0,), table_r=(0.1,), gamma_r=(0.1,))
    as_var = {(c, q, r): m for c, q, r, m, *_ in pff1d._cases(pff1d.Params(**grid))}
    as_std = {(c, q, r): m for c, q, r, m, *_ in pff1d._cases(pff1d.Params(noise_values="std", **grid))}
    assert as_var.keys() == as_std.keys()  # the grid keeps the values as stated
    ungm_var, ungm_std = as_var[("ungm", 10.0, 0.1)], as_std[("ungm", 10.0, 0.1)]
    assert np.allclose(ungm_var.Q, 10.0) and np.allclose(ungm_var.R, 0.1)
    assert np.allclose(ungm_std.Q, 100.0) and np.allclose(ungm_std.R, 0.01)
    gamma_var = next(m for (c, *_), m in as_var.items() if c == "gamma")
    gamma_std = next(m for (c, *_), m in as_std.items() if c == "gamma")
    assert np.allclose(gamma_var.R, 0.1) and np.allclose(gamma_std.R, 0.01)
    # bearing: r1, r2 read as standard deviations give the model of the squared values
    std = bearing.Params(noise_values="std")
    assert std.process_variances == pytest.approx((0.05 ** 2, 0.1 ** 2))
    squared = bearing.Params(q_pos=0.05 ** 2, q_vel=0.1 ** 2)
    assert np.allclose(bearing._model(std).Q, bearing._model(squared).Q)
    assert not np.allclose(bearing._model(std).Q, bearing._model(bearing.Params()).Q)


def test_bearing_std_and_schedule_reach_the_model_and_the_claim():
    model = bearing._model(bearing.Params(bearing_std=0.005))
    assert np.allclose(model.R, 0.005 ** 2)
    res = bearing.summarize(bearing.Params(duration=3, spacing="exponential", exponential_steps=29),
                            [bearing.run_one(bearing.Params(duration=3, spacing="exponential", exponential_steps=29),
                                             np.random.SeedSequence(i)) for i in range(2)])
    assert "29 exponential λ-steps" in res["claims"][0].setting


def test_a_flow_diverging_under_one_schedule_only_makes_the_claim_not_decidable(tmp_path):
    # Δλ = 0.1 explicit Euler at Q = 10 diverges; Δλ = 0.001 does not: the Δλ = 0.1 claim compares
    # a diverged flow whose divergence is the schedule's, so it is not decidable
    params = pff1d.Params(dlambda=(0.1, 0.001), spacings=("uniform",), **TINY)
    res = run_experiment(pff1d, params, 3, 1, tmp_path, show_progress=False)
    checks = {(c["subject"], c["name"]): c for c in res["health"]}
    coarse = checks[("IE-PFF Δλ=0.1 uniform (UNGM Q = 10, R = 1)", "divergence")]
    fine = checks[("IE-PFF Δλ=0.001 uniform (UNGM Q = 10, R = 1)", "divergence")]
    assert not coarse["passed"] and coarse["statistic"] > 0 and fine["passed"]
    claims = {c.id: c for c in read_claims(res)}
    withheld = claims["pff1d/ie-pff-beats-pf-and-edh-at-large-q/dlambda=0.1"]
    assert withheld.verdict == "not decidable"
    assert ("IE-PFF Δλ=0.1 uniform (UNGM Q = 10, R = 1)", "divergence") in {
        (c.subject, c.name) for h in withheld.failed_filters for c in h.failed}
    assert claims["pff1d/ie-pff-beats-pf-and-edh-at-large-q/dlambda=0.001"].verdict != "not decidable"


def test_a_divergence_is_named_as_the_integrators_step_size_instability(tmp_path):
    """A flow that diverges under every schedule tried is still not decided on: explicit Euler
    diverges for large steps whatever the flow, so the comparisons of that flow are withheld and
    the claim says why."""
    params = pff1d.Params(dlambda=(0.1,), spacings=("uniform",), **TINY)
    res = run_experiment(pff1d, params, 3, 1, tmp_path, show_progress=False)
    claim = next(c for c in read_claims(res) if c.id == "pff1d/ie-pff-beats-pf-and-edh-at-large-q/dlambda=0.1")
    assert claim.verdict == "not decidable"
    text = " ".join(claim.caveats)
    assert "step-size instability" in text and "not a failure of the continuous flow" in text
    assert "withheld: R = " in text and "method's failure" not in text


def test_the_papers_fig1b_cell_is_a_claim_and_the_linear_measurement_reaches_the_model():
    params = pff1d.Params(steps=4, particles=10, table_q=(1.0,), table_r=(0.1,), dlambda=(0.01,),
                          spacings=("uniform",), gamma_r=(0.1,), gamma_dlambda=0.1)
    res = pff1d.summarize(params, [pff1d.run_one(params, np.random.SeedSequence(i)) for i in range(2)])
    fig1b = next(c for c in res["claims"] if c.id == "pff1d/ie-pff-beats-pf-and-edh-fig1b/dlambda=0.01")
    assert "Fig. 1(b)" in fig1b.source and "Q = 1, R = 0.1" in fig1b.setting
    assert fig1b.evidence.startswith("R = 0.1: IE-PFF vs PF:") and "R = 0.1: IE-PFF vs EDH:" in fig1b.evidence
    assert fig1b.source == "§3.1, Fig. 1(b)" and fig1b.quote.startswith("由圖1")
    linear = {c: m for c, _, _, m, *_ in pff1d._cases(params.replace(ungm_measurement="linear"))}["ungm"]
    x = np.array([[-3.0], [2.0]])
    assert np.allclose(linear.measures[0](x), x)  # one-to-one: y = x
    quadratic = {c: m for c, _, _, m, *_ in pff1d._cases(params)}["ungm"]
    assert np.allclose(quadratic.measures[0](x), x * x / 20.0)


def test_the_van_der_merwe_reading_runs_the_table1_grid_on_that_model_with_gaussian_noise():
    """table_model 'vdm': every cell of the grid is the benchmark of the gamma case (x_k = 1 +
    sin(0.04π(k − 1)) + x_{k−1}/2 + w_k, y = 0.2x² up to k = 30 and x/2 − 2 after) with w ~ N(0, Q):
    the model against those equations, its noise against Q by Monte Carlo, the claims' setting naming
    it; and the reading is compared on the Table-1 claims only."""
    from gpfverify.papers.particle_flow.pff1d_contract import INTERPRETATIONS
    from gpfverify.tolerances import MONTE_CARLO_SIGMAS, monte_carlo_atol

    params = pff1d.Params(steps=4, particles=10, table_q=(1.0, 10.0), table_r=(0.1,), dlambda=(0.01,),
                          spacings=("uniform",), gamma_r=(0.1,), gamma_dlambda=0.1, table_model="vdm")
    cases = {(c, q): m for c, q, _, m, *_ in pff1d._cases(params)}
    assert {c for c, _ in cases} == {"vdm", "gamma"}
    model = cases[("vdm", 10.0)]
    x = np.array([[-1.5], [0.5], [3.0]])
    for k in (1, 17, 30, 31, 50):
        assert np.allclose(model.f(x, k), 1.0 + np.sin(0.04 * np.pi * (k - 1)) + 0.5 * x)
        assert np.allclose(model.measures[0](x, k), 0.2 * x * x if k <= 30 else 0.5 * x - 2.0)
    assert np.allclose(model.Q, 10.0) and np.allclose(model.R, 0.1)
    assert np.allclose(model.prior_mean, 1.0) and np.allclose(model.prior_cov, 0.75)
    draws = model.sample_transition(np.zeros((40_000, 1)), 5, np.random.default_rng(3))[:, 0] - model.f(
        np.zeros((1, 1)), 5)[0, 0]
    assert abs(draws.mean()) <= monte_carlo_atol(draws.std(), draws.size)
    assert abs(draws.var() - 10.0) <= MONTE_CARLO_SIGMAS * 10.0 * np.sqrt(2.0 / draws.size)
    res = pff1d.summarize(params, [pff1d.run_one(params, np.random.SeedSequence(i)) for i in range(2)])
    fig1b = next(c for c in res["claims"] if c.id == "pff1d/ie-pff-beats-pf-and-edh-fig1b/dlambda=0.01")
    assert fig1b.setting.startswith("vdM-Gaussian, Q = 1, R = 0.1")
    assert {(r.Q, r.R) for r in res["table1"]} == {(1.0, 0.1), (10.0, 0.1)}
    vdm = next(s for s in INTERPRETATIONS if s.name == "vdm-gaussian")
    assert vdm.changes["table_model"] == "vdm"
    assert [c.id for c in res["claims"] if vdm.bears_on_claim(c.id)] == [
        c.id for c in res["claims"] if c.id.startswith("pff1d/ie-pff-beats-pf-and-edh")] != []
    with pytest.raises(InputError, match="--ungm-measurement linear applies to the UNGM only"):
        params.replace(ungm_measurement="linear")


def test_weight_collapse_is_flagged_in_the_experiments_settings():
    # a near-noiseless measurement: the bootstrap PF's weights collapse onto one particle
    model = ungm_model(10.0, 1e-8)
    _, ys = model.simulate(20, np.random.default_rng(0))
    run = run_method(PF, model, ys, 50, np.random.default_rng(1))
    assert run.ess_fraction is not None and run.ess_fraction.shape == (20,)
    check = ess_health("PF", [tuple(run.ess_fraction)], 50)
    assert isinstance(check, HealthCheck) and not check.passed and "collapsed" in check.detail
    assert run_method(IE_PFF, model, ys, 20, np.random.default_rng(1), flow_steps(0.1, "uniform", 1.2)).ess_fraction \
        is None
    # bearing: a very precise sensor collapses both PFs; the accuracy claim is then not decidable
    params = bearing.Params(duration=5, bearing_std=1e-6)
    res = bearing.summarize(params, [bearing.run_one(params, np.random.SeedSequence(i)) for i in range(2)])
    collapse = [c for c in res["health"] if c["name"] == "weight collapse"]
    assert collapse and not any(c["passed"] for c in collapse)
    accuracy = res["claims"][0]
    assert accuracy.verdict == "not decidable" and accuracy.would_be is not None
    assert "weight collapse" in {c.name for h in accuracy.failed_filters for c in h.failed}


def test_undecided_comparisons_state_the_runs_that_would_decide():
    rng = np.random.default_rng(3)
    worse = rng.normal(5.0, 1.0, 30)
    c = paired_comparison(list(worse - 0.1 + rng.normal(0, 1.0, 30)), list(worse), 0.05)
    assert c.verdict == "undecided" and c.t is not None and c.critical is not None
    assert c.runs_to_decide == int(np.ceil(30 * (c.critical / abs(c.t)) ** 2)) > 30
    decided = dataclasses.replace(c, verdict="held")
    assert decided.runs_to_decide is None


def test_a_ratio_claim_is_the_paired_t_test_of_the_log_ratios_against_the_bound():
    """ "Within a factor of" (does well, not improved by more particles): Student's t of the per-run
    log ratios against log(bound), computed here by scipy, decides it at the page's level."""
    from scipy.stats import ttest_1samp

    from gpfverify.papers.particle_flow.methods import ratio_comparison

    rng = np.random.default_rng(11)
    b = rng.uniform(0.5, 2.0, 30)
    a = 1.2 * b * np.exp(rng.normal(0.0, 0.1, b.size))
    for bound, verdict in ((1.5, "held"), (1.0, "NOT held")):
        c = ratio_comparison(list(a), list(b), bound, 0.05)
        expected = ttest_1samp(np.log(a / b) - np.log(bound), 0.0)
        assert c.t == pytest.approx(expected.statistic, rel=1e-10) and c.verdict == verdict
    lost = ratio_comparison([None, *a[1:]], list(b), 1.5, 0.05)  # a diverged where b did not: a loss
    assert lost.verdict == "NOT held" and lost.lost == 1
