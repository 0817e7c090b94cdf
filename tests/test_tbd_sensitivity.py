"""The tbd sensitivity study: each interpretation parameter
changes what it says, the interpretations are valid parameter changes, the health checks flag a
collapsed or diverged filter and withhold the verdicts resting on it, and the Monte Carlo
intervals behind the verdicts (bootstrap of the SNR gain, paired differences of Pd) state the runs
that would decide an undecided claim. Tiny run counts throughout."""

import math
from dataclasses import fields

import numpy as np
import pytest

from gpfverify.contract import read_claims, to_json
from gpfverify.contract.params import Params as BaseParams
from gpfverify.papers.tbd.contract import (INTERPRETATIONS, SNR_CONVENTIONS, MethodRun, Params, RunRecord, SnrRun,
                                   TbdMethod, main_methods, sweep_methods)
from gpfverify.papers.tbd import experiment as tbd
from gpfverify.experiments.runner import run_experiment
from gpfverify.filters.tbd import TbdModel, filter_sequence, pf_tbd_step, tpf_tbd_step
from gpfverify.filters.tbd.pf import initial_belief
from gpfverify.health import MIN_ESS_FRACTION
from gpfverify.papers.tbd.scenario import energy_factor, noise_std_for_snr, simulate

SMALL = Params(snr=(4.0, 6.0, 9.0), particles=80, tpf_particles=(80, 40), zeta_sweep_particles=40,
               zeta_sweep=(1.0, 0.6, 0.4), bootstrap=50)


# ---- interpretations ----------------------------------------------------------------------------
def test_interpretations_are_valid_named_parameter_changes():
    names = [s.name for s in INTERPRETATIONS]
    assert len(names) == len(set(names)) >= 5
    field_names = {f.name for f in fields(Params)} - {f.name for f in fields(BaseParams)}
    for spec in INTERPRETATIONS:
        assert spec.changes and set(spec.changes) <= field_names and spec.why
        changed = Params().replace(**spec.changes)  # validates
        assert isinstance(changed, Params) and changed != Params()
        assert all(getattr(changed, k) == v for k, v in spec.changes.items())
    # the readings of the lost details: SNR convention, patch size, N
    changed_fields = {k for s in INTERPRETATIONS for k in s.changes}
    assert {"snr_convention", "patch_radius", "second_stage_radius", "particles"} <= changed_fields
    assert {s.changes.get("snr_convention") for s in INTERPRETATIONS} >= {"intensity", "energy"}
    assert tbd.INTERPRETATIONS is INTERPRETATIONS  # the runner reads them from the experiment module


def test_the_snr_conventions_set_sigma_as_documented():
    p = Params()
    i0 = p.initial_state[-1]
    peak = i0 / (2 * math.pi * p.blur**2)  # Δ = 1
    for snr in (1.0, 6.0, 9.0):
        sigma = {c: tbd.model_of(p.replace(snr_convention=c), snr).noise_std for c in SNR_CONVENTIONS}
        assert 20 * math.log10(peak / sigma["peak"]) == pytest.approx(snr)
        assert 20 * math.log10(i0 / sigma["intensity"]) == pytest.approx(snr)
        # energy: the target's energy over the cells, a target centred on a cell, not truncated
        model = TbdModel(patch_radius=10, noise_std=1.0)
        energy = float(np.sum(model.expected_image(np.array([10.0, 0.0, 10.0, 0.0, i0])) ** 2))
        assert 10 * math.log10(energy / sigma["energy"] ** 2) == pytest.approx(snr)
    # at Σ = 0.7 the energy is 2.0 dB above the peak pixel's power and I₀² 9.8 dB above it
    assert 10 * math.log10(energy_factor(TbdModel())) == pytest.approx(2.01, abs=0.01)
    assert 20 * math.log10(noise_std_for_snr(6.0, i0, TbdModel(), "intensity")
                           / noise_std_for_snr(6.0, i0, TbdModel(), "peak")) == pytest.approx(9.8, abs=0.05)
    # and the images are simulated with that σ
    model = tbd.model_of(p.replace(snr_convention="energy"), 6.0)
    seq = simulate(model, tbd.scenario_of(p), np.random.default_rng(0), target=False)
    assert np.std(seq.images) == pytest.approx(model.noise_std, rel=0.02)


