"""Gaussian filter steps of several Monte Carlo runs at once (a leading run axis on the belief and
on y) against the same runs stepped one at a time: the same bits for every way of splitting the
runs into batches (1, 3, 8 and 5 + 3), and equal to the unbatched step functions to PER_RUN_RTOL —
for KF, EKF and UKF on a user's system (a numpy callable with a matrix product inside, whose rows
BLAS may map differently in a larger call) and GP-ADF, GP-UKF on each run's own learned GPs,
on the fused moment kernel and on the numpy reference path."""

import numpy as np
import pytest

from gpfverify.errors import InputError
from gpfverify.filters.families import gaussian_family
from gpfverify.filters.records import Gaussian
from gpfverify.filters.sigma_points import SigmaParams
from gpfverify.gp import GaussianProcess
from gpfverify.gp.batch import GaussianProcessBatch
from gpfverify.models import GPModel, Sensor, StateSpaceModel, batch_gp_models, fit_gp_model, linear_model
from gpfverify.tolerances import PER_RUN_RTOL

RUNS = 8
SPLITS = ((8,), (1,) * 8, (3, 3, 2), (5, 3))
FIELDS = ("mu_p", "C_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e")
MIX = np.array([[0.9, 0.2, 0.0], [-0.1, 0.8, 0.3], [0.05, 0.0, 0.95]])


def _transition(x):
    return np.sin(x) @ MIX.T + 0.5 * x  # a matrix product inside a user's function


def _radar(x):
    return np.stack([np.hypot(x[:, 0] - 3.0, x[:, 1] + 1.0), np.arctan2(x[:, 1] + 1.0, x[:, 0] - 3.0)], axis=1)


def _user_model() -> StateSpaceModel:
    return StateSpaceModel(_transition, 0.05 * np.eye(3),
                           [Sensor(_radar, np.diag([0.1, 0.01]), circular=[1]), Sensor(np.eye(2, 3), 0.2 * np.eye(2))],
                           np.zeros(3), np.eye(3))


def _linear_model() -> StateSpaceModel:
    return linear_model(MIX, np.vstack([np.eye(3), [[1.0, -1.0, 0.5]]]), 0.1 * np.eye(3), 0.3 * np.eye(4),
                        sizes=(3, 1))


def _runs_data(model, rng):
    means = rng.normal(size=(RUNS, model.state_dim))
    a = rng.normal(size=(RUNS, model.state_dim, model.state_dim))
    covs = a @ np.swapaxes(a, 1, 2) / 3 + 0.5 * np.eye(model.state_dim)
    ys = model.h(rng.normal(size=(RUNS, model.state_dim))) + rng.normal(scale=0.3, size=(RUNS, model.measurement_dim))
    return means, covs, ys


def _learned(seed: int) -> GPModel:
    """A run's GP model learned from its own trajectory of the user's system (equal sizes)."""
    model, rng = _user_model(), np.random.default_rng(seed)
    states, ys = model.simulate(25, rng)
    return fit_gp_model(states[:-1], states[1:], states, [ys[:, b] for b in model.blocks], rng, restarts=1,
                        sensor_circular=model.sensor_circular)


@pytest.fixture(scope="module")
def gp_models():
    return [_learned(seed) for seed in range(RUNS)]


def _steps(family, models_for, means, covs, ys, split):
    """Step the runs in batches of the sizes ``split``; every field concatenated over the runs."""
    step = gaussian_family(family, SigmaParams()).step
    out, start = [], 0
    for size in split:
        part = slice(start, start + size)
        out.append(step(Gaussian(means[part], covs[part]), models_for(part), ys[part], k=3))
        start += size
    return {f: np.concatenate([getattr(r, f) for r in out]) for f in FIELDS}


def _assert_per_run_close(batched, family, model_of, means, covs, ys):
    step = gaussian_family(family, SigmaParams()).step
    for b in range(RUNS):
        alone = step(Gaussian(means[b], covs[b]), model_of(b), ys[b], k=3)
        for f in FIELDS:
            ref = getattr(alone, f)
            np.testing.assert_allclose(batched[f][b], ref, rtol=PER_RUN_RTOL, atol=PER_RUN_RTOL * np.abs(ref).max(),
                                       err_msg=f"{family} run {b} {f}")


