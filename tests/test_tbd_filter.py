"""PF-TBD and TPFTBD (seed 004): likelihood ratio, existence recursion, second stage, ζ = 1,
lock-on and no-target behaviour."""

import copy
from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import norm

from gpfverify.errors import InputError
from gpfverify.filters.resampling import Particles, effective_sample_size, systematic_resample
from gpfverify.filters.tbd import TbdConfig, TbdModel, filter_sequence, pf_tbd_step, second_stage_update, tpf_tbd_step
from gpfverify.filters.tbd.pf import birth_proposal, sample_birth_prior
from gpfverify.filters.tbd.two_stage import (overlapping, second_stage_axes, second_stage_runs, transfer_particles,
                                              transfer_runs)
from gpfverify.papers.tbd.scenario import TbdScenario, noise_std_for_snr, scenario_model, simulate
from gpfverify.tolerances import MONTE_CARLO_SIGMAS, algebra_rtol, monte_carlo_atol

SCENARIO = TbdScenario()
HIGH_SNR_DB = 15.0


def _full_image_log_lr(model: TbdModel, state, image) -> float:
    """Reference: loop over every pixel of the image with the truncated point spread of eq. 9."""
    n, d, p = model.grid_size, model.cell_size, model.patch_radius
    cx, cy = round(state[0] / d), round(state[2] / d)
    amp = d * d * state[4] / (2 * np.pi * model.blur**2)
    total = 0.0
    for i in range(n):
        for j in range(n):
            if abs(i - cx) > p or abs(j - cy) > p:
                continue
            h = amp * np.exp(-((i * d - state[0]) ** 2 + (j * d - state[2]) ** 2) / (2 * model.blur**2))
            total += h * (2 * image[i, j] - h) / (2 * model.noise_std**2)
    return total


def test_patch_likelihood_ratio_equals_full_image_ratio():
    rng = np.random.default_rng(0)
    model = scenario_model(6.0, SCENARIO)
    image = model.noise_std * rng.standard_normal((model.grid_size, model.grid_size))
    image += model.expected_image(np.array([9.3, 0.0, 4.6, 0.0, 20.0]))
    lo, hi = model.image_extent
    states = np.column_stack([rng.uniform(lo - 3, hi + 3, 60), rng.normal(size=60),
                              rng.uniform(lo - 3, hi + 3, 60), rng.normal(size=60), rng.uniform(5, 30, 60)])
    states[:3, [0, 2]] = [[9.3, 4.6], [0.1, 19.2], [-2.4, 7.0]]  # on the target, in a corner, off the image
    fast = model.log_likelihood_ratio(states, image)
    slow = np.array([_full_image_log_lr(model, s, image) for s in states])
    np.testing.assert_allclose(fast, slow, rtol=algebra_rtol(), atol=algebra_rtol() * np.abs(slow).max())
    assert np.any(slow == 0.0) and np.any(slow != 0.0)  # both the off-image and the on-image cases occur


def _states_over_and_beyond_the_image(rng, model, n):
    """Random states with positions up to p + 3 cells beyond each side of the image (patches
    clipped at every edge and corner, and wholly off the image), plus a few exact corner cases."""
    lo, hi = model.image_extent
    margin = model.patch_radius + 3
    states = np.column_stack([rng.uniform(lo - margin, hi + margin, n), rng.normal(size=n),
                              rng.uniform(lo - margin, hi + margin, n), rng.normal(size=n), rng.uniform(5, 30, n)])
    states[:4, [0, 2]] = [[lo, lo], [hi, hi], [lo - 2.4, 7.0], [0.49999, hi + 2.5]]
    return states


def _image_log_lr(model: TbdModel, state, image) -> float:
    """Σ_c (h_c z_c − h_c²/2)/σ² over the whole image, h = ``expected_image`` (zero off the patch)."""
    h = model.expected_image(state)
    return float(np.sum(h * image - 0.5 * h * h) / model.noise_std**2)


@pytest.mark.parametrize("radius", [0, 1, 2, 3])
def test_patch_likelihood_ratio_equals_the_whole_image_sum_of_the_expected_image(radius):
    """The patch-row evaluation against Σ_c over the image of ``expected_image`` (an independent
    route: whole-image axis factors, no clipped indices), with patches clipped at the edges."""
    rng = np.random.default_rng(30 + radius)
    model = replace(scenario_model(6.0, SCENARIO), patch_radius=radius)
    image = model.noise_std * rng.standard_normal((model.grid_size, model.grid_size))
    image += model.expected_image(np.array([9.3, 0.0, 4.6, 0.0, 20.0]))
    states = _states_over_and_beyond_the_image(rng, model, 300)
    fast = model.log_likelihood_ratio(states, image)
    slow = np.array([_image_log_lr(model, s, image) for s in states])
    np.testing.assert_allclose(fast, slow, rtol=algebra_rtol(), atol=algebra_rtol() * np.abs(slow).max())
    assert np.any(slow == 0.0) and np.any(slow != 0.0)
    # the spread computed once and passed in gives the same bits
    assert np.array_equal(model.log_likelihood_ratio(states, image, model.patch_spread(states)), fast)