def test_the_patch_radii_change_the_likelihood_and_the_second_stage():
    p = Params(particles=40)
    image_rng = np.random.default_rng(1)
    for radius in (1, 2):
        model = tbd.model_of(p.replace(patch_radius=radius), 6.0)
        assert model.patch_radius == radius
        assert model.patch_cells(np.array([10.2])).shape == (1, 2 * radius + 1)
    states = np.array([[10.2, 0.0, 9.7, 0.0, 20.0]])
    image = image_rng.standard_normal((20, 20))
    lr = [tbd.model_of(p.replace(patch_radius=r), 6.0).log_likelihood_ratio(states, image)[0] for r in (1, 2)]
    assert lr[0] != lr[1]
    for radius in (1, 2):
        params = p.replace(second_stage_radius=radius)
        model = tbd.model_of(params, 6.0)
        config = tbd._config(params, TbdMethod("TPFTBD", 40))
        assert config.second_stage_radius == radius
        belief = initial_belief(model, config, np.random.default_rng(0))
        step = tpf_tbd_step(belief, model, image, rng=np.random.default_rng(2), config=config,
                            second_rng=np.random.default_rng(3))
        assert step.second_stage.cells_x.size == (2 * radius + 1) ** 2  # the (2r+1)² patch, inside the image


def test_the_particle_interpretation_doubles_every_count():
    spec = next(s for s in INTERPRETATIONS if s.name == "particles-4000")
    p = Params().replace(**spec.changes)
    assert [m.key for m in main_methods(p)] == ["PFTBD-N4000", "TPFTBD-N4000", "TPFTBD-N2000"]
    assert {m.particles for m in sweep_methods(p)} == {4000, 2000}
    assert tbd._config(p, main_methods(p)[0]).n_particles == 4000


def test_filter_sequence_records_n_eff_of_every_frame():
    """N_eff/N per frame, 1 / Σ w² / N of the weighted set, recomputed from the step functions."""
    p = Params(particles=60)
    model = tbd.model_of(p, 6.0)
    seq = simulate(model, tbd.scenario_of(p), np.random.default_rng(3), True)
    for method in (TbdMethod("PFTBD", 60), TbdMethod("TPFTBD", 60)):
        config = tbd._config(p, method)
        got = filter_sequence(seq.images, model, config, np.random.default_rng(1), np.random.default_rng(2))
        rng, second = np.random.default_rng(1), np.random.default_rng(2)
        belief, expected = initial_belief(model, config, rng), []
        for k, image in enumerate(seq.images):
            step = (tpf_tbd_step(belief, model, image, k=k + 1, rng=rng, config=config, second_rng=second)
                    if config.two_stage else pf_tbd_step(belief, model, image, k=k + 1, rng=rng, config=config))
            w = np.exp(step.weighted.log_weights - np.max(step.weighted.log_weights))
            expected.append(1.0 / np.sum((w / w.sum()) ** 2) / w.size)
            belief = step.posterior
        np.testing.assert_allclose(got.ess_fraction, expected, rtol=1e-12)
        assert got.ess_fraction.shape == (p.frames,)


# ---- health -------------------------------------------------------------------------------------
def test_a_bright_target_collapses_the_filter_and_its_verdicts_are_withheld(tmp_path):
    """At 30 dB the likelihood is so peaked that the weighted set carries its mass on one particle
    (N_eff/N = 1/N): the weight-collapse check fails and every detection claim resting on the
    collapsed filters becomes 'not decidable', with the numbers in its caveats."""
    p = Params(snr=(28.0, 30.0), particles=100, tpf_particles=(100, 50), zeta_sweep_particles=50,
               zeta_sweep=(1.0, 0.6, 0.4), bootstrap=20)
    results = run_experiment(tbd, p, 2, 3, tmp_path, show_progress=False)
    by_key = {(h["method"], h["snr_db"]): h for h in results["health"]}
    collapse = {c["name"]: c for c in by_key[("PFTBD-N100", 30.0)]["checks"]}["weight collapse"]
    assert not collapse["passed"] and collapse["statistic"] <= MIN_ESS_FRACTION
    assert "collapsed" in collapse["detail"]
    withheld = 0
    for claim in read_claims(results):
        collapsed = [c for h in claim.failed_filters for c in h.failed if c.name == "weight collapse"]
        if collapsed:  # the record carries the failed check with its numbers; the gate withheld the verdict
            withheld += 1
            assert claim.verdict == "not decidable" and claim.would_be is not None, claim.id
            assert claim.runs_to_decide is None and all("N_eff/N" in c.detail for c in collapsed)
    assert withheld >= 4  # the gain and every detection claim at 30 dB


