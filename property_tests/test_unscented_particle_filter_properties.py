"""The square-root UKF, the unscented particle filter and GPSR-UPF against oracles written here.

* rank-one updates and downdates of Cholesky factors (both the compiled and the numpy column loop)
  are scipy's Cholesky factor of the changed matrix, and a downdate past definiteness is flagged;
  the QR step's factor is the lower Cholesky factor of A Aᵀ;
* the SR-UKF on a linear-Gaussian model is the Kalman filter (information form, computed here for
  a batch of beliefs with *different* covariances) for every valid (α, β, κ), negative zeroth
  weights included; its factors are lower triangular with a positive diagonal;
* the UPF's UKF proposal and GPSR-UPF's SR-UKF proposal, each particle with its own covariance
  factor (and, for GPSR-UPF, its own process noise √Q_i), are per-particle Kalman updates;
* the UPF's weights are the importance weights w_i ∝ w_{i,k−1} p(y | x_i) p(x_i | x_{i,k−1}) /
  q_i(x_i), every density evaluated here with scipy — with distinct proposals q_i per particle,
  where a constant dropped from log q_i no longer cancels; and the self-normalised estimate of
  one step from a point x_{k−1} is within Monte Carlo error of the exact posterior mean;
* GPSR-UPF's weights use the GP-corrected transition N(x; f̂(x') + GP(x'), Q(x')), Q(x') with the
  GP predictive variance in place of the nominal Q on the learned output (evaluated here).
"""

import contextlib

import numpy as np
import scipy.linalg as sla
import scipy.stats
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import logsumexp

from gpfverify.errors import NumericalError
from gpfverify.filters import sr_ukf
from gpfverify.filters.gpsr_upf import GPResidualModel, gpsr_upf_step, sr_ukf_proposal
from gpfverify.filters.records import Gaussian
from gpfverify.filters.resampling import Particles
from gpfverify.filters.sr_ukf import SqrtGaussian, cholupdate, qr_factor, sr_ukf_step
from gpfverify.filters.ukf import ukf_step
from gpfverify.filters.upf import ukf_proposal, upf_step
from gpfverify.gp.residual import ResidualGP
from gpfverify.models import Sensor, StateSpaceModel, linear_model
from gpfverify.strategies import (batched_beliefs, gaussian_processes, linear_gaussian_models, scaled_examples,
                                  sigma_params, spd_matrices)
from gpfverify.strategies.matrices import float_arrays, log_uniform, unit_floats
from gpfverify.tolerances import EPS, algebra_rtol, monte_carlo_atol

PATHS = (True, False) if sr_ukf.compiled else (False,)


@contextlib.contextmanager
def cholupdate_path(compiled: bool):
    saved = sr_ukf.compiled
    sr_ukf.compiled = compiled
    try:
        yield
    finally:
        sr_ukf.compiled = saved


def _transpose(a):
    return np.swapaxes(a, -1, -2)


def kalman(means, covs, F, Q, H, R, y):
    """Batched Kalman step in information form (no library code): prior N(means (B, D), covs (B, D, D)),
    Q (D, D) or one per belief (B, D, D). Returns mu_p, C_p, mu_y, C_y, C_xy, mu_e, C_e."""
    mu_p = means @ F.T
    C_p = F @ covs @ F.T + Q
    r_inv = np.linalg.inv(R)
    p_inv = np.linalg.inv(C_p)
    C_e = np.linalg.inv(p_inv + H.T @ r_inv @ H)
    mu_e = np.einsum("bij,bj->bi", C_e, np.einsum("bij,bj->bi", p_inv, mu_p) + H.T @ r_inv @ y)
    return mu_p, C_p, mu_p @ H.T, H @ C_p @ H.T + R, C_p @ H.T, mu_e, C_e


def kalman_condition(C_p, R, H):
    info = np.linalg.inv(C_p) + H.T @ np.linalg.inv(R) @ H
    return float(np.max(np.linalg.cond(C_p)) * np.linalg.cond(R) * np.max(np.linalg.cond(info)))


