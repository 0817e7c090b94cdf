"""SINS/GPS scenario and GPSR-UPF: flight facts against closed forms, the error model's mismatch
structure, the SR-UKF against the exact KF over the flight, the SR-UKF proposal inside the
UPF against the UKF proposal and the KF, and factor validity of GPSR-UPF over the flight. The
sins-gps experiment: typed parameters and run records, results.json per CONTRACT.md (with the mean
N_eff/N of each particle filter), claim records with the collapse caveat, and the report page
rendered from a stored results.json."""

import dataclasses
import json
import shutil
from functools import partial
from pathlib import Path

import numpy as np
import pytest

from gpfverify.cli import main
from gpfverify.contract import VERDICTS, ClaimRecord, from_json, read_claims, to_json
from gpfverify.contract.claims import PairedDifference
from gpfverify.papers.gpsr_upf.contract import PROFILES, FilterRun, Params, ParticleFilterRun, RunRecord, collapsed
from gpfverify.errors import InputError
from gpfverify.papers.gpsr_upf import experiment as sins_gps
from gpfverify.experiments.runner import run_experiment, without_timing
from gpfverify.report.document import Figure, Paragraph, Section, Table
from gpfverify.report.inputs import load_section
from gpfverify.papers.gpsr_upf import section as sins_gps_section
from gpfverify.filters.gpsr_upf import GPResidualModel, gpsr_upf_step, sr_ukf_proposal
from gpfverify.filters.kalman import kf_step
from gpfverify.filters.likelihoods import batched_gaussian_logpdf, gaussian_logpdf
from gpfverify.filters.records import Gaussian
from gpfverify.filters.resampling import Particles
from gpfverify.filters.upf import ukf_proposal, upf_step
from gpfverify.gp.residual import fit_residual
from gpfverify.models import Sensor, StateSpaceModel, linear_model
from gpfverify.papers.gpsr_upf.scenario import (ATTITUDE, EARTH_RATE, EQUATORIAL_RADIUS, G0, UNITS, VELOCITY, SinsGpsConfig,
                                          build_models, generate_flight, gravity, measurement_matrix,
                                          training_set)
from gpfverify.tolerances import MONTE_CARLO_SIGMAS, algebra_rtol


@pytest.fixture(scope="module")
def scenario():
    """The paper's flight cut at 650 s: take-off and climb, cruise, the acceleration and turn, cruise
    again (the full 1000 s adds only more cruise, and time)."""
    config = SinsGpsConfig(duration=650.0)
    flight = generate_flight(config)
    return config, flight, build_models(flight, config)


def test_flight_profile_segments_and_turn(scenario):
    config, flight, _ = scenario
    t = flight.time
    manoeuvring = flight.manoeuvring()
    assert manoeuvring[(t > 5) & (t < 175)].all()
    cruise = ((t > 205) & (t < 495)) | (t > 605)
    assert not manoeuvring[cruise].any()
    # coordinated turn: horizontal specific force = centripetal acceleration v ψ̇ and the longitudinal
    # 0.4 m/s², up to the Coriolis and transport-rate terms, bounded by (2Ω + |ω_en|) |v| with
    # |ω_en| ≤ 2 v/R at 34° latitude;
    # roll = atan(v ψ̇ / g)
    k = np.searchsorted(t, 550.0)
    speed = np.linalg.norm(flight.velocity[k])
    rate = np.radians(1.8)
    horizontal = np.linalg.norm(flight.specific_force[k, :2])
    rotation_bound = (2 * EARTH_RATE + speed / EQUATORIAL_RADIUS * 2) * speed
    assert abs(horizontal - np.hypot(speed * rate, 0.4)) <= rotation_bound
    g = gravity(flight.latitude[k], flight.height[k])
    assert flight.attitude[k, 2] == pytest.approx(np.arctan(speed * rate / g), rel=algebra_rtol())
    # heading turned through ∫ψ̇ dt of the trapezoidal turn-rate schedule: 1.8°/s × 85 s
    turned = np.degrees(flight.attitude[-1, 0] - flight.attitude[0, 0])
    assert turned == pytest.approx(1.8 * 85, rel=algebra_rtol())
    # body-to-nav DCMs are rotations
    identity = np.broadcast_to(np.eye(3), flight.cbn.shape)
    np.testing.assert_allclose(flight.cbn @ np.swapaxes(flight.cbn, 1, 2), identity, atol=algebra_rtol())


