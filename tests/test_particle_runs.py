"""Particle filters over a leading run axis (:mod:`gpfverify.filters.runs`): B runs advanced
together give each run the same bits whatever the batch (B = 1, 3, 8 and 5 + 3), equal the
single-run step functions looped to PER_RUN_RTOL, and a run that breaks down fails alone; the
experiments' ``run_batch`` keeps every non-timing field of a run whatever its batch."""

import dataclasses

import numpy as np
import pytest

from gpfverify.contract.serial import to_json
from gpfverify.experiments.batching import without_seconds
from gpfverify.errors import InputError
from gpfverify.filters.flows import edh_step, ie_pff_step, uniform_steps
from gpfverify.filters.pf import pf_step
from gpfverify.filters.resampling import Particles
from gpfverify.filters.tbd import TbdConfig, filter_sequence
from gpfverify.filters.upf import upf_step
from gpfverify.papers.particle_flow.pff1d_scenario import gamma_benchmark_model, ungm_model
from gpfverify.papers.tbd.scenario import TbdScenario, scenario_model, simulate
from gpfverify.tolerances import PER_RUN_RTOL

RUNS, STEPS, PARTICLES = 8, 6, 20
SPLITS = ([range(8)], [range(5), range(5, 8)], [[i] for i in range(8)], [range(3), range(3, 8)])


def _prior(count, rngs):
    return np.stack([g.normal(0.0, 1.0, (count, 1)) for g in rngs])


FILTERS = {
    "pf": (pf_step, {"resample_threshold": 1.0}, lambda r: Particles.equally_weighted(_prior(PARTICLES, r))),
    "pf-adaptive": (pf_step, {"resample_threshold": 0.5}, lambda r: Particles.equally_weighted(_prior(PARTICLES, r))),
    "upf": (upf_step, {"resample_threshold": 1.0},
            lambda r: Particles.from_gaussian(np.zeros(1), np.eye(1), PARTICLES, r)),
    "ie-pff": (ie_pff_step, {"step_sizes": uniform_steps(10)},
               lambda r: Particles.equally_weighted(_prior(PARTICLES, r))),
    "edh": (edh_step, {"step_sizes": uniform_steps(10)},
            lambda r: Particles.equally_weighted(_prior(PARTICLES, r), ekf_cov=np.ones((len(r), 1, 1)))),
}
MODELS = {"ungm": ungm_model(1.0, 1.0), "gamma": gamma_benchmark_model(0.1)}


def _measurements(model):
    return np.stack([model.simulate(STEPS, np.random.default_rng(100 + i))[1] for i in range(RUNS)])


def _batched(name, model, ys, runs):
    step, params, prior = FILTERS[name]
    rngs = [np.random.default_rng(i) for i in runs]
    belief = prior(rngs)
    means = []
    with np.errstate(all="ignore"):
        for k in range(1, STEPS + 1):
            record = step(belief, model, ys[list(runs), k - 1], k=k, rng=rngs, **params)
            belief = record.posterior
            means.append(record.mean)
    return np.stack(means, axis=1)


def _alone(name, model, ys, run):
    """The single-run step functions (particles (N, D), one Generator), looped; NaN on an error."""
    step, params, prior = FILTERS[name]
    rng = np.random.default_rng(run)
    batch = prior([rng])
    belief = Particles(batch.particles[0], batch.log_weights[0],
                       None if batch.sqrt_covs is None else batch.sqrt_covs[0],
                       None if batch.ekf_cov is None else batch.ekf_cov[0])
    means = []
    try:
        with np.errstate(all="ignore"):
            for k in range(1, STEPS + 1):
                record = step(belief, model, ys[run, k - 1], k=k, rng=rng, **params)
                belief = record.posterior
                means.append(record.mean)
    except InputError:
        return np.full((STEPS, 1), np.nan)
    return np.stack(means)


@pytest.mark.parametrize("model_name", list(MODELS))
@pytest.mark.parametrize("name", list(FILTERS))
def test_runs_get_the_same_bits_in_every_batch_and_equal_the_single_run_steps(name, model_name):
    model = MODELS[model_name]
    ys = _measurements(model)
    results = [np.concatenate([_batched(name, model, ys, part) for part in split]) for split in SPLITS]
    for other in results[1:]:
        np.testing.assert_array_equal(other, results[0])
    alone = np.stack([_alone(name, model, ys, i) for i in range(RUNS)])
    failed = ~np.isfinite(results[0]).all(axis=(1, 2))
    np.testing.assert_array_equal(failed, ~np.isfinite(alone).all(axis=(1, 2)))
    np.testing.assert_allclose(results[0][~failed], alone[~failed], rtol=PER_RUN_RTOL, atol=0)