@pytest.mark.parametrize("family", ["kf", "ekf", "ukf"])
def test_known_model_runs_are_the_same_for_every_batch(family):
    model = _linear_model() if family == "kf" else _user_model()
    means, covs, ys = _runs_data(model, np.random.default_rng(5))
    results = [_steps(family, lambda part: model.for_runs(part.stop - part.start), means, covs, ys, split)
               for split in SPLITS]
    for other in results[1:]:
        for f in FIELDS:
            np.testing.assert_array_equal(other[f], results[0][f], err_msg=f)
    _assert_per_run_close(results[0], family, lambda b: model, means, covs, ys)


@pytest.mark.usefixtures("moment_path")
@pytest.mark.parametrize("family", ["gp-adf", "gp-ukf"])
def test_learned_model_runs_are_the_same_for_every_batch(family, gp_models):
    means, covs, ys = _runs_data(_user_model(), np.random.default_rng(6))
    results = [_steps(family, lambda part: batch_gp_models(gp_models[part]), means, covs, ys, split)
               for split in SPLITS]
    for other in results[1:]:
        for f in FIELDS:
            np.testing.assert_array_equal(other[f], results[0][f], err_msg=f)
    _assert_per_run_close(results[0], family, lambda b: gp_models[b], means, covs, ys)


@pytest.mark.usefixtures("moment_path")
@pytest.mark.parametrize("per_run", [7, 1])
def test_a_batch_of_gps_predicts_as_each_gp(gp_models, per_run):
    """Means and variances of run b's points against run b's GP, as the GP itself gives them (the
    variances of one point per run — the filters' case, whitened by BLAS trsv from a compiled loop
    when the compiled path is on — to the bit), and the same bits in every split of the runs into
    batches."""
    gps = [m.transition for m in gp_models]
    points = np.random.default_rng(2).normal(size=(RUNS * per_run, 3))
    mean, var = GaussianProcessBatch(gps).predict(points)
    for b, gp in enumerate(gps):
        rows = slice(per_run * b, per_run * (b + 1))
        ref_mean, ref_var = gp.predict(points[rows])
        np.testing.assert_allclose(mean[rows], ref_mean, rtol=PER_RUN_RTOL, atol=PER_RUN_RTOL)
        if per_run == 1:
            np.testing.assert_array_equal(var[rows], ref_var)
        np.testing.assert_allclose(var[rows], ref_var, rtol=PER_RUN_RTOL, atol=PER_RUN_RTOL)
    for split in SPLITS[1:]:
        bounds = np.cumsum((0,) + split)
        parts = [GaussianProcessBatch(gps[a:z]).predict(points[per_run * a:per_run * z])
                 for a, z in zip(bounds, bounds[1:])]
        np.testing.assert_array_equal(np.concatenate([m for m, _ in parts]), mean)
        np.testing.assert_array_equal(np.concatenate([v for _, v in parts]), var)


def test_a_batch_refuses_gps_of_different_shapes():
    x = np.linspace(0, 1, 6)[:, None]
    small = GaussianProcess(x, np.sin(x[:, 0]), [[0.5]], [1.0], [0.01])
    large = GaussianProcess(np.linspace(0, 1, 7)[:, None], np.zeros(7), [[0.5]], [1.0], [0.01])
    with pytest.raises(InputError, match="share their shapes"):
        GaussianProcessBatch([small, large])
    with pytest.raises(InputError, match="takes points"):
        GaussianProcessBatch([small, small]).predict_mean(np.zeros((3, 1)))


def test_runwise_functions_keep_what_a_model_is():
    """A model for runs keeps its linear matrices (the KF still runs on it) and its angles."""
    model = _linear_model()
    runs = model.for_runs(4)
    np.testing.assert_array_equal(runs.linear_matrices()[0], model.linear_matrices()[0])
    user = _user_model().for_runs(2)
    assert user.circular == (1,)
    with pytest.raises(InputError, match="takes points"):
        user.f(np.zeros((3, 3)))
    with pytest.raises(InputError, match="runs must be"):
        model.for_runs(0)