def test_measurement_on_patch_reads_the_expected_image():
    """h on a fixed patch, read from each particle's own patch factors, equals ``expected_image``
    at those cells; and the overlap set holds every particle with a non-zero h there."""
    rng = np.random.default_rng(40)
    model = scenario_model(6.0, SCENARIO)
    states = _states_over_and_beyond_the_image(rng, model, 400)
    spread = model.patch_spread(states)
    for estimate in ([9.6, 0, 4.2, 0, 20.0], [0.2, 0, 19.4, 0, 20.0], [-1.4, 0, 10.0, 0, 20.0]):
        axis_x, axis_y = second_stage_axes(model, TbdConfig(400, second_stage_radius=2), np.array(estimate))
        everyone = np.arange(states.shape[0])
        H = model.measurement_on_patch(spread, axis_x, axis_y, everyone)
        expected = np.array([model.expected_image(s)[np.ix_(axis_x, axis_y)].ravel() for s in states]).T
        np.testing.assert_allclose(H, expected, rtol=algebra_rtol(), atol=0.0)
        inside = overlapping(model, spread, axis_x, axis_y)
        assert 0 < inside.size < states.shape[0]
        assert not np.any(np.delete(expected, inside, axis=1))
        np.testing.assert_array_equal(model.measurement_on_patch(spread, axis_x, axis_y, inside), H[:, inside])


def test_expected_image_is_the_truncated_point_spread():
    """A target on a cell centre: the image is zero outside the (2p+1)² patch, peaks at the
    target's cell, and its sum is I/(2πΣ²) (Σ_{|i|≤p} exp(−i²/(2Σ²)))²."""
    model = TbdModel(blur=0.7, patch_radius=3)
    h = model.expected_image(np.array([9.0, 0.0, 10.0, 0.0, 20.0]))
    one_axis = sum(np.exp(-0.5 * (i / 0.7) ** 2) for i in range(-3, 4))
    np.testing.assert_allclose(h.sum(), 20.0 * one_axis**2 / (2 * np.pi * 0.49), rtol=algebra_rtol())
    assert h.argmax() == 9 * model.grid_size + 10
    assert np.count_nonzero(h) == 7 * 7 and np.all(h[:6] == 0) and np.all(h[:, 14:] == 0)


def test_existence_follows_the_markov_chain_when_the_image_carries_no_information():
    """σ → ∞ and a blank image: L = 1 for every particle and q_b = p_b, so
    P_k = P_b (1 − P_{k−1}) + (1 − P_d) P_{k−1} s_k exactly (the chain's prediction, eq. 7, with
    s_k the share of the equally weighted continuing particles still in the image)."""
    model = TbdModel(noise_std=1e12)
    config = TbdConfig(200)
    image = np.zeros((model.grid_size, model.grid_size))
    rng = np.random.default_rng(1)
    belief = Particles.equally_weighted(np.tile([10.0, 0.1, 10.0, 0.1, 20.0], (config.n_continuing, 1)),
                                        existence=0.3)
    for k in range(1, 6):
        step = pf_tbd_step(belief, model, image, k=k, rng=rng, config=config)
        inside = model.in_image(step.weighted.particles[config.n_birth:]).mean()
        expected = model.p_birth * (1 - belief.existence) + (1 - model.p_death) * belief.existence * inside
        np.testing.assert_allclose(step.posterior.existence, expected, rtol=algebra_rtol())
        belief = step.posterior