# -- factor algebra ---------------------------------------------------------------------------------
@given(dim=st.integers(1, 5), batch=st.integers(1, 4), data=st.data())
def test_rank_one_update_and_downdate_give_the_cholesky_factor_of_the_changed_matrix(dim, batch, data):
    covs = np.stack([data.draw(spd_matrices(dim, 1e3, log_uniform(1e-2, 10.0)), label="C") for _ in range(batch)])
    factors = np.linalg.cholesky(covs)
    u = data.draw(float_arrays((batch, dim), -1.0, 1.0), label="u")
    norms = np.linalg.norm(u, axis=1, keepdims=True)
    shrink = data.draw(unit_floats(0.0, 0.9), label="|u| for the downdate")
    u_down = np.where(norms > 0, u / np.maximum(norms, EPS) * shrink, 0.0)  # |u| ≤ 0.9: C − x xᵀ ⪰ 0.19 C
    grow = data.draw(unit_floats(1.1, 3.0), label="|u| past definiteness")
    u_past = np.zeros((batch, dim))
    u_past[:, data.draw(st.integers(0, dim - 1), label="axis")] = grow
    for compiled in PATHS:
        with cholupdate_path(compiled):
            for sign, x in ((1.0, 3.0 * np.einsum("bij,bj->bi", factors, u)),
                            (-1.0, np.einsum("bij,bj->bi", factors, u_down))):
                changed = covs + sign * x[:, :, None] * x[:, None, :]
                want = np.stack([sla.cholesky(c, lower=True) for c in changed])
                got, failed = cholupdate(factors, x, sign)
                assert not failed.any(), (compiled, sign)
                tol = algebra_rtol(max(np.linalg.cond(c) for c in changed)) * np.abs(want).max()
                np.testing.assert_allclose(got, want, rtol=0, atol=tol, err_msg=f"compiled={compiled} sign={sign}")
            _, failed = cholupdate(factors, np.einsum("bij,bj->bi", factors, u_past), -1.0)
            assert failed.all(), compiled


@given(dim=st.integers(1, 4), extra=st.integers(0, 6), batch=st.integers(1, 3), data=st.data())
def test_qr_factor_is_the_lower_cholesky_factor_of_a_a_transposed(dim, extra, batch, data):
    columns = data.draw(float_arrays((batch, dim, dim + extra), -2.0, 2.0), label="A")
    columns[:, :, :dim] += (2.0 * dim + 1.0) * np.eye(dim)  # strictly diagonally dominant: full row rank
    gram = columns @ _transpose(columns)
    got = qr_factor(columns)
    want = np.linalg.cholesky(gram)
    assert np.all(np.triu(got, 1) == 0.0) and np.all(np.diagonal(got, axis1=-2, axis2=-1) > 0)
    tol = algebra_rtol(max(np.linalg.cond(g) for g in gram)) * np.abs(want).max()
    np.testing.assert_allclose(got, want, rtol=0, atol=tol)


# -- the SR-UKF -------------------------------------------------------------------------------------
@given(model=linear_gaussian_models(max_condition=1e2), data=st.data())
def test_sr_ukf_is_the_kalman_filter_for_a_batch_of_beliefs(model, data):
    dim = model.F.shape[0]
    params = data.draw(sigma_params(dim, min_alpha=1e-2), label="sigma params")
    beliefs = data.draw(batched_beliefs(dim, max_variance=2.0), label="beliefs")
    system = linear_model(model.F, model.H, model.Q, model.R)
    want = kalman(beliefs.mean, beliefs.cov, model.F, model.Q, model.H, model.R, model.y)
    for compiled in PATHS:
        with cholupdate_path(compiled):
            record = sr_ukf_step(SqrtGaussian(beliefs.mean, np.linalg.cholesky(beliefs.cov)), system, model.y,
                                 params=params)
        for factor in (record.S_p, record.S_y, record.S_e):
            assert np.all(np.triu(factor, 1) == 0.0) and np.all(np.diagonal(factor, axis1=-2, axis2=-1) > 0)
        got = record.to_record()
        wm, _ = params.weights(dim)
        tol = algebra_rtol(kalman_condition(want[1], model.R, model.H) * np.abs(wm).sum()) + record.jitter
        names = ("mu_p", "C_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e")
        scale = max(np.abs(beliefs.mean).max(), np.abs(model.y).max(), np.abs(want[1]).max(), np.abs(want[3]).max(),
                    1.0)
        for name, value in zip(names, want):
            np.testing.assert_allclose(getattr(got, name), value, rtol=0, atol=tol * scale,
                                       err_msg=f"{name} compiled={compiled}")