def test_model_mismatch_is_exactly_the_stale_specific_force_term(scenario):
    config, flight, models = scenario
    level = np.array([0.0, 0.0, 1.0]) * gravity(flight.latitude, flight.height)[:, None]
    for k in (0, 120, 300, 550):
        diff = models.transitions_true[k] - models.transitions_approx[k]
        df = flight.specific_force[k] - level[k]
        cross = np.array([[0, -df[2], df[1]], [df[2], 0, -df[0]], [-df[1], df[0], 0]])
        expected = np.zeros_like(diff)
        expected[VELOCITY, ATTITUDE] = config.dt * cross * UNITS[ATTITUDE][None, :] / UNITS[VELOCITY][:, None]
        np.testing.assert_allclose(diff, expected, atol=algebra_rtol() * np.abs(expected).max(initial=1.0))
        np.testing.assert_allclose(models.transition_inputs[k], df)


def test_an_accelerometer_scale_factor_is_the_velocity_forcing_dt_s_fn_and_nothing_else(scenario):
    """An isotropic scale factor s adds Δt s fⁿ to the true model's velocity rows (closed form from the
    flight's specific force); Φ_true, the approximate model and the other rows are unchanged."""
    config, flight, models = scenario
    scaled_config = dataclasses.replace(config, accel_scale_ppm=1000.0)
    scaled = build_models(flight, scaled_config)
    np.testing.assert_array_equal(models.forcing_true, 0.0)
    np.testing.assert_array_equal(scaled.transitions_true, models.transitions_true)
    np.testing.assert_array_equal(scaled.transitions_approx, models.transitions_approx)
    expected = np.zeros_like(scaled.forcing_true)
    expected[:, VELOCITY] = 1e-3 * flight.specific_force[:-1] * config.dt
    np.testing.assert_allclose(scaled.forcing_true, expected, rtol=algebra_rtol())
    # in cruise the forcing is the vertical s g per step, up to s times the Coriolis and transport-rate
    # terms, bounded by (2Ω + 2 v/R) |v|
    k = np.searchsorted(flight.time, 300.0)
    g = gravity(flight.latitude[k], flight.height[k])
    speed = np.linalg.norm(flight.velocity[k])
    rotation_bound = (2 * EARTH_RATE + 2 * speed / EQUATORIAL_RADIUS) * speed
    assert abs(scaled.forcing_true[k, 5] - 1e-3 * g * config.dt) <= 1e-3 * rotation_bound * config.dt
    assert np.linalg.norm(scaled.forcing_true[k, 3:5]) <= 1e-3 * rotation_bound * config.dt
    x = np.random.default_rng(5).normal(size=(3, 15))
    np.testing.assert_allclose(scaled.true.f(x, k + 1), models.true.f(x, k + 1) + expected[k], rtol=algebra_rtol())
    np.testing.assert_array_equal(scaled.approx.f(x, k + 1), models.approx.f(x, k + 1))
    np.testing.assert_allclose(scaled.residual(np.zeros((flight.time.size - 1, 15))), expected, rtol=algebra_rtol())


def test_training_targets_carry_the_scale_factor_forcing():
    """The GP's training targets come from the true model: with a scale factor, the velocity
    residual minus the fⁿ × φ term averages Δt s fⁿ (fⁿ from the recorded inputs f^n − f̂^n plus
    level gravity), to within the accelerometer white noise's standard error."""
    config = SinsGpsConfig(duration=650.0, accel_scale_ppm=1000.0)
    data = training_set(config, [15.0, 75.0], 200, np.random.default_rng(2))
    phi = data.states[:, ATTITUDE] * UNITS[ATTITUDE]
    cross = np.cross(data.inputs, phi) * config.dt
    leftover = data.next_true[:, VELOCITY] - data.next_approx[:, VELOCITY] - cross
    level = np.array([0.0, 0.0, gravity(np.radians(34.0), 1000.0)])
    forcing = 1e-3 * (data.inputs + level) * config.dt
    noise_sd = config.accel_white_g_sqrt_hz * 9.78 * np.sqrt(config.dt)
    # gravity varies by < 1e-3 m/s² over the flights' latitude and height: 1e-6 m/s of forcing
    np.testing.assert_allclose((leftover - forcing).mean(axis=0), 0.0,
                               atol=5 * noise_sd / np.sqrt(len(leftover)) + 1e-5)
    assert abs(leftover[:, 2].mean()) > 100 * noise_sd / np.sqrt(len(leftover))  # the forcing is seen