def test_a_target_whose_particles_left_the_image_no_longer_exists():
    """E_k = 1 means the target is in the observed region: with every continuing particle moved off
    the image and no information in it (σ → ∞, q_b = p_b), the continuing mass joins the absent
    hypothesis and P_k = P_b (1 − P_{k−1}) — a new target's birth only — where particles kept off
    the image would give the chain's P_b (1 − P_{k−1}) + (1 − P_d) P_{k−1}."""
    model = TbdModel(noise_std=1e12)
    config = TbdConfig(200)
    image = np.zeros((model.grid_size, model.grid_size))
    prev = 0.8
    lo, hi = model.image_extent
    outside = np.tile([lo - 5.0, -0.5, 10.0, 0.0, 20.0], (config.n_continuing, 1))  # 5 cells left of the image
    belief = Particles.equally_weighted(outside, existence=prev)
    step = pf_tbd_step(belief, model, image, rng=np.random.default_rng(2), config=config)
    assert not model.in_image(step.weighted.particles[config.n_birth:]).any()  # still off after the move
    np.testing.assert_allclose(step.posterior.existence, model.p_birth * (1 - prev), rtol=algebra_rtol())
    assert np.all(np.isneginf(step.weighted.log_weights[config.n_birth:]))
    assert model.in_image(step.posterior.particles).all()  # resampled from the births only
    # half of them back inside: their mass continues, the other half's is absent
    half = outside.copy()
    half[::2, 0] = 0.5 * (lo + hi)
    step = pf_tbd_step(Particles.equally_weighted(half, existence=prev), model, image,
                       rng=np.random.default_rng(2), config=config)
    stayed = (1 - model.p_death) * prev * model.in_image(step.weighted.particles[config.n_birth:]).mean()
    np.testing.assert_allclose(step.posterior.existence, model.p_birth * (1 - prev) + stayed, rtol=algebra_rtol())
    assert 0.3 < stayed / ((1 - model.p_death) * prev) < 0.7


def test_existence_carries_the_birth_importance_weights():
    """L = 1 again (σ → ∞) but a few bright cells make q_b ≠ p_b: then
    M_b = P_b (1 − P)/N_b Σ_i p_b/q_b(s_b^i) and P_k = (M_b + M_c)/(M_b + M_c + P_d P + (1 − P_b)(1 − P)),
    with the proposal's own ratios replayed from a copy of the generator."""
    model = TbdModel(noise_std=1e12)
    config = TbdConfig(200, birth_threshold=1e-12)  # bright: z > 1
    image = np.zeros((model.grid_size, model.grid_size))
    image[4:7, 9:12] = 5.0
    rng = np.random.default_rng(17)
    prev = 0.3
    belief = Particles.equally_weighted(np.tile([10.0, 0.1, 10.0, 0.1, 20.0], (config.n_continuing, 1)),
                                        existence=prev)
    _, log_ratio = birth_proposal(model, config, image, copy.deepcopy(rng))
    m_b = model.p_birth * (1 - prev) * np.exp(log_ratio).mean()
    m_c = (1 - model.p_death) * prev
    expected = (m_b + m_c) / (m_b + m_c + model.p_death * prev + (1 - model.p_birth) * (1 - prev))
    step = pf_tbd_step(belief, model, image, rng=rng, config=config)
    np.testing.assert_allclose(step.posterior.existence, expected, rtol=algebra_rtol())
    assert abs(np.exp(log_ratio).mean() - 1.0) > algebra_rtol()  # the ratios matter here


def test_birth_importance_ratio_is_exact():
    """E_q[p_b/q_b] = 1 for the data-driven proposal: Monte Carlo over many draws."""
    rng = np.random.default_rng(2)
    model = scenario_model(3.0, SCENARIO)
    image = simulate(model, SCENARIO, rng).images[10]
    config = TbdConfig(40_000)
    _, log_ratio = birth_proposal(model, config, image, rng)
    ratio = np.exp(log_ratio)
    assert abs(ratio.mean() - 1.0) <= monte_carlo_atol(ratio.std(), ratio.size)
    assert ratio.min() < 1.0 < ratio.max()  # the proposal really favours the bright cells


def test_uniform_birth_proposal_is_the_birth_density():
    """The 'birth-uniform' reading (uniform share 1): every cell equally likely whatever the image,
    so p_b/q_b = 1 for every birth; the cells' counts pass a χ² test against the uniform law at the
    project's Monte Carlo level, and a data-driven proposal on the same image fails it."""
    from scipy.stats import chi2

    rng = np.random.default_rng(5)
    model = scenario_model(9.0, SCENARIO)
    image = simulate(model, SCENARIO, rng).images[12]
    cells = model.cell_count
    level = 2.0 * norm.sf(MONTE_CARLO_SIGMAS)

    def chi_square(config):
        states, log_ratio = birth_proposal(model, config, image, rng)
        index = model.nearest_cell(states[:, 0]) * model.grid_size + model.nearest_cell(states[:, 2])
        counts = np.bincount(index, minlength=cells)
        expected = config.n_birth / cells
        return log_ratio, float(np.sum((counts - expected) ** 2) / expected)

    log_ratio, statistic = chi_square(TbdConfig(80_000, birth_uniform_share=1.0))
    assert np.all(log_ratio == 0.0)
    assert statistic < chi2.isf(level, cells - 1)
    _, statistic = chi_square(TbdConfig(80_000))
    assert statistic > chi2.isf(level, cells - 1)