def _summary(records: list[RunRecord]) -> dict:
    """The results body as results.json holds it (claims as JSON)."""
    return to_json(tbd.summarize(SMALL, records))


def _records(runs: int, *, ess: float = 0.3, sq_error: float = 1.0, seed: int = 0) -> list[RunRecord]:
    """Made-up run records for SMALL: random existence, the given N_eff/N and squared error."""
    rng = np.random.default_rng(seed)
    frames = SMALL.frames
    keys = [m.key for m in main_methods(SMALL) + sweep_methods(SMALL)]
    out = []
    for _ in range(runs):
        cases = []
        for snr in SMALL.snr:
            methods = {k: MethodRun(tuple(rng.random(frames).tolist()), tuple(rng.random(frames).tolist()),
                                    (sq_error,) * 16, (ess,) * frames) for k in keys}
            cases.append(SnrRun(snr, methods))
        out.append(RunRecord(tuple(cases), {k: 1.0 for k in keys}))
    return out


def test_a_diverged_filter_is_flagged():
    healthy = _summary(_records(4))
    assert all(c["passed"] for h in healthy["health"] for c in h["checks"])
    far = _summary(_records(4, sq_error=1e6))  # 1000 cells off a 20-cell image
    for h in far["health"]:
        div = {c["name"]: c for c in h["checks"]}["divergence"]
        assert not div["passed"] and div["statistic"] == 1.0 and h["track_loss"] == 1.0
    assert all(c.verdict == "not decidable" for c in read_claims(far) if not c.timing)
    nan = tbd.health_checks(SMALL, _records(3, sq_error=float("nan")), 0, TbdMethod("PFTBD", 80))
    assert not {c["name"]: c for c in nan["checks"]}["divergence"]["passed"]


def test_records_without_n_eff_skip_only_the_collapse_check():
    records = [RunRecord(tuple(SnrRun(c.snr_db, {k: MethodRun(m.present, m.absent, m.sq_error)
                                                  for k, m in c.methods.items()}) for c in r.cases), r.seconds)
               for r in _records(3)]
    h = tbd.health_checks(SMALL, records, 1, TbdMethod("PFTBD", 80))
    assert [c["name"] for c in h["checks"]] == ["divergence"]


# ---- Monte Carlo intervals ----------------------------------------------------------------------
def test_the_gain_interval_shrinks_with_the_runs_and_repeats():
    rng = np.random.default_rng(4)
    snrs = (2.0, 5.0, 8.0)

    def method(shift: float, runs: int):
        out = []
        for s in snrs:
            p = 1 / (1 + np.exp(-(s + shift - 5.0)))
            out.append(((rng.random((runs, 16)) < p).astype(float) * 0.9 + 0.05, rng.random((runs, 30)) * 0.5))
        return out

    small = tbd.gain_interval(snrs, method(1.5, 40), method(0.0, 40), 0.05, 200)
    large = tbd.gain_interval(snrs, method(1.5, 640), method(0.0, 640), 0.05, 200)
    assert small["valid"] == 200 and small["low"] <= small["high"]
    assert large["se"] < small["se"] / 2  # about 1/4 at 16× the runs
    better, worse = method(1.5, 40), method(0.0, 40)
    assert tbd.gain_interval(snrs, better, worse, 0.05, 50) == tbd.gain_interval(snrs, better, worse, 0.05, 50)


