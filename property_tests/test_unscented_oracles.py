"""The UKF against oracles written here, for the input classes the linear-model check cannot see:
non-default (α, β, κ) on a nonlinear map, angle outputs and angle states across ±π, and batched
beliefs.

* A square: for h(x) = (x_0 + b)², x ~ N(μ, C), the scaled unscented transform (lower Cholesky
  factor, whose first row is (√C_00, 0, …, 0)) gives, with m = μ_0 + b, P = C_00,
  s² = D + λ = α²(D + κ):

      μ_y = m² + P,   C_y − R = 4m²P + P² (α²(D + κ − 1) + β),   C_xy = 2m C[:, 0]

  (the ± points contribute ±2msc_i + s²c_i² − P, the centre −P; Σ w_c over the ± points of
  s²c_i² terms gives s² P² · 2w = P², and w_c0 = λ/(D + λ) + 1 − α² + β); where
  α²(D + κ − 1) + β = 2 (D = 1, κ = 0, β = 2) it is the exact Gaussian variance 4m²P + 2P².
* Angles: a linear-Gaussian model whose angle state and angle output are wrapped (F e_0 = e_0,
  H e_0 = e_0, so a turn of 2π changes nothing else) is, modulo 2π in those components, the
  Kalman filter of the unwrapped model — written here in covariance form with numpy solves.
* Batches: B beliefs filtered in one call equal each filtered alone.

Tolerances: algebra_rtol(cond · Σ|w_m|) of the problem's scale, as for the linear-model check (the
weights reach ~1e6 at α = 1e-3 and the sums lose eps · Σ|w_m| of the points' size).
"""

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from gpfverify.angles import wrap
from gpfverify.filters.records import Gaussian
from gpfverify.filters.ukf import ukf_measurement, ukf_step
from gpfverify.models import Sensor, StateSpaceModel
from gpfverify.strategies import chunk_sizes, sigma_params, spd_matrices
from gpfverify.strategies.matrices import float_arrays, log_uniform, unit_floats
from gpfverify.strategies.models import angle_models, batched_beliefs
from gpfverify.tolerances import algebra_rtol


def _tolerance(params, dim: int, *covs) -> float:
    wm, _ = params.weights(dim)
    return algebra_rtol(max(np.linalg.cond(c) for c in covs) * np.abs(wm).sum())


@given(dim=st.integers(1, 4), data=st.data())
def test_unscented_transform_of_a_square_is_the_closed_form(dim, data):
    params = data.draw(sigma_params(dim, min_alpha=0.1), label="sigma params")
    cov = data.draw(spd_matrices(dim, 100.0, log_uniform(0.01, 1.0)), label="C")
    mean = data.draw(float_arrays((dim,), -2.0, 2.0), label="mu")
    b = data.draw(unit_floats(-2.0, 2.0), label="b")
    r = data.draw(log_uniform(1e-3, 1.0), label="R")
    model = StateSpaceModel(lambda x: x, np.eye(dim), Sensor(lambda x: (x[:, 0] + b) ** 2, [[r]]),
                            mean, cov)
    moments = ukf_measurement(Gaussian(mean, cov), model, params=params)
    m, p = mean[0] + b, cov[0, 0]
    variance = 4 * m * m * p + p * p * (params.alpha**2 * (dim + params.kappa - 1) + params.beta)
    tol = _tolerance(params, dim, cov)
    scale = (abs(m) + np.sqrt(p)) ** 2 * (1 + params.alpha**2 * (dim + params.kappa) + params.beta)
    np.testing.assert_allclose(moments.mu_y, [m * m + p], rtol=0, atol=tol * scale)
    np.testing.assert_allclose(moments.C_y, [[variance + r]], rtol=0, atol=tol * scale * scale)
    np.testing.assert_allclose(moments.C_xy[:, 0], 2 * m * cov[:, 0], rtol=0,
                               atol=tol * scale * np.abs(cov).max())


def _kalman(F, H, Q, R, mean, cov, y):
    """Covariance-form KF step on stacks: mean (B, D), cov (B, D, D), y (B, L)."""
    mu_p = mean @ F.T
    c_p = F @ cov @ F.T + Q
    mu_y = mu_p @ H.T
    c_y = H @ c_p @ H.T + R
    c_xy = c_p @ H.T
    gain = np.swapaxes(np.linalg.solve(c_y, np.swapaxes(c_xy, -1, -2)), -1, -2)
    mu_e = mu_p + np.einsum("bdl,bl->bd", gain, y - mu_y)
    c_e = c_p - gain @ np.swapaxes(c_xy, -1, -2)
    return dict(mu_p=mu_p, C_p=c_p, mu_y=mu_y, C_y=c_y, C_xy=c_xy, mu_e=mu_e, C_e=c_e)