def test_pf_tbd_resamples_the_merged_set_down_to_n_c_systematically():
    """Step ⑥ is the shared systematic resampler with size N_c < N_b + N_c: replaying the step's
    draws from a copy of the generator gives the same resampled particles, and each merged particle
    is kept ⌊N_c w_i⌋ or ⌈N_c w_i⌉ times."""
    model = scenario_model(6.0, SCENARIO)
    config = TbdConfig(400)
    rng = np.random.default_rng(3)
    image = model.noise_std * rng.standard_normal((20, 20)) + model.expected_image(np.array([8.0, 0, 12.0, 0, 20.0]))
    belief = Particles.equally_weighted(np.tile([8.0, 0.1, 12.0, 0.0, 20.0], (config.n_continuing, 1)), existence=0.5)
    replay = copy.deepcopy(rng)
    step = pf_tbd_step(belief, model, image, rng=rng, config=config)
    birth_proposal(model, config, image, replay)
    model.propagate(belief.particles, replay)
    idx = systematic_resample(step.weighted.log_weights, replay, size=config.n_continuing)
    np.testing.assert_array_equal(step.posterior.particles, step.weighted.particles[idx])
    assert step.ess == effective_sample_size(step.weighted.log_weights)
    n, w = config.n_continuing, np.exp(step.weighted.log_weights)
    counts = np.bincount(idx, minlength=w.size)
    assert counts.sum() == n < w.size and step.resampled
    assert np.all((counts == np.floor(n * w)) | (counts == np.ceil(n * w)))


def test_pf_tbd_needs_the_existence_probability():
    model, config = TbdModel(), TbdConfig(20)
    with pytest.raises(InputError, match="existence"):
        pf_tbd_step(Particles.equally_weighted(np.zeros((10, 5))), model, np.zeros((20, 20)),
                    rng=np.random.default_rng(0), config=config)


def _weighted_cloud(rng, model, n=400):
    mean = np.array([8.2, 0.3, 11.6, -0.2, 20.0])
    spread = np.array([0.6, 0.2, 0.6, 0.2, 2.0])
    merged = mean + spread * rng.standard_normal((n, 5))
    log_w = rng.normal(size=n)
    return merged, log_w - np.log(np.exp(log_w).sum())


def test_second_stage_equals_conditioning_of_the_joint_gaussian():
    """Independent route: moments of the stacked [s; h] sample with σ²I added, conditioned on
    z through the inverse of the joint covariance (precision blocks) instead of K = P_xz S⁻¹."""
    rng = np.random.default_rng(4)
    model = scenario_model(6.0, SCENARIO)
    merged, log_w = _weighted_cloud(rng, model)
    image = model.noise_std * rng.standard_normal((20, 20)) + model.expected_image(np.array([8.0, 0, 12.0, 0, 20.0]))
    config = TbdConfig(400, two_stage=True, second_stage_radius=2)
    record, cx, cy = second_stage_update(merged, log_w, model, config, image, np.exp(log_w) @ merged)
    assert cx.size == 25 and set(cx) == {6, 7, 8, 9, 10} and set(cy) == {10, 11, 12, 13, 14}
    w = np.exp(log_w)
    H = np.array([[model.expected_image(s)[i, j] for i, j in zip(cx, cy)] for s in merged])
    joint = np.hstack([merged, H])
    mean = w @ joint
    dev = joint - mean
    cov = (dev * w[:, None]).T @ dev
    cov[5:, 5:] += model.noise_std**2 * np.eye(25)
    precision = np.linalg.inv(cov)
    post_cov = np.linalg.inv(precision[:5, :5])
    post_mean = mean[:5] - post_cov @ precision[:5, 5:] @ (image[cx, cy] - mean[5:])
    rtol = algebra_rtol(np.linalg.cond(cov))
    np.testing.assert_allclose(record.mu_p, mean[:5], rtol=rtol)
    np.testing.assert_allclose(record.mu_e, post_mean, rtol=rtol, atol=rtol * np.abs(post_mean).max())
    np.testing.assert_allclose(record.C_e, post_cov, rtol=rtol, atol=rtol * np.abs(post_cov).max())
    assert np.linalg.eigvalsh(record.C_e).min() >= -rtol * np.abs(post_cov).max()