def test_a_misspecified_accelerometer_noise_changes_the_true_velocity_q_alone(scenario):
    """accel_noise_scale c: the true model's velocity block of Q is c² times the model's (the white
    accelerometer noise's variance per step, (c · 1e-5 g)² Δt, in closed form), every other entry and
    the approximate model unchanged; the transitions are not touched."""
    config, flight, models = scenario
    noisy = build_models(flight, dataclasses.replace(config, accel_noise_scale=100.0))
    np.testing.assert_array_equal(noisy.approx.Q, models.approx.Q)
    np.testing.assert_array_equal(noisy.transitions_true, models.transitions_true)
    expected = models.true.Q.copy()
    expected[VELOCITY, VELOCITY] = np.eye(3) * (100.0 * config.accel_white_g_sqrt_hz * G0) ** 2 * config.dt
    np.testing.assert_allclose(noisy.true.Q, expected, rtol=algebra_rtol())
    np.testing.assert_allclose(noisy.true.Q[VELOCITY, VELOCITY], 1e4 * models.true.Q[VELOCITY, VELOCITY],
                               rtol=algebra_rtol())
    # the ceiling's model: the design noise plus what the model leaves out
    ceiling = sins_gps.ceiling_model(noisy, noisy.approx)
    np.testing.assert_allclose(ceiling.Q, noisy.true.Q, rtol=algebra_rtol())


def test_the_gp_learns_the_misspecified_velocity_noise_from_the_training_flights():
    """The residual GP's noise variance on the velocity outputs is the flight's (10⁴ times the model's
    at accel_noise_scale 100), within the sampling error of a variance from the training points; the
    approximate model keeps the nominal Q, so only GPSR-UPF carries the learned one."""
    params = Params(duration=650.0, accel_noise_scale=100.0)
    config, models, upf_model, gpsr_model, _ = sins_gps.setup(params)
    true_var = np.diag(models.true.Q)[VELOCITY]
    learned = gpsr_model.transition.gp.noise_var
    # a variance estimated from n points: relative standard error √(2/n)
    np.testing.assert_allclose(learned, true_var, rtol=MONTE_CARLO_SIGMAS * np.sqrt(2.0 / params.train_points))
    np.testing.assert_array_equal(upf_model.Q, models.approx.Q)
    assert np.all(np.diag(upf_model.Q)[VELOCITY] < 1e-3 * learned)


def test_sr_ukf_equals_kf_over_the_flight(scenario):
    """On the (linear) approximate model the SR-UKF must be the KF: every step of the flight."""
    config, _, models = scenario
    rng = np.random.default_rng(0)
    prior = config.initial_cov()
    x0 = rng.multivariate_normal(np.zeros(15), prior)
    _, ys = models.true.simulate(config.steps, rng, x0=x0)
    H = measurement_matrix()
    kf = Gaussian(np.zeros(15), prior)
    mean, factor = np.zeros((1, 15)), np.linalg.cholesky(prior)[None]
    worst = 0.0
    for k, y in enumerate(ys, 1):
        linear = linear_model(models.transitions_approx[k - 1], H, models.approx.Q, models.approx.R)
        kf = kf_step(kf, linear, y, k=k).posterior
        mean, factor = sr_ukf_proposal(Particles(mean, np.zeros(1), factor), models.approx, y, k=k)
        assert np.all(np.diag(factor[0]) > 0) and np.all(np.isfinite(factor))
        scale = np.sqrt(np.diag(kf.cov))
        worst = max(worst, float(np.max(np.abs(mean[0] - kf.mean) / scale)),
                    float(np.max(np.abs(factor[0] @ factor[0].T - kf.cov) / np.outer(scale, scale))))
    assert worst < algebra_rtol(np.linalg.cond(kf.cov / np.outer(scale, scale)) * config.steps)


def _nonlinear_model():
    def f(x, k):
        return 0.9 * x + 0.3 * np.sin(x[:, ::-1])

    def h(x, k):
        return np.stack([x[:, 0] + 0.1 * x[:, 1] ** 2, np.tanh(x[:, 1])], axis=1)

    return StateSpaceModel(f, np.diag([0.3, 0.2]), [Sensor(h, np.diag([0.2, 0.1]))], np.zeros(2), np.eye(2))


def test_upf_with_sr_ukf_proposal_equals_upf_with_ukf_proposal():
    model = _nonlinear_model()
    rng = np.random.default_rng(1)
    x0 = np.array([0.5, -0.3])
    _, ys = model.simulate(15, rng, x0=x0)
    clouds = []
    for proposal in (ukf_proposal, sr_ukf_proposal):
        r = np.random.default_rng(2)
        cloud = Particles.from_gaussian(np.zeros(2), np.eye(2), 40, r)
        for k, y in enumerate(ys, 1):
            cloud = upf_step(cloud, model, y, k=k, rng=r, proposal=proposal).posterior
        clouds.append(cloud)
    covs = clouds[0].sqrt_covs @ np.swapaxes(clouds[0].sqrt_covs, 1, 2)
    tol = algebra_rtol(np.linalg.cond(covs).max() * len(ys))
    np.testing.assert_allclose(clouds[1].particles, clouds[0].particles, rtol=tol, atol=tol)
    np.testing.assert_allclose(clouds[1].sqrt_covs, clouds[0].sqrt_covs, rtol=tol, atol=tol)
    np.testing.assert_allclose(clouds[1].log_weights, clouds[0].log_weights, rtol=tol, atol=tol)


