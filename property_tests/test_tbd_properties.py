"""Track-before-detect (PF-TBD, TPFTBD) on drawn models, images and particle sets, against
evaluations written here over the whole image (vectorised, no library code):

* the patch log likelihood ratio Σ_{(i,j)} (h z − h²/2)/σ² of eq. 8–9, h the point spread truncated
  to the (2p+1)² patch around the nearest cell — for particles anywhere, on, near and off the image;
  and the second-stage measurement of a fixed patch is that same h read on the patch;
* one PF-TBD step: with the merged set it returns, the unnormalised weights ① and ② — the birth
  ratio P_b (1 − P_{k−1}) / N_b · L · p_b/q_b with q_b's cell probabilities recomputed from the image,
  the continuing (1 − P_d) P_{k−1} w_{k−1} L with unequal previous weights — the existence eq. 10
  and the normalised merged weights, its estimate (weighted moments) and the resampled set;
* the second stage eq. 11–20 as weighted sample moments over every particle and a plain solve;
* TPFTBD's estimate as the mixture ζ p_PF + (1 − ζ) N(ŝ⁺, P⁺), its moments formed here from second
  moments; the transfer replaces a 1 − ζ fraction of the particles (Hoeffding).
"""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import expit, logsumexp

from gpfverify.filters.resampling import Particles
from gpfverify.filters.tbd import TbdConfig, TbdModel, pf_tbd_step, second_stage_update, tpf_tbd_step
from gpfverify.filters.tbd.two_stage import second_stage_axes, transfer_particles
from gpfverify.strategies import scaled_examples, spd_matrices
from gpfverify.strategies.matrices import float_arrays, log_uniform, unit_floats
from gpfverify.tolerances import EPS, algebra_rtol, bounded_mean_atol, monte_carlo_atol


@st.composite
def tbd_models(draw):
    lo = draw(unit_floats(0.0, 20.0))
    return TbdModel(grid_size=draw(st.integers(3, 10)), cell_size=draw(log_uniform(0.5, 2.0)),
                    blur=draw(log_uniform(0.3, 1.5)), noise_std=draw(log_uniform(0.3, 3.0)),
                    q1=draw(log_uniform(1e-4, 1e-1)), q2=draw(log_uniform(1e-4, 1e-1)),
                    p_birth=draw(unit_floats(0.01, 0.5)), p_death=draw(unit_floats(0.01, 0.5)),
                    patch_radius=draw(st.integers(0, 3)), velocity_max=draw(log_uniform(0.1, 2.0)),
                    intensity_range=(lo, lo + draw(log_uniform(1.0, 20.0))))


def imaged_interval(model: TbdModel) -> tuple[float, float]:
    """The interval the cells image on each axis, from the grid's parameters (not the model's own
    extent): cell centres 0, Δ, …, (n − 1)Δ, each covering half a cell either side."""
    return -model.cell_size / 2.0, model.grid_size * model.cell_size - model.cell_size / 2.0


@st.composite
def states_around(draw, model: TbdModel, count=st.integers(1, 12)):
    """States (N, 5) with positions up to p + 2 cells beyond the image on every side."""
    n = draw(count)
    lo, hi = imaged_interval(model)
    margin = (model.patch_radius + 2) * model.cell_size
    x = draw(float_arrays((n, 2), lo - margin, hi + margin))
    velocity = draw(float_arrays((n, 2), -1.0, 1.0))
    intensity = draw(float_arrays((n,), 0.5, 30.0))
    return np.column_stack([x[:, 0], velocity[:, 0], x[:, 1], velocity[:, 1], intensity])