def _textbook_second_stage(merged, log_w, model, config, image, estimate):
    """Eq. 11–20 as written: weighted sample moments of [s; h_C(s)] over every particle (h_C from
    ``expected_image``), K = P_xz S⁻¹ by numpy's solve, ŝ⁺ = ŝ + K (z − ẑ), P⁺ = P − K S Kᵀ."""
    axis_x, axis_y = second_stage_axes(model, config, estimate)
    w = np.exp(log_w)
    H = np.array([model.expected_image(s)[np.ix_(axis_x, axis_y)].ravel() for s in merged])
    s_hat, z_hat = w @ merged, w @ H
    ds, dh = merged - s_hat, H - z_hat
    P, P_xz = (ds * w[:, None]).T @ ds, (ds * w[:, None]).T @ dh
    S = (dh * w[:, None]).T @ dh + model.noise_std**2 * np.eye(H.shape[1])
    K = np.linalg.solve(S, P_xz.T).T
    z = image[np.ix_(axis_x, axis_y)].ravel()
    return s_hat, P, z_hat, S, P_xz, s_hat + K @ (z - z_hat), P - K @ S @ K.T


@pytest.mark.parametrize("case", ["some particles off the patch", "every particle on the patch",
                                  "no particle on the patch", "patch at the image corner"])
def test_second_stage_equals_the_textbook_evaluation(case):
    """Every branch of the overlap split (particles off the measured patch, none, or all of them;
    a patch clipped by the image) against weighted sample moments over all particles and a plain
    solve."""
    rng = np.random.default_rng(50)
    model = scenario_model(6.0, SCENARIO)
    spread_std = {"some particles off the patch": 3.0, "every particle on the patch": 0.3,
                  "no particle on the patch": 0.3, "patch at the image corner": 1.5}[case]
    centre = [0.6, 0.2, 18.7, -0.1, 20.0] if case == "patch at the image corner" else [8.2, 0.3, 11.6, -0.2, 20.0]
    merged = np.array(centre) + np.array([spread_std, 0.2, spread_std, 0.2, 2.0]) * rng.standard_normal((300, 5))
    if case == "no particle on the patch":  # two clusters far either side of the patch
        merged[::2, 0] -= 7.0
        merged[1::2, 0] += 7.0
    log_w = rng.normal(size=300)
    log_w -= np.log(np.exp(log_w).sum())
    image = model.noise_std * rng.standard_normal((20, 20)) + model.expected_image(np.array(centre))
    config = TbdConfig(300, two_stage=True)
    estimate = np.array(centre) if case == "no particle on the patch" else np.exp(log_w) @ merged
    inside = overlapping(model, model.patch_spread(merged), *second_stage_axes(model, config, estimate))
    assert (inside.size == merged.shape[0]) == (case == "every particle on the patch")
    assert (inside.size == 0) == (case == "no particle on the patch")
    record, _, _ = second_stage_update(merged, log_w, model, config, image, estimate)
    expected = _textbook_second_stage(merged, log_w, model, config, image, estimate)
    rtol = algebra_rtol(np.linalg.cond(expected[3]) * np.linalg.cond(expected[1]))
    names = ("mu_p", "C_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e")
    for name, got, want in zip(names, (getattr(record, n) for n in names), expected):
        np.testing.assert_allclose(got, want, rtol=rtol, atol=rtol * np.abs(want).max(), err_msg=name)
    assert np.array_equal(record.C_e, record.C_e.T)
    # the PF stage's spread passed in gives the same bits
    again, _, _ = second_stage_update(merged, log_w, model, config, image, estimate, model.patch_spread(merged))
    assert np.array_equal(again.mu_e, record.mu_e) and np.array_equal(again.C_e, record.C_e)


def test_second_stage_with_the_patch_off_the_image_keeps_the_prediction():
    rng = np.random.default_rng(51)
    model = scenario_model(6.0, SCENARIO)
    merged, log_w = _weighted_cloud(rng, model)
    record, cells_x, cells_y = second_stage_update(merged, log_w, model, TbdConfig(400, two_stage=True),
                                                   np.zeros((20, 20)), np.array([-9.0, 0.0, 5.0, 0.0, 20.0]))
    w = np.exp(log_w)
    assert cells_x.size == cells_y.size == 0 and record.C_y.shape == (0, 0) and record.C_xy.shape == (5, 0)
    np.testing.assert_allclose(record.mu_e, w @ merged, rtol=algebra_rtol())
    dev = merged - w @ merged
    np.testing.assert_allclose(record.C_e, (dev * w[:, None]).T @ dev, rtol=algebra_rtol())


