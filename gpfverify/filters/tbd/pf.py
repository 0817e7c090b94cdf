"""Rutten's PF-TBD step (Rutten, Ristic & Gordon, FUSION 2005; steps ①–⑥ of seed 004 §2).

Given the continuing particles {s_{k−1}^i, w_{k−1}^i}, i = 1 … N_c (conditional on E_{k−1} = 1; Rutten's
filter carries them equally weighted, w_{k−1}^i = 1/N_c, after the resampling of ⑥) and the existence
probability P_{k−1} (``Particles.existence``):

① birth particles s_b^i ~ q_b(· | z_k), i = 1 … N_b (data-driven, see :func:`birth_proposal`),
   unnormalised weights  w̃_b^i = P_b (1 − P_{k−1}) / N_b · L(z_k | s_b^i) · p_b(s_b^i) / q_b(s_b^i);
② continuing particles s_c^i ~ N(F s_{k−1}^i, Q),
   unnormalised weights  w̃_c^i = (1 − P_d) P_{k−1} w_{k−1}^i · L(z_k | s_c^i)
   (= (1 − P_d) P_{k−1} / N_c · L(z_k | s_c^i) for equal weights);
   E_k = 1 says the target is in the observed region (seed 004 §1), so a continuing particle whose
   position left the image is a target that left it: weight 0, and its mass (1 − P_d) P_{k−1} w_{k−1}^i
   joins the absent hypothesis, M_out = Σ_out (1 − P_d) P_{k−1} w_{k−1}^i (the image is noise for it,
   L = 1). Without this, particles off the image, which no pixel can contradict, outlive a lost track
   with a high existence probability (an estimate 14 cells off the image, P_k ≈ 0.6, in 1 of 2000 runs);
③ existence (seed 004 eq. 10), with M_b = Σ w̃_b, M_c = Σ w̃_c:
   P_k = (M_b + M_c) / (M_b + M_c + M_out + P_d P_{k−1} + (1 − P_b)(1 − P_{k−1}));
④ merge the two sets, w^i = w̃^i / (M_b + M_c);
⑤ estimate ŝ_k = Σ w^i s^i, P̂_k = Σ w^i (s^i − ŝ_k)(s^i − ŝ_k)ᵀ (conditional on existence);
⑥ resample N_c particles from the N_b + N_c merged ones
   (:func:`~gpfverify.filters.resampling.systematic_resample` with ``size`` = N_c).

Everything is computed in the log domain (the likelihood ratios of a bright target overflow).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import cast

import numpy as np
from scipy.special import expit

from gpfverify.errors import InputError
from gpfverify.filters import runs
from gpfverify.filters.resampling import (Particles, ParticleStep, ess_from_weights, first_run, log_sum_exp,
                                          moments_from_weights, normalize_log_weights, resample_from_weights,
                                          search_runs, take_particles)
from gpfverify.filters.tbd.model import PatchSpread, TbdModel


@dataclass(frozen=True)
class TbdConfig:
    """Filter settings (not the model).

    n_particles N = N_b + N_c with N_b = N_c = N/2 (seed 004 §3: "N_c = N_b").
    Birth proposal: a cell is *bright* when z > birth_threshold · σ; cells are drawn with
    probability (1 − birth_uniform_share) / n_bright on bright cells plus birth_uniform_share / n²
    everywhere (full support, so the importance weights p_b / q_b are exact).
    Two-stage (TPFTBD): ``zeta`` is the transfer parameter ζ ∈ [0, 1] (ζ = 1: no particle is
    replaced); the second-stage measurement is the (2r+1)² patch, r = second_stage_radius, centred
    on the cell nearest to the PF estimate.
    ``exit_absent``: a continuing particle whose position left the image is a target that left the
    observed region (its mass joins the absent hypothesis, step ②); False keeps it with its weight,
    the image being noise for it (the rule seed 004 does not state, read the other way).
    """

    n_particles: int = 2000
    birth_threshold: float = 1.0
    birth_uniform_share: float = 0.1
    two_stage: bool = False
    zeta: float = 0.6
    second_stage_radius: int = 2
    exit_absent: bool = True

    def __post_init__(self):
        if int(self.n_particles) != self.n_particles or self.n_particles < 2 or self.n_particles % 2:
            raise InputError(f"n_particles must be an even integer >= 2, got {self.n_particles}")
        if not 0.0 < self.birth_uniform_share <= 1.0:
            raise InputError(f"birth_uniform_share must lie in (0, 1], got {self.birth_uniform_share}")
        if not np.isfinite(self.birth_threshold):
            raise InputError(f"birth_threshold must be finite, got {self.birth_threshold}")
        if not 0.0 <= self.zeta <= 1.0:
            raise InputError(f"zeta must lie in [0, 1], got {self.zeta}")
        if int(self.second_stage_radius) != self.second_stage_radius or self.second_stage_radius < 0:
            raise InputError(f"second_stage_radius must be a non-negative integer, got {self.second_stage_radius}")

    @property
    def n_birth(self) -> int:
        return self.n_particles // 2

    @property
    def n_continuing(self) -> int:
        return self.n_particles - self.n_birth


def sample_birth_prior(model: TbdModel, n: int, rng: runs.Streams) -> np.ndarray:
    """n draws from the birth density p_b (uniform position, velocity and intensity), (n, 5) — or
    (B, n, 5), one Generator per run: each column (b − a) u + a, velocities v_max (2u − 1), from
    one block u ~ U[0, 1)^(n×5)."""
    lo, hi = model.image_extent
    vmax = model.velocity_max
    i_lo, i_hi = model.intensity_range
    states = runs.random(rng, (n, 5))
    for column, (scale, shift) in enumerate(((hi - lo, lo), (2.0, -1.0), (hi - lo, lo), (2.0, -1.0),
                                             (i_hi - i_lo, i_lo))):
        states[..., column] *= scale
        states[..., column] += shift
    states[..., 1::2] *= vmax
    return states


def initial_belief(model: TbdModel, config: TbdConfig, rng: runs.Streams) -> Particles:
    """P_0 = 0 (no target before the first frame); the continuing set is a placeholder drawn from
    p_b — with P_0 = 0 its weights are zero. One set per run when ``rng`` is a sequence."""
    particles = sample_birth_prior(model, config.n_continuing, rng)
    existence = 0.0 if particles.ndim == 2 else np.zeros(particles.shape[0])
    return Particles.equally_weighted(particles, existence=existence)


def birth_proposal(model: TbdModel, config: TbdConfig, image: np.ndarray, rng: runs.Streams):
    """Birth particles from the bright cells of ``image`` and log p_b(s)/q_b(s) for each: (N_b, 5)
    and (N_b,), or (B, N_b, 5) and (B, N_b) for the images (B, n, n) of B runs.

    q_b: cell c with probability π_c = (1 − ε) 1[z_c > γσ] / n_bright + ε / n² (ε = birth_uniform_share,
    π_c = 1/n² when no cell is bright), position uniform inside the cell, velocity and intensity
    from p_b. Since p_b puts 1/n² on each cell, p_b/q_b = (1/n²) / π_c.
    """
    n_cells = model.cell_count
    bright = (image > config.birth_threshold * model.noise_std).reshape(image.shape[:-2] + (n_cells,))
    n_bright = np.count_nonzero(bright, axis=-1)
    eps = np.where(n_bright > 0, config.birth_uniform_share, 1.0)
    cell_prob = np.repeat((eps / n_cells)[..., None], n_cells, axis=-1)
    cell_prob += np.where(bright, ((1.0 - eps) / np.maximum(n_bright, 1))[..., None], 0.0)
    states = sample_birth_prior(model, config.n_birth, rng)
    targets = runs.random(rng, (config.n_birth,)) * cell_prob.sum(axis=-1)[..., None]
    cells = np.minimum(search_runs(np.cumsum(cell_prob, axis=-1), targets), n_cells - 1)
    ix, iy = np.divmod(cells, model.grid_size)
    within = runs.random(rng, (config.n_birth, 2)) - 0.5
    states[..., 0] = (ix + within[..., 0]) * model.cell_size
    states[..., 2] = (iy + within[..., 1]) * model.cell_size
    log_ratio = -math.log(n_cells) - np.log(np.take_along_axis(cell_prob, cells, axis=-1))
    return states, log_ratio


def _log(p: np.ndarray) -> np.ndarray:
    """log p, −inf where p = 0."""
    with np.errstate(divide="ignore"):
        return np.log(p)


def pf_tbd_step(belief: Particles, model: TbdModel, image: np.ndarray, *, k: int = 1,
                rng: runs.Streams, config: TbdConfig) -> ParticleStep:
    """Steps ①–⑥ above for one frame ``image`` (n, n); ``k`` is unused (the model is
    time-invariant). The record's ``weighted`` is the merged set of ④ (normalised log weights),
    its ``posterior`` the N_c resampled particles with the existence probability P_k. For B runs:
    particles (B, N_c, 5), existence (B,), images (B, n, n), one Generator per run."""
    return pf_tbd_stage(belief, model, image, rng=rng, config=config)[0]


def pf_tbd_stage(belief: Particles, model: TbdModel, image: np.ndarray, *, rng: runs.Streams,
                 config: TbdConfig) -> tuple[ParticleStep, PatchSpread]:
    """:func:`pf_tbd_step` and the point spread of its merged set (``model.patch_spread`` of
    ``weighted.particles``, all runs' rows in order), which the second stage of TPFTBD reuses."""
    if belief.existence is None:
        raise InputError("belief.existence: PF-TBD needs the existence probability (see initial_belief)")
    if belief.particles.ndim == 2:  # one run: a batch of one
        batch = Particles(belief.particles[None], belief.log_weights[None], existence=np.array([belief.existence]))
        step, spread = pf_tbd_stage(batch, model, image[None], rng=[cast(np.random.Generator, rng)], config=config)
        return first_run(step), spread
    runs.check_streams(rng, belief.particles.shape[:-2])
    prev = np.asarray(belief.existence, dtype=float)[:, None]
    births, log_ratio = birth_proposal(model, config, image, rng)
    continuing = model.propagate(belief.particles, rng)
    merged = np.concatenate([births, continuing], axis=1)
    spread = model.patch_spread(merged.reshape(-1, merged.shape[-1]))
    log_w = model.log_likelihood_ratio(merged, image, spread)
    log_w[:, :config.n_birth] += log_ratio + _log(model.p_birth * (1.0 - prev) / config.n_birth)
    # log(N_c w^i_{k−1}) is exactly 0 for the equally weighted set Rutten's filter carries
    n_prev = belief.size
    log_prior = _log((1.0 - model.p_death) * prev / n_prev) + (normalize_log_weights(belief.log_weights)
                                                               + math.log(n_prev))
    left = ~model.in_image(continuing) if config.exit_absent else np.zeros(continuing.shape[:-1], dtype=bool)
    log_w[:, config.n_birth:] += np.where(left, -math.inf, log_prior)
    log_mass = log_sum_exp(log_w)
    log_stay = _log(model.p_death * prev + (1.0 - model.p_birth) * (1.0 - prev))
    log_out = np.asarray(log_sum_exp(np.where(left, log_prior, -math.inf)))  # log M_out, −inf if none left
    log_absent = log_sum_exp(np.concatenate([log_stay, log_out[:, None]], axis=1))
    existence = expit(log_mass - log_absent)
    lost = log_mass == -math.inf  # P_{k−1} = 1 and every particle left: P_k = 0, the births kept as drawn
    log_w[lost, :config.n_birth] = 0.0
    log_mass = np.where(lost, math.log(config.n_birth), log_mass)
    log_w -= log_mass[:, None]
    mean, cov = moments_from_weights(merged, np.exp(log_w))
    # systematic_resample and effective_sample_size of log_w, from one normalisation
    weights = np.exp(normalize_log_weights(log_w))
    resampled = take_particles(merged, resample_from_weights(weights, rng, size=config.n_continuing))
    step = ParticleStep(Particles.equally_weighted(resampled, existence=existence),
                        Particles(merged, log_w, existence=existence), mean, cov,
                        ess_from_weights(weights), np.ones(existence.shape, dtype=bool))
    return step, spread