def test_batched_logpdf_matches_single_covariance_route():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(4, 3, 3))
    covs = a @ np.swapaxes(a, 1, 2) + np.eye(3)
    r = rng.normal(size=(4, 3))
    single = np.array([gaussian_logpdf(r[i:i + 1], covs[i])[0] for i in range(4)])
    np.testing.assert_allclose(batched_gaussian_logpdf(r, covs, "test"), single, rtol=algebra_rtol(100))


def test_gp_process_noise_replaces_the_learned_block(scenario):
    config, flight, models = scenario
    data = training_set(config, [15.0, 75.0], 60, np.random.default_rng(4))
    residual = fit_residual(data.states, data.next_true, data.next_approx, outputs=range(3, 6),
                            state_inputs=range(3), inputs=data.inputs, restarts=1, seed=0)
    floor = 0.01 * np.eye(15)
    model = GPResidualModel(models.approx, residual, transition_inputs=models.transition_inputs, extra_noise=floor)
    x = np.random.default_rng(5).normal(size=(3, 15))
    q = model.process_cov(x, 550)
    var = residual.noise_var(x, models.transition_inputs[549])
    for i in range(3):
        expected = models.approx.Q + floor
        expected[3:6, :] = floor[3:6, :]
        expected[:, 3:6] = floor[:, 3:6]
        expected[3:6, 3:6] += np.diag(var[i])
        np.testing.assert_allclose(q[i], expected, rtol=algebra_rtol())
    np.testing.assert_allclose(model.f(x, 550)[:, VELOCITY],
                               models.approx.f(x, 550)[:, VELOCITY] + residual.mean(x, models.transition_inputs[549]))


def test_gpsr_upf_factors_stay_valid_over_the_flight(scenario):
    """The paper's reason for the square root: every particle's factor stays a valid lower
    Cholesky factor (finite, positive diagonal) through take-off, climb, cruise and the turn."""
    config, _, models = scenario
    data = training_set(config, [15.0, 75.0], 60, np.random.default_rng(6))
    residual = fit_residual(data.states, data.next_true, data.next_approx, outputs=range(3, 6),
                            state_inputs=range(3), inputs=data.inputs, restarts=1, seed=0)
    model = GPResidualModel(models.approx, residual, transition_inputs=models.transition_inputs)
    rng = np.random.default_rng(7)
    x0 = rng.multivariate_normal(np.zeros(15), config.initial_cov())
    _, ys = models.true.simulate(config.steps, rng, x0=x0)
    cloud = Particles.from_gaussian(np.zeros(15), config.initial_cov(), 3, rng)
    step = partial(gpsr_upf_step, model=model, rng=rng)
    for k, y in enumerate(ys, 1):
        info = step(cloud, y=y, k=k)
        cloud = info.posterior
        diag = np.diagonal(cloud.sqrt_covs, axis1=1, axis2=2)
        assert np.all(diag > 0) and np.all(np.isfinite(cloud.sqrt_covs))
        assert np.allclose(np.triu(cloud.sqrt_covs, 1), 0.0)
        assert np.all(np.isfinite(info.mean))


def test_measurement_residual_in_the_gpsr_model():
    """h = ĥ + GP_h(u_k) and R_k with the learned block from the GP's predictive variance at u_k;
    a measurement GP reading the state is refused (the UPF weights need one R per step)."""
    rng = np.random.default_rng(8)
    x = rng.normal(size=(80, 2))
    u = rng.uniform(0, 2 * np.pi, size=(80, 1))
    z = x + np.concatenate([np.cos(u), np.zeros_like(u)], axis=1) + 0.05 * rng.standard_normal((80, 2))
    residual = fit_residual(x, z, x, outputs=(0,), inputs=u, restarts=1, seed=0)
    approx = linear_model(np.eye(2), np.eye(2), 0.1 * np.eye(2), np.diag([0.3, 0.2]))
    inputs = np.linspace(0, 6, 10)[:, None]
    model = GPResidualModel(approx, measurement=residual, measurement_inputs=inputs)
    states = rng.normal(size=(4, 2))
    expected_h = states.copy()
    expected_h[:, 0] += residual.mean(states[:1], inputs[3])[0, 0]
    np.testing.assert_allclose(model.h(states, 3), expected_h)
    R = model.measurement_cov(3)
    assert R[0, 0] == pytest.approx(residual.noise_var(states[:1], inputs[3])[0, 0])
    assert R[0, 1] == 0.0 and R[1, 1] == approx.R[1, 1]
    np.testing.assert_array_equal(model.at_step(3).R, R)
    state_reader = fit_residual(x, z, x, outputs=(0,), state_inputs=(0,), restarts=1, seed=0)
    with pytest.raises(InputError, match="exogenous"):
        GPResidualModel(approx, measurement=state_reader)


