"""sins-gps sensitivity parameters: each filter-design
choice changes what it says, the health checks flag a collapsed or diverged particle filter in this
setting, and the declared interpretations are valid parameter changes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from gpfverify.papers.gpsr_upf.contract import INTERPRETATIONS, ROUGHENING_CONSTANT, Params
from gpfverify.papers.gpsr_upf import experiment as sins_gps
from gpfverify.filters.resampling import Particles, ParticleStep
from gpfverify.contract.claims import ClaimRecord
from gpfverify.papers.gpsr_upf.scenario import VELOCITY

SHORT = Params(particles=8, duration=40.0, train_points=20)


def test_interpretations_are_valid_parameter_changes():
    names = [spec.name for spec in INTERPRETATIONS]
    assert len(set(names)) == len(names) and all(spec.why for spec in INTERPRETATIONS)
    base = Params()
    for spec in INTERPRETATIONS:
        changed = base.replace(**spec.changes)  # validates
        assert changed != base
        for field in dataclasses.fields(Params):
            expected = spec.changes.get(field.name, getattr(base, field.name))
            assert getattr(changed, field.name) == expected


def test_defaults_are_the_faithful_configuration():
    p = Params()
    assert (p.q_inflation, p.particle_covariance, p.jitter) == (1.0, "propagated", "none")


def test_q_inflation_scales_both_filters_design_q():
    _, models, upf1, gpsr1, _ = sins_gps.setup(SHORT)
    _, _, upf10, gpsr10, _ = sins_gps.setup(SHORT.replace(q_inflation=10.0))
    np.testing.assert_allclose(upf1.Q, models.approx.Q)
    np.testing.assert_allclose(upf10.Q, 10.0 * models.approx.Q)
    x = np.random.default_rng(0).normal(size=(3, 15))
    q1, q10 = gpsr1.process_cov(x, 20), gpsr10.process_cov(x, 20)
    outside = np.ones((15, 15), bool)
    outside[VELOCITY, VELOCITY] = False
    np.testing.assert_allclose(q10[:, outside], 10.0 * q1[:, outside])
    # the learned velocity block: the same GP variance plus (10 − 1) Q_vv
    extra = 9.0 * models.approx.Q[VELOCITY, VELOCITY]
    np.testing.assert_allclose(q10[:, VELOCITY, VELOCITY], q1[:, VELOCITY, VELOCITY] + extra)


def _resampled_step(n: int, rng) -> ParticleStep:
    x = rng.uniform(-1.0, 1.0, size=(n, 2)) * np.array([1.0, 5.0])
    weighted = Particles(x, np.full(n, -np.log(n)))
    cov = np.array([[0.3, 0.1], [0.1, 2.0]])
    return ParticleStep(weighted, weighted, x.mean(axis=0), cov, 1.0, True)


def test_roughening_adds_k_e_n_to_the_minus_one_over_d():
    rng = np.random.default_rng(1)
    step = _resampled_step(40000, rng)
    moved = sins_gps.jitter_particles(step, "roughening", rng).particles - step.posterior.particles
    expected = ROUGHENING_CONSTANT * np.ptp(step.posterior.particles, axis=0) * 40000 ** (-1 / 2)
    np.testing.assert_allclose(moved.std(axis=0), expected, rtol=0.03)
    np.testing.assert_allclose(moved.mean(axis=0), 0.0, atol=0.03 * expected.max())


def test_regularisation_kernel_has_the_optimal_bandwidth_times_the_weighted_covariance():
    rng = np.random.default_rng(2)
    step = _resampled_step(40000, rng)
    moved = sins_gps.jitter_particles(step, "regularised", rng).particles - step.posterior.particles
    h = (4.0 / (40000 * 4)) ** (1.0 / 6)
    np.testing.assert_allclose(np.cov(moved.T), h**2 * step.cov, rtol=0.05, atol=0.05 * h**2 * 0.3)


def test_no_move_without_resampling_or_without_jitter():
    rng = np.random.default_rng(3)
    step = _resampled_step(50, rng)
    assert sins_gps.jitter_particles(step, "none", rng) is step.posterior
    kept = dataclasses.replace(step, resampled=False)
    assert sins_gps.jitter_particles(kept, "roughening", rng) is kept.posterior


def _health(params: Params, seed: int = 7):
    record = sins_gps.run_one(params, np.random.SeedSequence(seed))
    return record, {(c.subject, c.name): c for c in sins_gps.health_checks(params, [record])}


def test_the_faithful_upf_collapses_and_is_flagged():
    """With the true Q each particle's UKF proposal is far wider than p(x_k | x_k−1): the weights
    collapse onto about one particle and the ess check fails for both filters."""
    record, checks = _health(SHORT)
    for method in ("UPF", "GPSR-UPF"):
        run = record.particle_filters[method]
        assert len(run.ess_fraction) == 40 and np.mean(run.ess_fraction) == pytest.approx(run.ess_mean)
        check = checks[(method, "weight collapse")]
        assert not check.passed and check.statistic < 1.5 / SHORT.particles and "one particle" in check.detail
    claim = ClaimRecord("c", "s", "NOT held", 0.0, 0.0, 1, "e").checked(["UPF", "GPSR-UPF"], checks.values())
    assert claim.verdict == "not decidable" and claim.would_be == "NOT held"
    assert {c.name for h in claim.failed_filters for c in h.failed} == {"weight collapse"}


def test_the_point_proposal_keeps_the_weights_healthy():
    """particle_covariance = 'reset': the proposal from the particle itself (optimal importance
    density of the linear model) — N_eff/N stays far from 1/N."""
    _, checks = _health(SHORT.replace(particle_covariance="reset", q_inflation=100.0))
    for method in ("UPF", "GPSR-UPF"):
        assert checks[(method, "weight collapse")].passed
        assert checks[(method, "weight collapse")].statistic > 0.3


def test_divergence_is_flagged():
    record, _ = _health(SHORT)
    bound = sins_gps.divergence_bounds(SHORT)["position"]
    run = record.particle_filters["UPF"]
    far = tuple((2 * bound, 0.0, 0.0) for _ in run.position)
    broken = dataclasses.replace(record, particle_filters={**record.particle_filters,
                                                           "UPF": dataclasses.replace(run, position=far)})
    checks = {(c.subject, c.name): c for c in sins_gps.health_checks(SHORT, [broken, record])}
    assert not checks[("UPF position", "divergence")].passed
    assert checks[("UPF position", "divergence")].statistic == 0.5
    assert checks[("GPSR-UPF position", "divergence")].passed


def test_page_lists_each_configuration_with_its_health(tmp_path):
    """The reference page's results.json carries the interpretations' health and errors
    (``interpretation_summaries``); the page shows them per configuration and filter."""
    import json
    from pathlib import Path

    from gpfverify.report.document import Table
    from gpfverify.papers.gpsr_upf import section

    stored = Path(__file__).parent / "fixtures" / "sins_gps" / "sins-gps-small" / "results.json"
    results = json.loads(stored.read_text())
    healthy = [dict(c, passed=True) for c in results["health"]]
    results["interpretation_summaries"] = {"point-proposal-q-x100": {
        "changes": {"particle_covariance": "reset", "q_inflation": 100.0}, "runs_ok": 2, "health": healthy,
        "mean_ess_fraction": {"UPF": 0.6, "GPSR-UPF": 0.5}, "rms": results["rms"], "reduction": results["reduction"],
        "reference_rms": results["reference"]["rms"]}}
    claims = {c["id"]: {k: c[k] for k in ("verdict", "statistic", "runs_to_decide", "evidence")}
              for c in results["claims"]}
    results["confirmation"] = {"interpretation": "point-proposal-q-x1000", "command": "gpfverify reproduce X",
                               "runs_ok": 10, "health": healthy, "mean_ess_fraction": {"UPF": 0.5, "GPSR-UPF": 0.5},
                               "rms": results["rms"], "claims": claims}
    page = section.render(results, tmp_path)
    from gpfverify.report.document import Paragraph
    text = " ".join(b.text for b in page.blocks if isinstance(b, Paragraph))
    assert "Confirmation at more runs of point-proposal-q-x1000 (`gpfverify reproduce X`, 10 runs" in text
    assert f"position: {claims['sins-gps/reduction-position']['verdict']}" in text
    (table,) = [b for b in page.blocks if isinstance(b, Table) and b.caption.startswith("Each configuration")]
    assert [row[0] for row in table.rows] == ["as run", "as run", "point-proposal-q-x100", "point-proposal-q-x100"]
    assert table.rows[0][4].startswith("FAILED: weight collapse") and table.rows[2][4] == "passed"
    assert table.rows[2][3] == 0.6
