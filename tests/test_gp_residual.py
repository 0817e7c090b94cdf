"""GP residual models recover a known injected residual (and its noise) from training data."""

import numpy as np
import pytest

from gpfverify.errors import InputError
from gpfverify.gp.residual import fit_residual
from gpfverify.tolerances import MONTE_CARLO_SIGMAS, monte_carlo_atol

NOISE_SD = 0.05


def _transition_data(rng, n):
    x = rng.uniform(-3, 3, size=(n, 2))
    approx = 0.9 * x
    injected = np.stack([0.5 * np.sin(x[:, 0]), np.zeros(n)], axis=1)
    targets = approx + injected
    targets[:, 0] += NOISE_SD * rng.standard_normal(n)
    return x, targets, approx


def test_transition_residual_recovers_injected_function_and_noise():
    rng = np.random.default_rng(0)
    n = 200
    x, targets, approx = _transition_data(rng, n)
    res = fit_residual(x, targets, approx, outputs=(0,), state_inputs=(0,), seed=1)
    xs = np.stack([np.linspace(-2.8, 2.8, 50), rng.uniform(-3, 3, 50)], axis=1)
    truth = 0.5 * np.sin(xs[:, 0])
    mean = res.mean(xs)[:, 0]
    _, latent = res.gp.predict(res.features(xs))
    # the GP's own posterior covers the injected function (standardised errors within the MC band)
    assert np.max(np.abs(mean - truth) / np.sqrt(latent[:, 0])) < MONTE_CARLO_SIGMAS
    # the corrected model is closer to the truth than the approximate one, on the corrected output only
    corrected = res.add_to(0.9 * xs, xs)
    assert np.mean((corrected[:, 0] - 0.9 * xs[:, 0] - truth) ** 2) < np.mean(truth**2)
    np.testing.assert_array_equal(corrected[:, 1], 0.9 * xs[:, 1])
    # learned noise variance: the sample variance of n residual noises has s.d. ≈ σ² √(2/n)
    assert abs(res.gp.noise_var[0] - NOISE_SD**2) <= monte_carlo_atol(np.sqrt(2) * NOISE_SD**2, n)
    np.testing.assert_allclose(res.noise_var(xs)[:, 0], latent[:, 0] + res.gp.noise_var[0])


def test_measurement_residual_with_exogenous_inputs_only():
    """ĥ(x) = x misses an input-dependent offset c(u) = [cos u, sin u] (a lever arm turning with
    heading u); the GP on u alone recovers it."""
    rng = np.random.default_rng(2)
    n = 150
    x = rng.normal(size=(n, 2))
    u = rng.uniform(0, 2 * np.pi, size=(n, 1))
    offset = np.concatenate([np.cos(u), np.sin(u)], axis=1)
    z = x + offset + NOISE_SD * rng.standard_normal((n, 2))
    res = fit_residual(x, z, x, outputs=(0, 1), inputs=u, seed=3)
    us = np.linspace(0.2, 6.0, 40)[:, None]
    states = rng.normal(size=(40, 2))  # irrelevant to the residual
    mean = res.mean(states, us)
    _, latent = res.gp.predict(res.features(states, us))
    truth = np.concatenate([np.cos(us), np.sin(us)], axis=1)
    assert np.max(np.abs(mean - truth) / np.sqrt(latent)) < MONTE_CARLO_SIGMAS
    assert np.all(np.abs(res.gp.noise_var - NOISE_SD**2) <= monte_carlo_atol(np.sqrt(2) * NOISE_SD**2, n))


def test_subset_and_bad_input():
    rng = np.random.default_rng(4)
    x, targets, approx = _transition_data(rng, 120)
    res = fit_residual(x, targets, approx, outputs=(0,), state_inputs=(0,), max_points=40, seed=0)
    assert res.gp.X.shape == (40, 1)
    with pytest.raises(InputError, match="outputs"):
        fit_residual(x, targets, approx, outputs=(5,), state_inputs=(0,))
    with pytest.raises(InputError, match="feature"):
        fit_residual(x, targets, approx, outputs=(0,))
    with pytest.raises(InputError, match="approx"):
        fit_residual(x, targets, approx[:, :1], outputs=(0,), state_inputs=(0,))
    with pytest.raises(InputError, match="inputs"):
        fit_residual(x, targets, approx, outputs=(0,), inputs=np.ones((3, 1)))


def test_distinct_rows_agree_with_numpy_unique():
    """The same distinct rows as numpy's unique(axis=0), and an inverse that rebuilds the input,
    with repeated rows, ±0.0 and the empty case."""
    from gpfverify.gp.residual import distinct_rows

    rng = np.random.default_rng(5)
    rows = np.repeat(rng.normal(size=(20, 4)), 7, axis=0)
    rows[::5, 1] += 1.0
    rows[3], rows[4] = 0.0, -0.0
    rng.shuffle(rows)
    distinct, inverse = distinct_rows(rows)
    np.testing.assert_array_equal(distinct[inverse], rows)
    expected = np.unique(rows, axis=0)
    assert distinct.shape == expected.shape
    np.testing.assert_array_equal(distinct[np.lexsort(distinct.T[::-1])], expected)
    empty, none = distinct_rows(np.zeros((0, 3)))
    assert empty.shape == (0, 3) and none.shape == (0,)