def point_spread(model: TbdModel, states: np.ndarray) -> np.ndarray:
    """h^{(i,j)}(s) of eq. 9 over the whole image for every state, (N, n, n): the untruncated spread
    times the indicator of the (2p+1)² patch around the nearest cell."""
    cells = np.arange(model.grid_size) * model.cell_size
    amp = model.cell_size**2 * states[:, 4] / (2.0 * np.pi * model.blur**2)
    dx = cells[None, :] - states[:, [0]]
    dy = cells[None, :] - states[:, [2]]
    index = np.arange(model.grid_size)[None, :]
    near_x = np.abs(index - np.rint(states[:, [0]] / model.cell_size)) <= model.patch_radius
    near_y = np.abs(index - np.rint(states[:, [2]] / model.cell_size)) <= model.patch_radius
    gx = np.where(near_x, np.exp(-dx**2 / (2 * model.blur**2)), 0.0)
    gy = np.where(near_y, np.exp(-dy**2 / (2 * model.blur**2)), 0.0)
    return amp[:, None, None] * gx[:, :, None] * gy[:, None, :]


def whole_image_log_ratio(model: TbdModel, states, image) -> tuple[np.ndarray, np.ndarray]:
    """(log L (N,), the magnitude of its terms (N,)) summed over every pixel."""
    h = point_spread(model, states)
    terms = (h * image - 0.5 * h * h) / model.noise_std**2
    magnitude = (np.abs(h * image) + h * h).sum(axis=(1, 2)) / model.noise_std**2
    return terms.sum(axis=(1, 2)), magnitude


def images(model: TbdModel):
    n = model.grid_size
    return float_arrays((n, n), -3.0, 12.0).map(lambda z: z * model.noise_std)


@given(model=tbd_models(), data=st.data())
def test_patch_log_likelihood_ratio_is_the_whole_image_sum(model, data):
    states = data.draw(states_around(model), label="states")
    image = data.draw(images(model), label="image")
    want, magnitude = whole_image_log_ratio(model, states, image)
    got = model.log_likelihood_ratio(states, image)
    np.testing.assert_allclose(got, want, rtol=0, atol=algebra_rtol() * (magnitude.max() + 1.0))
    # the second stage reads the same h on a fixed patch of the image (cells row-major)
    first_x, first_y = (data.draw(st.integers(0, model.grid_size - 1)) for _ in range(2))
    axis_x = np.arange(first_x, data.draw(st.integers(first_x, model.grid_size - 1)) + 1)
    axis_y = np.arange(first_y, data.draw(st.integers(first_y, model.grid_size - 1)) + 1)
    chosen = np.flatnonzero(data.draw(st.lists(st.booleans(), min_size=len(states), max_size=len(states))))
    h = point_spread(model, states)[np.ix_(chosen, axis_x, axis_y)].reshape(chosen.size, axis_x.size * axis_y.size).T
    got_h = model.measurement_on_patch(model.patch_spread(states), axis_x, axis_y, chosen)
    np.testing.assert_allclose(got_h, h, rtol=0, atol=algebra_rtol() * (np.abs(h).max(initial=0.0) + EPS))


@st.composite
def tbd_steps(draw):
    model = draw(tbd_models())
    n_particles = 2 * draw(st.integers(1, 15))
    config = TbdConfig(n_particles, birth_threshold=draw(unit_floats(-1.0, 4.0)),
                       birth_uniform_share=draw(unit_floats(0.01, 1.0)), zeta=draw(unit_floats(0.0, 1.0)),
                       second_stage_radius=draw(st.integers(0, 3)))
    belief_states = draw(states_around(model, st.just(config.n_continuing)))
    existence = draw(st.one_of(st.just(0.0), st.just(1.0), unit_floats(0.0, 1.0)))
    belief = Particles(belief_states, draw(float_arrays((config.n_continuing,), -3.0, 0.0)), existence=existence)
    return model, config, belief, draw(images(model)), draw(st.integers(0, 2**32 - 1))


def birth_log_ratio(model: TbdModel, config: TbdConfig, image, births) -> np.ndarray:
    """log p_b(s)/q_b(s) of birth particles: (1/n²)/π_c, c the cell holding s, π_c from the image."""
    n = model.grid_size
    bright = image > config.birth_threshold * model.noise_std
    share = config.birth_uniform_share if bright.any() else 1.0
    prob = share / n**2 + (1.0 - share) * bright / max(bright.sum(), 1)
    ix = np.floor(births[:, 0] / model.cell_size + 0.5).astype(int)
    iy = np.floor(births[:, 2] / model.cell_size + 0.5).astype(int)
    return -np.log(n**2) - np.log(prob[ix, iy])


