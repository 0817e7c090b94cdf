"""predict_uncertain over a batch of Gaussian inputs against the single call per input (the
reference, itself checked against quadrature and Monte Carlo in test_gp_moments.py): equal to
rounding, for one GP, a stack with cross-sensor blocks, a batch split into chunks and a batch that
mixes the ordinary and the log-space branch."""

import numpy as np
import pytest

import gpfverify.gp.moments as moments
from gpfverify.errors import InputError
from gpfverify.gp import GaussianProcess, GaussianProcessStack
from gpfverify.tolerances import algebra_rtol

#: every test here runs on the fused kernel (numba) and on the numpy reference path
pytestmark = pytest.mark.usefixtures("moment_path")


def _gp(seed, d, e, n=40, x=None):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-2, 2, size=(n, d)) if x is None else x
    y = np.stack([np.cos(x @ rng.normal(size=d)) + x[:, 0] * (a + 1) / e for a in range(e)], 1)
    return GaussianProcess(x, y, lengthscales=rng.uniform(0.7, 2.0, size=(e, d)),
                           signal_var=rng.uniform(0.5, 2.0, size=e), noise_var=rng.uniform(0.01, 0.1, size=e))


def _inputs(rng, batch, d, scale=0.4):
    mus = rng.uniform(-1.5, 1.5, size=(batch, d))
    a = rng.normal(size=(batch, d, d))
    return mus, scale * (a @ np.swapaxes(a, 1, 2) / d + 0.1 * np.eye(d))


def _assert_equal_per_input(batch, singles, gp):
    tol = algebra_rtol(max(np.linalg.cond(np.linalg.inv(k)) for k in np.atleast_3d(gp.K_inv))
                       if hasattr(gp, "K_inv") else max(np.linalg.cond(np.linalg.inv(k)) for g in gp.gps
                                                        for k in g.K_inv))
    for b, one in enumerate(singles):
        for name in ("mean", "cov", "cross_cov"):
            ours, ref = getattr(batch, name)[b], getattr(one, name)
            np.testing.assert_allclose(ours, ref, rtol=tol, atol=tol * np.abs(ref).max(), err_msg=name)


@pytest.mark.parametrize("d, e", [(1, 1), (2, 4), (3, 2)])
def test_batch_equals_single_calls(d, e):
    gp = _gp(d * 10 + e, d, e)
    mus, sigmas = _inputs(np.random.default_rng(1), 7, d)
    batch = gp.predict_uncertain_batch(mus, sigmas)
    assert batch.mean.shape == (7, e) and batch.cov.shape == (7, e, e) and batch.cross_cov.shape == (7, d, e)
    _assert_equal_per_input(batch, [gp.predict_uncertain(m, s) for m, s in zip(mus, sigmas)], gp)
    np.testing.assert_array_equal(batch.cov, np.swapaxes(batch.cov, 1, 2))


def test_stack_batch_equals_single_calls():
    stack = GaussianProcessStack([_gp(3, 2, 2), _gp(4, 2, 1, n=25), _gp(5, 2, 3, n=31)])
    mus, sigmas = _inputs(np.random.default_rng(2), 5, 2)
    batch = stack.predict_uncertain_batch(mus, sigmas)
    _assert_equal_per_input(batch, [stack.predict_uncertain(m, s) for m, s in zip(mus, sigmas)], stack)


def test_batch_in_chunks_equals_single_calls(monkeypatch):
    monkeypatch.setattr(moments, "_CHUNK_ENTRIES", 3 * 40 * 40)  # three inputs' pairs at most per chunk
    gp = _gp(7, 2, 2)
    mus, sigmas = _inputs(np.random.default_rng(3), 8, 2)
    batch = gp.predict_uncertain_batch(mus, sigmas)
    _assert_equal_per_input(batch, [gp.predict_uncertain(m, s) for m, s in zip(mus, sigmas)], gp)


def test_batch_with_a_log_space_input_equals_single_calls():
    """One input far wider than the lengthscales (the log-space branch) among ordinary ones."""
    rng = np.random.default_rng(9)
    x = np.concatenate([rng.uniform(-10, 10, size=(30, 1)), rng.uniform(250, 400, size=(30, 1))])
    gp = GaussianProcess(x, np.sin(3 * x[:, 0]), lengthscales=[[0.5]], signal_var=[1.0], noise_var=[0.01])
    mus, sigmas = np.array([[0.5], [0.2], [1.0]]), np.array([[[30.0]], [[0.1]], [[0.3]]])
    batch = gp.predict_uncertain_batch(mus, sigmas)
    _assert_equal_per_input(batch, [gp.predict_uncertain(m, s) for m, s in zip(mus, sigmas)], gp)


def test_batch_arguments_are_checked():
    gp = _gp(1, 2, 1)
    with pytest.raises(InputError, match="Sigmas"):
        gp.predict_uncertain_batch(np.zeros((2, 2)), np.zeros((3, 2, 2)))
    with pytest.raises(InputError, match=r"Sigmas\[1\]"):
        gp.predict_uncertain_batch(np.zeros((2, 2)), np.stack([np.eye(2), -np.eye(2)]))