def test_birth_prior_columns_are_the_uniform_maps_of_one_block_of_draws():
    """Bitwise: position a + (b − a) u, velocity v_max (2u − 1), intensity i_lo + (i_hi − i_lo) u."""
    model = TbdModel(velocity_max=0.7, intensity_range=(8.0, 25.0))
    u = np.random.default_rng(60).random((50, 5))
    states = sample_birth_prior(model, 50, np.random.default_rng(60))
    lo, hi = model.image_extent
    expected = np.column_stack([lo + (hi - lo) * u[:, 0], 0.7 * (2 * u[:, 1] - 1), lo + (hi - lo) * u[:, 2],
                                0.7 * (2 * u[:, 3] - 1), 8.0 + (25.0 - 8.0) * u[:, 4]])
    assert np.array_equal(states, expected)


def test_transfer_with_zeta_zero_draws_every_particle_from_the_posterior():
    rng = np.random.default_rng(5)
    mean = np.array([3.0, 0.1, 4.0, -0.1, 18.0])
    a = rng.normal(size=(5, 5))
    cov = a @ a.T / 5 + 0.1 * np.eye(5)
    particles = np.zeros((20_000, 5))
    out, replaced = transfer_particles(particles, mean, cov, 0.0, rng)
    assert replaced.all()
    assert np.all(np.abs(out.mean(0) - mean) <= monte_carlo_atol(np.sqrt(np.diag(cov)), out.shape[0]))
    kept, none = transfer_particles(particles, mean, cov, 1.0, rng)
    assert not none.any() and np.array_equal(kept, particles)


#: runs whose second-stage patches differ: (cloud centre, estimate or None for the cloud's mean);
#: a full patch, one clipped on one axis, one at a corner, one off the image, one with no particle
#: on it (the cloud split either side), and two more full ones
CORNER_RUNS = (([8.2, 0.3, 11.6, -0.2, 20.0], None), ([10.0, 0.1, 1.4, 0.0, 18.0], None),
               ([19.3, 0.0, 0.4, 0.1, 22.0], None), ([8.2, 0.3, 11.6, -0.2, 20.0], [-9.0, 0.0, 5.0, 0.0, 20.0]),
               ([8.2, 0.3, 11.6, -0.2, 20.0], "split"), ([5.0, -0.2, 5.0, 0.2, 20.0], None),
               ([14.4, 0.0, 9.6, 0.0, 25.0], None))


def _corner_batch(rng, model, n=300):
    """Merged clouds, normalised log weights, images and estimates of the :data:`CORNER_RUNS`."""
    merged, log_w, images, estimates = [], [], [], []
    for centre, estimate in CORNER_RUNS:
        cloud = np.array(centre) + np.array([1.0, 0.2, 1.0, 0.2, 2.0]) * rng.standard_normal((n, 5))
        if estimate == "split":  # two clusters far either side of the patch around the centre
            cloud[::2, 0] -= 10.0
            cloud[1::2, 0] += 10.0
        weights = rng.normal(size=n)
        weights -= np.log(np.exp(weights).sum())
        merged.append(cloud)
        log_w.append(weights)
        images.append(model.noise_std * rng.standard_normal((20, 20)) + model.expected_image(np.array(centre)))
        estimates.append(np.exp(weights) @ cloud if estimate is None else
                         np.array(centre) if estimate == "split" else np.array(estimate))
    return np.stack(merged), np.stack(log_w), np.stack(images), np.stack(estimates)


def test_second_stage_of_a_batch_is_each_run_alone_bit_for_bit():
    """Runs whose patches differ in size (full, clipped on one axis, at a corner, off the image) and
    a run with no particle on its patch, updated together (B = 7) and one at a time (B = 1): every
    field of every record and the cells are the same bits."""
    model = scenario_model(6.0, SCENARIO)
    config = TbdConfig(300, two_stage=True)
    merged, log_w, images, estimates = _corner_batch(np.random.default_rng(60), model)
    together = second_stage_runs(merged, log_w, model, config, images, estimates,
                                 model.patch_spread(merged.reshape(-1, 5)))
    sizes, overlaps = [], []
    for b, (record, cells_x, cells_y) in enumerate(together):
        alone, alone_x, alone_y = second_stage_update(merged[b], log_w[b], model, config, images[b], estimates[b])
        for name in ("mu_p", "C_p", "mu_y", "C_y", "C_xy", "mu_e", "C_e"):
            assert np.array_equal(getattr(record, name), getattr(alone, name)), (b, name)
        assert np.array_equal(cells_x, alone_x) and np.array_equal(cells_y, alone_y)
        sizes.append(cells_x.size)
        if cells_x.size:
            overlaps.append(overlapping(model, model.patch_spread(merged[b]), *second_stage_axes(model, config,
                                                                                               estimates[b])).size)
    assert set(sizes) == {25, 20, 9, 0}  # full, clipped on one axis, at a corner, off the image
    assert 0 in overlaps and max(overlaps) > 0  # a measured patch no particle reaches