# ---- the experiment -----------------------------------------------------------------------------
FIXTURE = Path(__file__).parent / "fixtures" / "sins_gps"
TINY = Params(particles=4, duration=60.0, train_points=20)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("sins-gps")
    return run_experiment(sins_gps, TINY, 2, 4, out, show_progress=False), out


def test_results_follow_the_contract(tiny_run):
    r, _ = tiny_run
    assert r["experiment"] == "sins-gps" and r["runs"] == 2 and r["runs_ok"] == 2 and r["seed"] == 4
    for q in ("position", "velocity", "attitude"):
        assert set(r[f"{q}_error"]) == {"UPF", "GPSR-UPF"}
        assert all(len(v) == 60 for v in r[f"{q}_error"].values())
        rms = r["rms"]
        assert r["reduction"][q] == pytest.approx(1 - rms["GPSR-UPF"][q] / rms["UPF"][q])
    assert set(r["time_per_run"]) == {"UPF", "GPSR-UPF", "SR-UKF", "GP-SR-UKF", "TRUE-SR-UKF"}
    assert Params.from_json(r["params"]) == TINY
    json.dumps(r, allow_nan=False)


def test_mean_ess_fraction_is_the_mean_over_runs_of_each_particle_filter(tiny_run):
    r, out = tiny_run
    saved = [from_json(RunRecord, json.loads(path.read_text())["result"])
             for path in sorted((out / "runs").glob("run-*.json"))]
    assert set(r["mean_ess_fraction"]) == {"UPF", "GPSR-UPF"}
    for method, fraction in r["mean_ess_fraction"].items():
        assert fraction == pytest.approx(np.mean([rec.particle_filters[method].ess_mean for rec in saved]))
        assert 1 / TINY.particles - 1e-12 <= fraction <= 1.0  # N_eff lies in [1, N]
    assert r["ess_fraction"] == r["mean_ess_fraction"]  # the older name, kept


def test_params_and_run_records_round_trip(tiny_run):
    for params in (TINY, Params(), *(s.params for p in PROFILES.values() for s in p.settings)):
        assert from_json(Params, json.loads(json.dumps(to_json(params)))) == params
    saved = json.loads((tiny_run[1] / "runs" / "run-000000.json").read_text())
    record = from_json(RunRecord, saved["result"])
    assert isinstance(record.particle_filters["GPSR-UPF"], ParticleFilterRun)
    assert isinstance(record.references["SR-UKF"], FilterRun) and len(record.references["SR-UKF"].position) == 60
    assert from_json(RunRecord, json.loads(json.dumps(to_json(record)))) == record


def test_profiles():
    assert PROFILES["quick"].runs == 2 and PROFILES["quick"].settings[0].params.particles == 20
    assert PROFILES["full"].runs == sins_gps.DEFAULT_RUNS == 20 and PROFILES["full"].settings[0].params == Params()
    # the report tries the model error within the claims' reach, the healthy configuration and the
    # mis-specified Q
    names = {spec.name for spec in sins_gps.INTERPRETATIONS}
    for profile in PROFILES.values():
        assert set(profile.interpretations) == {"scale-factor-1000ppm", "point-proposal-q-x1000",
                                                "q-misspecified"} <= names


@pytest.mark.parametrize("changes, option", [
    ({"particles": 1}, "--particles"),
    ({"resample_threshold": 0.0}, "--resample-threshold"),
    ({"resample_threshold": 1.5}, "--resample-threshold"),
    ({"train_points": 5}, "--train-points"),
    ({"train_headings": ()}, "--train-headings"),
    ({"noise_floor": (0.0, -1.0, 0.0, 0.0, 0.0)}, "--noise-floor"),
    ({"noise_floor": (0.0, 0.0)}, "--noise-floor"),
    ({"duration": 0.5}, "--duration"),
    ({"gps_position_sd": 0.0}, "--gps-position-sd"),
    ({"q_inflation": 0.5}, "--q-inflation"),
    ({"particle_covariance": "shrunk"}, "--particle-covariance"),
    ({"jitter": "kernel"}, "--jitter"),
])
def test_invalid_params_name_the_option(changes, option):
    with pytest.raises(InputError, match=option):
        Params(**changes)


def test_reproduce_offers_the_generated_options(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["reproduce", "sins-gps", "--help"])
    out = capsys.readouterr().out
    assert exit_info.value.code == 0
    for option in ("--particles", "--resample-threshold", "--train-headings", "--noise-floor", "--gps-position-sd",
                   "--q-inflation", "--particle-covariance", "--jitter"):
        assert option in out