@given(drawn=angle_models(), data=st.data())
def test_ukf_with_angles_across_the_cut_is_the_kalman_filter_modulo_two_pi(drawn, data):
    """Angle state near ±π and an angle output whose sigma points straddle ±π, filtered as a batch
    with non-default (α, β, κ): every moment equals the KF's of the unwrapped model, the angle
    components compared on the circle; the angle components of μ_p, μ_y and μ_e lie in (−π, π]."""
    d, l = drawn.F.shape[0], drawn.H.shape[0]
    params = data.draw(sigma_params(d, min_alpha=0.1), label="sigma params")
    F, H, offset = drawn.F, drawn.H, drawn.offset

    def transition(x):
        out = x @ F.T
        out[:, 0] = wrap(out[:, 0])
        return out

    def measure(x):
        out = x @ H.T
        out[:, 0] = wrap(out[:, 0] + offset)
        return out

    model = StateSpaceModel(transition, drawn.Q, Sensor(measure, drawn.R, circular=(0,)),
                            drawn.means[0], drawn.covs[0], circular_state=(0,))
    batch = drawn.means.shape[0]
    got = ukf_step(Gaussian(drawn.means, drawn.covs), model, drawn.ys, params=params)
    mu_y_kf = drawn.means @ F.T @ H.T
    y_unwrapped = drawn.ys.copy()
    y_unwrapped[:, 0] = mu_y_kf[:, 0] + wrap(drawn.ys[:, 0] - offset - mu_y_kf[:, 0])
    want = _kalman(F, H, drawn.Q, drawn.R, drawn.means, drawn.covs, y_unwrapped)
    want["mu_y"][:, 0] += offset
    tol = _tolerance(params, d, *want["C_p"], *want["C_y"]) * 4 * np.pi
    for name, value in want.items():
        diff = np.asarray(getattr(got, name)).reshape(value.shape) - value
        if name.startswith("mu"):
            diff[:, 0] = wrap(diff[:, 0])
        size = np.abs(value).max() if name.startswith("C") else 1.0
        assert np.abs(diff).max() <= tol * size, (name, diff)
    for name in ("mu_p", "mu_y", "mu_e"):
        angle = np.asarray(getattr(got, name)).reshape(batch, -1)[:, 0]
        assert np.all((angle > -np.pi) & (angle <= np.pi)), (name, angle)
    assert l == got.mu_y.shape[-1]


def _nonlinear_model(dim: int, r_scale: float) -> StateSpaceModel:
    def transition(x):
        return x + 0.3 * np.sin(x[:, ::-1])

    def measure(x):
        return np.stack([np.arctan2(x[:, 0], 1.0 + x[:, -1] ** 2), x[:, 0] * x[:, -1]], axis=1)

    return StateSpaceModel(transition, 0.1 * np.eye(dim), Sensor(measure, r_scale * np.eye(2), circular=(0,)),
                           np.zeros(dim), np.eye(dim))


@given(dim=st.integers(1, 3), data=st.data())
def test_a_batch_of_beliefs_filtered_at_once_equals_each_filtered_alone(dim, data):
    """A nonlinear model with an angle output, non-default (α, β, κ): ukf_step on B beliefs at
    once against B separate calls."""
    beliefs = data.draw(batched_beliefs(dim), label="beliefs")
    params = data.draw(sigma_params(dim, min_alpha=0.1), label="sigma params")
    ys = data.draw(float_arrays((beliefs.mean.shape[0], 2), -3.0, 3.0), label="y")
    model = _nonlinear_model(dim, data.draw(log_uniform(0.01, 1.0), label="R scale"))
    together = ukf_step(beliefs, model, ys, params=params)
    for i in range(beliefs.mean.shape[0]):
        alone = ukf_step(Gaussian(beliefs.mean[i], beliefs.cov[i]), model, ys[i], params=params)
        tol = _tolerance(params, dim, alone.C_p, alone.C_y)
        for name in ("mu_p", "C_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e"):
            want, got = getattr(alone, name), getattr(together, name)[i]
            scale = max(np.abs(want).max(), np.abs(alone.C_p).max(), np.abs(alone.C_y).max(), 1.0)
            np.testing.assert_allclose(got, want, rtol=0, atol=tol * scale, err_msg=name)


@given(dim=st.integers(1, 3), data=st.data())
def test_a_batch_filtered_in_chunks_equals_the_batch_filtered_at_once(dim, data):
    """Metamorphic: the beliefs of a batch cut into chunks of drawn, uneven sizes (ones included),
    each chunk filtered by its own ukf_step call, give the batch's own results row for row."""
    beliefs = data.draw(batched_beliefs(dim, batch=st.integers(2, 7)), label="beliefs")
    b = beliefs.mean.shape[0]
    chunks = data.draw(chunk_sizes(b), label="chunks")
    params = data.draw(sigma_params(dim, min_alpha=0.1), label="sigma params")
    ys = data.draw(float_arrays((b, 2), -3.0, 3.0), label="y")
    model = _nonlinear_model(dim, data.draw(log_uniform(0.01, 1.0), label="R scale"))
    together = ukf_step(beliefs, model, ys, params=params)
    start = 0
    for size in chunks:
        rows = slice(start, start + size)
        part = ukf_step(Gaussian(beliefs.mean[rows], beliefs.cov[rows]), model, ys[rows], params=params)
        for name in ("mu_p", "C_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e"):
            want, got = getattr(together, name)[rows], getattr(part, name)
            tol = _tolerance(params, dim, *together.C_p[rows], *together.C_y[rows])
            scale = max(np.abs(want).max(), np.abs(together.C_p[rows]).max(), np.abs(together.C_y[rows]).max(), 1.0)
            np.testing.assert_allclose(got, want, rtol=0, atol=tol * scale, err_msg=name)
        start += size
    assert start == b