@pytest.mark.parametrize("count", [2, 300])
def test_transfer_of_a_batch_is_each_run_alone_bit_for_bit(count):
    """Eq. 21 for B = 7 runs, each with its own posterior and stream, against each run alone (B = 1):
    the same draws and the same particles, runs with no particle replaced among them (count = 2)."""
    rng = np.random.default_rng(61)
    particles = rng.standard_normal((7, count, 5))
    means = rng.standard_normal((7, 5))
    factors = rng.standard_normal((7, 5, 5))
    covs = factors @ factors.swapaxes(-1, -2) / 5 + 0.1 * np.eye(5)
    out, replaced = transfer_runs(particles, means, covs, 0.6, [np.random.default_rng(70 + b) for b in range(7)])
    for b in range(7):
        alone, alone_replaced = transfer_particles(particles[b], means[b], covs[b], 0.6, np.random.default_rng(70 + b))
        assert np.array_equal(out[b], alone) and np.array_equal(replaced[b], alone_replaced)
    assert replaced.any()
    if count == 2:
        assert not replaced.all(axis=1).all() and (~replaced.any(axis=1)).any()


def test_tpftbd_step_of_a_batch_is_each_run_alone_bit_for_bit():
    """A TPFTBD step on B = 7 runs with beliefs in different places (patches full, clipped, at a
    corner, off the image) against each run alone (B = 1): posterior, weighted set, estimate and
    every second-stage record the same bits."""
    model = scenario_model(6.0, SCENARIO)
    config = TbdConfig(300, two_stage=True)
    merged, _, images, _ = _corner_batch(np.random.default_rng(62), model, config.n_continuing)
    existence = np.linspace(0.2, 0.9, 7)
    batch = tpf_tbd_step(Particles.equally_weighted(merged, existence=existence), model, images,
                         rng=[np.random.default_rng(80 + b) for b in range(7)], config=config,
                         second_rng=[np.random.default_rng(90 + b) for b in range(7)])
    assert isinstance(batch.second_stage, tuple)
    for b in range(7):
        alone = tpf_tbd_step(Particles.equally_weighted(merged[b], existence=float(existence[b])), model, images[b],
                             rng=np.random.default_rng(80 + b), config=config,
                             second_rng=np.random.default_rng(90 + b))
        for got, want in ((batch.posterior.particles[b], alone.posterior.particles), (batch.mean[b], alone.mean),
                          (batch.cov[b], alone.cov), (batch.weighted.log_weights[b], alone.weighted.log_weights),
                          (batch.second_stage[b].record.mu_e, alone.second_stage.record.mu_e),
                          (batch.second_stage[b].record.C_y, alone.second_stage.record.C_y),
                          (batch.second_stage[b].replaced, alone.second_stage.replaced)):
            assert np.array_equal(got, want), b


def test_zeta_one_tpftbd_equals_pftbd_for_the_same_stream():
    model = scenario_model(6.0, SCENARIO)
    seq = simulate(model, SCENARIO, np.random.default_rng(6))
    pf = filter_sequence(seq.images, model, TbdConfig(300), np.random.default_rng(7))
    tpf = filter_sequence(seq.images, model, TbdConfig(300, two_stage=True, zeta=1.0),
                          np.random.default_rng(7), np.random.default_rng(8))
    assert np.array_equal(pf.existence, tpf.existence)
    assert np.array_equal(pf.estimates, tpf.estimates)
    moved = filter_sequence(seq.images, model, TbdConfig(300, two_stage=True, zeta=0.6),
                            np.random.default_rng(7), np.random.default_rng(8))
    assert not np.array_equal(pf.existence, moved.existence)  # ζ < 1 really changes the filter