@st.composite
def mildly_nonlinear_models(draw):
    """x_k = A x + a sin(x) + w, y = C x + b tanh(B x) + v with |a|, |b| ≤ 0.3: curved enough that the
    zeroth sigma point's deviation from the mean is not zero (on a linear map it is, whatever its weight)."""
    dim, size = draw(st.integers(1, 3)), draw(st.integers(1, 3))
    A, C, B = (draw(float_arrays(shape, -1.2, 1.2)) for shape in ((dim, dim), (size, dim), (size, dim)))
    a, b = draw(unit_floats(-0.3, 0.3)), draw(unit_floats(-0.3, 0.3))
    Q = draw(spd_matrices(dim, 1e2, log_uniform(1e-2, 0.3)))
    R = draw(spd_matrices(size, 1e2, log_uniform(1e-2, 0.3)))

    def f(x, k):
        return x @ A.T + a * np.sin(x)

    def h(x, k):
        return x @ C.T + b * np.tanh(x @ B.T)

    return StateSpaceModel(f, Q, [Sensor(h, R)], np.zeros(dim), np.eye(dim)), draw(float_arrays((size,), -3.0, 3.0))


@given(problem=mildly_nonlinear_models(), data=st.data())
def test_sr_ukf_is_the_covariance_form_ukf_on_nonlinear_models(problem, data):
    """The same sigma points (the factors are the Cholesky factors of the UKF's covariances), so the
    same numbers to rounding for every valid (α, β, κ) — including a negative zeroth weight w_c0,
    whose rank-one downdate is exercised here. Where the UKF's own covariance is indefinite the
    SR-UKF must refuse (NumericalError) or report the jitter it added, never return a factor of
    something else."""
    model, y = problem
    dim = model.state_dim
    params = data.draw(sigma_params(dim, min_alpha=0.5), label="sigma params")
    beliefs = data.draw(batched_beliefs(dim, max_variance=1.0), label="beliefs")
    want = ukf_step(Gaussian(beliefs.mean, beliefs.cov), model, y, params=params)
    lowest = min(np.linalg.eigvalsh(getattr(want, name)).min() / np.abs(getattr(want, name)).max()
                 for name in ("C_p", "C_y", "C_e"))
    wm, _ = params.weights(dim)
    rounding = algebra_rtol(np.abs(wm).sum() * max(np.max(np.linalg.cond(want.C_p)), np.max(np.linalg.cond(want.C_y))))
    for compiled in PATHS:
        with cholupdate_path(compiled):
            try:
                record = sr_ukf_step(SqrtGaussian(beliefs.mean, np.linalg.cholesky(beliefs.cov)), model, y,
                                     params=params)
            except NumericalError:
                assert lowest <= rounding, ("refused a definite step", lowest)
                continue
        if lowest <= -rounding:
            assert record.jitter > 0, ("an indefinite UKF covariance factored without jitter", lowest)
            continue
        got = record.to_record()
        cond = max(np.max(np.linalg.cond(want.C_e)), np.max(np.linalg.cond(want.C_y)))
        tol = algebra_rtol(cond * np.abs(wm).sum()) + record.jitter
        for name in ("mu_p", "C_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e"):
            value = getattr(want, name)
            scale = max(np.abs(value).max(), np.abs(beliefs.mean).max(), np.abs(y).max(), 1.0)
            np.testing.assert_allclose(getattr(got, name), value, rtol=0, atol=tol * scale,
                                       err_msg=f"{name} compiled={compiled}")


# -- per-particle proposals -------------------------------------------------------------------------
@st.composite
def particle_beliefs(draw, dim: int, count=st.integers(2, 6)):
    """Particles (N, D) in [−3, 3] with unequal log weights and their own covariance factors."""
    n = draw(count)
    covs = np.stack([draw(spd_matrices(dim, 1e2, log_uniform(1e-2, 1.0))) for _ in range(n)])
    return Particles(draw(float_arrays((n, dim), -3.0, 3.0)), draw(float_arrays((n,), -2.0, 0.0)),
                     np.linalg.cholesky(covs))