def test_collapse_criterion():
    assert collapsed(50, {"UPF": 0.02, "GPSR-UPF": 0.021})
    assert not collapsed(50, {"UPF": 0.02, "GPSR-UPF": 0.3})  # one healthy filter: no collapse of both


def test_claims_are_records_with_the_ess_and_the_health_checks(tiny_run):
    r, _ = tiny_run
    records = read_claims(r)
    by_id = {c.id: c for c in records}
    ess = r["mean_ess_fraction"]
    health = r["health"]
    assert {c["subject"] for c in health} == {"UPF", "GPSR-UPF"} | {f"{m} {q}" for m in ("UPF", "GPSR-UPF")
                                                                      for q in ("position", "velocity", "attitude")}
    failed = [c for c in health if not c["passed"]]
    for q, claimed in (("position", 0.33), ("velocity", 0.33), ("attitude", 0.40)):
        claim = by_id[f"sins-gps/reduction-{q}"]
        per_run = 1 - np.asarray(r["per_run_rms"]["GPSR-UPF"][q]) / np.asarray(r["per_run_rms"]["UPF"][q])
        assert claim.statistic == pytest.approx(per_run.mean()) and claim.threshold == pytest.approx(claimed - 0.10)
        test = PairedDifference.of(np.full(per_run.size, claimed - 0.10), per_run)
        out_of_reach = r["reference"]["ceiling"][q] < claimed - 0.10
        assert claim.verdict == ("not decidable" if failed or (out_of_reach and test.verdict == "NOT held")
                                 else test.verdict)
        assert f"true-model ceiling (TRUE-SR-UKF against SR-UKF) {100 * r['reference']['ceiling'][q]:.1f} %" \
            in claim.evidence
        assert any("out of reach in this scenario" in c for c in claim.caveats) == out_of_reach
        assert f"UPF {ess['UPF']:.4f}" in claim.evidence and f"GPSR-UPF {ess['GPSR-UPF']:.4f}" in claim.evidence
        # the filters' health is the record's, with every check run of each (the gate's words are rendered from it)
        assert (claim.would_be is not None) == (claim.verdict == "not decidable")
        assert {(c.subject, c.name) for h in claim.failed_filters for c in h.failed} == \
            {(c["subject"], c["name"]) for c in failed if c["subject"] in {h.subject for h in claim.health}}
        assert claim.source == "§3, Table 1" and "33%" in claim.quote and claim.kind == "claim"
        assert claim.paper == "seed001" and claim.n == 2
        assert any("rests on 2 runs" in c for c in claim.caveats)
    # with 4 particles the weights collapse onto one particle: the comparison is withheld
    assert not next(c for c in health if c["subject"] == "UPF")["passed"]
    for q in ("position", "velocity", "attitude"):
        assert r["reference"]["reduction"][q] == by_id[f"sins-gps/single-filter-reduction-{q}"].statistic
    rms = r["reference"]["rms"]
    for q, claimed in (("position", 0.33), ("velocity", 0.33), ("attitude", 0.40)):
        ceiling = by_id[f"sins-gps/true-model-ceiling-{q}"]
        assert ceiling.statistic == pytest.approx(1 - rms["TRUE-SR-UKF"][q] / rms["SR-UKF"][q])
        assert ceiling.verdict == ("held" if ceiling.statistic >= claimed - 0.10 else "NOT held")
    assert by_id["sins-gps/factors-valid"].verdict == "held"  # every factor diagonal stayed positive
    for c in records:
        assert ClaimRecord.from_json(json.loads(json.dumps(c.to_json()))) == c


def test_same_numbers_for_the_same_seed(tiny_run, tmp_path):
    again = run_experiment(sins_gps, TINY, 2, 4, tmp_path, show_progress=False)
    assert without_timing(again) == without_timing(tiny_run[0])


def _cell_text(cell) -> str:
    return str(getattr(cell, "verdict", cell)) + " " + " ".join(getattr(cell, "cautions", ()))