def test_tpftbd_step_replaces_about_one_minus_zeta_of_the_particles():
    model = scenario_model(9.0, SCENARIO)
    config = TbdConfig(4000, two_stage=True, zeta=0.6)
    rng = np.random.default_rng(9)
    image = model.noise_std * rng.standard_normal((20, 20)) + model.expected_image(np.array([8.0, 0, 12.0, 0, 20.0]))
    belief = Particles.equally_weighted(np.tile([8.0, 0.0, 12.0, 0.0, 20.0], (config.n_continuing, 1)), existence=0.9)
    step = tpf_tbd_step(belief, model, image, rng=rng, config=config, second_rng=np.random.default_rng(10))
    second = step.second_stage
    share = second.replaced.mean()
    assert abs(share - 0.4) <= monte_carlo_atol(np.sqrt(0.4 * 0.6), second.replaced.size)
    pf_mean = np.exp(step.weighted.log_weights) @ step.weighted.particles
    np.testing.assert_allclose(step.mean, 0.6 * pf_mean + 0.4 * second.record.mu_e, rtol=algebra_rtol())
    # the estimate's covariance is that of the mixture the transferred particles are drawn from
    transferred = step.posterior.particles[second.replaced]
    assert np.all(np.abs(transferred.mean(0) - second.record.mu_e)
                  <= monte_carlo_atol(np.sqrt(np.diag(second.record.C_e)), transferred.shape[0]))
    # Weyl: the mixture covariance ζ P + (1 − ζ) P⁺ + ζ (1 − ζ) d dᵀ dominates (1 − ζ) P⁺
    floor = (1 - config.zeta) * np.linalg.eigvalsh(second.record.C_e).min()
    assert np.linalg.eigvalsh(step.cov).min() >= floor * (1 - algebra_rtol(np.linalg.cond(step.cov)))


@pytest.mark.parametrize("two_stage", [False, True])
def test_high_snr_target_is_locked_on(two_stage):
    """Target present in every frame at 15 dB: after a few frames the existence probability
    exceeds 1 − P_d (the evidence beats the prior death rate) and the position error is below a cell."""
    scenario = TbdScenario(frames=16, first_frame=1, last_frame=16)
    model = scenario_model(HIGH_SNR_DB, scenario)
    seq = simulate(model, scenario, np.random.default_rng(11))
    track = filter_sequence(seq.images, model, TbdConfig(1000, two_stage=two_stage),
                            np.random.default_rng(12), np.random.default_rng(13))
    settled = slice(5, None)
    assert np.all(track.existence[settled] > 1 - model.p_death)
    error = np.hypot(*(track.estimates[settled][:, [0, 2]] - seq.truth[settled][:, [0, 2]]).T)
    assert np.sqrt(np.mean(error**2)) < model.cell_size


@pytest.mark.parametrize("two_stage", [False, True])
def test_no_target_existence_stays_low(two_stage):
    """Noise only: the existence probability stays below the chain's stationary value
    P_b / (P_b + P_d) in every frame — the data pull it down."""
    model = scenario_model(HIGH_SNR_DB, SCENARIO)
    seq = simulate(model, SCENARIO, np.random.default_rng(14), target=False)
    track = filter_sequence(seq.images, model, TbdConfig(1000, two_stage=two_stage),
                            np.random.default_rng(15), np.random.default_rng(16))
    assert np.all(track.existence < model.p_birth / (model.p_birth + model.p_death))


def test_snr_conventions():
    model = TbdModel()
    peak = float(model.amplitude(20.0))
    assert np.isclose(20 * np.log10(peak / noise_std_for_snr(6.0, 20.0, model, "peak")), 6.0,
                      rtol=algebra_rtol())
    assert np.isclose(20 * np.log10(20.0 / noise_std_for_snr(6.0, 20.0, model, "intensity")), 6.0,
                      rtol=algebra_rtol())
    with pytest.raises(InputError, match="convention"):
        noise_std_for_snr(6.0, 20.0, model, "rutten")


def test_bad_input_raises_input_error():
    model = TbdModel()
    with pytest.raises(InputError, match="n_particles"):
        TbdConfig(1001)
    with pytest.raises(InputError, match="zeta"):
        TbdConfig(1000, zeta=1.5)
    with pytest.raises(InputError, match="p_birth"):
        replace(model, p_birth=0.0)
    with pytest.raises(InputError, match="images"):
        filter_sequence(np.zeros((3, 10, 10)), model, TbdConfig(10), 0)
    with pytest.raises(InputError, match="second_rng"):
        filter_sequence(np.zeros((3, 20, 20)), model, TbdConfig(10, two_stage=True), 0)
    with pytest.raises(InputError, match="first_frame"):
        TbdScenario(first_frame=25, last_frame=22)