@given(model=linear_gaussian_models(max_condition=1e2), data=st.data())
def test_ukf_and_sr_ukf_proposals_are_per_particle_kalman_updates(model, data):
    """Each particle's own N(x_i, S_i S_iᵀ), and for the SR-UKF proposal its own process noise √Q_i
    (GPSR-UPF's state-dependent Q), updated by the Kalman filter."""
    dim = model.F.shape[0]
    belief = data.draw(particle_beliefs(dim), label="particles")
    n = belief.size
    q_i = np.stack([data.draw(spd_matrices(dim, 1e2, log_uniform(1e-2, 1.0)), label="Q_i") for _ in range(n)])
    system = linear_model(model.F, model.H, model.Q, model.R)
    covs = belief.sqrt_covs @ _transpose(belief.sqrt_covs)
    cases = (("UKF", ukf_proposal(belief, system, model.y), model.Q),
             ("SR-UKF", sr_ukf_proposal(belief, system, model.y, process_sqrt=lambda x, k: np.linalg.cholesky(q_i)),
              q_i))
    for name, (means, factors), q in cases:
        want = kalman(belief.particles, covs, model.F, q, model.H, model.R, model.y)
        tol = algebra_rtol(kalman_condition(want[1], model.R, model.H))
        scale = max(np.abs(belief.particles).max(), np.abs(model.y).max(), np.abs(want[1]).max(), 1.0)
        assert np.all(np.triu(factors, 1) == 0.0) and np.all(np.diagonal(factors, axis1=-2, axis2=-1) > 0), name
        np.testing.assert_allclose(means, want[5], rtol=0, atol=tol * scale, err_msg=name)
        np.testing.assert_allclose(factors @ _transpose(factors), want[6], rtol=0, atol=tol * scale, err_msg=name)


# -- importance weights -----------------------------------------------------------------------------
def _mvn_logpdf(x, means, covs):
    """log N(x_i; m_i, C_i) row by row with scipy."""
    return np.array([scipy.stats.multivariate_normal(m, c).logpdf(v) for v, m, c in zip(x, means, covs)])


def _log_weight_tolerance(terms, conds):
    """Rounding of a sum of log densities: each quadratic form loses eps · cond of its magnitude."""
    return algebra_rtol(max(conds)) * (np.abs(terms).sum(axis=0) + 1.0)


@given(model=linear_gaussian_models(max_condition=1e2), seed=st.integers(0, 2**32 - 1), data=st.data())
def test_upf_weights_are_the_importance_weights_of_each_particles_own_proposal(model, seed, data):
    dim = model.F.shape[0]
    belief = data.draw(particle_beliefs(dim), label="particles")
    system = linear_model(model.F, model.H, model.Q, model.R)
    step = upf_step(belief, system, model.y, rng=np.random.default_rng(seed), resample_threshold=0.0)
    assert not step.resampled and step.posterior is step.weighted
    x = step.weighted.particles
    covs = belief.sqrt_covs @ _transpose(belief.sqrt_covs)
    _, _, _, _, _, m_q, c_q = kalman(belief.particles, covs, model.F, model.Q, model.H, model.R, model.y)
    n = belief.size
    terms = np.stack([belief.log_weights,
                      _mvn_logpdf(np.broadcast_to(model.y, (n, model.y.size)), x @ model.H.T, [model.R] * n),
                      _mvn_logpdf(x, belief.particles @ model.F.T, [model.Q] * n),
                      -_mvn_logpdf(x, m_q, c_q)])
    want = terms.sum(axis=0)
    want -= logsumexp(want)
    conds = [np.linalg.cond(model.R), np.linalg.cond(model.Q), kalman_condition(c_q, model.R, model.H)]
    tol = _log_weight_tolerance(terms, conds)
    np.testing.assert_allclose(step.weighted.log_weights, want, rtol=0, atol=2 * tol.max())
    np.testing.assert_array_equal(step.weighted.sqrt_covs.shape, belief.sqrt_covs.shape)