def test_report_page_renders_from_a_stored_results_file(tmp_path):
    shutil.copytree(FIXTURE, tmp_path / "sins-gps")
    section = sins_gps_section.render_section(load_section(tmp_path, "sins-gps"))
    assert isinstance(section, Section) and "Meng et al. 2015" in section.title
    figures = [b for b in section.blocks if isinstance(b, Figure)]
    assert len(figures) == 4 and all(f.path.exists() and f.path.parent == tmp_path / "sins-gps" for f in figures)
    stored = json.loads((FIXTURE / "sins-gps-small" / "results.json").read_text())
    (claims,) = [b for b in section.blocks if isinstance(b, Table) and b.caption.startswith("Claims")]
    assert len(claims.rows) == len(read_claims(stored)) == 7
    verdicts = [next(v for v in VERDICTS if any(_cell_text(c).startswith(v + " ") for c in row)) for row in claims.rows]
    assert verdicts == [c.verdict for c in read_claims(stored)]
    # the stored run has 6 particles whose weights collapsed: the page says so, with the numbers
    text = " ".join(b.text for b in section.blocks if isinstance(b, Paragraph))
    assert "Diagnosis" in text and f"{stored['mean_ess_fraction']['UPF']:.3g}" in text
    (health,) = [b for b in section.blocks if isinstance(b, Table) and b.caption.startswith("Health checks")]
    assert len(health.rows) == len(stored["health"]) and any(row[2] == "NO" for row in health.rows)
    # the verdict under each interpretation tried, with the robustness sentence
    (tried,) = [b for b in section.blocks if isinstance(b, Table) and b.caption.startswith("Verdict (statistic)")]
    assert tried.headers[:4] == ["claim", "as run", "q-x100", "point-proposal-q-x100"]
    position = next(row for row in tried.rows if row[0].startswith("GPSR-UPF lowers the position error"))
    assert position[1].startswith("not decidable") and position[2].value.startswith("not decidable")
    assert position[-2].startswith("depends on the interpretation")
    assert "First configuration in which both particle filters pass their health checks: point-proposal-q-x100" in text
    assert "x_{" not in text and "^n" not in text  # Unicode maths, no pseudo-LaTeX


def test_the_renderer_runs_no_experiment():
    source = Path(sins_gps_section.__file__).read_text()
    assert "gpfverify.experiments" not in source and "run_for_report" not in source
    assert not hasattr(sins_gps_section, "build")


# ---- the true-model ceiling ---------------------------------------------------------------------
def test_the_ceiling_filter_is_the_kalman_filter_of_the_generating_model(scenario):
    """TRUE-SR-UKF runs the SR-UKF on the model that generated the flight: on this linear model it
    must be the KF with the true transitions, at every step."""
    config, _, models = scenario
    rng = np.random.default_rng(1)
    prior = config.initial_cov()
    x0 = rng.multivariate_normal(np.zeros(15), prior)
    xs, ys = models.true.simulate(config.steps, rng, x0=x0)
    true_model = sins_gps.ceiling_model(models, models.approx)
    run = sins_gps.run_sr_ukf(lambda k: true_model, prior, ys, xs)
    kf = Gaussian(np.zeros(15), prior)
    worst, cond = 0.0, 1.0
    for k, y in enumerate(ys, 1):
        linear = linear_model(models.transitions_true[k - 1], measurement_matrix(), models.true.Q, models.true.R)
        kf = kf_step(kf, linear, y, k=k).posterior
        error = np.concatenate([run.attitude[k - 1], run.velocity[k - 1], run.position[k - 1]])
        scale = np.sqrt(np.diag(kf.cov))
        worst = max(worst, float(np.max(np.abs(error - (kf.mean - xs[k - 1])[:9]) / scale[:9])))
        cond = max(cond, float(np.linalg.cond(kf.cov / np.outer(scale, scale))))
    assert worst < algebra_rtol(cond * config.steps)


def test_zero_model_error_gives_a_zero_ceiling_and_withholds_nothing_as_unreachable(monkeypatch):
    """With the true model equal to the inaccurate one, TRUE-SR-UKF is the SR-UKF (one route, the
    same numbers): the ceiling is 0 and every ceiling claim is NOT held."""
    def no_model_error(flight, config):
        models = build_models(flight, config)
        return dataclasses.replace(models, true=models.approx, transitions_true=models.transitions_approx)

    sins_gps.setup.cache_clear()
    monkeypatch.setattr(sins_gps, "build_models", no_model_error)
    try:
        record = sins_gps.run_one(TINY, np.random.SeedSequence(3))
    finally:
        sins_gps.setup.cache_clear()
    assert record.references["TRUE-SR-UKF"].position == record.references["SR-UKF"].position
    body = sins_gps.summarize(TINY, [record])
    assert body["reference"]["ceiling"] == {"attitude": 0.0, "velocity": 0.0, "position": 0.0}
    by_id = {c.id: c for c in body["claims"]}
    for q in ("position", "velocity", "attitude"):
        assert by_id[f"sins-gps/true-model-ceiling-{q}"].verdict == "NOT held"
        assert any("out of reach" in c for c in by_id[f"sins-gps/reduction-{q}"].caveats)


@pytest.mark.parametrize(("verdict", "ceiling", "expected"), [
    ("NOT held", 0.05, "not decidable"), ("undecided", 0.05, "undecided"), ("held", 0.05, "held"),
    ("NOT held", 0.30, "NOT held")])