def test_undecided_claims_state_the_runs_that_would_decide_them():
    results = _summary(_records(6))
    claims = {c.id: c for c in read_claims(results)}
    assert set(results["snr_gain_interval"]) <= {"TPFTBD-N80", "TPFTBD-N40"}
    for claim in claims.values():
        if claim.timing:
            continue
        assert claim.verdict in ("held", "NOT held", "undecided")
        if claim.verdict == "undecided" and claim.statistic not in (None, 0.0, claim.threshold):
            assert claim.runs_to_decide is not None and claim.runs_to_decide > 6
        if claim.verdict != "undecided":
            assert claim.runs_to_decide is None
    gain = claims["tbd/snr-gain-equal-n"]
    interval = results["snr_gain_interval"].get("TPFTBD-N80")
    if gain.statistic is not None and interval:
        atol = 5.0 * interval["se"]
        margin = gain.statistic - 1.0
        assert gain.verdict == ("held" if margin > atol else "NOT held" if margin < -atol else "undecided")
        assert f"{interval['se']:.2f}" in gain.evidence


def test_pd_comparisons_are_paired_over_runs():
    results = _summary(_records(8, seed=2))
    claim = next(c for c in read_claims(results) if c.id == "tbd/half-n-detects-as-well")
    assert "paired difference" in claim.evidence and "tolerance" in claim.evidence
    assert claim.statistic == pytest.approx(results["pd_at_pfa"]["TPFTBD-N40"] - results["pd_at_pfa"]["PFTBD-N80"])


# ---- the page -----------------------------------------------------------------------------------
def test_the_page_shows_verdicts_under_each_interpretation_health_and_runs_to_decide(tmp_path):
    import json
    import shutil
    from pathlib import Path

    from gpfverify.contract.interpretations import robustness
    from gpfverify.report.document import Table
    from gpfverify.report.inputs import load_section
    from gpfverify.papers.tbd import section as tbd_section

    fixture = Path(__file__).parent / "fixtures" / "tbd"
    shutil.copytree(fixture, tmp_path / "tbd")
    section = tbd_section.render_section(load_section(tmp_path, "tbd"))
    tables = {b.caption.split(":")[0].split(" (")[0]: b for b in section.blocks if isinstance(b, Table)}
    stored = json.loads((fixture / "tbd-small" / "results.json").read_text())
    claims = [c for c in read_claims(stored) if c.interpretations]
    assert claims  # the fixture was made with two interpretations
    sensitivity = tables["Verdicts"]
    assert sensitivity.headers[:2] == ["claim", "as run"] and "snr-energy" in sensitivity.headers
    assert "second-stage-3x3" in sensitivity.headers and sensitivity.headers[-2] == "robustness"
    for row, claim in zip(sensitivity.rows, claims):
        assert row[0] == claim.claim and row[1].startswith(claim.verdict)
        assert row[-2] == robustness(claim)
        assert row[-1] == (claim.runs_to_decide or "")
    assert "Interpretations tried" in tables
    health = tables["Health checks"]
    assert {row[0] for row in health.rows} == {h["method"] for h in stored["health"]}
    assert len(health.headers) == 1 + len(stored["snr_db"])


def test_the_birth_readings_run_the_gain_claims_filters_with_the_streams_they_have_beside_the_others():
    """The birth readings run PF-TBD and TPFTBD at equal N only: each method's runs are the same
    whether or not the other methods run beside it, so the SNR-gain claim reads the same numbers."""
    from gpfverify.papers.tbd.contract import BIRTH_INTERPRETATIONS, GAIN_METHODS_ONLY

    reduced = SMALL.replace(tpf_particles=(SMALL.particles,), zeta_sweep=())
    seed = np.random.SeedSequence(4, spawn_key=(1,))
    full, alone = tbd.run_one(SMALL, seed), tbd.run_one(reduced, seed)
    for case_full, case_alone in zip(full.cases, alone.cases):
        assert set(case_alone.methods) == {"PFTBD-N80", "TPFTBD-N80"}
        assert all(case_alone.methods[k] == case_full.methods[k] for k in case_alone.methods)
    for spec in BIRTH_INTERPRETATIONS:
        assert Params().replace(**spec.changes).tpf_particles == (Params().particles,) == \
            GAIN_METHODS_ONLY["tpf_particles"]
        assert spec.bears_on == ("tbd/snr-gain-equal-n",)