@settings(max_examples=scaled_examples(0.25))
@given(model=linear_gaussian_models(state_dim=st.integers(1, 2), measurement_dim=st.integers(1, 2), max_condition=1e2),
       seed=st.integers(0, 2**32 - 1), data=st.data())
def test_upf_estimate_from_one_point_is_the_exact_posterior_mean_within_monte_carlo_error(model, seed, data):
    """Every particle at one x_{k−1} but with its own covariance factor S_i = s_i L_Q, s_i ∈ [0.1, 2]:
    the target p(x_k | x_{k−1}, y_k) is the Kalman posterior of the prior N(F x_{k−1}, Q); each
    proposal is wider than it, so the weights are bounded, and y lies within two standard deviations
    (per whitened axis) of its prediction, so the proposals' means stay near the target's and the
    effective sample size a fair fraction of the 4000 particles: the delta-method standard error holds."""
    dim, count = model.F.shape[0], 4000
    rng = np.random.default_rng(seed)
    x_prev = model.prior.mean
    predicted = model.H @ model.F @ x_prev
    S = model.H @ model.Q @ model.H.T + model.R
    y = predicted + np.linalg.cholesky(S) @ data.draw(float_arrays((model.y.size,), -2.0, 2.0), label="z")
    spread = np.exp(rng.uniform(np.log(0.1), np.log(2.0), count))
    factor = np.linalg.cholesky(model.Q)
    belief = Particles(np.tile(x_prev, (count, 1)), np.zeros(count), spread[:, None, None] * factor)
    system = linear_model(model.F, model.H, model.Q, model.R)
    step = upf_step(belief, system, y, rng=rng, resample_threshold=0.0)
    _, _, _, _, _, exact, _ = kalman(x_prev[None], np.zeros((1, dim, dim)), model.F, model.Q, model.H, model.R, y)
    w = np.exp(step.weighted.log_weights)
    se = np.sqrt(np.einsum("n,ni->i", w**2, (step.weighted.particles - step.mean) ** 2))
    assert np.all(np.abs(step.mean - exact[0]) <= monte_carlo_atol(se, 1)), (step.mean, exact[0], se)


@given(model=linear_gaussian_models(max_condition=1e2), seed=st.integers(0, 2**32 - 1), data=st.data())
def test_gpsr_upf_weights_use_the_gp_corrected_transition_with_its_predictive_variance(model, seed, data):
    dim = model.F.shape[0]
    belief = data.draw(particle_beliefs(dim), label="particles")
    gp = data.draw(gaussian_processes(input_dim=1, output_dim=1), label="GP")
    source = data.draw(st.integers(0, dim - 1), label="input")
    output = data.draw(st.integers(0, dim - 1), label="output")
    residual = ResidualGP(gp, (source,), 0, (output,))
    corrected = GPResidualModel(linear_model(model.F, model.H, model.Q, model.R), transition=residual)
    step = gpsr_upf_step(belief, corrected, model.y, rng=np.random.default_rng(seed), resample_threshold=0.0)
    x, x_prev, n = step.weighted.particles, belief.particles, belief.size
    gp_mean, gp_var = gp.predict(x_prev[:, [source]])
    f = x_prev @ model.F.T
    f[:, output] += gp_mean[:, 0]
    q = np.repeat(model.Q[None], n, axis=0)
    q[:, output, :] = 0.0
    q[:, :, output] = 0.0
    q[:, output, output] = gp_var[:, 0] + gp.noise_var[0]
    means, factors = sr_ukf_proposal(belief, corrected.model, model.y, process_sqrt=corrected.process_sqrt)
    terms = np.stack([belief.log_weights,
                      _mvn_logpdf(np.broadcast_to(model.y, (n, model.y.size)), x @ model.H.T, [model.R] * n),
                      _mvn_logpdf(x, f, q), -_mvn_logpdf(x, means, factors @ _transpose(factors))])
    want = terms.sum(axis=0)
    want -= logsumexp(want)
    conds = [np.linalg.cond(model.R), max(np.linalg.cond(c) for c in q),
             max(np.linalg.cond(s) ** 2 for s in factors)]
    tol = _log_weight_tolerance(terms, conds)
    np.testing.assert_allclose(step.weighted.log_weights, want, rtol=0, atol=2 * tol.max())