def test_a_claim_out_of_reach_is_never_not_held(verdict, ceiling, expected):
    decided, would_be, caveats = sins_gps._within_reach(verdict, {"position": ceiling}, "position", 0.23)
    assert decided == expected
    assert would_be == (verdict if decided != verdict else None)  # the verdict the runs gave, kept
    assert bool(caveats) == (ceiling < 0.23)


def test_cruise_range_is_the_extreme_of_mean_plus_minus_two_sd_over_cruise_steps_and_axes():
    band = {"mean": [[0.0, 1.0, 2.0], [50.0, 50.0, -50.0], [1.0, 1.0, 1.0]],
            "sd": [[1.0, 1.0, 1.0], [0.0, 0.0, 0.0], [0.5, 0.5, 0.5]]}
    # step 1 manoeuvres: its ±50 is left out; cruise steps 0 and 2 give −2 (0 − 2·1) and 4 (2 + 2·1)
    assert sins_gps.cruise_range(band, np.array([False, True, False])) == [-2.0, 4.0]
    assert sins_gps.cruise_range(band, np.array([True, True, True])) is None


def test_page_sets_the_paper_error_levels_beside_each_configuration(tmp_path):
    stored = FIXTURE / "sins-gps-small" / "results.json"
    results = json.loads(stored.read_text())
    results.pop("cruise_range", None)
    page = sins_gps_section.render(results, tmp_path)
    assert not [b for b in page.blocks if isinstance(b, Table) and b.caption.startswith("The paper's error levels")]
    results["cruise_range"] = {"UPF": {"position": [-3.0, 4.0], "velocity": [-0.5, 0.25], "attitude": [-9.0, 8.0]},
                               "GPSR-UPF": {"position": [-2.0, 2.5], "velocity": [-0.4, 0.2], "attitude": [-5.0, 6.0]}}
    page = sins_gps_section.render(results, tmp_path)
    (table,) = [b for b in page.blocks if isinstance(b, Table) and b.caption.startswith("The paper's error levels")]
    assert table.rows[0] == ["the paper (its text on Figs. 1–6)", "UPF", "-7.5 to 7.9", "-1.8 to 1.5", "-1.4 to 1.6"]
    assert table.rows[2] == ["as run", "UPF", "-3 to 4", "-0.5 to 0.25", "-9 to 8"]
    assert table.rows[3][1] == "GPSR-UPF" and table.rows[3][2] == "-2 to 2.5"


def test_page_says_where_the_claims_are_within_reach_and_where_the_filters_are_healthy(tmp_path):
    """From the claim records alone, per claimed reduction: the configurations whose true-model
    ceiling reaches its threshold, and which of them have healthy particle filters."""
    results = json.loads((FIXTURE / "sins-gps-small" / "results.json").read_text())
    healthy_checks = [dict(c, passed=True) for c in results["health"]]
    failed_checks = [dict(c, passed=False) for c in results["health"]]
    ceiling_verdicts = {"position": ("NOT held", "held", "NOT held"), "velocity": ("NOT held", "held", "NOT held"),
                        "attitude": ("held", "held", "held")}

    def tried(as_run: str, wide: str, point: str) -> list[dict]:
        return [{"name": "wide", "params": {"accel_scale_ppm": 1000.0}, "verdict": wide, "statistic": 0.3},
                {"name": "point", "params": {"particle_covariance": "reset"}, "verdict": point, "statistic": 0.1}]

    for claim in results["claims"]:
        if claim["id"].startswith("sins-gps/reduction-"):
            claim["interpretations"] = tried(claim["verdict"], "not decidable", "undecided")
    template = next(c for c in results["claims"] if c["id"] == "sins-gps/single-filter-reduction-position")
    for q, (as_run, wide, point) in ceiling_verdicts.items():
        results["claims"].append(dict(template, id=f"sins-gps/true-model-ceiling-{q}", verdict=as_run,
                                      interpretations=tried(as_run, wide, point)))
    results["interpretation_summaries"] = {
        name: {"changes": {}, "runs_ok": 2, "health": checks, "mean_ess_fraction": results["mean_ess_fraction"],
               "rms": results["rms"], "reduction": results["reduction"], "reference_rms": results["reference"]["rms"]}
        for name, checks in (("wide", failed_checks), ("point", healthy_checks))}
    page = sins_gps_section.render(results, tmp_path)
    (text,) = [b.text for b in page.blocks if isinstance(b, Paragraph) and b.text.startswith("Where each claimed")]
    assert "(healthy: point)." in text
    assert "position: within reach in wide, healthy there in none;" in text
    assert "velocity: within reach in wide, healthy there in none;" in text
    assert text.endswith("attitude: within reach in as run, wide, point, healthy there in point.")