@given(drawn=tbd_steps())
def test_pf_tbd_step_weights_and_existence_are_eqs_1_to_10_on_the_image(drawn):
    model, config, belief, image, seed = drawn
    step = pf_tbd_step(belief, model, image, rng=np.random.default_rng(seed), config=config)
    merged = step.weighted.particles
    n_b, prev = config.n_birth, belief.existence
    assert merged.shape == (config.n_particles, 5)
    births = merged[:n_b]
    lo, hi = imaged_interval(model)
    assert np.all((births[:, [0, 2]] >= lo) & (births[:, [0, 2]] <= hi))
    log_l, magnitude = whole_image_log_ratio(model, merged, image)
    # a continuing particle off the image is a target that left it: its prior mass counts as absent
    left = np.any((merged[n_b:, [0, 2]] < lo) | (merged[n_b:, [0, 2]] > hi), axis=1)
    with np.errstate(divide="ignore"):
        log_prior = np.log((1.0 - model.p_death) * prev) + belief.log_weights - logsumexp(belief.log_weights)
        log_w = log_l + np.concatenate([
            birth_log_ratio(model, config, image, births) + np.log(model.p_birth * (1.0 - prev) / n_b),
            np.where(left, -np.inf, log_prior)])
        log_mass = logsumexp(log_w)
        log_absent = np.log(model.p_death * prev + (1.0 - model.p_birth) * (1.0 - prev) + np.exp(log_prior[left]).sum())
    existence = expit(log_mass - log_absent)
    if np.isneginf(log_mass):  # P_{k−1} = 1 and every particle left: P_k = 0, the births equally weighted
        log_w, log_mass = np.where(np.arange(len(merged)) < n_b, 0.0, -np.inf), np.log(n_b)
    tol = algebra_rtol() * (magnitude.max() + np.abs(log_w[np.isfinite(log_w)]).max() + 1.0)
    assert abs(step.posterior.existence - existence) <= tol
    want = log_w - log_mass
    finite = np.isfinite(want)
    np.testing.assert_array_equal(np.isfinite(step.weighted.log_weights), finite)
    np.testing.assert_allclose(step.weighted.log_weights[finite], want[finite], rtol=0, atol=2 * tol)
    w = np.exp(want)
    mean = w @ merged
    cov = (merged - mean).T @ ((merged - mean) * w[:, None])
    scale = np.abs(merged).max()
    np.testing.assert_allclose(step.mean, mean, rtol=0, atol=2 * tol * scale)
    np.testing.assert_allclose(step.cov, cov, rtol=0, atol=2 * tol * scale**2)
    # ⑥: N_c equally weighted draws of the merged particles that carry weight
    resampled = step.posterior.particles
    assert resampled.shape == (config.n_continuing, 5) and step.posterior.existence == step.weighted.existence
    matches = np.all(resampled[:, None, :] == merged[None, :, :], axis=2)
    assert np.all(matches.any(axis=1)) and np.all(w[matches.argmax(axis=1)] > 0)


@st.composite
def weighted_clouds(draw, model: TbdModel):
    n = draw(st.integers(2, 25))
    states = draw(states_around(model, st.just(n)))
    log_w = draw(float_arrays((n,), -4.0, 0.0))
    return states, log_w - logsumexp(log_w)