def test_a_run_that_breaks_down_fails_alone():
    """IE-PFF with Δλ = 0.05 on the UNGM diverges in some runs (explicit Euler): those runs come out
    NaN, the others as when filtered alone, and at least one run of each kind occurs."""
    model = MODELS["ungm"]
    ys = _measurements(model)
    step, params, prior = FILTERS["ie-pff"]
    FILTERS["ie-pff-coarse"] = (step, {"step_sizes": uniform_steps(20)}, prior)
    try:
        together = _batched("ie-pff-coarse", model, ys, range(RUNS))
        alone = np.stack([_alone("ie-pff-coarse", model, ys, i) for i in range(RUNS)])
    finally:
        del FILTERS["ie-pff-coarse"]
    failed = ~np.isfinite(together).all(axis=(1, 2))
    assert failed.any() and not failed.all()
    np.testing.assert_array_equal(failed, ~np.isfinite(alone).all(axis=(1, 2)))
    np.testing.assert_allclose(together[~failed], alone[~failed], rtol=PER_RUN_RTOL, atol=0)


def test_a_batch_needs_one_generator_per_run():
    model = MODELS["ungm"]
    belief = Particles.equally_weighted(np.zeros((3, PARTICLES, 1)))
    with pytest.raises(InputError, match="one numpy Generator per run"):
        pf_step(belief, model, np.zeros((3, 1)), rng=[np.random.default_rng(0)] * 2)
    with pytest.raises(InputError, match="one numpy Generator per run"):
        pf_step(belief, model, np.zeros((3, 1)), rng=np.random.default_rng(0))


@pytest.mark.parametrize("two_stage", [False, True])
def test_tbd_runs_get_the_same_bits_in_every_batch_and_equal_the_single_run_filter(two_stage):
    scenario = TbdScenario()
    model = scenario_model(6.0, scenario)
    images = np.stack([simulate(model, scenario, np.random.default_rng(i), True).images[:8] for i in range(RUNS)])
    config = TbdConfig(60, two_stage=two_stage)

    def together(runs):
        runs = list(runs)
        return filter_sequence(images[runs], model, config, [np.random.default_rng(10 + i) for i in runs],
                               [np.random.default_rng(20 + i) for i in runs])

    tracks = [[together(part) for part in split] for split in SPLITS]
    alone = [filter_sequence(images[i], model, config, np.random.default_rng(10 + i), np.random.default_rng(20 + i))
             for i in range(RUNS)]
    for field in ("existence", "estimates", "ess_fraction"):
        first = np.concatenate([getattr(t, field) for t in tracks[0]])
        for split in tracks[1:]:
            np.testing.assert_array_equal(np.concatenate([getattr(t, field) for t in split]), first)
        np.testing.assert_allclose(first, np.stack([getattr(t, field) for t in alone]), rtol=PER_RUN_RTOL, atol=0)


def _experiment_cases():
    from gpfverify.papers.particle_flow.pff1d_contract import QUICK_PARAMS
    from gpfverify.papers.tbd.contract import QUICK_PARAMS as TBD_QUICK
    from gpfverify.papers.particle_flow import bearing_experiment as bearing, pff1d_experiment as pff1d
    from gpfverify.papers.tbd import experiment as tbd

    return {
        "pff1d": (pff1d, dataclasses.replace(QUICK_PARAMS, steps=5, dlambda=(0.1,), table_q=(10.0,))),
        "bearing": (bearing, dataclasses.replace(bearing.PROFILES["quick"].settings[0].params, duration=8)),
        "tbd": (tbd, dataclasses.replace(TBD_QUICK, snr=(6.0,), focus_snr=6.0, frames=8, first_frame=2,
                                         last_frame=7, particles=40, tpf_particles=(40, 20),
                                         zeta_sweep_particles=20)),
    }


@pytest.mark.parametrize("experiment", ["pff1d", "bearing", "tbd"])
def test_run_batch_keeps_every_non_timing_field_whatever_the_batch(experiment):
    module, params = _experiment_cases()[experiment]
    seeds = [np.random.SeedSequence(3, spawn_key=(i,)) for i in range(5)]
    together = without_seconds(to_json(module.run_batch(params, seeds)))
    split = without_seconds(to_json(module.run_batch(params, seeds[:3]) + module.run_batch(params, seeds[3:])))
    alone = without_seconds(to_json([module.run_one(params, s) for s in seeds]))
    assert together == split == alone