@given(model=tbd_models(), radius=st.integers(0, 3), data=st.data())
def test_second_stage_is_the_textbook_conditioning_of_weighted_sample_moments(model, radius, data):
    merged, log_w = data.draw(weighted_clouds(model), label="cloud")
    image = data.draw(images(model), label="image")
    lo, hi = imaged_interval(model)
    estimate = np.array([data.draw(unit_floats(lo - 2.0, hi + 2.0)), 0.0, data.draw(unit_floats(lo - 2.0, hi + 2.0)),
                         0.0, 10.0])
    config = TbdConfig(2, two_stage=True, second_stage_radius=radius)
    record, cells_x, cells_y = second_stage_update(merged, log_w, model, config, image, estimate)
    axis_x, axis_y = second_stage_axes(model, config, estimate)
    w = np.exp(log_w)
    H = point_spread(model, merged)[:, axis_x][:, :, axis_y].reshape(merged.shape[0], -1)
    s_hat, z_hat = w @ merged, w @ H
    ds, dh = merged - s_hat, H - z_hat
    P = (ds * w[:, None]).T @ ds
    P_xz = (ds * w[:, None]).T @ dh
    S = (dh * w[:, None]).T @ dh + model.noise_std**2 * np.eye(H.shape[1])
    z = image[np.ix_(axis_x, axis_y)].ravel()
    gain = np.linalg.solve(S, P_xz.T).T
    want = (s_hat, P, z_hat, S, P_xz, s_hat + gain @ (z - z_hat), P - gain @ S @ gain.T)
    np.testing.assert_array_equal(image[cells_x, cells_y], z)
    cond = np.linalg.cond(S) if S.size else 1.0
    scale = max(np.abs(merged).max(), np.abs(H).max(initial=0.0), np.abs(z).max(initial=0.0), 1.0)
    for name, value in zip(("mu_p", "C_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e"), want):
        np.testing.assert_allclose(getattr(record, name), value, rtol=0, atol=algebra_rtol(cond) * scale**2,
                                   err_msg=name)


@settings(max_examples=scaled_examples(0.5))
@given(drawn=tbd_steps(), second_seed=st.integers(0, 2**32 - 1))
def test_tpf_tbd_estimate_is_the_moments_of_its_mixture(drawn, second_seed):
    model, config, belief, image, seed = drawn
    step = tpf_tbd_step(belief, model, image, rng=np.random.default_rng(seed), config=config,
                        second_rng=np.random.default_rng(second_seed))
    zeta = config.zeta
    merged, w = step.weighted.particles, np.exp(step.weighted.log_weights)
    post = step.second_stage.record
    mean = zeta * (w @ merged) + (1.0 - zeta) * post.mu_e
    second = zeta * (merged.T * w) @ merged + (1.0 - zeta) * (post.C_e + np.outer(post.mu_e, post.mu_e))
    scale = max(np.abs(merged).max(), np.abs(post.mu_e).max())
    tol = algebra_rtol(np.linalg.cond(post.C_y) if post.C_y.size else 1.0) * scale**2
    np.testing.assert_allclose(step.mean, mean, rtol=0, atol=tol)
    np.testing.assert_allclose(step.cov, second - np.outer(mean, mean), rtol=0, atol=4 * tol)


@settings(max_examples=scaled_examples(0.25))
@given(zeta=unit_floats(0.0, 1.0), seed=st.integers(0, 2**32 - 1), data=st.data())
def test_transfer_replaces_one_minus_zeta_of_the_particles_by_posterior_draws(zeta, seed, data):
    count = 2000
    cov = data.draw(spd_matrices(5, 1e2, log_uniform(1e-2, 1.0)), label="P+")
    mean = data.draw(float_arrays((5,), -5.0, 5.0), label="s+")
    particles = np.full((count, 5), 100.0)  # far from every posterior draw
    out, replaced = transfer_particles(particles, mean, cov, zeta, np.random.default_rng(seed))
    np.testing.assert_array_equal(out[~replaced], particles[~replaced])
    assert abs(replaced.mean() - (1.0 - zeta)) <= bounded_mean_atol(1.0, count), (replaced.mean(), zeta)
    if replaced.any():  # the replaced ones are draws of N(s+, P+): whitened, each coordinate N(0, 1)
        whitened = np.linalg.solve(np.linalg.cholesky(cov), (out[replaced] - mean).T).T
        m = whitened.shape[0]
        assert np.all(np.abs(whitened.mean(axis=0)) <= monte_carlo_atol(1.0, m))
        assert np.all(np.abs((whitened**2).mean(axis=0) - 1.0) <= monte_carlo_atol(np.sqrt(2.0), m))
